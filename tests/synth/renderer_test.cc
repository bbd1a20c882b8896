#include "clutterseg/synth/renderer.h"

#include <cmath>
#include <cstring>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"
#include "clutterseg/synth/scene.h"
#include "test_scenes.h"

namespace clutterseg::synth {
namespace {

using testing::CameraFrameScene;
using testing::FrontalWall;
using testing::MakePrimitive;

constexpr double kPi = 3.14159265358979323846;

TEST(RenderScene, FrontalBoxDepthMatchesAnalyticValue) {
  Scene scene = CameraFrameScene();
  scene.primitives.push_back(
      MakePrimitive(PrimitiveKind::kBox, {0.05, -0.02, 1.1}, {0.4, 0.3, 0.2}, 1));
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  RenderedFrame frame;
  RenderScene(scene, k, IdealSensorParams(), 1, &frame);
  int inside = 0;
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      // The ray through (u, v) meets the plane z = 1 at x = (u - cx) / fx.
      const double x = (u - k.cx) / k.fx;
      const double y = (v - k.cy) / k.fy;
      const bool on_face = std::abs(x - 0.05) < 0.2 && std::abs(y + 0.02) < 0.15;
      if (on_face) {
        ++inside;
        ASSERT_EQ(frame.label.at(u, v), 1u) << u << "," << v;
        ASSERT_NEAR(frame.depth.at(u, v), 1000, 1) << u << "," << v;
        ASSERT_NEAR(frame.true_depth_m.at(u, v), 1.0, 1e-6);
      } else {
        ASSERT_EQ(frame.label.at(u, v), 0u) << u << "," << v;
        ASSERT_EQ(frame.depth.at(u, v), 0) << u << "," << v;
        ASSERT_EQ(frame.status.at(u, v), static_cast<uint8_t>(DepthStatus::kNoSurface));
      }
    }
  }
  EXPECT_NEAR(inside, 0.4 * 0.3 * k.fx * k.fy, 0.4 * 0.3 * k.fx * k.fy * 0.02);
}

TEST(RenderScene, RotatedBoxFaceDepthWithinOneMillimetre) {
  // A box rotated 35 degrees about the camera's y axis, seen at about 1.3 m.
  Scene scene = CameraFrameScene();
  Primitive box = MakePrimitive(PrimitiveKind::kBox, {0.0, 0.0, 1.5}, {0.5, 0.3, 0.4}, 1);
  const double a = 35.0 * kPi / 180.0;
  box.pose = Pose::FromAxes({std::cos(a), 0.0, -std::sin(a)}, {0.0, 1.0, 0.0},
                            {std::sin(a), 0.0, std::cos(a)}, {0.0, 0.0, 1.5});
  scene.primitives.push_back(box);
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  RenderedFrame frame;
  RenderScene(scene, k, IdealSensorParams(), 1, &frame);
  // Front face: local z = -0.2, i.e. points p with n . (p - c) = 0.2 (n = -local z)
  // restricted to |local x| < 0.25, |local y| < 0.15.
  const Vec3 n = -box.pose.Axis(2);
  const Vec3 face_center = box.pose.translation + 0.2 * n;
  int checked = 0;
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const Vec3 d{(u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0};
      const double t = Dot(n, face_center) / Dot(n, d);
      const Vec3 local = box.pose.InverseApply(t * d);
      // Keep 5 mm off the face edges so neighbouring faces cannot be involved.
      if (std::abs(local.x) > 0.245 || std::abs(local.y) > 0.145) continue;
      ++checked;
      ASSERT_EQ(frame.label.at(u, v), 1u);
      ASSERT_NEAR(frame.depth.at(u, v) * 0.001, t, 0.001) << u << "," << v;
    }
  }
  EXPECT_GT(checked, 15000);
}

TEST(RenderScene, SphereSilhouetteMatchesProjectedDisc) {
  Scene scene = CameraFrameScene();
  const double r = 0.1, d = 1.5;
  scene.primitives.push_back(MakePrimitive(PrimitiveKind::kSphere, {0.0, 0.0, d}, {r, r, r}, 1));
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  RenderedFrame frame;
  RenderScene(scene, k, IdealSensorParams(), 1, &frame);
  int count = 0;
  for (uint32_t l : frame.label.data) count += l == 1 ? 1 : 0;
  // On the optical axis the silhouette is a circle of radius f r / sqrt(d^2 - r^2).
  const double radius_px = k.fx * r / std::sqrt(d * d - r * r);
  const double expected = kPi * radius_px * radius_px;
  EXPECT_NEAR(count, expected, 0.02 * expected);
}

