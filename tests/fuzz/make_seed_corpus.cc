// Writes the seed corpora of the fuzz targets (tests/fuzz/corpus/<target>/) with the
// project's own writers: tiny PCDs in each encoding, depth and colour PNGs, configuration
// texts, ONI recordings, segmenter frames, LCM logs as the daemon writes them and labelled
// PCDs as clutterseg-segment writes them. Usage: fuzz_make_seed_corpus <corpus_dir>.
// Regression inputs found by fuzzing live beside the seeds and are not touched.

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/types.h"
#include "clutterseg/daemon/daemon_config.h"
#include "clutterseg/daemon/lcm_log_file.h"
#include "clutterseg/daemon/messages.h"
#include "clutterseg/drivers/oni/oni_writer.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/io/png_io.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/pipeline/segmentation_result.h"
#include "clutterseg/status_t.hpp"

namespace clutterseg::fuzz {
namespace {

namespace fs = std::filesystem;

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

void WriteBytes(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

// A tabletop in millimetres: a plane tilted away from the camera with a box on it.
core::DepthImage Tabletop(int width, int height) {
  core::DepthImage depth(width, height, 0);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      double z = 1400.0 - 600.0 * v / std::max(1, height - 1);
      if (u > width / 3 && u < 2 * width / 3 && v > height / 4 && v < height / 2) z -= 120.0;
      depth.at(u, v) = static_cast<uint16_t>(z);
    }
  }
  depth.at(0, 0) = 0;  // one invalid pixel
  return depth;
}

core::ColorImage Colors(int width, int height) {
  core::ColorImage color(width, height);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      color.at(u, v) = core::Rgb8{static_cast<uint8_t>(u * 40), static_cast<uint8_t>(v * 40),
                                  static_cast<uint8_t>(u * v)};
    }
  }
  return color;
}

void MakePcd(const fs::path& dir) {
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics().Scaled(4, 3);
  const core::DepthImage depth = Tabletop(4, 3);
  const core::ColorImage color = Colors(4, 3);
  core::PointCloud organized;
  core::DepthToPointCloud(depth, k, &color, &organized);
  organized.label.assign(organized.size(), 0);
  for (size_t i = 0; i < organized.size(); ++i) organized.label[i] = static_cast<uint32_t>(i % 3);
  core::PointCloud flat;
  flat.width = 5;
  flat.height = 1;
  for (int i = 0; i < 5; ++i) flat.xyz.push_back(core::Vec3f{0.1f * i, -0.2f, 1.f + 0.01f * i});
  const struct {
    const char* name;
    io::PcdEncoding encoding;
  } encodings[] = {{"ascii", io::PcdEncoding::kAscii},
                   {"binary", io::PcdEncoding::kBinary},
                   {"compressed", io::PcdEncoding::kBinaryCompressed}};
  for (const auto& e : encodings) {
    io::WritePcd((dir / (std::string("organized_") + e.name + ".pcd")).string(), organized,
                 e.encoding);
    io::WritePcd((dir / (std::string("unorganized_") + e.name + ".pcd")).string(), flat,
                 e.encoding);
  }
  // Hand-written headers for the layouts WritePcd does not produce: packed rgb, a label of
  // another size, an extra field with COUNT > 1, a v0.5-style header and an empty cloud.
  WriteText(dir / "rgb_u16label_ascii.pcd",
            "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb label\nSIZE 4 4 4 4 2\n"
            "TYPE F F F F U\nCOUNT 1 1 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
            "POINTS 2\nDATA ascii\n0.1 0.2 1.0 4.2108e+06 7\nnan nan nan 0 0\n");
  WriteText(dir / "extra_field_ascii.pcd",
            "VERSION .7\nFIELDS normal_x z y x intensity\nSIZE 4 4 4 4 4\nTYPE F F F F F\n"
            "COUNT 3 1 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n"
            "0 0 1 1.5 0.25 -0.5 9\n");
  WriteText(dir / "v05_ascii.pcd",
            "VERSION .5\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\n"
            "HEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n");
  WriteText(dir / "empty_binary.pcd",
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 0\n"
            "HEIGHT 1\nPOINTS 0\nDATA binary\n");
}

void MakePng(const fs::path& dir) {
  io::WriteDepthPng((dir / "depth_4x3.png").string(), Tabletop(4, 3));
  io::WriteDepthPng((dir / "depth_1x1.png").string(), core::DepthImage(1, 1, 65535));
  io::WriteColorPng((dir / "color_4x3.png").string(), Colors(4, 3));
}

