#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/types.h"
#include "clutterseg/synth/pose.h"

namespace clutterseg::synth {

/// Analytic surfaces the ray caster intersects. Each is defined in its local frame (see
/// Primitive::size_m for the dimensions).
enum class PrimitiveKind : uint8_t {
  kBox,              ///< solid box centred on the origin
  kCylinder,         ///< along local z, centred on the origin; caps optional (open = tube)
  kFrustum,          ///< cone frustum along local z, centred on the origin; caps optional
  kSphere,           ///< solid sphere centred on the origin
  kHemisphereShell,  ///< zero-thickness shell: the part of a sphere with local z <= 0
  kPlane,            ///< infinite plane z = 0 (two-sided)
};

/// Procedural surface colouring.
enum class SurfaceTexture : uint8_t { kPlain, kWood, kTiles };

/// One analytic surface of the scene. Several primitives may share a label (a bottle is a
/// cylinder, a frustum and a neck cylinder).
struct Primitive {
  PrimitiveKind kind{PrimitiveKind::kBox};
  /// World-from-local transform (world: z up, metres, table top centred above the origin).
  Pose pose;
  /// Dimensions in metres, by kind: kBox full extents (x, y, z); kCylinder (radius, unused,
  /// height); kFrustum (radius at z = -h/2, radius at z = +h/2, height h); kSphere and
  /// kHemisphereShell (radius, unused, unused); kPlane unused.
  Vec3 size_m;
  bool cap_bottom{true};  ///< kCylinder / kFrustum: disc at local z = -h/2 present
  bool cap_top{true};     ///< kCylinder / kFrustum: disc at local z = +h/2 present
  core::Rgb8 color;
  SurfaceTexture texture{SurfaceTexture::kPlain};
  /// 0 = background (table, floor, wall); 1..N = object in placement order.
  uint32_t label{0};
};

/// Object categories the generator places.
enum class ObjectKind : uint8_t {
  kBox,
  kBook,           ///< thin flat box lying flat
  kCan,            ///< upright closed cylinder
  kBottle,         ///< upright cylinder + shoulder frustum + neck
  kLyingCylinder,  ///< cylinder with a horizontal axis
  kSphere,
  kBowl,  ///< hemispherical shell, open top
  kCup,   ///< open cylinder with a bottom
};

/// All object kinds, in enum order.
std::vector<ObjectKind> AllObjectKinds();
/// Lower-case name ("box", "lying_cylinder", ...).
std::string ToString(ObjectKind kind);

/// How an object was placed relative to the others.
enum class Placement : uint8_t {
  kFree,       ///< on the table, clear of every other object
  kTouching,   ///< on the table beside `partner_label` with a gap below 2 mm
  kStacked,    ///< resting on top of `partner_label` (a box or book)
  kOccluding,  ///< on the table between the camera and `partner_label`
};

/// Lower-case name ("free", "touching", ...).
std::string ToString(Placement placement);

/// The 2-D outline of an object on its supporting surface (world x-y, metres).
struct Footprint {
  enum class Shape : uint8_t { kRectangle, kCircle };
  Shape shape{Shape::kRectangle};
  double center_x_m{0.0};
  double center_y_m{0.0};
  double yaw_rad{0.0};   ///< kRectangle: rotation of the half_x axis from world x
  double half_x_m{0.0};  ///< kRectangle half length; kCircle radius
  double half_y_m{0.0};  ///< kRectangle half width; kCircle radius
};

/// Smallest distance between two footprints in metres; 0 when they overlap or touch.
double FootprintDistance(const Footprint& a, const Footprint& b);

/// Object-level ground truth.
struct SceneObject {
  uint32_t label{0};  ///< 1..N, equal to the index in Scene::objects plus one
  ObjectKind kind{ObjectKind::kBox};
  Placement placement{Placement::kFree};
  uint32_t partner_label{0};  ///< see Placement; 0 when free
  Footprint footprint;
  double bottom_z_m{0.0};  ///< lowest point, world z
  double top_z_m{0.0};     ///< highest point, world z
  core::Rgb8 color;
};

/// A labelled tabletop scene: analytic primitives and a camera.
struct Scene {
  std::vector<Primitive> primitives;  ///< background first, then objects in label order
  /// By increasing label; objects[i].label == i + 1 in a scene from GenerateScene. Frames of a
  /// sequence keep every object's label, so a frame may hold a subset of them.
  std::vector<SceneObject> objects;
  /// Label of a moving occluder's primitives (GenerateScenarioSequence), 0 when there is none.
  /// It is not in `objects`.
  uint32_t occluder_label{0};
  /// World-from-camera pose; camera frame x right, y down, z forward (optical axis).
  Pose camera_pose;
  double table_top_z_m{0.0};
  double table_width_m{0.0};  ///< along world x
  double table_depth_m{0.0};  ///< along world y
  bool has_floor{false};
  bool has_wall{false};
};

/// Seed-independent knobs of the scene generator. Distances in metres, angles in degrees.
struct SceneParams {
  int min_objects{3};
  int max_objects{8};
  std::vector<ObjectKind> object_kinds{AllObjectKinds()};
  /// Probability that a new object is stacked on a free box/book top (if one exists).
  double stack_probability{0.2};
  /// Probability that a new object is placed touching an object on the table.
  double touch_probability{0.25};
  /// Probability that a new object is placed in front of another, as seen by the camera.
  double occlude_probability{0.2};
  double touch_gap_min_m{0.0003};
  double touch_gap_max_m{0.0018};
  /// Minimum footprint gap between objects that are not deliberately touching.
  double min_gap_m{0.01};

  double table_width_m{1.2};
  double table_depth_m{0.8};
  double table_height_m{0.72};
  double table_thickness_m{0.03};
  /// Objects keep this distance from the table edges.
  double table_margin_m{0.03};

  double camera_distance_min_m{0.6};  ///< from the camera to the look-at point
  double camera_distance_max_m{1.5};
  double camera_elevation_min_deg{30.0};  ///< optical axis below the horizontal
  double camera_elevation_max_deg{60.0};
  double camera_azimuth_max_deg{30.0};  ///< about world z, 0 = looking along +y
  double camera_roll_max_deg{3.0};
  double look_at_jitter_m{0.05};

  bool with_floor{true};
  double wall_probability{0.5};
  double wall_distance_m{0.25};  ///< from the table's far edge to the back wall

  /// Every object must project fully inside this camera's image (with `view_margin_px`).
  core::CameraIntrinsics intrinsics{core::DefaultKinectIntrinsics()};
  double view_margin_px{8.0};
  int max_attempts_per_object{300};

  /// @throws std::invalid_argument naming the key and value when a field is out of range.
  void ValidateOrThrow() const;
};

/// Generates one scene: camera, table, optional floor and wall, and between min_objects and
/// max_objects objects resting on the table without interpenetration. When the table area in
/// view is too crowded the scene holds fewer objects than drawn (see Scene::objects).
/// Deterministic: the same params and seed give the same scene (random draws use a portable
/// generator; geometry goes through the C math library).
/// Thread-safety: pure function.
/// @throws std::invalid_argument when `params` is invalid.
Scene GenerateScene(const SceneParams& params, uint64_t seed);

/// An incremental sequence (as in OCID): frame 0 is the empty table, frame k holds the first
/// min(k, M) objects of one scene, where M <= num_frames - 1 is the number that could be
/// placed; all frames share the camera. Thread-safety: pure function.
/// @throws std::invalid_argument when `params` is invalid or num_frames < 1.
std::vector<Scene> GenerateSequence(const SceneParams& params, uint64_t seed, int num_frames);

}  // namespace clutterseg::synth