TEST(RenderScene, NearObjectOverwritesFarOne) {
  Scene scene = CameraFrameScene();
  scene.primitives.push_back(
      MakePrimitive(PrimitiveKind::kBox, {0.0, 0.0, 1.5}, {0.4, 0.4, 0.1}, 1));
  scene.primitives.push_back(
      MakePrimitive(PrimitiveKind::kSphere, {0.05, 0.0, 1.0}, {0.08, 0.08, 0.08}, 2));
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  RenderedFrame frame;
  RenderScene(scene, k, IdealSensorParams(), 1, &frame);
  const int u = static_cast<int>(k.cx + k.fx * 0.05 / 0.92);
  const int v = static_cast<int>(k.cy);
  EXPECT_EQ(frame.label.at(u, v), 2u);
  EXPECT_NEAR(frame.depth.at(u, v), 920, 2);
  // Order in the primitive list does not matter.
  std::swap(scene.primitives[0], scene.primitives[1]);
  RenderedFrame swapped;
  RenderScene(scene, k, IdealSensorParams(), 1, &swapped);
  EXPECT_EQ(swapped.label.data, frame.label.data);
  EXPECT_EQ(swapped.depth.data, frame.depth.data);
  // The far box is still visible around the sphere.
  EXPECT_EQ(frame.label.at(static_cast<int>(k.cx - 50), v), 1u);
}

// A bowl (hemispherical shell) with its opening towards the camera is seen from inside; the
// same bowl turned away, and a solid box, from outside. The measured `inside` image follows
// the label image.
TEST(RenderScene, ASurfaceSeenFromInsideIsMarked) {
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  const auto count = [](const RenderedFrame& f, uint32_t label, int inside) {
    int n = 0;
    for (size_t i = 0; i < f.label.data.size(); ++i) {
      n += f.label.data[i] == label && f.inside.data[i] == inside ? 1 : 0;
    }
    return n;
  };
  for (const bool open_to_camera : {true, false}) {
    Scene scene = CameraFrameScene();
    Primitive bowl =
        MakePrimitive(PrimitiveKind::kHemisphereShell, {0.1, 0.0, 1.2}, {0.1, 0.1, 0.1}, 1);
    // The shell is the local z <= 0 half: local z away from the camera opens it to it.
    if (open_to_camera)
      bowl.pose = Pose::FromAxes({1, 0, 0}, {0, -1, 0}, {0, 0, -1}, {0.1, 0.0, 1.2});
    scene.primitives.push_back(bowl);
    scene.primitives.push_back(
        MakePrimitive(PrimitiveKind::kBox, {-0.2, 0.0, 1.2}, {0.15, 0.15, 0.15}, 2));
    RenderedFrame frame;
    RenderScene(scene, k, IdealSensorParams(), 1, &frame);
    const int bowl_pixels = count(frame, 1, 0) + count(frame, 1, 1);
    ASSERT_GT(bowl_pixels, 5000);
    EXPECT_EQ(count(frame, 1, 1), open_to_camera ? bowl_pixels : 0) << open_to_camera;
    EXPECT_GT(count(frame, 2, 0), 5000);
    EXPECT_EQ(count(frame, 2, 1), 0);
    EXPECT_EQ(count(frame, 0, 1), 0);
    for (size_t i = 0; i < frame.label.data.size(); ++i) {
      if (frame.label.data[i] != 0) {
        ASSERT_EQ(frame.inside.data[i], frame.true_inside.data[i]);
      }
    }
  }
}

class GeneratedScenes : public ::testing::Test {
 protected:
  static SceneParams Params() {
    SceneParams p;
    p.min_objects = 4;
    p.max_objects = 8;
    return p;
  }
};

TEST_F(GeneratedScenes, DeterministicBySeed) {
  const Scene scene = GenerateScene(Params(), 3);
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  RenderedFrame a, b, c;
  RenderScene(scene, k, SensorParams{}, 100, &a);
  RenderScene(scene, k, SensorParams{}, 100, &b);
  RenderScene(scene, k, SensorParams{}, 101, &c);
  EXPECT_EQ(a.depth.data, b.depth.data);
  EXPECT_EQ(a.label.data, b.label.data);
  EXPECT_EQ(a.color.data.size(), b.color.data.size());
  EXPECT_EQ(0, std::memcmp(a.color.data.data(), b.color.data.data(), a.color.data.size() * 3));
  EXPECT_NE(a.depth.data, c.depth.data);                // other noise
  EXPECT_EQ(a.true_depth_m.data, c.true_depth_m.data);  // same geometry

  RenderedFrame other;
  RenderScene(GenerateScene(Params(), 4), k, SensorParams{}, 100, &other);
  EXPECT_NE(a.true_label.data, other.true_label.data);
}

