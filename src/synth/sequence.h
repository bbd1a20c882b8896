#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

#include "clutterseg/synth/scene.h"

namespace clutterseg::synth {

/// What happens on the table over a generated sequence. Every frame shares the camera of one
/// generated scene (unless SequenceParams::camera_jitter_m / _deg shake it) and every physical
/// object keeps its label in every frame it is in (its label in the full scene).
enum class Scenario : uint8_t {
  kAdd,        ///< "add": frame 0 is the empty table, one object added every step_frames
  kRemove,     ///< "remove": every object at first, one removed every step_frames (never one
               ///< something stands on)
  kAddRemove,  ///< "add-remove": half the objects at first, then every step_frames one added
               ///< or one removed at random; an object is added and removed at most once
  kOccluder,   ///< "occluder": every object, and an occluder between camera and table that
               ///< sweeps across the view from one side to the other over the sequence
  kStatic,     ///< "static": every object in every frame (only the sensor noise changes)
  /// "piles": objects in touching piles (the scene is drawn with PileSceneParams), one
  /// placed every step_frames frames until all are on the table, an occluder sweeping across
  /// the view over the next step_frames frames, step_frames frames of nothing but noise, then
  /// one removed every step_frames frames (never one something stands on) until the table is
  /// empty: (2 N + 2) step_frames frames for N objects; frames past that show the empty table.
  kPiles,
};

/// Parses "add", "remove", "add-remove", "occluder", "static" or "piles".
/// @throws std::invalid_argument naming the value otherwise.
Scenario ParseScenario(std::string_view name);
/// The name ParseScenario accepts.
std::string_view ScenarioName(Scenario scenario);

/// Shape of the Scenario::kOccluder occluder.
enum class OccluderShape : uint8_t {
  kArm,  ///< a cylinder along the camera's image vertical, longer than the view is high
  kBox,  ///< a cube held in the air
};

/// Parses "arm" or "box". @throws std::invalid_argument naming the value otherwise.
OccluderShape ParseOccluderShape(std::string_view name);
std::string_view OccluderShapeName(OccluderShape shape);

/// `base` with the placement probabilities of Scenario::kPiles: most objects touch another one
/// (touch_probability 0.6) or stand on one (stack_probability 0.25), a few stand in front of
/// another (occlude_probability 0.1), the rest stand free; the gaps of touching objects and
/// everything else as in `base`.
SceneParams PileSceneParams(SceneParams base);

/// Knobs of GenerateScenarioSequence. Distances in metres, angles in degrees.
struct SequenceParams {
  Scenario scenario{Scenario::kAdd};
  int num_frames{30};
  /// Objects placed in the underlying scene (fewer when the table in view is too crowded).
  int num_objects{6};
  /// kAdd, kRemove, kAddRemove, kPiles: frames between two changes of the object set (>= 1);
  /// kPiles: also the length of the occluder's sweep and of the static stretch after it.
  int step_frames{3};
  OccluderShape occluder_shape{OccluderShape::kArm};
  /// Arm radius, or half the side of the box.
  double occluder_radius_m{0.04};
  /// Where the occluder passes: this fraction of the way from the camera to the point its
  /// optical axis meets the table (0..1 exclusive).
  double occluder_depth_fraction{0.5};
  /// Per-frame random camera shake (a hand-held camera held still): each frame's camera is
  /// moved by up to this much along each axis and turned by up to camera_jitter_deg about
  /// each axis (0 = a camera on a tripod).
  double camera_jitter_m{0.0};
  double camera_jitter_deg{0.0};

  /// @throws std::invalid_argument naming the key and value when a field is out of range.
  void ValidateOrThrow() const;
};

/// Generates the frames of one scenario over one scene drawn with `scene_params` (its
/// min_objects / max_objects replaced by params.num_objects; Scenario::kPiles draws it with
/// PileSceneParams(scene_params)) and `seed`. frames[k].objects
/// lists the objects present in frame k (by increasing label, labels of the full scene, so
/// objects[i].label == i + 1 no longer holds once one is removed); the occluder's primitives
/// carry Scene::occluder_label. Scenario::kAdd with step_frames = 1 and num_objects =
/// num_frames - 1 gives the frames of GenerateSequence. Deterministic in (params, seed).
/// Thread-safety: pure function.
/// @throws std::invalid_argument when either params is invalid.
std::vector<Scene> GenerateScenarioSequence(const SceneParams& scene_params,
                                            const SequenceParams& params, uint64_t seed);

}  // namespace clutterseg::synth
