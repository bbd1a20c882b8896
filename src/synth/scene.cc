#include "clutterseg/synth/scene.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "clutterseg/core/assert.h"
#include "clutterseg/core/param_check.h"
#include "clutterseg/core/text_and_color.h"
#include "clutterseg/synth/random.h"

namespace clutterseg::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
// Objects must be at least this far from the camera to be measured.
constexpr double kMinViewDepthM = 0.45;
// Stacked objects keep this margin from the edges of their support's top.
constexpr double kStackMarginM = 0.005;

// The seed-independent shape of an object before it is placed.
struct Shape {
  ObjectKind kind{ObjectKind::kBox};
  bool circle{false};
  double half_x{0.0};  // rectangle half length or circle radius
  double half_y{0.0};  // rectangle half width or circle radius
  double height{0.0};
  // Bottle: body height, shoulder height, neck radius, neck height.
  double body_h{0.0};
  double shoulder_h{0.0};
  double neck_r{0.0};
  double neck_h{0.0};
};

struct Placed {
  SceneObject object;
  std::vector<Primitive> primitives;
  bool has_child{false};
};

Shape SampleShape(ObjectKind kind, Rng* rng) {
  Shape s;
  s.kind = kind;
  switch (kind) {
    case ObjectKind::kBox:
      s.half_x = 0.5 * rng->Uniform(0.05, 0.20);
      s.half_y = 0.5 * rng->Uniform(0.05, 0.20);
      s.height = rng->Uniform(0.04, 0.20);
      break;
    case ObjectKind::kBook:
      s.half_x = 0.5 * rng->Uniform(0.13, 0.25);
      s.half_y = 0.5 * rng->Uniform(0.10, 0.18);
      s.height = rng->Uniform(0.015, 0.04);
      break;
    case ObjectKind::kCan:
      s.circle = true;
      s.half_x = s.half_y = rng->Uniform(0.03, 0.045);
      s.height = rng->Uniform(0.08, 0.16);
      break;
    case ObjectKind::kBottle:
      s.circle = true;
      s.half_x = s.half_y = rng->Uniform(0.03, 0.045);
      s.body_h = rng->Uniform(0.10, 0.18);
      s.shoulder_h = rng->Uniform(0.025, 0.05);
      s.neck_r = rng->Uniform(0.011, 0.016);
      s.neck_h = rng->Uniform(0.03, 0.06);
      s.height = s.body_h + s.shoulder_h + s.neck_h;
      break;
    case ObjectKind::kLyingCylinder: {
      const double r = rng->Uniform(0.025, 0.05);
      s.half_x = 0.5 * rng->Uniform(0.10, 0.24);
      s.half_y = r;
      s.height = 2.0 * r;
      break;
    }
    case ObjectKind::kSphere:
      s.circle = true;
      s.half_x = s.half_y = rng->Uniform(0.03, 0.07);
      s.height = 2.0 * s.half_x;
      break;
    case ObjectKind::kBowl:
      s.circle = true;
      s.half_x = s.half_y = rng->Uniform(0.06, 0.10);
      s.height = s.half_x;
      break;
    case ObjectKind::kCup:
      s.circle = true;
      s.half_x = s.half_y = rng->Uniform(0.035, 0.05);
      s.height = rng->Uniform(0.07, 0.12);
      break;
  }
  return s;
}

