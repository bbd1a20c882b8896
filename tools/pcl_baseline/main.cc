// clutterseg-pcl-baseline: segments PCD files with PCL's supervoxels + LCCP or with PCL's
// organized planes + Euclidean clusters, writing organized labelled PCDs and per-frame times.

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>
#include <pcl/console/print.h>

#include "clutterseg/core/text_and_color.h"
#include "tools/pcl_baseline/pcl_baseline.h"

namespace clutterseg::pcl_baseline {
namespace {

namespace fs = std::filesystem;

std::string JsonEscape(const std::string& s) {
  std::string out;
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\u%04x", c);
      out += buf;
    } else {
      out += c;
    }
  }
  return out;
}

std::string TimesJson(const std::string& file, Method method, const FrameReport& r) {
  const bool lccp = method == Method::kLccp;
  const std::string name = JsonEscape(file);
  std::vector<char> buf(name.size() + 512);
  std::snprintf(buf.data(), buf.size(),
                "{\"file\":\"%s\",\"method\":\"%s\",\"%s\":%.3f,\"%s\":%.3f,\"total_ms\":%.3f,"
                "\"total_cpu_ms\":%.3f,"
                "\"%s\":%zu,\"segments\":%zu,\"valid_points\":%zu,\"labelled_points\":%zu}",
                name.c_str(), MethodName(method).c_str(), lccp ? "supervoxels_ms" : "planes_ms",
                r.stage1_ms, lccp ? "lccp_ms" : "clusters_ms", r.stage2_ms, r.total_ms,
                r.total_cpu_ms, lccp ? "supervoxels" : "planes", r.intermediate_count,
                r.segment_count, r.valid_points, r.labelled_points);
  return buf.data();
}

int Run(int argc, char** argv) {
  CLI::App app{
      "Segments organized PCD files with PCL (supervoxels + LCCP, or organized planes + "
      "Euclidean clusters) and writes PCDs with fields x y z rgba label (0 = no segment), "
      "same size and point order as the input. IN and OUT are files, or directories in which "
      "case every *.pcd in IN is processed into OUT under the same name."};
  std::string in;
  std::string out;
  std::string method_name = "lccp";
  std::string times_path;
  bool no_extended = false;
  bool no_sanity = false;
  bool quiet = false;
  BaselineParams params;
  app.add_option("IN", in, "input PCD file or directory")->required();
  app.add_option("OUT", out, "output PCD file or directory")->required();
  app.add_option("--method", method_name, "lccp | planes-clusters")
      ->check(CLI::IsMember({"lccp", "planes-clusters"}))
      ->capture_default_str();
  app.add_option("--voxel", params.voxel_resolution_m, "voxel resolution [m]")
      ->capture_default_str();
  app.add_option("--seed", params.seed_resolution_m, "seed resolution [m]")->capture_default_str();
  app.add_option("--color", params.color_importance, "colour importance")->capture_default_str();
  app.add_option("--spatial", params.spatial_importance, "spatial importance")
      ->capture_default_str();
  app.add_option("--normal", params.normal_importance, "normal importance")->capture_default_str();
  app.add_flag("--single-camera-transform", params.use_single_camera_transform,
               "voxelize in the depth-dependent space (PCL example's -tvoxel)");
  app.add_option("--concavity", params.concavity_tolerance_deg, "concavity tolerance [deg]")
      ->capture_default_str();
  app.add_option("--smoothness", params.smoothness_threshold, "LCCP smoothness threshold [0,1]")
      ->capture_default_str();
  app.add_flag("--no-extended", no_extended, "disable LCCP extended convexity");
  app.add_flag("--no-sanity", no_sanity, "disable LCCP sanity criterion");
  app.add_option("--min-segment", params.min_segment_supervoxels,
                 "LCCP minimum segment size [supervoxels] (0 = no merging)")
      ->capture_default_str();
  app.add_option("--plane-min-inliers", params.plane_min_inliers,
                 "planes-clusters: points for a plane to be excluded")
      ->capture_default_str();
  app.add_option("--plane-angle", params.plane_angular_threshold_deg,
                 "planes-clusters: plane angular threshold [deg]")
      ->capture_default_str();
  app.add_option("--plane-distance", params.plane_distance_threshold_m,
                 "planes-clusters: plane distance threshold [m]")
      ->capture_default_str();
  app.add_option("--cluster-distance", params.cluster_distance_threshold_m,
                 "planes-clusters: neighbour distance threshold [m]")
      ->capture_default_str();
  app.add_option("--min-cluster", params.min_cluster_points,
                 "planes-clusters: minimum cluster size [points]")
      ->capture_default_str();
  app.add_option("--times", times_path, "write per-frame times as JSON lines to this file");
  app.add_flag("--quiet", quiet, "no per-frame progress on stderr");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  params.method = ParseMethod(method_name);
  params.use_extended_convexity = !no_extended;
  params.use_sanity_criterion = !no_sanity;
  params.ValidateOrThrow();
  pcl::console::setVerbosityLevel(pcl::console::L_ERROR);

  std::vector<std::pair<fs::path, fs::path>> jobs;
  if (fs::is_directory(in)) {
    std::vector<std::string> names;
    for (const fs::directory_entry& e : fs::directory_iterator(in)) {
      if (e.is_regular_file() && e.path().extension() == ".pcd") {
        names.push_back(e.path().filename().string());
      }
    }
    // Natural order (learn2 before learn10) so outputs and times follow frame numbers.
    std::sort(names.begin(), names.end(),
              [](const std::string& a, const std::string& b) { return core::NaturalLess(a, b); });
    if (names.empty()) throw std::runtime_error("no *.pcd files in directory '" + in + "'");
    fs::create_directories(out);
    for (const std::string& n : names) jobs.emplace_back(fs::path(in) / n, fs::path(out) / n);
  } else {
    if (!fs::exists(in)) throw std::runtime_error("input '" + in + "' does not exist");
    jobs.emplace_back(in, out);
  }

  std::ofstream times;
  if (!times_path.empty()) {
    times.open(times_path, std::ios::trunc);
    if (!times) throw std::runtime_error("cannot open times file '" + times_path + "'");
  }
  for (const auto& [src, dst] : jobs) {
    const FrameReport r = SegmentPcdFile(src, dst, params);
    const std::string line = TimesJson(src.filename().string(), params.method, r);
    if (times) {
      times << line << '\n';
      times.flush();
    }
    if (!quiet) std::cerr << line << '\n';
  }
  return 0;
}

}  // namespace
}  // namespace clutterseg::pcl_baseline

int main(int argc, char** argv) {
  try {
    return clutterseg::pcl_baseline::Run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "clutterseg-pcl-baseline: error: " << e.what() << '\n';
    return 1;
  }
}
