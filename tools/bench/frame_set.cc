#include "tools/bench/frame_set.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <random>
#include <stdexcept>

#include "clutterseg/core/text_and_color.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/synth/random.h"
#include "clutterseg/synth/renderer.h"
#include "clutterseg/synth/scene.h"
#include "clutterseg/synth/sensor_params.h"

namespace clutterseg::bench {

namespace fs = std::filesystem;

size_t FrameSet::HeapBytes() const {
  size_t bytes = 0;
  for (const core::PointCloud& c : clouds) {
    bytes += c.xyz.capacity() * sizeof(core::Vec3f) + c.rgba.capacity() * sizeof(uint32_t) +
             c.label.capacity() * sizeof(uint32_t);
  }
  return bytes;
}

FrameSet LoadPcdDirectory(const std::string& dir, size_t max_frames) {
  if (!fs::is_directory(dir)) throw std::runtime_error("'" + dir + "' is not a directory");
  std::vector<std::string> names;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    if (e.is_regular_file() && e.path().extension() == ".pcd") {
      names.push_back(e.path().filename().string());
    }
  }
  std::sort(names.begin(), names.end(),
            [](const std::string& a, const std::string& b) { return core::NaturalLess(a, b); });
  if (names.empty()) throw std::runtime_error("no *.pcd files in directory '" + dir + "'");
  if (max_frames > 0 && names.size() > max_frames) names.resize(max_frames);
  FrameSet set;
  set.source = dir;
  set.intrinsics = core::DefaultKinectIntrinsics();
  set.clouds.resize(names.size());
  for (size_t i = 0; i < names.size(); ++i) {
    set.clouds[i] = io::ReadPcd((fs::path(dir) / names[i]).string());
    set.clouds[i].label.clear();
    set.clouds[i].label.shrink_to_fit();
  }
  set.names = std::move(names);
  return set;
}

FrameSet RenderSyntheticFrames(int count, uint64_t seed, int threads) {
  FrameSet set;
  set.source = "synthetic(seed=" + std::to_string(seed) + ")";
  synth::SceneParams scene_params;
  set.intrinsics = scene_params.intrinsics;
  const synth::SensorParams sensor;
  core::ThreadPool pool(threads);
  synth::RenderedFrame frame;
  for (int s = 0; s < count; ++s) {
    const uint64_t scene_seed = synth::HashCounter(seed, static_cast<uint64_t>(s), 0);
    const uint64_t noise_seed = synth::HashCounter(seed, static_cast<uint64_t>(s), 1);
    const synth::Scene scene = synth::GenerateScene(scene_params, scene_seed);
    synth::RenderScene(scene, set.intrinsics, sensor, noise_seed, &frame, &pool);
    core::PointCloud cloud;
    synth::ToPointCloud(frame, &cloud);
    cloud.label.clear();
    cloud.label.shrink_to_fit();
    char name[32];
    std::snprintf(name, sizeof(name), "scene_%04d", s);
    set.names.emplace_back(name);
    set.clouds.push_back(std::move(cloud));
  }
  return set;
}

FrameSet ShuffledUnorganized(const FrameSet& frames, uint64_t seed) {
  FrameSet set;
  set.source = frames.source + ", shuffled unorganized";
  set.names = frames.names;
  set.intrinsics = frames.intrinsics;
  set.clouds.resize(frames.size());
  std::vector<size_t> order;
  for (size_t s = 0; s < frames.size(); ++s) {
    const core::PointCloud& in = frames.clouds[s];
    order.clear();
    for (size_t i = 0; i < in.size(); ++i) {
      if (core::IsValid(in.xyz[i])) order.push_back(i);
    }
    std::mt19937_64 rng(seed + s);
    std::shuffle(order.begin(), order.end(), rng);
    core::PointCloud& out = set.clouds[s];
    out.width = static_cast<int>(order.size());
    out.height = 1;
    const bool color = in.rgba.size() == in.size();
    out.xyz.reserve(order.size());
    if (color) out.rgba.reserve(order.size());
    for (const size_t i : order) {
      out.xyz.push_back(in.xyz[i]);
      if (color) out.rgba.push_back(in.rgba[i]);
    }
  }
  return set;
}

}  // namespace clutterseg::bench