// Builds the primitives of `shape` standing at (cx, cy) on the surface at height base_z.
Placed Instantiate(const Shape& s, double cx, double cy, double yaw, double base_z,
                   core::Rgb8 color, uint32_t label) {
  Placed out;
  SceneObject& o = out.object;
  o.label = label;
  o.kind = s.kind;
  o.color = color;
  o.bottom_z_m = base_z;
  o.top_z_m = base_z + s.height;
  o.footprint.shape = s.circle ? Footprint::Shape::kCircle : Footprint::Shape::kRectangle;
  o.footprint.center_x_m = cx;
  o.footprint.center_y_m = cy;
  o.footprint.yaw_rad = s.circle ? 0.0 : yaw;
  o.footprint.half_x_m = s.half_x;
  o.footprint.half_y_m = s.half_y;

  auto add = [&](PrimitiveKind kind, const Pose& pose, const Vec3& size, bool cap_bottom,
                 bool cap_top) {
    Primitive p;
    p.kind = kind;
    p.pose = pose;
    p.size_m = size;
    p.cap_bottom = cap_bottom;
    p.cap_top = cap_top;
    p.color = color;
    p.label = label;
    out.primitives.push_back(p);
  };
  const double r = s.half_x;
  switch (s.kind) {
    case ObjectKind::kBox:
    case ObjectKind::kBook:
      add(PrimitiveKind::kBox, Pose::FromYaw(yaw, {cx, cy, base_z + 0.5 * s.height}),
          {2.0 * s.half_x, 2.0 * s.half_y, s.height}, true, true);
      break;
    case ObjectKind::kCan:
      add(PrimitiveKind::kCylinder, Pose::FromYaw(0.0, {cx, cy, base_z + 0.5 * s.height}),
          {r, r, s.height}, true, true);
      break;
    case ObjectKind::kCup:
      add(PrimitiveKind::kCylinder, Pose::FromYaw(0.0, {cx, cy, base_z + 0.5 * s.height}),
          {r, r, s.height}, true, false);
      break;
    case ObjectKind::kBottle: {
      double z = base_z;
      add(PrimitiveKind::kCylinder, Pose::FromYaw(0.0, {cx, cy, z + 0.5 * s.body_h}),
          {r, r, s.body_h}, true, false);
      z += s.body_h;
      add(PrimitiveKind::kFrustum, Pose::FromYaw(0.0, {cx, cy, z + 0.5 * s.shoulder_h}),
          {r, s.neck_r, s.shoulder_h}, false, false);
      z += s.shoulder_h;
      add(PrimitiveKind::kCylinder, Pose::FromYaw(0.0, {cx, cy, z + 0.5 * s.neck_h}),
          {s.neck_r, s.neck_r, s.neck_h}, false, true);
      break;
    }
    case ObjectKind::kLyingCylinder: {
      const Vec3 axis{std::cos(yaw), std::sin(yaw), 0.0};
      const Vec3 x_axis{0.0, 0.0, 1.0};
      const Pose pose =
          Pose::FromAxes(x_axis, Cross(axis, x_axis), axis, {cx, cy, base_z + s.half_y});
      add(PrimitiveKind::kCylinder, pose, {s.half_y, s.half_y, 2.0 * s.half_x}, true, true);
      break;
    }
    case ObjectKind::kSphere:
      add(PrimitiveKind::kSphere, Pose::FromYaw(0.0, {cx, cy, base_z + r}), {r, r, r}, true, true);
      break;
    case ObjectKind::kBowl:
      add(PrimitiveKind::kHemisphereShell, Pose::FromYaw(0.0, {cx, cy, base_z + r}), {r, r, r},
          true, true);
      break;
  }
  return out;
}

// Corners (x, y) of a footprint's bounding rectangle (a circle's circumscribed square).
void FootprintCorners(const Footprint& f, double xs[4], double ys[4]) {
  const double c = std::cos(f.yaw_rad);
  const double s = std::sin(f.yaw_rad);
  const double sx[4] = {-1.0, 1.0, 1.0, -1.0};
  const double sy[4] = {-1.0, -1.0, 1.0, 1.0};
  for (int i = 0; i < 4; ++i) {
    const double lx = sx[i] * f.half_x_m;
    const double ly = sy[i] * f.half_y_m;
    xs[i] = f.center_x_m + c * lx - s * ly;
    ys[i] = f.center_y_m + s * lx + c * ly;
  }
}

// Distance from point (x, y) to a rectangle footprint (0 inside).
double PointRectDistance(const Footprint& r, double x, double y) {
  const double c = std::cos(r.yaw_rad);
  const double s = std::sin(r.yaw_rad);
  const double dx = x - r.center_x_m;
  const double dy = y - r.center_y_m;
  const double lx = c * dx + s * dy;
  const double ly = -s * dx + c * dy;
  const double ex = std::max(std::abs(lx) - r.half_x_m, 0.0);
  const double ey = std::max(std::abs(ly) - r.half_y_m, 0.0);
  return std::hypot(ex, ey);
}

// True when a separating axis exists between two rectangles.
bool RectsSeparated(const Footprint& a, const Footprint& b) {
  double ax[4], ay[4], bx[4], by[4];
  FootprintCorners(a, ax, ay);
  FootprintCorners(b, bx, by);
  const double yaws[4] = {a.yaw_rad, a.yaw_rad + 0.5 * kPi, b.yaw_rad, b.yaw_rad + 0.5 * kPi};
  for (double yaw : yaws) {
    const double nx = std::cos(yaw);
    const double ny = std::sin(yaw);
    double a0 = std::numeric_limits<double>::infinity(), a1 = -a0, b0 = a0, b1 = -a0;
    for (int i = 0; i < 4; ++i) {
      const double pa = ax[i] * nx + ay[i] * ny;
      const double pb = bx[i] * nx + by[i] * ny;
      a0 = std::min(a0, pa);
      a1 = std::max(a1, pa);
      b0 = std::min(b0, pb);
      b1 = std::max(b1, pb);
    }
    if (a1 < b0 || b1 < a0) return true;
  }
  return false;
}

