#include "clutterseg/drivers/replay/pcd_directory_source.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "clutterseg/core/param_check.h"
#include "clutterseg/core/text_and_color.h"
#include "clutterseg/io/pcd.h"

namespace clutterseg::drivers {
namespace fs = std::filesystem;

namespace internal {

void NaturalSort(std::vector<std::string>* names) {
  std::sort(names->begin(), names->end(),
            [](const std::string& a, const std::string& b) { return core::NaturalLess(a, b); });
}

std::string ScalingProblem(const core::CameraIntrinsics& k, int width, int height) {
  if (width == k.width && height == k.height) return "";
  // Aspect ratios within 1% (e.g. 640x480 and 320x240, or 1280x960) scale; others are
  // another sensor mode or a crop whose intrinsics cannot be derived by scaling.
  const double a = static_cast<double>(width) * k.height;
  const double b = static_cast<double>(height) * k.width;
  if (width > 0 && height > 0 && std::abs(a - b) <= 0.01 * std::max(a, b)) return "";
  return "the frame is " + std::to_string(width) + "x" + std::to_string(height) +
         " but the intrinsics are for " + std::to_string(k.width) + "x" + std::to_string(k.height) +
         ", another aspect ratio";
}

}  // namespace internal

void PcdDirectorySourceOptions::ValidateOrThrow() const {
  const core::ParamCheck check("source.pcd");
  check.NonEmpty("path", path, "a directory or a .pcd file");
  check.Positive("frame_period_us", frame_period_us, "us");
  if (!estimate_intrinsics) intrinsics.ValidateOrThrow();
  limits.ValidateOrThrow("limits");
}

core::CameraIntrinsics EstimateIntrinsics(const core::PointCloud& cloud, double* rms_px) {
  if (!cloud.organized() || cloud.width <= 1 ||
      cloud.xyz.size() != static_cast<size_t>(cloud.width) * cloud.height) {
    throw std::runtime_error("cannot estimate intrinsics from an unorganized cloud");
  }
  // Per axis: minimise sum (fx * a + cx - u)^2 with a = x / z (and likewise for v).
  double sa = 0, saa = 0, su = 0, sau = 0;
  double sb = 0, sbb = 0, sv = 0, sbv = 0;
  double n = 0;
  int min_u = std::numeric_limits<int>::max(), max_u = -1;
  int min_v = std::numeric_limits<int>::max(), max_v = -1;
  for (int v = 0; v < cloud.height; ++v) {
    for (int u = 0; u < cloud.width; ++u) {
      const core::Vec3f& p = cloud.xyz[static_cast<size_t>(v) * cloud.width + u];
      if (!core::IsValid(p) || !(p.z > 0.f)) continue;
      const double a = double{p.x} / p.z;
      const double b = double{p.y} / p.z;
      sa += a;
      saa += a * a;
      su += u;
      sau += a * u;
      sb += b;
      sbb += b * b;
      sv += v;
      sbv += b * v;
      n += 1;
      min_u = std::min(min_u, u);
      max_u = std::max(max_u, u);
      min_v = std::min(min_v, v);
      max_v = std::max(max_v, v);
    }
  }
  if (n < 16) {
    throw std::runtime_error("cannot estimate intrinsics: only " + std::to_string(int(n)) +
                             " finite points");
  }
  if (max_u <= min_u || max_v <= min_v) {
    throw std::runtime_error(
        "cannot estimate intrinsics: the finite points span one row or "
        "column only");
  }
  const double det_u = n * saa - sa * sa;
  const double det_v = n * sbb - sb * sb;
  if (!(std::abs(det_u) > 1e-12 * n * n) || !(std::abs(det_v) > 1e-12 * n * n)) {
    throw std::runtime_error("cannot estimate intrinsics: degenerate point directions");
  }
  core::CameraIntrinsics k;
  k.width = cloud.width;
  k.height = cloud.height;
  k.fx = (n * sau - sa * su) / det_u;
  k.cx = (su - k.fx * sa) / n;
  k.fy = (n * sbv - sb * sv) / det_v;
  k.cy = (sv - k.fy * sb) / n;
  if (!(k.fx > 0.0) || !(k.fy > 0.0) || !std::isfinite(k.cx) || !std::isfinite(k.cy)) {
    std::ostringstream os;
    os << "cannot estimate intrinsics: the fit gave " << k.ToString()
       << " (the cloud is not a pinhole image)";
    throw std::runtime_error(os.str());
  }
  if (rms_px != nullptr) {
    double sq = 0;
    for (int v = 0; v < cloud.height; ++v) {
      for (int u = 0; u < cloud.width; ++u) {
        const core::Vec3f& p = cloud.xyz[static_cast<size_t>(v) * cloud.width + u];
        if (!core::IsValid(p) || !(p.z > 0.f)) continue;
        const double du = k.fx * p.x / p.z + k.cx - u;
        const double dv = k.fy * p.y / p.z + k.cy - v;
        sq += du * du + dv * dv;
      }
    }
    *rms_px = std::sqrt(sq / n);
  }
  return k;
}

void CloudToDepth(const core::PointCloud& cloud, const core::CameraIntrinsics& k,
                  core::DepthImage* depth, core::ColorImage* color) {
  auto to_mm = [](float z) -> uint16_t {
    if (!std::isfinite(z) || !(z > 0.f)) return 0;
    const double mm = std::round(double{z} * 1000.0);
    return mm > 65535.0 ? uint16_t{0} : static_cast<uint16_t>(mm);
  };
  const bool with_color = cloud.has_color() && cloud.rgba.size() == cloud.xyz.size();
  if (cloud.organized()) {
    depth->width = cloud.width;
    depth->height = cloud.height;
    depth->data.resize(cloud.xyz.size());
    for (size_t i = 0; i < cloud.xyz.size(); ++i) {
      const core::Vec3f& p = cloud.xyz[i];
      depth->data[i] = core::IsValid(p) ? to_mm(p.z) : uint16_t{0};
    }
    if (with_color) {
      color->width = cloud.width;
      color->height = cloud.height;
      color->data.resize(cloud.rgba.size());
      for (size_t i = 0; i < cloud.rgba.size(); ++i)
        color->data[i] = core::UnpackRgba(cloud.rgba[i]);
    } else {
      color->Reset(0, 0);
    }
    return;
  }
  depth->Reset(k.width, k.height, 0);
  if (with_color) {
    color->Reset(k.width, k.height);
  } else {
    color->Reset(0, 0);
  }
  for (size_t i = 0; i < cloud.xyz.size(); ++i) {
    const core::Vec3f& p = cloud.xyz[i];
    if (!core::IsValid(p) || !(p.z > 0.f)) continue;
    const double uf = std::round(k.fx * p.x / p.z + k.cx);
    const double vf = std::round(k.fy * p.y / p.z + k.cy);
    if (!(uf >= 0 && vf >= 0 && uf < k.width && vf < k.height)) continue;
    const int u = static_cast<int>(uf);
    const int v = static_cast<int>(vf);
    const uint16_t mm = to_mm(p.z);
    uint16_t& d = depth->at(u, v);
    if (mm != 0 && (d == 0 || mm < d)) {
      d = mm;
      if (with_color) color->at(u, v) = core::UnpackRgba(cloud.rgba[i]);
    }
  }
}

PcdDirectorySource::PcdDirectorySource(const PcdDirectorySourceOptions& options)
    : options_(options) {
  options_.ValidateOrThrow();
}

void PcdDirectorySource::Open() {
  Close();
  std::error_code ec;
  const fs::path root(options_.path);
  if (fs::is_directory(root, ec)) {
    for (const fs::directory_entry& e : fs::directory_iterator(root, ec)) {
      if (!e.is_regular_file()) continue;
      if (core::HasExtension(e.path().filename().string(), ".pcd")) {
        files_.push_back(e.path().string());
      }
    }
    if (ec) {
      throw std::runtime_error("PCD directory source: cannot list '" + options_.path +
                               "': " + ec.message());
    }
    internal::NaturalSort(&files_);
  } else if (fs::is_regular_file(root, ec)) {
    files_.push_back(root.string());
  } else {
    throw std::runtime_error("PCD directory source: '" + options_.path +
                             "' is neither a directory nor a file");
  }
  if (files_.empty()) {
    throw std::runtime_error("PCD directory source: no .pcd files in '" + options_.path + "'");
  }
  if (options_.estimate_intrinsics) {
    // The first readable organized file that gives plausible intrinsics; the files skipped
    // here are skipped (and counted) again by Read().
    io::ReadLimits limits;
    static_cast<core::FrameLimits&>(limits) = options_.limits;
    std::string first_problem;
    bool found = false;
    for (const std::string& file : files_) {
      try {
        io::ReadPcd(file, limits, &cloud_);
        if (!cloud_.organized()) continue;
        intrinsics_ = EstimateIntrinsics(cloud_, &fit_rms_px_);
        intrinsics_.ValidateOrThrow("intrinsics");
        found = true;
        break;
      } catch (const std::exception& e) {
        if (first_problem.empty()) first_problem = std::string(": ") + e.what();
      }
    }
    cloud_ = core::PointCloud{};
    if (!found) {
      const std::string path = options_.path;
      files_.clear();
      throw std::runtime_error("PCD directory source: " + path +
                               ": no readable organized cloud gives plausible intrinsics" +
                               first_problem + "; give the intrinsics explicitly");
    }
  } else {
    intrinsics_ = options_.intrinsics;
  }
  counters_.SetFramesInSource(static_cast<int64_t>(files_.size()));
  next_ = 0;
  sequence_ = 0;
  error_.clear();
  open_ = true;
}

core::ReadStatus PcdDirectorySource::Read(int /*timeout_ms*/, core::RgbdFrame* frame) {
  if (!open_) {
    error_ = "Read() on a closed source";
    return core::ReadStatus::kError;
  }
  io::ReadLimits limits;
  static_cast<core::FrameLimits&>(limits) = options_.limits;
  core::PointCloud& cloud = frame->cloud;
  // Bad files are skipped; at most one pass over the directory per call.
  for (size_t tries = 0; tries < files_.size(); ++tries) {
    if (next_ >= files_.size()) {
      if (!options_.loop) return core::ReadStatus::kEndOfStream;
      next_ = 0;
    }
    const std::string& file = files_[next_++];
    if (next_ == files_.size()) counters_.PassCompleted();
    try {
      io::ReadPcd(file, limits, &cloud);  // reuses the frame's buffers
    } catch (const core::FrameTooLargeError& e) {
      counters_.Skipped(core::SkipReason::kTooLarge, e.what());
      continue;
    } catch (const std::exception& e) {
      counters_.Skipped(core::SkipReason::kUnreadable, e.what());
      continue;
    }
    if (cloud.organized()) {
      const std::string problem = internal::ScalingProblem(intrinsics_, cloud.width, cloud.height);
      if (!problem.empty()) {
        counters_.Skipped(core::SkipReason::kSizeMismatch, file + ": " + problem);
        continue;
      }
      frame->intrinsics = cloud.width == intrinsics_.width && cloud.height == intrinsics_.height
                              ? intrinsics_
                              : intrinsics_.Scaled(cloud.width, cloud.height);
    } else {
      frame->intrinsics = intrinsics_;
    }
    // The cloud is what gets segmented; its depth image serves display and recording.
    CloudToDepth(cloud, frame->intrinsics, &frame->depth, &frame->color);
    core::StampReplayFrame(sequence_++, options_.frame_period_us, options_.camera_name, frame);
    counters_.Delivered(cloud.CountValid() == 0);
    return core::ReadStatus::kOk;
  }
  if (next_ >= files_.size() && !options_.loop) return core::ReadStatus::kEndOfStream;
  error_ = "PCD directory source: no file of '" + options_.path + "' can be read (" +
           counters_.Snapshot().ToString() + ")";
  return core::ReadStatus::kError;
}

void PcdDirectorySource::Close() {
  open_ = false;
  files_.clear();
  next_ = 0;
}

std::string PcdDirectorySource::Describe() const {
  std::ostringstream os;
  os << "pcd:" << options_.path;
  if (!open_) return os.str() + " (closed)";
  os << " (" << files_.size() << " file" << (files_.size() == 1 ? "" : "s") << ", intrinsics "
     << intrinsics_.ToString();
  if (options_.estimate_intrinsics) os << " fitted, rms " << fit_rms_px_ << " px";
  if (options_.loop) os << ", loop";
  os << ")";
  return os.str();
}

}  // namespace clutterseg::drivers
