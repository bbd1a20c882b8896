#include "clutterseg/synth/sequence.h"

#include <algorithm>
#include <cstdint>
#include <map>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/synth/renderer.h"

namespace clutterseg::synth {
namespace {

SceneParams Params() {
  SceneParams p;
  p.camera_distance_min_m = 0.8;
  p.camera_distance_max_m = 1.1;
  return p;
}

SequenceParams Sequence(Scenario s, int frames, int objects = 6, int step = 2) {
  SequenceParams p;
  p.scenario = s;
  p.num_frames = frames;
  p.num_objects = objects;
  p.step_frames = step;
  return p;
}

std::vector<uint32_t> Labels(const Scene& s) {
  std::vector<uint32_t> l;
  for (const SceneObject& o : s.objects) l.push_back(o.label);
  return l;
}

bool SamePrimitive(const Primitive& a, const Primitive& b) {
  return a.kind == b.kind && a.label == b.label && a.pose.rotation == b.pose.rotation &&
         a.pose.translation.x == b.pose.translation.x &&
         a.pose.translation.y == b.pose.translation.y &&
         a.pose.translation.z == b.pose.translation.z && a.size_m.x == b.size_m.x &&
         a.size_m.y == b.size_m.y && a.size_m.z == b.size_m.z;
}

// Every object keeps its label and its geometry in every frame it is in: the label stands
// for one physical object across the sequence.
void ExpectStableLabels(const std::vector<Scene>& frames, const char* what) {
  std::map<uint32_t, std::vector<Primitive>> first;
  for (const Scene& f : frames) {
    std::map<uint32_t, std::vector<Primitive>> prims;
    for (const Primitive& p : f.primitives) {
      if (p.label != 0 && p.label != f.occluder_label) prims[p.label].push_back(p);
    }
    EXPECT_TRUE(std::is_sorted(
        f.objects.begin(), f.objects.end(),
        [](const SceneObject& a, const SceneObject& b) { return a.label < b.label; }))
        << what;
    EXPECT_EQ(prims.size(), f.objects.size()) << what;
    for (const auto& [label, list] : prims) {
      auto [it, inserted] = first.emplace(label, list);
      if (inserted) continue;
      ASSERT_EQ(it->second.size(), list.size()) << what << " label " << label;
      for (size_t i = 0; i < list.size(); ++i) {
        EXPECT_TRUE(SamePrimitive(it->second[i], list[i])) << what << " label " << label;
      }
    }
  }
}

TEST(ScenarioSequence, AddWithStepOneIsTheIncrementalSequence) {
  const std::vector<Scene> a =
      GenerateScenarioSequence(Params(), Sequence(Scenario::kAdd, 6, 5, 1), 4);
  const std::vector<Scene> b = GenerateSequence(Params(), 4, 6);
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(Labels(a[k]), Labels(b[k]));
    ASSERT_EQ(a[k].primitives.size(), b[k].primitives.size());
    for (size_t i = 0; i < a[k].primitives.size(); ++i) {
      EXPECT_TRUE(SamePrimitive(a[k].primitives[i], b[k].primitives[i]));
    }
  }
}

TEST(ScenarioSequence, AddAndRemoveChangeOneObjectPerStep) {
  for (Scenario s : {Scenario::kAdd, Scenario::kRemove, Scenario::kAddRemove}) {
    for (uint64_t seed : {1u, 2u, 3u}) {
      const std::vector<Scene> frames = GenerateScenarioSequence(Params(), Sequence(s, 24), seed);
      ASSERT_EQ(frames.size(), 24u);
      ExpectStableLabels(frames, std::string(ScenarioName(s)).c_str());
      std::map<uint32_t, int> added, removed;
      for (size_t k = 1; k < frames.size(); ++k) {
        const std::vector<uint32_t> before = Labels(frames[k - 1]), now = Labels(frames[k]);
        std::vector<uint32_t> plus, minus;
        std::set_difference(now.begin(), now.end(), before.begin(), before.end(),
                            std::back_inserter(plus));
        std::set_difference(before.begin(), before.end(), now.begin(), now.end(),
                            std::back_inserter(minus));
        EXPECT_LE(plus.size() + minus.size(), k % 2 == 0 ? 1u : 0u) << "frame " << k;
        for (uint32_t l : plus) ++added[l];
        for (uint32_t l : minus) ++removed[l];
        if (s == Scenario::kAdd) {
          EXPECT_TRUE(minus.empty());
        }
        if (s == Scenario::kRemove) {
          EXPECT_TRUE(plus.empty());
        }
        // Nothing floats: a stacked object's support is there whenever it is.
        for (const SceneObject& o : frames[k].objects) {
          if (o.placement != Placement::kStacked) continue;
          EXPECT_TRUE(std::count(now.begin(), now.end(), o.partner_label)) << "frame " << k;
        }
      }
      for (const auto& [l, n] : added) EXPECT_EQ(n, 1) << "label " << l << " added twice";
      for (const auto& [l, n] : removed) EXPECT_EQ(n, 1) << "label " << l << " removed twice";
      if (s == Scenario::kAdd) {
        EXPECT_TRUE(frames.front().objects.empty());
      }
      if (s == Scenario::kRemove) {
        EXPECT_GE(frames.front().objects.size(), 4u);
        EXPECT_GE(removed.size(), frames.front().objects.size() - 1);
      }
      if (s == Scenario::kAddRemove) {
        EXPECT_GE(added.size(), 1u);
        EXPECT_GE(removed.size(), 1u);
      }
    }
  }
}

TEST(ScenarioSequence, OccluderSweepsAcrossTheViewWithItsOwnLabel) {
  for (OccluderShape shape : {OccluderShape::kArm, OccluderShape::kBox}) {
    SequenceParams seq = Sequence(Scenario::kOccluder, 15);
    seq.occluder_shape = shape;
    const std::vector<Scene> frames = GenerateScenarioSequence(Params(), seq, 5);
    ExpectStableLabels(frames, "occluder");
    const uint32_t occluder = frames[0].occluder_label;
    ASSERT_GT(occluder, 0u);
    RenderedFrame r;
    std::vector<int> occluder_pixels;
    std::vector<int> hidden;  // objects with fewer visible pixels than in the first frame
    std::map<uint32_t, int> first_pixels;
    for (size_t k = 0; k < frames.size(); ++k) {
      EXPECT_EQ(frames[k].occluder_label, occluder);
      EXPECT_EQ(frames[k].objects.size(), frames[0].objects.size());
      RenderScene(frames[k], Params().intrinsics, NoiselessSensorParams(), 1, &r);
      std::map<uint32_t, int> pixels;
      for (uint32_t l : r.true_label.data) ++pixels[l];
      occluder_pixels.push_back(pixels[occluder]);
      if (k == 0) first_pixels = pixels;
      int h = 0;
      for (const SceneObject& o : frames[k].objects) {
        h += pixels[o.label] < first_pixels[o.label] / 2 ? 1 : 0;
      }
      hidden.push_back(h);
    }
    // Outside the view at both ends, inside in the middle, hiding objects on its way.
    EXPECT_EQ(occluder_pixels.front(), 0);
    EXPECT_EQ(occluder_pixels.back(), 0);
    EXPECT_GT(occluder_pixels[7], 0);
    EXPECT_GE(*std::max_element(hidden.begin(), hidden.end()), 1);
  }
}

TEST(ScenarioSequence, StaticSceneAndCameraJitter) {
  const std::vector<Scene> still =
      GenerateScenarioSequence(Params(), Sequence(Scenario::kStatic, 5), 9);
  for (const Scene& f : still) {
    EXPECT_EQ(f.camera_pose.rotation, still[0].camera_pose.rotation);
    EXPECT_EQ(Labels(f), Labels(still[0]));
    EXPECT_EQ(f.occluder_label, 0u);
  }
  ExpectStableLabels(still, "static");
  SequenceParams shaky = Sequence(Scenario::kStatic, 5);
  shaky.camera_jitter_m = 0.002;
  shaky.camera_jitter_deg = 0.2;
  const std::vector<Scene> a = GenerateScenarioSequence(Params(), shaky, 9);
  const std::vector<Scene> b = GenerateScenarioSequence(Params(), shaky, 9);
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].camera_pose.rotation, b[k].camera_pose.rotation);
    const Vec3 d = a[k].camera_pose.translation - still[k].camera_pose.translation;
    EXPECT_LE(std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)}), 0.002 + 1e-12);
    EXPECT_GT(Norm(d), 0.0);
    // Still a rotation.
    const Vec3 x = a[k].camera_pose.Axis(0), y = a[k].camera_pose.Axis(1);
    EXPECT_NEAR(Dot(x, y), 0.0, 1e-12);
    EXPECT_NEAR(Norm(x), 1.0, 1e-12);
  }
}