// Footprint `inner` lies inside rectangle `outer` shrunk by `margin`.
bool InsideRect(const Footprint& inner, const Footprint& outer, double margin) {
  Footprint shrunk = outer;
  shrunk.half_x_m -= margin;
  shrunk.half_y_m -= margin;
  if (shrunk.half_x_m <= 0.0 || shrunk.half_y_m <= 0.0) return false;
  const double c = std::cos(outer.yaw_rad);
  const double s = std::sin(outer.yaw_rad);
  auto inside = [&](double x, double y, double slack) {
    const double dx = x - outer.center_x_m;
    const double dy = y - outer.center_y_m;
    const double lx = c * dx + s * dy;
    const double ly = -s * dx + c * dy;
    return std::abs(lx) <= shrunk.half_x_m - slack && std::abs(ly) <= shrunk.half_y_m - slack;
  };
  if (inner.shape == Footprint::Shape::kCircle) {
    return inside(inner.center_x_m, inner.center_y_m, inner.half_x_m);
  }
  double xs[4], ys[4];
  FootprintCorners(inner, xs, ys);
  for (int i = 0; i < 4; ++i) {
    if (!inside(xs[i], ys[i], 0.0)) return false;
  }
  return true;
}

// Image-space bounding rectangle of an object (from its footprint box); false when any
// corner is too close to or behind the camera.
struct ImageRect {
  double u0, u1, v0, v1;
};
bool ProjectObject(const SceneObject& o, const Pose& camera, const core::CameraIntrinsics& k,
                   ImageRect* rect) {
  double xs[4], ys[4];
  FootprintCorners(o.footprint, xs, ys);
  rect->u0 = rect->v0 = std::numeric_limits<double>::infinity();
  rect->u1 = rect->v1 = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < 8; ++i) {
    const Vec3 w{xs[i % 4], ys[i % 4], i < 4 ? o.bottom_z_m : o.top_z_m};
    const Vec3 c = camera.InverseApply(w);
    if (c.z < kMinViewDepthM) return false;
    const double u = k.fx * c.x / c.z + k.cx;
    const double v = k.fy * c.y / c.z + k.cy;
    rect->u0 = std::min(rect->u0, u);
    rect->u1 = std::max(rect->u1, u);
    rect->v0 = std::min(rect->v0, v);
    rect->v1 = std::max(rect->v1, v);
  }
  return true;
}

class Generator {
 public:
  Generator(const SceneParams& params, uint64_t seed) : p_(params), rng_(seed) {}

  Scene Run() {
    Scene scene;
    PlaceCamera(&scene);
    AddBackground(&scene);
    table_.shape = Footprint::Shape::kRectangle;
    table_.half_x_m = 0.5 * p_.table_width_m;
    table_.half_y_m = 0.5 * p_.table_depth_m;
    camera_ = scene.camera_pose;

    const int count = rng_.UniformInt(p_.min_objects, p_.max_objects);
    hue0_ = rng_.Uniform(0.0, 1.0);
    for (int i = 0; i < count; ++i) {
      const uint32_t label = static_cast<uint32_t>(placed_.size()) + 1;
      const ObjectKind kind = p_.object_kinds[static_cast<size_t>(
          rng_.UniformInt(0, static_cast<int>(p_.object_kinds.size()) - 1))];
      const core::Rgb8 color = core::HsvToRgb(hue0_ + 0.618033988749895 * label,
                                              rng_.Uniform(0.45, 0.9), rng_.Uniform(0.45, 0.95));
      const double mode = rng_.Uniform(0.0, 1.0);
      Placement wanted = Placement::kFree;
      if (mode < p_.stack_probability) {
        wanted = Placement::kStacked;
      } else if (mode < p_.stack_probability + p_.touch_probability) {
        wanted = Placement::kTouching;
      } else if (mode < p_.stack_probability + p_.touch_probability + p_.occlude_probability) {
        wanted = Placement::kOccluding;
      }
      Placed placed;
      bool ok = wanted != Placement::kFree && TryPlace(wanted, kind, color, label, &placed);
      if (!ok) ok = TryPlace(Placement::kFree, kind, color, label, &placed);
      if (!ok) continue;
      if (placed.object.placement == Placement::kStacked) {
        placed_[placed.object.partner_label - 1].has_child = true;
      }
      placed_.push_back(std::move(placed));
    }
    for (Placed& pl : placed_) {
      scene.objects.push_back(pl.object);
      scene.primitives.insert(scene.primitives.end(), pl.primitives.begin(), pl.primitives.end());
    }
    return scene;
  }