void MakeConfig(const fs::path& dir) {
  WriteText(dir / "defaults.yaml", daemon::ConfigToYaml(daemon::DaemonConfig{}));
  WriteText(dir / "empty.yaml", "");
  WriteText(dir / "partial.yaml",
            "source: synthetic\nspeed: max\nprocessing:\n  threads: 2\n  max_frames: 10\n"
            "segmenter:\n  supervoxel:\n    voxel_resolution_m: 0.008\n");
  WriteText(dir / "flow.yaml", "{source: rec.oni, loop: true, lcm: {url: 'memq://'}}\n");
  WriteText(dir / "anchors.yaml", "base: &b {threads: 1}\nprocessing: *b\n");
}

void MakeOni(const fs::path& dir) {
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics().Scaled(8, 6);
  for (const bool with_color : {false, true}) {
    drivers::OniWriter writer;
    const fs::path path = dir / (with_color ? "rgbd_8x6.oni" : "depth_8x6.oni");
    writer.Open(path.string(), 8, 6, 30, k, with_color);
    const core::ColorImage color = Colors(8, 6);
    for (int f = 0; f < 2; ++f) {
      writer.WriteFrame(Tabletop(8, 6), with_color ? &color : nullptr, 33333 * f);
    }
    writer.Close();
  }
}

// Segmenter inputs: width-1 and height-1 as uint16 LE, a focal scale byte, then depths.
std::vector<uint8_t> SegmenterInput(const core::DepthImage& depth, uint8_t focal) {
  const int w = depth.width - 1;
  const int h = depth.height - 1;
  std::vector<uint8_t> bytes = {static_cast<uint8_t>(w & 0xff), static_cast<uint8_t>(w >> 8),
                                static_cast<uint8_t>(h & 0xff), static_cast<uint8_t>(h >> 8),
                                focal};
  for (const uint16_t d : depth.data) {
    bytes.push_back(static_cast<uint8_t>(d & 0xff));
    bytes.push_back(static_cast<uint8_t>(d >> 8));
  }
  return bytes;
}

void MakeSegmenter(const fs::path& dir) {
  WriteBytes(dir / "tabletop_40x30.bin", SegmenterInput(Tabletop(40, 30), 48));
  WriteBytes(dir / "tabletop_80x60.bin", SegmenterInput(Tabletop(80, 60), 48));
  WriteBytes(dir / "invalid_16x12.bin", SegmenterInput(core::DepthImage(16, 12, 0), 48));
  WriteBytes(dir / "wall_32x24.bin", SegmenterInput(core::DepthImage(32, 24, 900), 48));
  WriteBytes(dir / "far_8x8.bin", SegmenterInput(core::DepthImage(8, 8, 65535), 48));
}

// Segmenter configurations (the `segmenter:` section clutterseg-segment and the Python
// binding read): the defaults as the daemon writes them, and a few keys in flow style.
void MakeSegmenterConfig(const fs::path& dir) {
  WriteText(dir / "defaults.yaml", daemon::ConfigToYaml(daemon::DaemonConfig{}));
  WriteText(dir / "few_keys.yaml",
            "segmenter:\n  points: {min_depth_m: 0.5, max_depth_m: 2.0}\n  support:\n"
            "    enabled: false\n");
  WriteText(dir / "empty_section.yaml", "segmenter: {}\n");
}

// A frame's messages as the daemon publishes them: objects_t with two objects and the
// label_image_t of the same frame.
template <typename Message>
void WriteEvent(daemon::LcmLogFile* log, const std::string& channel, const Message& msg) {
  std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  if (!log->Write(channel, bytes.data(), bytes.size())) {
    throw std::runtime_error("cannot write " + log->path() + ": " + log->last_error());
  }
}

