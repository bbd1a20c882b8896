// clutterseg-synth: writes synthetic labelled tabletop scenes rendered through a
// structured-light sensor model, as organized PCD files (x y z rgba label) and optionally
// depth / colour / label PNGs, plus a manifest (scenes.json).
//
// With --oni FILE the rendered depth (mm) and colour frames go into one .oni recording at
// 30 fps timestamps (frame k at k / 30 s) instead; with --out as well, the ground truth of ONI
// frame k is written beside it as <out>/frame_<k, 6 digits>.pcd (the replay's frame sequence
// number), plus the manifest.
//
// With --scenario add|remove|add-remove|occluder|static|piles each sequence is one scenario of
// synth::GenerateScenarioSequence: every physical object keeps its label in every frame (the
// occluder has a label of its own, in the manifest), so the frames can score tracking. The
// manifest gives every object's centroid and point count per frame; with --gt-labels-only the
// ground truth of a frame is its label PNG alone (no PCD: long recordings stay small).
//
// Exit codes: 0 success, 1 I/O failure, 2 bad arguments.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/io/png_io.h"
#include "clutterseg/synth/random.h"
#include "clutterseg/synth/renderer.h"
#include "clutterseg/synth/scene.h"
#include "clutterseg/synth/sensor_params.h"
#include "clutterseg/synth/sequence.h"
#include "clutterseg/version.h"

#ifdef CLUTTERSEG_SYNTH_WITH_ONI
#include "clutterseg/drivers/oni/oni_writer.h"
#endif

namespace fs = std::filesystem;

namespace clutterseg::synth {
namespace {

constexpr int kExitOk = 0;
constexpr int kExitIo = 1;
constexpr int kExitUsage = 2;

// A command-line problem found after parsing (exit code 2).
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Options {
  std::string out_dir;
  std::string oni_path;
  int count{1};
  uint64_t seed{1};
  bool sequence{false};
  std::string scenario;  // empty: no scenario
  int step_frames{3};
  std::string occluder{"arm"};
  double occluder_radius_m{0.04};
  double camera_jitter_mm{0.0};
  double camera_jitter_deg{0.0};
  int frames{10};
  std::string objects;
  bool png{false};
  bool labels_only{false};
  bool part_labels{false};
  bool no_noise{false};
  double noise_correlation_px{-1.0};  // < 0: the sensor default
  int width{640};
  int height{480};
  int threads{1};
  bool verbose{false};
};

// What the manifest records about one written frame.
struct FrameRecord {
  std::string name;  // file stem
  int scene_index{0};
  int frame_index{-1};  // -1 outside sequence mode
  int oni_frame{-1};    // index in the .oni recording, -1 without one
  uint64_t scene_seed{0};
  uint64_t noise_seed{0};
  std::vector<SceneObject> objects;
  std::vector<int> visible_pixels;     // per object, labelled pixels with valid depth
  std::vector<int> valid_points;       // per object, labelled points of finite xyz
  std::vector<core::Vec3f> centroids;  // per object, mean of those points (camera frame, m)
  uint32_t occluder_label{0};          // 0: no occluder
  int occluder_visible_pixels{0};
  std::vector<std::pair<std::string, std::string>> files;  // (key, file name)
};

// Destination of rendered frames: a directory of PCD (and PNG) files, or an .oni recording
// with an optional directory of ground truth beside it.
class FrameSink {
 public:
  FrameSink() = default;
  FrameSink(const FrameSink&) = delete;
  FrameSink& operator=(const FrameSink&) = delete;
  virtual ~FrameSink() = default;