 private:
  void PlaceCamera(Scene* scene) {
    const double azimuth =
        kDeg * rng_.Uniform(-p_.camera_azimuth_max_deg, p_.camera_azimuth_max_deg);
    const double elevation =
        kDeg * rng_.Uniform(p_.camera_elevation_min_deg, p_.camera_elevation_max_deg);
    const double distance = rng_.Uniform(p_.camera_distance_min_m, p_.camera_distance_max_m);
    const double roll = kDeg * rng_.Uniform(-p_.camera_roll_max_deg, p_.camera_roll_max_deg);
    const Vec3 target{rng_.Uniform(-p_.look_at_jitter_m, p_.look_at_jitter_m),
                      rng_.Uniform(-p_.look_at_jitter_m, p_.look_at_jitter_m), p_.table_height_m};
    const Vec3 forward{std::sin(azimuth) * std::cos(elevation),
                       std::cos(azimuth) * std::cos(elevation), -std::sin(elevation)};
    const Vec3 right = Normalized(Cross(forward, Vec3{0.0, 0.0, 1.0}));
    const Vec3 down = Cross(forward, right);
    const Vec3 x_axis = std::cos(roll) * right + std::sin(roll) * down;
    const Vec3 y_axis = std::cos(roll) * down + (-std::sin(roll)) * right;
    scene->camera_pose = Pose::FromAxes(x_axis, y_axis, forward, target - distance * forward);
  }

  void AddBackground(Scene* scene) {
    scene->table_top_z_m = p_.table_height_m;
    scene->table_width_m = p_.table_width_m;
    scene->table_depth_m = p_.table_depth_m;
    const core::Rgb8 wood{static_cast<uint8_t>(rng_.UniformInt(135, 175)),
                          static_cast<uint8_t>(rng_.UniformInt(90, 115)),
                          static_cast<uint8_t>(rng_.UniformInt(50, 70))};
    Primitive top;
    top.kind = PrimitiveKind::kBox;
    top.pose = Pose::FromYaw(0.0, {0.0, 0.0, p_.table_height_m - 0.5 * p_.table_thickness_m});
    top.size_m = {p_.table_width_m, p_.table_depth_m, p_.table_thickness_m};
    top.color = wood;
    top.texture = SurfaceTexture::kWood;
    scene->primitives.push_back(top);
    const double leg = 0.05;
    const double leg_h = p_.table_height_m - p_.table_thickness_m;
    for (int i = 0; i < 4; ++i) {
      Primitive l = top;
      l.texture = SurfaceTexture::kPlain;
      l.color = {static_cast<uint8_t>(wood.r * 3 / 4), static_cast<uint8_t>(wood.g * 3 / 4),
                 static_cast<uint8_t>(wood.b * 3 / 4)};
      const double x = (i & 1 ? 1.0 : -1.0) * (0.5 * p_.table_width_m - 0.06);
      const double y = (i & 2 ? 1.0 : -1.0) * (0.5 * p_.table_depth_m - 0.06);
      l.pose = Pose::FromYaw(0.0, {x, y, 0.5 * leg_h});
      l.size_m = {leg, leg, leg_h};
      scene->primitives.push_back(l);
    }
    const bool wall = rng_.Bernoulli(p_.wall_probability);
    const uint8_t grey = static_cast<uint8_t>(rng_.UniformInt(90, 150));
    const core::Rgb8 wall_color{static_cast<uint8_t>(rng_.UniformInt(200, 235)),
                                static_cast<uint8_t>(rng_.UniformInt(200, 235)),
                                static_cast<uint8_t>(rng_.UniformInt(190, 225))};
    if (p_.with_floor) {
      Primitive floor;
      floor.kind = PrimitiveKind::kPlane;
      floor.color = {grey, grey, static_cast<uint8_t>(grey + 10)};
      floor.texture = SurfaceTexture::kTiles;
      scene->primitives.push_back(floor);
      scene->has_floor = true;
    }
    if (wall) {
      Primitive w;
      w.kind = PrimitiveKind::kPlane;
      w.pose = Pose::FromAxes({1.0, 0.0, 0.0}, {0.0, 0.0, 1.0}, {0.0, -1.0, 0.0},
                              {0.0, 0.5 * p_.table_depth_m + p_.wall_distance_m, 0.0});
      w.color = wall_color;
      scene->primitives.push_back(w);
      scene->has_wall = true;
    }
  }