// LCM logs written by the daemon's own writer (daemon::LcmLogFile): two frames with each
// label compression, a status_t, and the same log cut in the middle of its last event.
void MakeLcmLog(const fs::path& dir) {
  const daemon::LabelCompression compressions[] = {daemon::LabelCompression::kNone,
                                                   daemon::LabelCompression::kRle,
                                                   daemon::LabelCompression::kZlib};
  for (const daemon::LabelCompression compression : compressions) {
    const fs::path path =
        dir / (std::string("two_frames_") + daemon::ToString(compression) + ".lcmlog");
    {
      daemon::FileLogUrl url;
      url.path = path.string();
      daemon::LcmLogFile log(url);
      for (int f = 0; f < 2; ++f) {
        pipeline::SegmentationResult r;
        r.width = 8;
        r.height = 6;
        r.labels = core::LabelImage(8, 6, 0);
        for (uint32_t id = 1; id <= 2; ++id) {
          pipeline::Object o;
          o.id = id;
          o.num_points = 6;
          o.centroid = {0.1f * static_cast<float>(id), 0.0f, 1.0f + 0.01f * static_cast<float>(f)};
          o.aabb_min = o.centroid;
          o.aabb_max = o.centroid;
          r.objects.push_back(o);
          for (int u = 0; u < 3; ++u) {
            for (int v = 0; v < 2; ++v) r.labels.at(static_cast<int>(id) * 3 - 3 + u, v + 2) = id;
          }
        }
        daemon::FrameInfo info;
        info.frame_seq = f;
        info.utime = 1000000 + 33333 * f;
        info.camera_name = "camera";
        info.intrinsics = core::DefaultKinectIntrinsics().Scaled(8, 6);
        clutterseg::objects_t objects;
        daemon::ToObjectsMessage(r, info, &objects);
        clutterseg::label_image_t labels;
        daemon::EncodeLabelImage(r.labels, info, compression, &labels);
        WriteEvent(&log, "CLUTTERSEG_OBJECTS", objects);
        WriteEvent(&log, "CLUTTERSEG_LABELS", labels);
      }
      clutterseg::status_t status;
      status.camera_name = "camera";
      status.frames_captured = status.frames_processed = status.frames_published = 2;
      WriteEvent(&log, "CLUTTERSEG_STATUS", status);
    }
    if (compression == daemon::LabelCompression::kRle) {
      const auto size = fs::file_size(path);
      fs::copy_file(path, dir / "torn_end.lcmlog", fs::copy_options::overwrite_existing);
      fs::resize_file(dir / "torn_end.lcmlog", size - 7);
    }
  }
}

// Labelled clouds as clutterseg-segment writes them (x y z rgba label) and as ground truth
// comes (x y z label): organized and not, ascii and binary.
void MakeEvalLabels(const fs::path& dir) {
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics().Scaled(8, 6);
  core::PointCloud cloud;
  core::DepthToPointCloud(Tabletop(8, 6), k, nullptr, &cloud);
  cloud.label.resize(cloud.xyz.size());
  for (size_t i = 0; i < cloud.label.size(); ++i)
    cloud.label[i] = static_cast<uint32_t>(i % 5) * 10;
  io::WritePcd((dir / "labels_organized_ascii.pcd").string(), cloud, io::PcdEncoding::kAscii);
  for (size_t i = 0; i < cloud.label.size(); ++i) cloud.label[i] = static_cast<uint32_t>(i % 3);
  cloud.rgba.assign(cloud.xyz.size(), 0xFF808080u);
  io::WritePcd((dir / "labels_rgba_binary.pcd").string(), cloud, io::PcdEncoding::kBinary);
  WriteText(dir / "labels_nan_ascii.pcd",
            "VERSION .7\nFIELDS x y z label\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
            "WIDTH 3\nHEIGHT 1\nPOINTS 3\nDATA ascii\n0 0 1 1\nnan nan nan 1\n0.1 0 1 2\n");
}

}  // namespace
}  // namespace clutterseg::fuzz

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <corpus_dir>\n", argv[0]);
    return 2;
  }
  try {
    const fs::path root(argv[1]);
    const struct {
      const char* target;
      void (*make)(const fs::path&);
    } targets[] = {{"pcd_reader", clutterseg::fuzz::MakePcd},
                   {"depth_png", clutterseg::fuzz::MakePng},
                   {"config_parser", clutterseg::fuzz::MakeConfig},
                   {"oni_reader", clutterseg::fuzz::MakeOni},
                   {"segmenter", clutterseg::fuzz::MakeSegmenter},
                   {"segmenter_config", clutterseg::fuzz::MakeSegmenterConfig},
                   {"lcm_log", clutterseg::fuzz::MakeLcmLog},
                   {"eval_labels", clutterseg::fuzz::MakeEvalLabels}};
    for (const auto& t : targets) {
      fs::create_directories(root / t.target);
      t.make(root / t.target);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