TEST_F(GeneratedScenes, OutputIndependentOfThreadCount) {
  const Scene scene = GenerateScene(Params(), 9);
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  RenderedFrame serial;
  RenderScene(scene, k, SensorParams{}, 5, &serial);
  for (int threads : {1, 2, 3}) {
    core::ThreadPool pool(threads);
    RenderedFrame parallel;
    RenderScene(scene, k, SensorParams{}, 5, &parallel, &pool);
    EXPECT_EQ(parallel.depth.data, serial.depth.data) << threads;
    EXPECT_EQ(parallel.label.data, serial.label.data) << threads;
    EXPECT_EQ(parallel.status.data, serial.status.data) << threads;
    EXPECT_EQ(0, std::memcmp(parallel.color.data.data(), serial.color.data.data(),
                             serial.color.data.size() * 3));
  }
}

TEST_F(GeneratedScenes, EveryUnoccludedObjectIsLabelledWithValidDepth) {
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  for (uint64_t seed = 0; seed < 6; ++seed) {
    const Scene scene = GenerateScene(Params(), seed);
    RenderedFrame full;
    RenderScene(scene, k, SensorParams{}, seed, &full);
    for (size_t i = 0; i < full.label.size(); ++i) {
      if (full.label.data[i] != 0) {
        ASSERT_GT(full.depth.data[i], 0) << "label without depth";
      }
      if (full.depth.data[i] == 0) {
        ASSERT_EQ(full.label.data[i], 0u);
      }
    }
    std::vector<int> measured(scene.objects.size() + 1, 0);
    for (uint32_t l : full.label.data) ++measured[l];
    for (const SceneObject& o : scene.objects) {
      // Render the object alone: if some of its pixels are not covered by a nearer surface
      // in the full scene, it is (partly) unoccluded and must be labelled.
      Scene alone = scene;
      alone.primitives.clear();
      for (const Primitive& p : scene.primitives) {
        if (p.label == 0 || p.label == o.label) alone.primitives.push_back(p);
      }
      RenderedFrame solo;
      RenderScene(alone, k, IdealSensorParams(), seed, &solo);
      int unoccluded = 0;
      for (size_t i = 0; i < solo.label.size(); ++i) {
        if (solo.true_label.data[i] != o.label) continue;
        if (full.true_depth_m.data[i] >= solo.true_depth_m.data[i] - 1e-6f) ++unoccluded;
      }
      ASSERT_GT(solo.true_label.size(), 0u);
      if (unoccluded >= 30) {
        EXPECT_GT(measured[o.label], 0) << "seed " << seed << " label " << o.label;
      }
      // Objects are placed fully in view and placement keeps most of them visible.
      if (o.placement != Placement::kStacked) {
        int solo_count = 0;
        for (uint32_t l : solo.true_label.data) solo_count += l == o.label ? 1 : 0;
        EXPECT_GT(solo_count, 100) << "seed " << seed << " label " << o.label;
      }
    }
  }
}

TEST_F(GeneratedScenes, ToPointCloudIsOrganizedWithLabels) {
  const Scene scene = GenerateScene(Params(), 2);
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  RenderedFrame frame;
  RenderScene(scene, k, SensorParams{}, 2, &frame);
  core::PointCloud cloud;
  ToPointCloud(frame, &cloud);
  ASSERT_EQ(cloud.width, k.width);
  ASSERT_EQ(cloud.height, k.height);
  ASSERT_EQ(cloud.size(), frame.depth.size());
  ASSERT_TRUE(cloud.has_label());
  ASSERT_TRUE(cloud.has_color());
  size_t valid = 0;
  for (int v = 0; v < k.height; v += 7) {
    for (int u = 0; u < k.width; u += 5) {
      const size_t i = static_cast<size_t>(v) * k.width + u;
      EXPECT_EQ(cloud.label[i], frame.label.data[i]);
      EXPECT_EQ(cloud.rgba[i], core::PackRgba(frame.color.data[i]));
      if (frame.depth.data[i] == 0) {
        EXPECT_FALSE(core::IsValid(cloud.xyz[i]));
        continue;
      }
      ++valid;
      const double z = frame.depth.data[i] * 0.001;
      EXPECT_NEAR(cloud.xyz[i].z, z, 1e-6);
      EXPECT_NEAR(cloud.xyz[i].x, (u - k.cx) * z / k.fx, 1e-5);
    }
  }
  EXPECT_GT(valid, 1000u);
}

TEST(RenderScene, RejectsInvalidInputs) {
  const Scene scene = CameraFrameScene();
  RenderedFrame frame;
  core::CameraIntrinsics bad = core::DefaultKinectIntrinsics();
  bad.fx = -1.0;
  EXPECT_THROW(RenderScene(scene, bad, SensorParams{}, 1, &frame), std::invalid_argument);
  SensorParams sp;
  sp.max_incidence_deg = 120.0;
  EXPECT_THROW(RenderScene(scene, core::DefaultKinectIntrinsics(), sp, 1, &frame),
               std::invalid_argument);
}

}  // namespace
}  // namespace clutterseg::synth