  // A random point of the table top visible through a random pixel; false when that pixel
  // does not see the table.
  bool SampleVisibleTablePoint(double* x, double* y) {
    const core::CameraIntrinsics& k = p_.intrinsics;
    const double u = rng_.Uniform(0.0, k.width - 1.0);
    const double v = rng_.Uniform(0.0, k.height - 1.0);
    const Vec3 dir = camera_.Rotate({(u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0});
    if (dir.z >= -1e-6) return false;
    const double t = (p_.table_height_m - camera_.translation.z) / dir.z;
    *x = camera_.translation.x + t * dir.x;
    *y = camera_.translation.y + t * dir.y;
    return std::abs(*x) < table_.half_x_m && std::abs(*y) < table_.half_y_m;
  }

  bool InView(const SceneObject& o, ImageRect* rect) const {
    if (!ProjectObject(o, camera_, p_.intrinsics, rect)) return false;
    const double m = p_.view_margin_px;
    return rect->u0 >= m && rect->v0 >= m && rect->u1 <= p_.intrinsics.width - 1 - m &&
           rect->v1 <= p_.intrinsics.height - 1 - m;
  }

  // Checks a candidate resting on the table: on the table, clear of other table objects
  // (except `partner` which must be touched with a gap below touch_gap_max_m), in view.
  bool AcceptOnTable(const Placed& c, uint32_t partner) const {
    if (!InsideRect(c.object.footprint, table_, p_.table_margin_m)) return false;
    for (const Placed& other : placed_) {
      if (other.object.placement == Placement::kStacked) continue;  // inside its support
      const double d = FootprintDistance(c.object.footprint, other.object.footprint);
      if (other.object.label == partner) {
        if (!(d > 0.0 && d < p_.touch_gap_max_m + 1e-6)) return false;
      } else if (d < p_.min_gap_m) {
        return false;
      }
    }
    ImageRect rect;
    return InView(c.object, &rect);
  }

  bool TryPlace(Placement mode, ObjectKind kind, core::Rgb8 color, uint32_t label, Placed* out) {
    std::vector<uint32_t> partners;
    for (const Placed& pl : placed_) {
      const SceneObject& o = pl.object;
      switch (mode) {
        case Placement::kStacked:
          if ((o.kind == ObjectKind::kBox || o.kind == ObjectKind::kBook) && !pl.has_child &&
              o.footprint.half_x_m > 0.03 && o.footprint.half_y_m > 0.03) {
            partners.push_back(o.label);
          }
          break;
        case Placement::kTouching:
          if (o.placement != Placement::kStacked) partners.push_back(o.label);
          break;
        case Placement::kOccluding:
          partners.push_back(o.label);
          break;
        case Placement::kFree:
          break;
      }
    }
    if (mode != Placement::kFree && partners.empty()) return false;
    if (mode == Placement::kStacked) {
      // Only flat-bottomed upright objects stack: boxes, books, cans and cups.
      std::vector<ObjectKind> stackable;
      for (ObjectKind k : p_.object_kinds) {
        if (k == ObjectKind::kBox || k == ObjectKind::kBook || k == ObjectKind::kCan ||
            k == ObjectKind::kCup) {
          stackable.push_back(k);
        }
      }
      if (stackable.empty()) return false;
      if (std::find(stackable.begin(), stackable.end(), kind) == stackable.end()) {
        kind = stackable[static_cast<size_t>(
            rng_.UniformInt(0, static_cast<int>(stackable.size()) - 1))];
      }
    }
    for (int attempt = 0; attempt < p_.max_attempts_per_object; ++attempt) {
      Shape shape = SampleShape(kind, &rng_);
      const uint32_t partner = partners.empty() ? 0
                                                : partners[static_cast<size_t>(rng_.UniformInt(
                                                      0, static_cast<int>(partners.size()) - 1))];
      bool ok = false;
      switch (mode) {
        case Placement::kFree:
          ok = ProposeFree(shape, color, label, out);
          break;
        case Placement::kTouching:
          ok = ProposeTouching(&shape, placed_[partner - 1].object, color, label, out);
          break;
        case Placement::kStacked:
          ok = ProposeStacked(&shape, placed_[partner - 1].object, color, label, out);
          break;
        case Placement::kOccluding:
          ok = ProposeOccluding(shape, placed_[partner - 1].object, color, label, out);
          break;
      }
      if (ok) {
        out->object.placement = mode;
        out->object.partner_label = mode == Placement::kFree ? 0 : partner;
        return true;
      }
    }
    return false;
  }

  bool ProposeFree(const Shape& s, core::Rgb8 color, uint32_t label, Placed* out) {
    double x, y;
    const double yaw = rng_.Uniform(0.0, kPi);
    if (!SampleVisibleTablePoint(&x, &y)) return false;
    *out = Instantiate(s, x, y, yaw, p_.table_height_m, color, label);
    return AcceptOnTable(*out, 0);
  }

  bool ProposeTouching(Shape* s, const SceneObject& a, core::Rgb8 color, uint32_t label,
                       Placed* out) {
    const double gap = rng_.Uniform(p_.touch_gap_min_m, p_.touch_gap_max_m);
    const Footprint& fa = a.footprint;
    double x = 0.0, y = 0.0, yaw = 0.0;
    if (fa.shape == Footprint::Shape::kRectangle) {
      // Beside one face of A, parallel to it.
      const int side = rng_.UniformInt(0, 3);
      const double face_yaw = fa.yaw_rad + 0.5 * kPi * side;
      const Vec3 e{std::cos(face_yaw), std::sin(face_yaw), 0.0};
      const Vec3 lat{-e.y, e.x, 0.0};
      const double a_e = side % 2 == 0 ? fa.half_x_m : fa.half_y_m;
      const double a_p = side % 2 == 0 ? fa.half_y_m : fa.half_x_m;
      double b_e = s->half_x, b_p = s->half_y;
      yaw = fa.yaw_rad;
      if (!s->circle && rng_.Bernoulli(0.5)) yaw += 0.5 * kPi;
      if (!s->circle) {
        // B's extent along e depends on whether its x axis is along e.
        const bool b_x_along_e = std::abs(std::cos(yaw - face_yaw)) > 0.5;
        b_e = b_x_along_e ? s->half_x : s->half_y;
        b_p = b_x_along_e ? s->half_y : s->half_x;
      }
      // Keep at least 1 cm of the facing sides overlapping so the gap is face to face.
      const double lat_max = s->circle ? a_p - 0.005 : a_p + b_p - 0.01;
      if (lat_max <= 0.0) return false;
      const double shift = rng_.Uniform(-lat_max, lat_max);
      const double along = a_e + b_e + gap;
      x = fa.center_x_m + along * e.x + shift * lat.x;
      y = fa.center_y_m + along * e.y + shift * lat.y;
    } else {
      const double ra = fa.half_x_m;
      if (s->circle) {
        const double phi = rng_.Uniform(0.0, 2.0 * kPi);
        const double along = ra + s->half_x + gap;
        x = fa.center_x_m + along * std::cos(phi);
        y = fa.center_y_m + along * std::sin(phi);
      } else {
        // A's centre faces the middle of one of B's sides.
        yaw = rng_.Uniform(0.0, kPi);
        const int side = rng_.UniformInt(0, 3);
        const double face_yaw = yaw + 0.5 * kPi * side;
        const double b_e = side % 2 == 0 ? s->half_x : s->half_y;
        const double along = ra + b_e + gap;
        x = fa.center_x_m + along * std::cos(face_yaw);
        y = fa.center_y_m + along * std::sin(face_yaw);
      }
    }
    *out = Instantiate(*s, x, y, yaw, p_.table_height_m, color, label);
    return AcceptOnTable(*out, a.label);
  }

  bool ProposeStacked(Shape* s, const SceneObject& a, core::Rgb8 color, uint32_t label,
                      Placed* out) {
    const Footprint& fa = a.footprint;
    const double room_x = fa.half_x_m - kStackMarginM;
    const double room_y = fa.half_y_m - kStackMarginM;
    const bool rotated = !s->circle && rng_.Bernoulli(0.5);
    const double yaw = fa.yaw_rad + (rotated ? 0.5 * kPi : 0.0);
    double bx = 0.0;  // B's half extent along A's x axis
    double by = 0.0;  // and along A's y axis
    if (s->circle) {
      s->half_x = s->half_y = std::min(s->half_x, std::min(room_x, room_y));
      bx = by = s->half_x;
    } else {
      double& along_x = rotated ? s->half_y : s->half_x;
      double& along_y = rotated ? s->half_x : s->half_y;
      along_x = std::min(along_x, room_x);
      along_y = std::min(along_y, room_y);
      bx = along_x;
      by = along_y;
    }
    if (bx < 0.02 || by < 0.02) return false;
    const double ox = rng_.Uniform(-(room_x - bx), room_x - bx + 1e-12);
    const double oy = rng_.Uniform(-(room_y - by), room_y - by + 1e-12);
    const double c = std::cos(fa.yaw_rad);
    const double sn = std::sin(fa.yaw_rad);
    const double x = fa.center_x_m + c * ox - sn * oy;
    const double y = fa.center_y_m + sn * ox + c * oy;
    if (a.top_z_m + s->height > p_.table_height_m + 0.45) return false;
    *out = Instantiate(*s, x, y, yaw, a.top_z_m, color, label);
    if (!InsideRect(out->object.footprint, fa, 0.0)) return false;
    ImageRect rect;
    return InView(out->object, &rect);
  }

  bool ProposeOccluding(const Shape& s, const SceneObject& a, core::Rgb8 color, uint32_t label,
                        Placed* out) {
    const Footprint& fa = a.footprint;
    const Vec3 to_camera = Normalized(
        Vec3{camera_.translation.x - fa.center_x_m, camera_.translation.y - fa.center_y_m, 0.0});
    const Vec3 lat{-to_camera.y, to_camera.x, 0.0};
    const double ea = std::hypot(fa.half_x_m, fa.half_y_m);
    const double eb = std::hypot(s.half_x, s.half_y);
    const double along = ea + eb + rng_.Uniform(p_.min_gap_m, p_.min_gap_m + 0.06);
    const double shift = rng_.Uniform(-0.6, 0.6) * ea;
    const double x = fa.center_x_m + along * to_camera.x + shift * lat.x;
    const double y = fa.center_y_m + along * to_camera.y + shift * lat.y;
    *out = Instantiate(s, x, y, rng_.Uniform(0.0, kPi), p_.table_height_m, color, label);
    if (!AcceptOnTable(*out, 0)) return false;
    // The new object must overlap its target in the image.
    ImageRect ra, rb;
    if (!ProjectObject(a, camera_, p_.intrinsics, &ra) ||
        !ProjectObject(out->object, camera_, p_.intrinsics, &rb)) {
      return false;
    }
    return rb.u0 < ra.u1 && ra.u0 < rb.u1 && rb.v0 < ra.v1 && ra.v0 < rb.v1;
  }

  const SceneParams& p_;
  Rng rng_;
  Pose camera_;
  Footprint table_;
  double hue0_{0.0};
  std::vector<Placed> placed_;
};

// Every check goes through core::ParamCheck: one message format, naming the field.
[[noreturn]] void Invalid(const char* key, double value, const char* want) {
  const std::string_view w(want);
  core::ParamCheck("scene").Fail(key, core::FormatParamValue(value),
                                 w.rfind("expected ", 0) == 0 ? w.substr(9) : w);
}

}  // namespace