TEST(ScenarioSequence, PilesArePlacedOneByOneSweptThenRemovedOneByOne) {
  const int step = 3;
  const SequenceParams seq = Sequence(Scenario::kPiles, 200, 14, step);
  const std::vector<Scene> frames = GenerateScenarioSequence(Params(), seq, 21);
  ASSERT_EQ(frames.size(), 200u);
  ExpectStableLabels(frames, "piles");
  const size_t n = frames[step * 14 - 1].objects.size();
  ASSERT_GE(n, 12u);
  const int placed_end = static_cast<int>(n) * step;
  const int removal_start = placed_end + 2 * step;
  const int end = removal_start + static_cast<int>(n) * step;
  // Piles: most objects touch another one or stand on one.
  int piled = 0;
  for (const SceneObject& o : frames[placed_end].objects) {
    piled += o.placement == Placement::kTouching || o.placement == Placement::kStacked;
  }
  EXPECT_GE(piled, static_cast<int>(n) / 2);
  for (int k = 0; k < 200; ++k) {
    const Scene& f = frames[static_cast<size_t>(k)];
    const size_t count = f.objects.size();
    if (k < placed_end) {
      EXPECT_EQ(count, static_cast<size_t>(k / step) + 1) << "frame " << k;
      EXPECT_EQ(f.objects.back().label, count) << "placed in label order, frame " << k;
    } else if (k < removal_start) {
      EXPECT_EQ(count, n) << "frame " << k;
    } else if (k < end) {
      EXPECT_EQ(count, n - static_cast<size_t>((k - removal_start) / step) - 1) << "frame " << k;
    } else {
      EXPECT_EQ(count, 0u) << "frame " << k;
    }
    // The occluder only during its sweep; nothing stands on an absent support.
    EXPECT_EQ(f.occluder_label != 0, k >= placed_end && k < placed_end + step) << "frame " << k;
    std::vector<uint8_t> present(n + 2, 0);
    for (const SceneObject& o : f.objects) present[o.label] = 1;
    for (const SceneObject& o : f.objects) {
      if (o.placement == Placement::kStacked) {
        EXPECT_TRUE(present[o.partner_label]) << "frame " << k << " label " << o.label;
      }
    }
    // Static stretches: the object set changes only at a step's first frame.
    if (k > 0 && k % step != 0) {
      EXPECT_EQ(Labels(f), Labels(frames[static_cast<size_t>(k) - 1])) << "frame " << k;
    }
  }
  // Deterministic in the seed.
  const std::vector<Scene> again = GenerateScenarioSequence(Params(), seq, 21);
  for (size_t k = 0; k < frames.size(); ++k) EXPECT_EQ(Labels(again[k]), Labels(frames[k]));
  EXPECT_EQ(PileSceneParams(Params()).touch_probability, 0.6);
}

TEST(ScenarioSequence, NamesAndValidation) {
  for (Scenario s : {Scenario::kAdd, Scenario::kRemove, Scenario::kAddRemove, Scenario::kOccluder,
                     Scenario::kStatic, Scenario::kPiles}) {
    EXPECT_EQ(ParseScenario(ScenarioName(s)), s);
  }
  EXPECT_THROW(ParseScenario("shuffle"), std::invalid_argument);
  EXPECT_EQ(ParseOccluderShape("box"), OccluderShape::kBox);
  EXPECT_THROW(ParseOccluderShape("hand"), std::invalid_argument);
  SequenceParams p;
  p.step_frames = 0;
  EXPECT_THROW(p.ValidateOrThrow(), std::invalid_argument);
  p = {};
  p.occluder_depth_fraction = 1.0;
  EXPECT_THROW(GenerateScenarioSequence(Params(), p, 1), std::invalid_argument);
}

}  // namespace
}  // namespace clutterseg::synth
