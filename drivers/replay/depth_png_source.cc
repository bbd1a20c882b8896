#include "clutterseg/drivers/replay/depth_png_source.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <sstream>
#include <stdexcept>

#include "clutterseg/core/param_check.h"
#include "clutterseg/core/text_and_color.h"
#include "clutterseg/drivers/replay/pcd_directory_source.h"
#include "clutterseg/io/png_io.h"

namespace clutterseg::drivers {
namespace fs = std::filesystem;
namespace {

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::vector<std::string> ListFiles(const fs::path& dir, const std::string& ext) {
  std::vector<std::string> out;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return out;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
    if (e.is_regular_file() && core::HasExtension(e.path().filename().string(), ext)) {
      out.push_back(e.path().filename().string());
    }
  }
  internal::NaturalSort(&out);
  return out;
}

bool IsFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

}  // namespace

void DepthPngSourceOptions::ValidateOrThrow() const {
  const core::ParamCheck check("source.depth_png");
  check.NonEmpty("directory", directory, "a directory");
  check.Require(depth_scale_to_mm > 0.0 && depth_scale_to_mm < 1000.0, "depth_scale_to_mm",
                depth_scale_to_mm, "(0, 1000)");
  check.Positive("frame_period_us", frame_period_us, "us");
  intrinsics.ValidateOrThrow();
  limits.ValidateOrThrow("limits");
}

DepthPngSource::DepthPngSource(const DepthPngSourceOptions& options) : options_(options) {
  options_.ValidateOrThrow();
}

void DepthPngSource::Open() {
  Close();
  const fs::path dir(options_.directory);
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    throw std::runtime_error("depth PNG source: '" + options_.directory + "' is not a directory");
  }
  std::vector<Entry> entries;
  // Split layout: depth/NAME.png with colour in a sibling directory.
  const std::vector<std::string> split = ListFiles(dir / "depth", ".png");
  if (!split.empty()) {
    for (const std::string& name : split) {
      Entry e;
      e.depth = (dir / "depth" / name).string();
      for (const char* sub : {"color", "rgb", "image", "image_color"}) {
        if (IsFile(dir / sub / name)) {
          e.color = (dir / sub / name).string();
          break;
        }
      }
      entries.push_back(e);
    }
  } else {
    for (const std::string& name : ListFiles(dir, ".png")) {
      const std::string lower = Lower(name);
      const size_t at = lower.rfind("depth");
      if (at == std::string::npos) continue;
      Entry e;
      e.depth = (dir / name).string();
      for (const char* word : {"color", "rgb", "image"}) {
        std::string cname = name;
        cname.replace(at, 5, word);
        if (IsFile(dir / cname)) {
          e.color = (dir / cname).string();
          break;
        }
      }
      entries.push_back(e);
    }
  }
  if (entries.empty()) {
    throw std::runtime_error("depth PNG source: no depth PNGs in '" + options_.directory +
                             "' (expected *depth*.png or depth/*.png)");
  }
  std::string json = options_.intrinsics_json;
  if (json.empty()) {
    const std::vector<std::string> jsons = ListFiles(dir, ".json");
    if (jsons.size() == 1) json = (dir / jsons.front()).string();
    if (jsons.size() > 1) {
      std::string names;
      for (const std::string& name : jsons) {
        names += (names.empty() ? "'" : ", '") + (dir / name).string() + "'";
      }
      throw std::runtime_error("depth PNG source: '" + options_.directory + "' holds " +
                               std::to_string(jsons.size()) + " intrinsics files (" + names +
                               "): choose one (intrinsics_json)");
    }
  }
  if (!json.empty()) {
    intrinsics_ = io::ReadIntrinsicsJson(json);
    intrinsics_source_ = json;
  } else {
    intrinsics_ = options_.intrinsics;
    intrinsics_source_ = "given";
  }
  if (!options_.color) {
    for (Entry& e : entries) e.color.clear();
  }
  entries_ = std::move(entries);
  counters_.SetFramesInSource(static_cast<int64_t>(entries_.size()));
  next_ = 0;
  sequence_ = 0;
  error_.clear();
  open_ = true;
}

core::ReadStatus DepthPngSource::Read(int /*timeout_ms*/, core::RgbdFrame* frame) {
  if (!open_) {
    error_ = "Read() on a closed source";
    return core::ReadStatus::kError;
  }
  // Bad frames are skipped; at most one pass over the directory per call.
  for (size_t tries = 0; tries < entries_.size(); ++tries) {
    if (next_ >= entries_.size()) {
      if (!options_.loop) return core::ReadStatus::kEndOfStream;
      next_ = 0;
    }
    const Entry& e = entries_[next_++];
    if (next_ == entries_.size()) counters_.PassCompleted();
    try {
      frame->depth = io::ReadDepthPng(e.depth, options_.depth_scale_to_mm, options_.limits);
    } catch (const core::FrameTooLargeError& ex) {
      counters_.Skipped(core::SkipReason::kTooLarge, ex.what());
      continue;
    } catch (const std::exception& ex) {
      counters_.Skipped(core::SkipReason::kUnreadable, ex.what());
      continue;
    }
    const std::string problem =
        internal::ScalingProblem(intrinsics_, frame->depth.width, frame->depth.height);
    if (!problem.empty()) {
      counters_.Skipped(core::SkipReason::kSizeMismatch,
                        e.depth + ": " + problem + " (from " + intrinsics_source_ + ")");
      continue;
    }
    bool with_color = false;
    frame->color.Reset(0, 0);
    if (!e.color.empty()) {
      try {
        frame->color = io::ReadColorPng(e.color, options_.limits);
        with_color =
            frame->color.width == frame->depth.width && frame->color.height == frame->depth.height;
      } catch (const std::exception&) {
        with_color = false;
      }
      if (!with_color) {
        counters_.ColorUnmatched();
        frame->color.Reset(0, 0);
      }
    }
    frame->intrinsics = intrinsics_;
    if (frame->depth.width != intrinsics_.width || frame->depth.height != intrinsics_.height) {
      frame->intrinsics = intrinsics_.Scaled(frame->depth.width, frame->depth.height);
    }
    core::StampReplayFrame(sequence_++, options_.frame_period_us, options_.camera_name, frame);
    const bool empty = std::none_of(frame->depth.data.begin(), frame->depth.data.end(),
                                    [](uint16_t d) { return d != 0; });
    counters_.Delivered(empty, !e.color.empty() && !with_color);
    return core::ReadStatus::kOk;
  }
  if (next_ >= entries_.size() && !options_.loop) return core::ReadStatus::kEndOfStream;
  error_ = "depth PNG source: no frame of '" + options_.directory + "' can be read (" +
           counters_.Snapshot().ToString() + ")";
  return core::ReadStatus::kError;
}

void DepthPngSource::Close() {
  open_ = false;
  entries_.clear();
  next_ = 0;
}

std::string DepthPngSource::Describe() const {
  std::ostringstream os;
  os << "png:" << options_.directory;
  if (!open_) return os.str() + " (closed)";
  size_t with_color = 0;
  for (const Entry& e : entries_) with_color += e.color.empty() ? 0 : 1;
  os << " (" << entries_.size() << " depth frames, " << with_color << " with colour, intrinsics "
     << intrinsics_.ToString() << " from " << intrinsics_source_;
  if (options_.loop) os << ", loop";
  os << ")";
  return os.str();
}

}  // namespace clutterseg::drivers