std::vector<ObjectKind> AllObjectKinds() {
  return {ObjectKind::kBox,           ObjectKind::kBook,   ObjectKind::kCan,  ObjectKind::kBottle,
          ObjectKind::kLyingCylinder, ObjectKind::kSphere, ObjectKind::kBowl, ObjectKind::kCup};
}

std::string ToString(ObjectKind kind) {
  switch (kind) {
    case ObjectKind::kBox:
      return "box";
    case ObjectKind::kBook:
      return "book";
    case ObjectKind::kCan:
      return "can";
    case ObjectKind::kBottle:
      return "bottle";
    case ObjectKind::kLyingCylinder:
      return "lying_cylinder";
    case ObjectKind::kSphere:
      return "sphere";
    case ObjectKind::kBowl:
      return "bowl";
    case ObjectKind::kCup:
      return "cup";
  }
  return "unknown";
}

std::string ToString(Placement placement) {
  switch (placement) {
    case Placement::kFree:
      return "free";
    case Placement::kTouching:
      return "touching";
    case Placement::kStacked:
      return "stacked";
    case Placement::kOccluding:
      return "occluding";
  }
  return "unknown";
}

double FootprintDistance(const Footprint& a, const Footprint& b) {
  using S = Footprint::Shape;
  if (a.shape == S::kCircle && b.shape == S::kCircle) {
    const double d = std::hypot(a.center_x_m - b.center_x_m, a.center_y_m - b.center_y_m);
    return std::max(0.0, d - a.half_x_m - b.half_x_m);
  }
  if (a.shape == S::kCircle || b.shape == S::kCircle) {
    const Footprint& circle = a.shape == S::kCircle ? a : b;
    const Footprint& rect = a.shape == S::kCircle ? b : a;
    return std::max(
        0.0, PointRectDistance(rect, circle.center_x_m, circle.center_y_m) - circle.half_x_m);
  }
  if (!RectsSeparated(a, b)) return 0.0;
  // Disjoint convex polygons: the closest pair involves a vertex of one of them.
  double ax[4], ay[4], bx[4], by[4];
  FootprintCorners(a, ax, ay);
  FootprintCorners(b, bx, by);
  double d = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 4; ++i) {
    d = std::min(d, PointRectDistance(b, ax[i], ay[i]));
    d = std::min(d, PointRectDistance(a, bx[i], by[i]));
  }
  return d;
}

