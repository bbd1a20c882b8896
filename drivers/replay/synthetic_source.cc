#include "clutterseg/drivers/replay/synthetic_source.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include "clutterseg/core/param_check.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/synth/renderer.h"

namespace clutterseg::drivers {

void SyntheticSourceOptions::ValidateOrThrow() const {
  const core::ParamCheck check("source.synthetic");
  check.AtLeast("num_frames", num_frames, decltype(num_frames){1});
  check.Positive("frame_period_us", frame_period_us, "us");
  check.InRange("render_threads", render_threads, 1, 256);
  scene.ValidateOrThrow();
  sensor.ValidateOrThrow();
  intrinsics.ValidateOrThrow();
}

struct SyntheticSource::Impl {
  std::vector<synth::Scene> scenes;  // incremental mode: the whole sequence
  synth::Scene scene;                // independent mode: the current scene
  synth::RenderedFrame rendered;
  std::unique_ptr<core::ThreadPool> pool;
  int next{0};
  uint64_t sequence{0};
  bool open{false};
  std::atomic<bool> stop{false};
  std::chrono::steady_clock::time_point start;
  core::SourceCounters counters;
};

SyntheticSource::SyntheticSource(const SyntheticSourceOptions& options)
    : options_(options), impl_(std::make_unique<Impl>()) {
  options_.ValidateOrThrow();
}

SyntheticSource::~SyntheticSource() = default;

void SyntheticSource::Open() {
  Close();
  Impl& m = *impl_;
  try {
    if (options_.incremental) {
      m.scenes = synth::GenerateSequence(options_.scene, options_.seed, options_.num_frames);
    }
  } catch (const std::exception& e) {
    throw std::runtime_error("synthetic source: cannot generate scenes for seed " +
                             std::to_string(options_.seed) + ": " + e.what());
  }
  if (options_.render_threads > 1 && !m.pool) {
    m.pool = std::make_unique<core::ThreadPool>(options_.render_threads);
  }
  m.next = 0;
  m.sequence = 0;
  m.stop = false;
  m.start = std::chrono::steady_clock::now();
  m.counters.SetFramesInSource(options_.num_frames);
  m.open = true;
  error_.clear();
}

core::ReadStatus SyntheticSource::Read(int timeout_ms, core::RgbdFrame* frame) {
  Impl& m = *impl_;
  if (!m.open) {
    error_ = "Read() on a closed source";
    return core::ReadStatus::kError;
  }
  if (m.next >= options_.num_frames) {
    if (!options_.loop) return core::ReadStatus::kEndOfStream;
    m.next = 0;
  }
  if (options_.real_time) {
    const auto due = m.start + std::chrono::microseconds(static_cast<int64_t>(m.sequence) *
                                                         options_.frame_period_us);
    const auto limit = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    while (std::chrono::steady_clock::now() < due) {
      if (m.stop.load() || std::chrono::steady_clock::now() >= limit) {
        return core::ReadStatus::kTimeout;
      }
      std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(
          due - std::chrono::steady_clock::now(), std::chrono::milliseconds(10)));
    }
  }
  const int k = m.next++;
  try {
    const synth::Scene* scene = nullptr;
    if (options_.incremental) {
      scene =
          &m.scenes[static_cast<size_t>(std::min<int>(k, static_cast<int>(m.scenes.size()) - 1))];
    } else {
      m.scene = synth::GenerateScene(options_.scene, options_.seed + static_cast<uint64_t>(k));
      scene = &m.scene;
    }
    // Noise depends on the frame's place in the sequence only, so a loop repeats exactly.
    const uint64_t noise_seed = options_.seed * 0x9E3779B97F4A7C15ull + static_cast<uint64_t>(k);
    synth::RenderScene(*scene, options_.intrinsics, options_.sensor, noise_seed, &m.rendered,
                       m.pool.get());
  } catch (const std::exception& e) {
    error_ = "synthetic source: rendering frame " + std::to_string(k) + " failed: " + e.what();
    return core::ReadStatus::kError;
  }
  frame->depth = m.rendered.depth;
  frame->color = m.rendered.color;
  frame->intrinsics = m.rendered.intrinsics;
  core::StampReplayFrame(m.sequence++, options_.frame_period_us, options_.camera_name, frame);
  m.counters.Delivered(std::none_of(frame->depth.data.begin(), frame->depth.data.end(),
                                    [](uint16_t d) { return d != 0; }));
  if (m.next == options_.num_frames) m.counters.PassCompleted();
  return core::ReadStatus::kOk;
}

void SyntheticSource::Close() {
  impl_->open = false;
  impl_->scenes.clear();
}

void SyntheticSource::RequestStop() { impl_->stop.store(true); }

core::SourceReport SyntheticSource::report() const { return impl_->counters.Snapshot(); }

const core::LabelImage& SyntheticSource::last_labels() const { return impl_->rendered.label; }

std::string SyntheticSource::Describe() const {
  std::ostringstream os;
  os << "synthetic:seed " << options_.seed << " (" << options_.num_frames << " "
     << (options_.incremental ? "incremental" : "independent") << " frames, "
     << options_.intrinsics.width << "x" << options_.intrinsics.height;
  if (options_.loop) os << ", loop";
  if (options_.real_time) os << ", real time";
  os << ")";
  return os.str();
}

}  // namespace clutterseg::drivers