  // Called once before the first frame.
  virtual void Begin(const core::CameraIntrinsics& intrinsics) = 0;
  // Writes one frame and adds the written files to `record`.
  // @throws std::runtime_error on I/O failure.
  virtual void Write(const RenderedFrame& frame, FrameRecord* record) = 0;
  // Called once after the last frame.
  virtual void End() = 0;
};

std::string JsonString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
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
  return out + "\"";
}

void WriteTextFile(const fs::path& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw std::runtime_error("cannot open '" + path.string() + "' for writing");
  f << text;
  f.close();
  if (!f) throw std::runtime_error("failed writing '" + path.string() + "'");
}

// The label written for pixel i: the object label, or with `parts` mOSD's part label
// 10 x label + part (part 1: the object's surface seen from inside, a vessel's inside).
uint32_t OutputLabel(const RenderedFrame& frame, size_t i, bool parts) {
  const uint32_t label = frame.label.data[i];
  return parts && label != 0 ? 10 * label + frame.inside.data[i] : label;
}

// Writes <stem>.pcd and, with PNGs, <stem>_depth.png, <stem>_color.png, <stem>_label.png
// and intrinsics.json into one directory; with `labels_only` <stem>_label.png alone. With
// `part_labels` the PCD and the label PNG carry part labels (OutputLabel).
class DirectorySink : public FrameSink {
 public:
  DirectorySink(fs::path dir, bool png, bool labels_only, bool part_labels)
      : dir_(std::move(dir)), png_(png), labels_only_(labels_only), part_labels_(part_labels) {}

  void Begin(const core::CameraIntrinsics& k) override {
    if (!png_) return;
    std::ostringstream os;
    os.precision(17);
    os << "{\"fx\": " << k.fx << ", \"fy\": " << k.fy << ", \"cx\": " << k.cx
       << ", \"cy\": " << k.cy << ", \"width\": " << k.width << ", \"height\": " << k.height
       << "}\n";
    WriteTextFile(dir_ / "intrinsics.json", os.str());
  }

  void Write(const RenderedFrame& frame, FrameRecord* record) override {
    if (!labels_only_) {
      ToPointCloud(frame, &cloud_);
      if (part_labels_) {
        for (size_t i = 0; i < cloud_.label.size(); ++i)
          cloud_.label[i] = OutputLabel(frame, i, true);
      }
      const std::string pcd = record->name + ".pcd";
      io::WritePcd((dir_ / pcd).string(), cloud_, io::PcdEncoding::kBinary);
      record->files.emplace_back("pcd", pcd);
    }
    if (png_ && !labels_only_) {
      const std::string depth = record->name + "_depth.png";
      const std::string color = record->name + "_color.png";
      io::WriteDepthPng((dir_ / depth).string(), frame.depth);
      io::WriteColorPng((dir_ / color).string(), frame.color);
      record->files.emplace_back("depth_png", depth);
      record->files.emplace_back("color_png", color);
    }
    if (!png_ && !labels_only_) return;
    const std::string label = record->name + "_label.png";
    label16_.Reset(frame.label.width, frame.label.height);
    for (size_t i = 0; i < frame.label.size(); ++i) {
      label16_.data[i] =
          static_cast<uint16_t>(std::min<uint32_t>(OutputLabel(frame, i, part_labels_), 65535));
    }
    io::WriteDepthPng((dir_ / label).string(), label16_);
    record->files.emplace_back("label_png", label);
  }

  void End() override {}

 private:
  fs::path dir_;
  bool png_;
  bool labels_only_;
  bool part_labels_;
  core::PointCloud cloud_;
  core::DepthImage label16_;
};

#ifdef CLUTTERSEG_SYNTH_WITH_ONI
constexpr int kOniFps = 30;

// Writes the depth (mm) and colour of every frame into one .oni recording at 30 fps
// timestamps; forwards the frames to `ground_truth` (when non-null) for the labelled files.
class OniSink : public FrameSink {
 public:
  OniSink(std::string path, std::unique_ptr<FrameSink> ground_truth)
      : path_(std::move(path)), ground_truth_(std::move(ground_truth)) {}

  void Begin(const core::CameraIntrinsics& k) override {
    writer_.Open(path_, k.width, k.height, kOniFps, k, /*with_color=*/true);
    if (ground_truth_) ground_truth_->Begin(k);
  }

  void Write(const RenderedFrame& frame, FrameRecord* record) override {
    const int index = writer_.frames_written();
    const int64_t timestamp_us = static_cast<int64_t>(index) * 1000000 / kOniFps;
    writer_.WriteFrame(frame.depth, &frame.color, timestamp_us);
    record->oni_frame = index;
    if (ground_truth_) ground_truth_->Write(frame, record);
  }