void SceneParams::ValidateOrThrow() const {
  if (min_objects < 0 || min_objects > 64) Invalid("min_objects", min_objects, "expected 0..64");
  if (max_objects < min_objects || max_objects > 64) {
    Invalid("max_objects", max_objects, "expected min_objects..64");
  }
  if (object_kinds.empty()) Invalid("object_kinds", 0, "expected at least one kind");
  auto prob = [](const char* key, double v) {
    if (!(v >= 0.0 && v <= 1.0)) Invalid(key, v, "expected a probability in [0, 1]");
  };
  prob("stack_probability", stack_probability);
  prob("touch_probability", touch_probability);
  prob("occlude_probability", occlude_probability);
  prob("wall_probability", wall_probability);
  if (!(stack_probability + touch_probability + occlude_probability <= 1.0 + 1e-9)) {
    Invalid("stack_probability + touch_probability + occlude_probability",
            stack_probability + touch_probability + occlude_probability, "expected <= 1");
  }
  if (!(touch_gap_min_m > 0.0)) Invalid("touch_gap_min_m", touch_gap_min_m, "expected > 0");
  if (!(touch_gap_max_m >= touch_gap_min_m && touch_gap_max_m <= 0.002)) {
    Invalid("touch_gap_max_m", touch_gap_max_m, "expected touch_gap_min_m..0.002");
  }
  if (!(min_gap_m >= touch_gap_max_m && min_gap_m < 0.5)) {
    Invalid("min_gap_m", min_gap_m, "expected touch_gap_max_m..0.5");
  }
  if (!(table_width_m >= 0.3 && table_width_m <= 5.0))
    Invalid("table_width_m", table_width_m, "expected 0.3..5");
  if (!(table_depth_m >= 0.3 && table_depth_m <= 5.0))
    Invalid("table_depth_m", table_depth_m, "expected 0.3..5");
  if (!(table_height_m >= 0.1 && table_height_m <= 2.0))
    Invalid("table_height_m", table_height_m, "expected 0.1..2");
  if (!(table_thickness_m > 0.0 && table_thickness_m < table_height_m)) {
    Invalid("table_thickness_m", table_thickness_m, "expected 0..table_height_m");
  }
  if (!(table_margin_m >= 0.0 && 2.0 * table_margin_m < std::min(table_width_m, table_depth_m))) {
    Invalid("table_margin_m", table_margin_m, "expected >= 0 and smaller than half the table");
  }
  if (!(camera_distance_min_m >= 0.3))
    Invalid("camera_distance_min_m", camera_distance_min_m, "expected >= 0.3");
  if (!(camera_distance_max_m >= camera_distance_min_m && camera_distance_max_m <= 5.0)) {
    Invalid("camera_distance_max_m", camera_distance_max_m, "expected camera_distance_min_m..5");
  }
  if (!(camera_elevation_min_deg >= 5.0 && camera_elevation_min_deg <= 90.0)) {
    Invalid("camera_elevation_min_deg", camera_elevation_min_deg, "expected 5..90");
  }
  if (!(camera_elevation_max_deg >= camera_elevation_min_deg && camera_elevation_max_deg <= 90.0)) {
    Invalid("camera_elevation_max_deg", camera_elevation_max_deg,
            "expected camera_elevation_min_deg..90");
  }
  if (!(camera_azimuth_max_deg >= 0.0 && camera_azimuth_max_deg <= 80.0)) {
    Invalid("camera_azimuth_max_deg", camera_azimuth_max_deg, "expected 0..80");
  }
  if (!(camera_roll_max_deg >= 0.0 && camera_roll_max_deg <= 45.0)) {
    Invalid("camera_roll_max_deg", camera_roll_max_deg, "expected 0..45");
  }
  if (!(look_at_jitter_m >= 0.0 && look_at_jitter_m <= 1.0))
    Invalid("look_at_jitter_m", look_at_jitter_m, "expected 0..1");
  if (!(wall_distance_m >= 0.0 && wall_distance_m <= 5.0))
    Invalid("wall_distance_m", wall_distance_m, "expected 0..5");
  if (!(view_margin_px >= 0.0)) Invalid("view_margin_px", view_margin_px, "expected >= 0");
  if (max_attempts_per_object < 1)
    Invalid("max_attempts_per_object", max_attempts_per_object, "expected >= 1");
  intrinsics.ValidateOrThrow();
}

Scene GenerateScene(const SceneParams& params, uint64_t seed) {
  params.ValidateOrThrow();
  Generator generator(params, seed);
  return generator.Run();
}

std::vector<Scene> GenerateSequence(const SceneParams& params, uint64_t seed, int num_frames) {
  if (num_frames < 1 || num_frames > 65) Invalid("num_frames", num_frames, "expected 1..65");
  SceneParams p = params;
  p.min_objects = p.max_objects = num_frames - 1;
  const Scene full = GenerateScene(p, seed);
  std::vector<Scene> frames(static_cast<size_t>(num_frames));
  for (int k = 0; k < num_frames; ++k) {
    Scene& f = frames[static_cast<size_t>(k)];
    f = full;
    const uint32_t max_label = static_cast<uint32_t>(k);
    f.primitives.clear();
    for (const Primitive& prim : full.primitives) {
      if (prim.label <= max_label) f.primitives.push_back(prim);
    }
    f.objects.resize(std::min(full.objects.size(), static_cast<size_t>(k)));
  }
  return frames;
}

}  // namespace clutterseg::synth
