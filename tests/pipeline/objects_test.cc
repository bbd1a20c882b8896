// The object statistics' gravity-aligned boxes: a box seen from a corner above a table that is
// tilted in the camera frame, its points on the faces the camera sees (top and two sides).
#include "clutterseg/pipeline/objects.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"

namespace clutterseg::pipeline {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kOneDegree = kPi / 180.0;

struct V {
  double x, y, z;
};
V Add(V a, V b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
V Scale(V a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double Dot(V a, V b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
V Of(const core::Vec3f& v) { return {v.x, v.y, v.z}; }

// Angle between two directions, radians.
double Angle(V a, V b) {
  const double c = Dot(a, b) / std::sqrt(Dot(a, a) * Dot(b, b));
  return std::acos(std::min(1.0, std::max(-1.0, c)));
}

// A camera 0.9 m above a table (world z up), looking down at 50 degrees and rolled by 8: the
// rows of R map world directions into the camera frame (x right, y down, z forward).
struct Camera {
  double r[3][3];
  V position{-0.6, -0.35, 0.9};
  Camera() {
    const double pitch = 50.0 * kOneDegree, roll = 8.0 * kOneDegree, yaw = 25.0 * kOneDegree;
    // Forward: from the yaw direction, down by pitch; right: horizontal, then rolled.
    const V forward{std::cos(pitch) * std::cos(yaw), std::cos(pitch) * std::sin(yaw),
                    -std::sin(pitch)};
    const V right0{std::sin(yaw), -std::cos(yaw), 0.0};
    const V down0{forward.y * right0.z - forward.z * right0.y,
                  forward.z * right0.x - forward.x * right0.z,
                  forward.x * right0.y - forward.y * right0.x};
    const V right = Add(Scale(right0, std::cos(roll)), Scale(down0, std::sin(roll)));
    const V down = Add(Scale(down0, std::cos(roll)), Scale(right0, -std::sin(roll)));
    const V rows[3] = {right, down, forward};
    for (int i = 0; i < 3; ++i) {
      r[i][0] = rows[i].x;
      r[i][1] = rows[i].y;
      r[i][2] = rows[i].z;
    }
  }
  V Direction(V w) const {
    return {r[0][0] * w.x + r[0][1] * w.y + r[0][2] * w.z,
            r[1][0] * w.x + r[1][1] * w.y + r[1][2] * w.z,
            r[2][0] * w.x + r[2][1] * w.y + r[2][2] * w.z};
  }
  V Point(V w) const { return Direction(Add(w, Scale(position, -1.0))); }
};

// The box: 0.20 x 0.08 x 0.12 m, turned by 30 degrees about the world's z, standing on z = 0.
constexpr double kLength = 0.20, kWidth = 0.08, kHeight = 0.12, kYaw = 30.0 * kOneDegree;
constexpr V kCenter{0.10, 0.05, 0.0};

V BoxPoint(double a, double b, double z) {  // a along the long side, b along the short one
  return {kCenter.x + a * std::cos(kYaw) - b * std::sin(kYaw),
          kCenter.y + a * std::sin(kYaw) + b * std::cos(kYaw), z};
}

class GravityBox : public ::testing::Test {
 protected:
  void SetUp() override {
    // Points every 2 mm on the faces the camera sees: the top, the side at b = -W/2 and the
    // end at a = -L/2 (both face the camera, which stands at -x, -y): an L and the top.
    std::vector<V> world;
    const double step = 0.002;
    for (double a = -kLength / 2; a <= kLength / 2 + 1e-9; a += step) {
      for (double b = -kWidth / 2; b <= kWidth / 2 + 1e-9; b += step) {
        world.push_back(BoxPoint(a, b, kHeight));
      }
      for (double z = 0.004; z <= kHeight + 1e-9; z += step) {
        world.push_back(BoxPoint(a, -kWidth / 2, z));
      }
    }
    for (double b = -kWidth / 2; b <= kWidth / 2 + 1e-9; b += step) {
      for (double z = 0.004; z <= kHeight + 1e-9; z += step) {
        world.push_back(BoxPoint(-kLength / 2, b, z));
      }
    }
    Load(world);
  }

  // The points `world` as one object of a cloud, and the table as its support plane.
  void Load(const std::vector<V>& world) {
    // An organized-looking layout: 100 points a row (the extractor reads rows of labels);
    // the last row's tail is invalid, and 3 NaN points sit among the box's.
    const int width = 100;
    const int height = static_cast<int>((world.size() + width - 1) / width);
    cloud_.width = width;
    cloud_.height = height;
    cloud_.xyz.assign(static_cast<size_t>(width) * height,
                      core::Vec3f{core::kInvalidDepth, core::kInvalidDepth, core::kInvalidDepth});
    result_.labels.Reset(width, height, 0);
    for (size_t i = 0; i < world.size(); ++i) {
      const V c = camera_.Point(world[i]);
      cloud_.xyz[i] =
          core::Vec3f{static_cast<float>(c.x), static_cast<float>(c.y), static_cast<float>(c.z)};
      result_.labels.data[i] = 1;
    }
    for (size_t i : {size_t{7}, size_t{1000}, size_t{2500}}) cloud_.xyz[i].x = core::kInvalidDepth;
    result_.planes.clear();
    result_.width = width;
    result_.height = height;
    result_.objects.assign(1, Object{});
    // The table, n . p + d = 0 in the camera frame, n towards the camera (world up).
    up_ = camera_.Direction(V{0.0, 0.0, 1.0});
    const V on_table = camera_.Point(V{0.0, 0.0, 0.0});
    Plane table;
    table.id = 4;
    table.normal = core::Vec3f{static_cast<float>(up_.x), static_cast<float>(up_.y),
                               static_cast<float>(up_.z)};
    table.d = static_cast<float>(-Dot(up_, on_table));
    table.is_support = true;
    result_.planes.push_back(table);
  }

  Camera camera_;
  V up_{};
  core::PointCloud cloud_;
  SegmentationResult result_;
};

TEST_F(GravityBox, StandsUprightOnItsPlaneWithTheBoxsOwnSidesAndSize) {
  ObjectExtractor dut;
  dut.Compute(cloud_, &result_);
  const Object& o = result_.objects[0];
  ASSERT_EQ(o.support_plane_id, 4);
  ASSERT_TRUE(o.has_gravity_box);
  // Upright: the box's third axis is the plane's normal, pointing away from the table.
  EXPECT_LT(Angle(Of(o.gbox_axes[2]), up_), kOneDegree);
  EXPECT_GT(Dot(Of(o.gbox_axes[2]), up_), 0.0);
  // Yaw only: the other two axes lie in the plane, and the first runs along the long side
  // (either way), although the camera sees an L of two sides, whose principal axes would not.
  EXPECT_LT(std::abs(Dot(Of(o.gbox_axes[0]), up_)), std::sin(kOneDegree));
  EXPECT_LT(std::abs(Dot(Of(o.gbox_axes[1]), up_)), std::sin(kOneDegree));
  const V long_side = camera_.Direction(V{std::cos(kYaw), std::sin(kYaw), 0.0});
  EXPECT_LT(std::min(Angle(Of(o.gbox_axes[0]), long_side),
                     Angle(Of(o.gbox_axes[0]), Scale(long_side, -1.0))),
            kOneDegree);
  // Right-handed unit axes.
  const V a0 = Of(o.gbox_axes[0]), a1 = Of(o.gbox_axes[1]), a2 = Of(o.gbox_axes[2]);
  const V cross{a0.y * a1.z - a0.z * a1.y, a0.z * a1.x - a0.x * a1.z, a0.x * a1.y - a0.y * a1.x};
  EXPECT_GT(Dot(cross, a2), 0.999);
  // Size, height and place, within a few millimetres (2 mm sampling, float points).
  EXPECT_NEAR(o.gbox_extents.x, kLength, 0.003);
  EXPECT_NEAR(o.gbox_extents.y, kWidth, 0.003);
  EXPECT_NEAR(o.gbox_extents.z, kHeight, 0.002);
  EXPECT_NEAR(o.height_m, kHeight, 0.002);
  EXPECT_NEAR(o.bottom_m, 0.004, 0.002);
  const V center = camera_.Point(V{kCenter.x, kCenter.y, kHeight / 2});
  EXPECT_NEAR(o.gbox_center.x, center.x, 0.003);
  EXPECT_NEAR(o.gbox_center.y, center.y, 0.003);
  EXPECT_NEAR(o.gbox_center.z, center.z, 0.003);
}

// A can: its top and the half of its side the camera sees project onto a disk, whose smallest
// rectangle is the square around it (the rectangle's hull has hundreds of vertices).
TEST_F(GravityBox, ACylinderGetsTheSquareAroundItsDisk) {
  std::vector<V> world;
  const double radius = 0.04, height = 0.10;
  for (double r = 0.0; r <= radius + 1e-9; r += 0.0015) {
    const int around = std::max(1, static_cast<int>(2 * kPi * r / 0.0015));
    for (int k = 0; k < around; ++k) {
      const double a = 2 * kPi * k / around;
      world.push_back({0.3 + r * std::cos(a), 0.2 + r * std::sin(a), height});
    }
  }
  for (int k = 0; k < 400; ++k) {
    const double a = 2 * kPi * k / 400;
    for (double z = 0.003; z < height; z += 0.002) {
      // The side facing the camera (at -x, -y).
      if (std::cos(a) + std::sin(a) < 0.0) {
        world.push_back({0.3 + radius * std::cos(a), 0.2 + radius * std::sin(a), z});
      }
    }
  }
  Load(world);
  ObjectExtractor dut;
  dut.Compute(cloud_, &result_);
  const Object& o = result_.objects[0];
  ASSERT_TRUE(o.has_gravity_box);
  EXPECT_LT(Angle(Of(o.gbox_axes[2]), up_), kOneDegree);
  EXPECT_NEAR(o.gbox_extents.x, 2 * radius, 0.002);
  EXPECT_NEAR(o.gbox_extents.y, 2 * radius, 0.002);
  EXPECT_NEAR(o.height_m, height, 0.002);
  const V center = camera_.Point(V{0.3, 0.2, height / 2});
  EXPECT_NEAR(o.gbox_center.x, center.x, 0.002);
  EXPECT_NEAR(o.gbox_center.y, center.y, 0.002);
  EXPECT_NEAR(o.gbox_center.z, center.z, 0.002);
}

TEST_F(GravityBox, SameBoxWhateverTheThreadCount) {
  ObjectExtractor serial;
  serial.Compute(cloud_, &result_);
  const Object a = result_.objects[0];
  core::ThreadPool pool(3);
  ObjectExtractor parallel(&pool);
  parallel.Compute(cloud_, &result_);
  const Object& b = result_.objects[0];
  ASSERT_TRUE(b.has_gravity_box);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(a.gbox_axes[i].x, b.gbox_axes[i].x);
    EXPECT_EQ(a.gbox_axes[i].y, b.gbox_axes[i].y);
    EXPECT_EQ(a.gbox_axes[i].z, b.gbox_axes[i].z);
  }
  EXPECT_EQ(a.gbox_center.x, b.gbox_center.x);
  EXPECT_EQ(a.gbox_extents.x, b.gbox_extents.x);
  EXPECT_EQ(a.gbox_extents.y, b.gbox_extents.y);
  EXPECT_EQ(a.height_m, b.height_m);
}

TEST_F(GravityBox, NoSupportPlaneNoBox) {
  result_.planes[0].is_support = false;  // a wall-like plane the object does not stand on
  ObjectExtractor dut;
  dut.Compute(cloud_, &result_);
  const Object& o = result_.objects[0];
  EXPECT_EQ(o.support_plane_id, -1);
  EXPECT_FALSE(o.has_gravity_box);
  EXPECT_EQ(o.gbox_extents.x, 0.f);
  EXPECT_EQ(o.gbox_extents.z, 0.f);
  EXPECT_EQ(o.height_m, 0.f);
  EXPECT_GT(o.obb_extents.x, 0.1f);  // the other statistics are still there
}

}  // namespace
}  // namespace clutterseg::pipeline