  void End() override {
    writer_.Close();
    if (ground_truth_) ground_truth_->End();
  }

 private:
  std::string path_;
  std::unique_ptr<FrameSink> ground_truth_;
  drivers::OniWriter writer_;
};
#endif

void ParseObjectRange(const std::string& text, SceneParams* params) {
  const size_t colon = text.find(':');
  auto parse_int = [&](const std::string& s) {
    size_t used = 0;
    int v = 0;
    try {
      v = std::stoi(s, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != s.size()) {
      throw UsageError("--objects: expected MIN:MAX or N with integers, got '" + text + "'");
    }
    return v;
  };
  if (colon == std::string::npos) {
    params->min_objects = params->max_objects = parse_int(text);
  } else {
    params->min_objects = parse_int(text.substr(0, colon));
    params->max_objects = parse_int(text.substr(colon + 1));
  }
}

std::string ManifestJson(const Options& opt, const core::CameraIntrinsics& k,
                         const std::vector<FrameRecord>& records) {
  std::ostringstream os;
  os << "{\n  \"generator\": \"clutterseg-synth\",\n";
  os << "  \"seed\": " << opt.seed << ",\n  \"count\": " << opt.count << ",\n";
  os << "  \"sequence\": " << (opt.sequence ? "true" : "false") << ",\n";
  if (!opt.scenario.empty()) {
    os << "  \"scenario\": " << JsonString(opt.scenario)
       << ",\n  \"step_frames\": " << opt.step_frames << ",\n";
  }
  if (opt.sequence) os << "  \"frames_per_sequence\": " << opt.frames << ",\n";
  os << "  \"noise\": " << (opt.no_noise ? "false" : "true") << ",\n";
  if (!opt.oni_path.empty()) {
    os << "  \"oni\": " << JsonString(opt.oni_path) << ",\n  \"oni_fps\": 30,\n";
  }
  os << "  \"width\": " << k.width << ",\n  \"height\": " << k.height << ",\n";
  if (opt.png) os << "  \"intrinsics\": \"intrinsics.json\",\n";
  os << "  \"scenes\": [";
  for (size_t r = 0; r < records.size(); ++r) {
    const FrameRecord& rec = records[r];
    os << (r == 0 ? "\n" : ",\n") << "    {\"name\": " << JsonString(rec.name)
       << ", \"scene_index\": " << rec.scene_index;
    if (rec.frame_index >= 0) os << ", \"frame_index\": " << rec.frame_index;
    if (rec.oni_frame >= 0) os << ", \"oni_frame\": " << rec.oni_frame;
    os << ", \"scene_seed\": " << rec.scene_seed << ", \"noise_seed\": " << rec.noise_seed
       << ", \"object_count\": " << rec.objects.size();
    if (rec.occluder_label != 0) {
      os << ", \"occluder_label\": " << rec.occluder_label
         << ", \"occluder_visible_pixels\": " << rec.occluder_visible_pixels;
    }
    os << ",\n     \"files\": {";
    for (size_t f = 0; f < rec.files.size(); ++f) {
      os << (f == 0 ? "" : ", ") << JsonString(rec.files[f].first) << ": "
         << JsonString(rec.files[f].second);
    }
    os << "},\n     \"objects\": [";
    for (size_t i = 0; i < rec.objects.size(); ++i) {
      const SceneObject& o = rec.objects[i];
      os << (i == 0 ? "\n" : ",\n") << "       {\"label\": " << o.label
         << ", \"kind\": " << JsonString(ToString(o.kind))
         << ", \"placement\": " << JsonString(ToString(o.placement))
         << ", \"partner\": " << o.partner_label
         << ", \"visible_pixels\": " << rec.visible_pixels[i]
         << ", \"valid_points\": " << rec.valid_points[i] << ", \"centroid\": ["
         << rec.centroids[i].x << ", " << rec.centroids[i].y << ", " << rec.centroids[i].z
         << "], \"color\": [" << int{o.color.r} << ", " << int{o.color.g} << ", " << int{o.color.b}
         << "]}";
    }
    os << (rec.objects.empty() ? "]}" : "\n     ]}");
  }
  os << (records.empty() ? "]\n}\n" : "\n  ]\n}\n");
  return os.str();
}

int Run(int argc, char** argv) {
  Options opt;
  CLI::App app{"Writes synthetic labelled RGB-D tabletop scenes (organized PCD x y z rgba label)."};
  app.add_option("--out", opt.out_dir,
                 "output directory (created when missing); with --oni: ground truth PCDs "
                 "frame_NNNNNN.pcd numbered like the recording's frames");
  app.add_option("--oni", opt.oni_path,
                 "write the rendered depth (mm) and colour frames as one .oni recording at "
                 "30 fps instead of scene files");
  app.add_option("--count", opt.count, "number of scenes (sequences with --sequence)")
      ->check(CLI::Range(1, 100000));
  app.add_option("--seed", opt.seed, "random seed; the same seed gives byte-identical files");
  app.add_flag("--sequence", opt.sequence,
               "incremental sequences: frame k holds k objects on the same table");
  app.add_option("--scenario", opt.scenario,
                 "sequences of one scenario (implies --sequence; objects keep their label in "
                 "every frame): add (one object added every --step-frames frames to the empty "
                 "table), remove (all objects, one removed every --step-frames), add-remove "
                 "(half of them, then one added or removed every --step-frames), occluder (an "
                 "occluder sweeps across the view once), static (nothing changes but the "
                 "sensor noise), piles (objects in touching piles placed one every "
                 "--step-frames, an occluder's sweep, a static stretch, then removed one every "
                 "--step-frames: (2 N + 2) x --step-frames frames for N objects); the scene "
                 "holds the --objects count (its maximum)")
      ->check(CLI::IsMember({"add", "remove", "add-remove", "occluder", "static", "piles"}));
  app.add_option("--step-frames", opt.step_frames,
                 "--scenario add/remove/add-remove/piles: frames between two changes")
      ->check(CLI::Range(1, 10000));
  app.add_option("--occluder", opt.occluder,
                 "--scenario occluder: arm (a cylinder along the image vertical) or box")
      ->check(CLI::IsMember({"arm", "box"}));
  app.add_option("--occluder-radius", opt.occluder_radius_m,
                 "--scenario occluder: arm radius or half the box side, metres")
      ->check(CLI::Range(0.005, 0.5));
  app.add_option("--camera-jitter-mm", opt.camera_jitter_mm,
                 "sequences of a scenario: per-frame camera shake, up to this many mm per axis")
      ->check(CLI::Range(0.0, 100.0));
  app.add_option("--camera-jitter-deg", opt.camera_jitter_deg,
                 "sequences of a scenario: per-frame camera turn, up to this many degrees per "
                 "axis")
      ->check(CLI::Range(0.0, 5.0));
  app.add_option("--frames", opt.frames,
                 "frames per sequence (--sequence: objects = frames - 1, at most 65; "
                 "--scenario: up to 10000)")
      ->check(CLI::Range(1, 10000));
  app.add_option("--objects", opt.objects, "object count range MIN:MAX (or N)");
  app.add_flag("--png", opt.png, "also write depth (16-bit mm), colour and label PNGs");
  app.add_flag("--gt-labels-only", opt.labels_only,
               "write each frame's label PNG (16-bit) and no PCD; the manifest's per-object "
               "centroids and point counts are the rest of the ground truth");
  app.add_flag("--part-labels", opt.part_labels,
               "label object points as mOSD's parts do: 10 x label + part, part 1 on a surface "
               "seen from inside (a bowl's inside, a cup's inner wall and bottom), 0 elsewhere; "
               "score with clutterseg-eval --gt-convention mosd-parts (mosd-objects: whole "
               "objects). Scenes only (not with --sequence, --scenario or --oni)");
  app.add_flag("--no-noise", opt.no_noise,
               "no random sensor noise or quantisation (shadows and grazing limits stay)");
  app.add_option("--noise-correlation", opt.noise_correlation_px,
                 "correlation length of the depth noise in pixels (0 = independent per pixel; "
                 "default: the sensor model's)")
      ->check(CLI::Range(0.0, 256.0));
  app.add_option("--width", opt.width, "image width in pixels")->check(CLI::Range(16, 4096));
  app.add_option("--height", opt.height, "image height in pixels")->check(CLI::Range(16, 4096));
  app.add_option("--threads", opt.threads, "render threads (0 = all cores)")
      ->check(CLI::Range(0, 256));
  app.add_flag("--verbose,-v", opt.verbose, "print per-frame timing");
  app.set_version_flag("--version", std::string("clutterseg-synth ") + clutterseg::kVersion);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kExitOk : kExitUsage;
  }

  if (!opt.scenario.empty()) opt.sequence = true;
  if (opt.scenario.empty() && opt.frames > 65) {
    throw UsageError("--frames: at most 65 with --sequence (no --scenario)");
  }
  if (opt.out_dir.empty() && opt.oni_path.empty()) {
    throw UsageError("one of --out DIR or --oni FILE is required");
  }
  if (opt.labels_only && opt.out_dir.empty()) throw UsageError("--gt-labels-only needs --out DIR");
  if (opt.part_labels && (opt.sequence || !opt.oni_path.empty())) {
    throw UsageError("--part-labels: scenes only (not with --sequence, --scenario or --oni)");
  }
#ifndef CLUTTERSEG_SYNTH_WITH_ONI
  if (!opt.oni_path.empty()) throw UsageError("--oni: built without the ONI writer");
#endif
  SceneParams scene_params;
  if (!opt.objects.empty()) ParseObjectRange(opt.objects, &scene_params);
  const core::CameraIntrinsics intrinsics =
      core::DefaultKinectIntrinsics().Scaled(opt.width, opt.height);
  scene_params.intrinsics = intrinsics;
  SensorParams sensor = opt.no_noise ? NoiselessSensorParams() : SensorParams{};
  if (opt.noise_correlation_px >= 0.0) sensor.axial_noise_correlation_px = opt.noise_correlation_px;
  try {
    scene_params.ValidateOrThrow();
    sensor.ValidateOrThrow();
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }

  const fs::path dir(opt.out_dir);
  std::unique_ptr<FrameSink> sink;
  if (!opt.out_dir.empty()) {
    if (fs::exists(dir) && !fs::is_directory(dir)) {
      throw std::runtime_error("output path '" + dir.string() + "' exists and is not a directory");
    }
    fs::create_directories(dir);
    sink = std::make_unique<DirectorySink>(dir, opt.png, opt.labels_only, opt.part_labels);
  }
#ifdef CLUTTERSEG_SYNTH_WITH_ONI
  if (!opt.oni_path.empty()) sink = std::make_unique<OniSink>(opt.oni_path, std::move(sink));
#endif
  core::ThreadPool pool(opt.threads);
  RenderedFrame frame;
  core::PointCloud cloud;
  std::vector<FrameRecord> records;
  double render_ms_total = 0.0;
  int rendered = 0;
  sink->Begin(intrinsics);
  for (int s = 0; s < opt.count; ++s) {
    const uint64_t scene_seed = synth::HashCounter(opt.seed, static_cast<uint64_t>(s), 0);
    std::vector<Scene> scenes;
    if (!opt.scenario.empty()) {
      SequenceParams seq;
      seq.scenario = ParseScenario(opt.scenario);
      seq.num_frames = opt.frames;
      seq.num_objects = scene_params.max_objects;
      seq.step_frames = opt.step_frames;
      seq.occluder_shape = ParseOccluderShape(opt.occluder);
      seq.occluder_radius_m = opt.occluder_radius_m;
      seq.camera_jitter_m = opt.camera_jitter_mm / 1000.0;
      seq.camera_jitter_deg = opt.camera_jitter_deg;
      scenes = GenerateScenarioSequence(scene_params, seq, scene_seed);
    } else if (opt.sequence) {
      scenes = GenerateSequence(scene_params, scene_seed, opt.frames);
    } else {
      scenes.push_back(GenerateScene(scene_params, scene_seed));
    }
    for (size_t f = 0; f < scenes.size(); ++f) {
      FrameRecord rec;
      char name[64];
      if (!opt.oni_path.empty()) {
        // Ground truth is named by the frame's index in the recording.
        std::snprintf(name, sizeof(name), "frame_%06d", rendered);
      } else if (opt.sequence) {
        std::snprintf(name, sizeof(name), "scene_%04d_frame_%04d", s, static_cast<int>(f));
      } else {
        std::snprintf(name, sizeof(name), "scene_%04d", s);
      }
      if (opt.sequence) rec.frame_index = static_cast<int>(f);
      rec.name = name;
      rec.scene_index = s;
      rec.scene_seed = scene_seed;
      rec.noise_seed = synth::HashCounter(opt.seed, static_cast<uint64_t>(s), f + 1);
      rec.objects = scenes[f].objects;
      const std::clock_t c0 = std::clock();
      const auto t0 = std::chrono::steady_clock::now();
      RenderScene(scenes[f], intrinsics, sensor, rec.noise_seed, &frame, &pool);
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      const double cpu_ms = 1000.0 * static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
      render_ms_total += ms;
      ++rendered;
      // Labels are stable across a sequence's frames, so a frame may hold a subset of them.
      rec.occluder_label = scenes[f].occluder_label;
      uint32_t max_label = rec.occluder_label;
      for (const SceneObject& o : rec.objects) max_label = std::max(max_label, o.label);
      std::vector<int> pixels(max_label + 1, 0);
      for (uint32_t l : frame.label.data) {
        if (l > 0 && l <= max_label) ++pixels[l];
      }
      rec.visible_pixels.clear();
      for (const SceneObject& o : rec.objects) rec.visible_pixels.push_back(pixels[o.label]);
      // Centroids as a scorer computes them from the PCD: labelled points of finite xyz.
      ToPointCloud(frame, &cloud);
      std::vector<int> valid(max_label + 1, 0);
      std::vector<double> sums(3 * (static_cast<size_t>(max_label) + 1), 0.0);
      for (size_t i = 0; i < cloud.size(); ++i) {
        const uint32_t l = cloud.label[i];
        const core::Vec3f& q = cloud.xyz[i];
        if (l == 0 || l > max_label || !std::isfinite(q.x) || !std::isfinite(q.y) ||
            !std::isfinite(q.z)) {
          continue;
        }
        ++valid[l];
        sums[3 * l] += q.x;
        sums[3 * l + 1] += q.y;
        sums[3 * l + 2] += q.z;
      }
      rec.valid_points.clear();
      rec.centroids.clear();
      for (const SceneObject& o : rec.objects) {
        const int c = valid[o.label];
        const double w = c > 0 ? 1.0 / c : 0.0;
        rec.valid_points.push_back(c);
        rec.centroids.push_back(core::Vec3f{static_cast<float>(sums[3 * o.label] * w),
                                            static_cast<float>(sums[3 * o.label + 1] * w),
                                            static_cast<float>(sums[3 * o.label + 2] * w)});
      }
      if (rec.occluder_label != 0) rec.occluder_visible_pixels = pixels[rec.occluder_label];
      sink->Write(frame, &rec);
      if (opt.verbose) {
        std::fprintf(stderr, "%s: %zu objects, %zu primitives, render %.1f ms (%.1f ms CPU)\n",
                     name, rec.objects.size(), scenes[f].primitives.size(), ms, cpu_ms);
      }
      records.push_back(std::move(rec));
    }
  }
  sink->End();
  if (!opt.out_dir.empty()) {
    WriteTextFile(dir / "scenes.json", ManifestJson(opt, intrinsics, records));
  }
  const std::string where = opt.oni_path.empty() ? dir.string() : opt.oni_path;
  std::fprintf(stderr, "clutterseg-synth: wrote %d frame(s) to %s (mean render %.1f ms)\n",
               rendered, where.c_str(), rendered > 0 ? render_ms_total / rendered : 0.0);
  return kExitOk;
}

}  // namespace
}  // namespace clutterseg::synth

int main(int argc, char** argv) {
  try {
    return clutterseg::synth::Run(argc, argv);
  } catch (const clutterseg::synth::UsageError& e) {
    std::cerr << "clutterseg-synth: " << e.what() << "\n";
    return clutterseg::synth::kExitUsage;
  } catch (const std::exception& e) {
    std::cerr << "clutterseg-synth: " << e.what() << "\n";
    return clutterseg::synth::kExitIo;
  }
}
