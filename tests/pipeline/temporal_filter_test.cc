#include "clutterseg/pipeline/temporal_filter.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/pipeline/segmenter.h"
#include "clutterseg/synth/random.h"
#include "clutterseg/synth/renderer.h"
#include "clutterseg/synth/sequence.h"
#include "tests/pipeline/tracking_sequences.h"
#include "tests/testing/expect_invalid_argument.h"

namespace clutterseg::pipeline {
namespace {

core::DepthImage Constant(int w, int h, uint16_t mm) { return core::DepthImage(w, h, mm); }

// The band the filter uses at raw depth `mm`, millimetres.
float BandMm(const TemporalFilterParams& p, uint16_t mm) {
  const float z = static_cast<float>(mm) * 1e-3f;
  return std::max(p.min_band_m, p.band_at_1m_m * z * z) * 1e3f;
}

TEST(TemporalFilter, RejectsInvalidParamsNamingTheKey) {
  TemporalFilterParams p;
  p.max_frames = 0;
  testing::ExpectInvalidArgumentNaming([&] { TemporalDepthFilter f(p); },
                                       "segmenter.temporal.max_frames");
  p = TemporalFilterParams{};
  p.band_at_1m_m = -0.001f;
  testing::ExpectInvalidArgumentNaming([&] { TemporalDepthFilter f(p); },
                                       "segmenter.temporal.band_at_1m_m");
  p = TemporalFilterParams{};
  p.hole_fill_frames = 300;
  testing::ExpectInvalidArgumentNaming([&] { TemporalDepthFilter f(p); },
                                       "segmenter.temporal.hole_fill_frames");
}

TEST(TemporalFilter, AveragesWithinTheBandAndResetsAtOnceBeyondIt) {
  TemporalDepthFilter dut{TemporalFilterParams{}};
  // 1000 mm with +-2 mm of alternating noise: band 5.6 mm, so every frame is averaged in.
  for (int k = 0; k < 10; ++k) {
    core::DepthImage d = Constant(4, 2, static_cast<uint16_t>(k % 2 == 0 ? 998 : 1002));
    dut.Apply(&d);
    EXPECT_EQ(dut.num_reset(), k == 0 ? 8u : 0u) << "frame " << k;
    if (k > 0) {
      for (const uint16_t v : d.data) EXPECT_NEAR(v, 1000, 1) << "frame " << k;
    }
  }
  // A step of 1 cm in one pixel: that pixel takes the new depth in the same frame.
  core::DepthImage d = Constant(4, 2, 1002);
  d.at(1, 1) = 1010;
  dut.Apply(&d);
  EXPECT_EQ(dut.num_reset(), 1u);
  EXPECT_EQ(d.at(1, 1), 1010);
  EXPECT_NEAR(d.at(0, 0), 1000, 1);
  // The next frame averages from the new depth only.
  d = Constant(4, 2, 1000);
  d.at(1, 1) = 1008;
  dut.Apply(&d);
  EXPECT_EQ(d.at(1, 1), 1009);
}

TEST(TemporalFilter, HolesStayHolesAndKeepTheHistory) {
  TemporalDepthFilter dut{TemporalFilterParams{}};
  for (int k = 0; k < 8; ++k) {
    core::DepthImage d = Constant(2, 1, static_cast<uint16_t>(k % 2 == 0 ? 1497 : 1503));
    dut.Apply(&d);
  }
  core::DepthImage d = Constant(2, 1, 0);
  d.at(1, 0) = 1500;
  dut.Apply(&d);
  EXPECT_EQ(d.at(0, 0), 0);  // no depth is made up
  EXPECT_EQ(d.at(1, 0), 1500);
  // After the dropout the pixel's history continues: 1503 within the band is averaged in.
  d = Constant(2, 1, 1503);
  dut.Apply(&d);
  EXPECT_EQ(dut.num_reset(), 0u);
  EXPECT_EQ(d.at(0, 0), 1500);
  // A first measurement after a hole that differs resets as any change does.
  d = Constant(2, 1, 0);
  dut.Apply(&d);
  d = Constant(2, 1, 1400);
  dut.Apply(&d);
  EXPECT_EQ(dut.num_reset(), 2u);
  EXPECT_EQ(d.at(0, 0), 1400);
}

TEST(TemporalFilter, FillsHolesForAtMostHoleFillFrames) {
  TemporalFilterParams p;
  p.hole_fill_frames = 2;
  TemporalDepthFilter dut(p);
  core::DepthImage d = Constant(1, 1, 1200);
  dut.Apply(&d);
  for (int k = 0; k < 4; ++k) {
    d = Constant(1, 1, 0);
    dut.Apply(&d);
    EXPECT_EQ(d.at(0, 0), k < 2 ? 1200 : 0) << "hole frame " << k;
  }
  // A pixel never measured stays a hole.
  TemporalDepthFilter fresh(p);
  d = Constant(1, 1, 0);
  fresh.Apply(&d);
  EXPECT_EQ(d.at(0, 0), 0);
}

TEST(TemporalFilter, ANewSizeOrResetStartsAfreshAndMemoryIsSixBytesAPixel) {
  TemporalDepthFilter dut{TemporalFilterParams{}};
  core::DepthImage d = Constant(640, 480, 1000);
  dut.Apply(&d);
  EXPECT_EQ(dut.memory_bytes(), 640u * 480u * 6u);
  d = Constant(640, 480, 1003);
  dut.Apply(&d);
  EXPECT_EQ(dut.num_reset(), 0u);
  d = Constant(320, 240, 1003);
  dut.Apply(&d);
  EXPECT_EQ(dut.num_reset(), 320u * 240u);
  dut.Reset();
  d = Constant(320, 240, 1000);
  dut.Apply(&d);
  EXPECT_EQ(dut.num_reset(), 320u * 240u);
  EXPECT_EQ(d.at(5, 5), 1000);
}

TEST(TemporalFilter, EveryPixelIsFilteredAsIfAlone) {
  // The vector path (eight pixels at a time) and the scalar path for the rest of a row give
  // the same bits: an image of 91 pixels against 91 one-pixel filters, over frames with noise,
  // steps and holes.
  TemporalFilterParams p;
  p.hole_fill_frames = 2;
  TemporalDepthFilter image(p);
  std::vector<TemporalDepthFilter> alone(91, TemporalDepthFilter(p));
  uint32_t state = 12345;
  const auto next = [&] { return state = state * 1664525u + 1013904223u; };
  for (int frame = 0; frame < 60; ++frame) {
    core::DepthImage d(13, 7);
    for (size_t i = 0; i < d.size(); ++i) {
      const uint32_t r = next() >> 8;
      const int base = 600 + 40 * static_cast<int>(i % 50) + ((frame / 20) % 2) * 50 * (i % 3 == 0);
      d.data[i] = r % 9 == 0 ? 0 : static_cast<uint16_t>(base + static_cast<int>(r % 11) - 5);
    }
    core::DepthImage expected = d;
    image.Apply(&d);
    for (size_t i = 0; i < d.size(); ++i) {
      core::DepthImage one(1, 1, expected.data[i]);
      alone[i].Apply(&one);
      ASSERT_EQ(d.data[i], one.data[0]) << "frame " << frame << " pixel " << i;
    }
  }
}

// One rendered scenario: the raw depth, the filtered depth and the ground truth per frame.
struct FilteredSequence {
  std::vector<synth::Scene> scenes;
  std::vector<synth::RenderedFrame> raw;
  std::vector<core::DepthImage> filtered;
  core::CameraIntrinsics intrinsics;
};

FilteredSequence RenderAndFilter(synth::Scenario scenario, int frames, int step, uint64_t seed,
                                 const TemporalFilterParams& params = {}) {
  const synth::SceneParams scene = tracking_test::TrackingSceneParams();
  synth::SequenceParams seq;
  seq.scenario = scenario;
  seq.num_frames = frames;
  seq.num_objects = 5;
  seq.step_frames = step;
  FilteredSequence out;
  out.scenes = synth::GenerateScenarioSequence(scene, seq, seed);
  out.intrinsics = scene.intrinsics;
  TemporalDepthFilter filter(params);
  for (size_t k = 0; k < out.scenes.size(); ++k) {
    out.raw.emplace_back();
    synth::RenderScene(out.scenes[k], scene.intrinsics, synth::SensorParams{},
                       synth::HashCounter(seed, 0x7e3, k + 1), &out.raw.back());
    out.filtered.push_back(out.raw.back().depth);
    filter.Apply(&out.filtered.back());
  }
  return out;
}

// Every filtered depth lies within the band of the frame's own measurement (plus rounding to
// the millimetre), and a hole stays a hole: nothing of an earlier frame is shown where the
// scene changed.
void ExpectWithinBandOfRaw(const FilteredSequence& s) {
  const TemporalFilterParams p;
  for (size_t k = 0; k < s.raw.size(); ++k) {
    const core::DepthImage& raw = s.raw[k].depth;
    size_t bad = 0;
    for (size_t i = 0; i < raw.size(); ++i) {
      const uint16_t r = raw.data[i], f = s.filtered[k].data[i];
      if (r == 0 ? f != 0 : std::abs(int{f} - int{r}) > BandMm(p, r) + 0.5f) ++bad;
    }
    EXPECT_EQ(bad, 0u) << "frame " << k;
  }
}

// The labels present in frame k and not in frame k - 1 (added) or the reverse (removed).
std::vector<uint32_t> Difference(const synth::Scene& a, const synth::Scene& b) {
  std::vector<uint32_t> out;
  for (const auto& o : a.objects) {
    if (std::none_of(b.objects.begin(), b.objects.end(),
                     [&](const auto& x) { return x.label == o.label; })) {
      out.push_back(o.label);
    }
  }
  return out;
}

// The first frame after at least `settled` unchanged frames whose object set differs from the
// previous frame's.
size_t FirstChange(const FilteredSequence& s, size_t settled) {
  for (size_t k = settled; k < s.scenes.size(); ++k) {
    if (Difference(s.scenes[k], s.scenes[k - 1]).size() +
            Difference(s.scenes[k - 1], s.scenes[k]).size() >
        0) {
      return k;
    }
  }
  return 0;
}

TEST(TemporalFilter, ReducesTheNoiseOfAStaticScene) {
  const FilteredSequence s = RenderAndFilter(synth::Scenario::kStatic, 16, 3, 21);
  ExpectWithinBandOfRaw(s);
  const synth::RenderedFrame& last = s.raw.back();
  double raw_sq = 0.0, filtered_sq = 0.0;
  size_t n = 0;
  for (size_t i = 0; i < last.depth.size(); ++i) {
    if (last.depth.data[i] == 0 || last.true_depth_m.data[i] <= 0.f) continue;
    const double truth_mm = last.true_depth_m.data[i] * 1e3;
    const double er = last.depth.data[i] - truth_mm, ef = s.filtered.back().data[i] - truth_mm;
    if (std::fabs(er) > 20.0) continue;  // lateral noise at depth edges: not axial noise
    raw_sq += er * er;
    filtered_sq += ef * ef;
    ++n;
  }
  ASSERT_GT(n, 100000u);
  const double raw_rms = std::sqrt(raw_sq / n), filtered_rms = std::sqrt(filtered_sq / n);
  EXPECT_LT(filtered_rms, 0.6 * raw_rms) << raw_rms << " mm raw, " << filtered_rms << " filtered";
}

TEST(TemporalFilter, AnObjectPutDownShowsInItsFirstFrame) {
  const FilteredSequence s = RenderAndFilter(synth::Scenario::kAdd, 14, 6, 22);
  ExpectWithinBandOfRaw(s);
  const size_t k = FirstChange(s, 5);
  ASSERT_GT(k, 0u);
  const std::vector<uint32_t> added = Difference(s.scenes[k], s.scenes[k - 1]);
  ASSERT_EQ(added.size(), 1u);
  const synth::RenderedFrame& raw = s.raw[k];
  // Its pixels show this frame's measurement, not the table's history.
  size_t pixels = 0, unchanged = 0;
  for (size_t i = 0; i < raw.label.size(); ++i) {
    if (raw.label.data[i] != added[0] || raw.depth.data[i] == 0) continue;
    ++pixels;
    unchanged += s.filtered[k].data[i] == raw.depth.data[i] ? 1 : 0;
  }
  ASSERT_GT(pixels, 500u);
  EXPECT_GT(static_cast<double>(unchanged) / pixels, 0.95);
  // And the segmentation of the filtered frame has it: an object covering most of its pixels.
  Segmenter segmenter{SegmenterParams{}};
  SegmentationResult result;
  segmenter.ProcessDepth(s.filtered[k], nullptr, s.intrinsics, &result);
  std::vector<size_t> overlap(result.objects.size() + 1, 0);
  for (size_t i = 0; i < raw.label.size(); ++i) {
    if (raw.label.data[i] == added[0]) ++overlap[result.labels.data[i]];
  }
  const size_t best = *std::max_element(overlap.begin() + 1, overlap.end());
  EXPECT_GT(static_cast<double>(best) / pixels, 0.7);
}

TEST(TemporalFilter, AnObjectTakenAwayIsGoneInItsFirstFrame) {
  const FilteredSequence s = RenderAndFilter(synth::Scenario::kRemove, 14, 6, 23);
  ExpectWithinBandOfRaw(s);
  const size_t k = FirstChange(s, 5);
  ASSERT_GT(k, 0u);
  const std::vector<uint32_t> removed = Difference(s.scenes[k - 1], s.scenes[k]);
  ASSERT_EQ(removed.size(), 1u);
  // Where it stood, this frame's measurement (what was behind it), not its history.
  size_t pixels = 0, unchanged = 0;
  for (size_t i = 0; i < s.raw[k].depth.size(); ++i) {
    if (s.raw[k - 1].label.data[i] != removed[0] || s.raw[k].depth.data[i] == 0) continue;
    ++pixels;
    unchanged += s.filtered[k].data[i] == s.raw[k].depth.data[i] ? 1 : 0;
  }
  ASSERT_GT(pixels, 500u);
  EXPECT_GT(static_cast<double>(unchanged) / pixels, 0.95);
}

TEST(TemporalFilter, AnArmSweepingAcrossIsNeverSmeared) {
  const FilteredSequence s = RenderAndFilter(synth::Scenario::kOccluder, 12, 3, 24);
  // Every frame: every depth within the band of that frame's measurement, the arm included.
  ExpectWithinBandOfRaw(s);
  size_t total = 0;
  for (size_t k = 1; k < s.scenes.size(); ++k) {
    const synth::RenderedFrame& raw = s.raw[k];
    size_t pixels = 0, unchanged = 0;
    for (size_t i = 0; i < raw.label.size(); ++i) {
      // The arm's pixels that were something else in the previous frame.
      if (raw.label.data[i] != s.scenes[k].occluder_label || raw.depth.data[i] == 0 ||
          s.raw[k - 1].label.data[i] == s.scenes[k].occluder_label) {
        continue;
      }
      ++pixels;
      unchanged += s.filtered[k].data[i] == raw.depth.data[i] ? 1 : 0;
    }
    EXPECT_EQ(unchanged, pixels) << "frame " << k;
    total += pixels;
  }
  EXPECT_GT(total, 1000u);
}

}  // namespace
}  // namespace clutterseg::pipeline
