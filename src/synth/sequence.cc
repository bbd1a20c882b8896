#include "clutterseg/synth/sequence.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "clutterseg/core/param_check.h"
#include "clutterseg/synth/random.h"

namespace clutterseg::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

// The frame of `full` that holds the objects with present[label] set (and no occluder).
Scene FrameWith(const Scene& full, const std::vector<uint8_t>& present) {
  Scene f = full;
  f.primitives.clear();
  for (const Primitive& p : full.primitives) {
    if (p.label == 0 || present[p.label]) f.primitives.push_back(p);
  }
  f.objects.clear();
  for (const SceneObject& o : full.objects) {
    if (present[o.label]) f.objects.push_back(o);
  }
  return f;
}

// The object stacked on `label`, if present; stacking is one level deep or more, so every
// present object standing on it counts.
bool HasPresentChild(const Scene& full, const std::vector<uint8_t>& present, uint32_t label) {
  for (const SceneObject& o : full.objects) {
    if (present[o.label] && o.placement == Placement::kStacked && o.partner_label == label) {
      return true;
    }
  }
  return false;
}

bool CanAdd(const SceneObject& o, const std::vector<uint8_t>& present) {
  return o.placement != Placement::kStacked || present[o.partner_label];
}

// Rotation about a unit axis by `angle` radians (Rodrigues), row-major.
std::array<double, 9> AxisAngle(const Vec3& a, double angle) {
  const double c = std::cos(angle), s = std::sin(angle), t = 1.0 - c;
  return {t * a.x * a.x + c,       t * a.x * a.y - s * a.z, t * a.x * a.z + s * a.y,
          t * a.x * a.y + s * a.z, t * a.y * a.y + c,       t * a.y * a.z - s * a.x,
          t * a.x * a.z - s * a.y, t * a.y * a.z + s * a.x, t * a.z * a.z + c};
}

std::array<double, 9> Multiply(const std::array<double, 9>& a, const std::array<double, 9>& b) {
  std::array<double, 9> r{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      for (int k = 0; k < 3; ++k) r[3 * i + j] += a[3 * i + k] * b[3 * k + j];
    }
  }
  return r;
}

// Shakes the camera of frame `k` (a hand-held camera held still).
void Jitter(const SequenceParams& params, uint64_t seed, int k, Pose* camera) {
  if (params.camera_jitter_m <= 0.0 && params.camera_jitter_deg <= 0.0) return;
  Rng rng(HashCounter(seed, 0x6a17, static_cast<uint64_t>(k)));
  const double m = params.camera_jitter_m;
  const Vec3 shift{rng.Uniform(-m, m), rng.Uniform(-m, m), rng.Uniform(-m, m)};
  std::array<double, 9> r = camera->rotation;
  for (int axis = 0; axis < 3; ++axis) {
    const double angle = kDeg * rng.Uniform(-params.camera_jitter_deg, params.camera_jitter_deg);
    r = Multiply(
        r, AxisAngle(Vec3{axis == 0 ? 1.0 : 0.0, axis == 1 ? 1.0 : 0.0, axis == 2 ? 1.0 : 0.0},
                     angle));
  }
  camera->rotation = r;
  camera->translation = camera->translation + shift;
}

// Adds the occluder of frame `k` of `n` to `frame`.
void AddOccluder(const SceneParams& scene_params, const SequenceParams& params, int k, int n,
                 uint32_t label, Scene* frame) {
  const Pose& cam = frame->camera_pose;
  const Vec3 x_cam = cam.Axis(0), y_cam = cam.Axis(1), z_cam = cam.Axis(2);
  // Distance along the optical axis to the table top (the look-at point).
  double range = 1.0;
  if (z_cam.z < -1e-6) range = (frame->table_top_z_m - cam.translation.z) / z_cam.z;
  const double depth = params.occluder_depth_fraction * range;
  const core::CameraIntrinsics& in = scene_params.intrinsics;
  // Just outside the view at both ends: the occluder's far side (depth + r) is where the
  // view is widest.
  const double r = params.occluder_radius_m;
  const double half_view = (depth + r) * std::max(in.cx, in.width - in.cx) / in.fx;
  const double reach = half_view + r + 0.02;
  const double t = n > 1 ? static_cast<double>(k) / (n - 1) : 0.5;
  const Vec3 center = cam.translation + depth * z_cam + (-reach + 2.0 * reach * t) * x_cam;
  Primitive p;
  p.label = label;
  p.color = core::Rgb8{200, 160, 130};
  if (params.occluder_shape == OccluderShape::kArm) {
    const double view_height = depth * in.height / in.fy;
    p.kind = PrimitiveKind::kCylinder;
    p.pose = Pose::FromAxes(x_cam, -z_cam, y_cam, center);
    p.size_m = Vec3{r, r, 3.0 * view_height};
  } else {
    p.kind = PrimitiveKind::kBox;
    p.pose = Pose::FromAxes(x_cam, y_cam, z_cam, center);
    p.size_m = Vec3{2.0 * r, 2.0 * r, 2.0 * r};
  }
  frame->primitives.push_back(p);
  frame->occluder_label = label;
}

}  // namespace

Scenario ParseScenario(std::string_view name) {
  for (Scenario s : {Scenario::kAdd, Scenario::kRemove, Scenario::kAddRemove, Scenario::kOccluder,
                     Scenario::kStatic, Scenario::kPiles}) {
    if (name == ScenarioName(s)) return s;
  }
  throw std::invalid_argument("unknown scenario '" + std::string(name) +
                              "' (expected add, remove, add-remove, occluder, static or piles)");
}

std::string_view ScenarioName(Scenario scenario) {
  switch (scenario) {
    case Scenario::kAdd:
      return "add";
    case Scenario::kRemove:
      return "remove";
    case Scenario::kAddRemove:
      return "add-remove";
    case Scenario::kOccluder:
      return "occluder";
    case Scenario::kStatic:
      return "static";
    case Scenario::kPiles:
      return "piles";
  }
  return "unknown";
}

SceneParams PileSceneParams(SceneParams base) {
  base.touch_probability = 0.6;
  base.stack_probability = 0.25;
  base.occlude_probability = 0.1;
  return base;
}

OccluderShape ParseOccluderShape(std::string_view name) {
  if (name == "arm") return OccluderShape::kArm;
  if (name == "box") return OccluderShape::kBox;
  throw std::invalid_argument("unknown occluder shape '" + std::string(name) +
                              "' (expected arm or box)");
}

std::string_view OccluderShapeName(OccluderShape shape) {
  return shape == OccluderShape::kArm ? "arm" : "box";
}

void SequenceParams::ValidateOrThrow() const {
  const core::ParamCheck check("sequence");
  check.InRange("num_frames", num_frames, 1, 100000);
  check.InRange("num_objects", num_objects, 0, 64);
  check.AtLeast("step_frames", step_frames, 1);
  check.Require(occluder_radius_m > 0.0 && occluder_radius_m <= 0.5, "occluder_radius_m",
                occluder_radius_m, "a radius in (0, 0.5] m");
  check.Require(occluder_depth_fraction > 0.0 && occluder_depth_fraction < 1.0,
                "occluder_depth_fraction", occluder_depth_fraction, "a fraction in (0, 1)");
  check.InRange("camera_jitter_m", camera_jitter_m, 0.0, 0.1, "m");
  check.InRange("camera_jitter_deg", camera_jitter_deg, 0.0, 5.0, "degrees");
}

std::vector<Scene> GenerateScenarioSequence(const SceneParams& scene_params,
                                            const SequenceParams& params, uint64_t seed) {
  params.ValidateOrThrow();
  SceneParams p =
      params.scenario == Scenario::kPiles ? PileSceneParams(scene_params) : scene_params;
  p.min_objects = p.max_objects = params.num_objects;
  const Scene full = GenerateScene(p, seed);
  const uint32_t num_labels = static_cast<uint32_t>(full.objects.size());
  const int n = params.num_frames;
  std::vector<Scene> frames;
  frames.reserve(static_cast<size_t>(n));
  std::vector<uint8_t> present(num_labels + 1, 0);
  Rng rng(HashCounter(seed, 0x5e9, static_cast<uint64_t>(params.scenario)));

  switch (params.scenario) {
    case Scenario::kAdd:
      for (int k = 0; k < n; ++k) {
        const uint32_t count = std::min<uint32_t>(num_labels, k / params.step_frames);
        for (uint32_t l = 1; l <= num_labels; ++l) present[l] = l <= count ? 1 : 0;
        frames.push_back(FrameWith(full, present));
      }
      break;
    case Scenario::kRemove:
    case Scenario::kAddRemove: {
      const bool add_remove = params.scenario == Scenario::kAddRemove;
      std::vector<uint8_t> added(num_labels + 1, 0);  // was ever present
      const uint32_t initial = add_remove ? (num_labels + 1) / 2 : num_labels;
      for (uint32_t l = 1; l <= initial; ++l) present[l] = added[l] = 1;
      std::vector<uint32_t> candidates;
      for (int k = 0; k < n; ++k) {
        if (k > 0 && k % params.step_frames == 0) {
          // One change: add (add-remove only) or remove, at random among the possible ones.
          std::vector<uint32_t> addable, removable;
          for (const SceneObject& o : full.objects) {
            if (!added[o.label] && CanAdd(o, present)) addable.push_back(o.label);
            if (present[o.label] && !HasPresentChild(full, present, o.label)) {
              removable.push_back(o.label);
            }
          }
          int present_count = 0;
          for (uint32_t l = 1; l <= num_labels; ++l) present_count += present[l];
          bool add = add_remove && !addable.empty() &&
                     (removable.empty() || present_count < 2 || rng.Bernoulli(0.5));
          candidates = add ? addable : removable;
          if (!candidates.empty()) {
            const uint32_t l = candidates[static_cast<size_t>(
                rng.UniformInt(0, static_cast<int>(candidates.size()) - 1))];
            present[l] = add ? 1 : 0;
            added[l] = 1;
          }
        }
        frames.push_back(FrameWith(full, present));
      }
      break;
    }
    case Scenario::kOccluder:
    case Scenario::kStatic:
      for (uint32_t l = 1; l <= num_labels; ++l) present[l] = 1;
      for (int k = 0; k < n; ++k) {
        frames.push_back(FrameWith(full, present));
        if (params.scenario == Scenario::kOccluder) {
          AddOccluder(p, params, k, n, num_labels + 1, &frames.back());
        }
      }
      break;
    case Scenario::kPiles: {
      // Placed in label order (a stacked object's support and a touching object's partner
      // come first), removed in a random order that never takes away a support first.
      const int s = params.step_frames;
      const int placed_end = static_cast<int>(num_labels) * s;
      const int sweep_end = placed_end + s;
      const int removal_start = sweep_end + s;
      std::vector<uint8_t> all(num_labels + 1, 1);
      std::vector<uint32_t> removal;
      std::vector<uint32_t> removable;
      while (removal.size() < num_labels) {
        removable.clear();
        for (const SceneObject& o : full.objects) {
          if (all[o.label] && !HasPresentChild(full, all, o.label)) removable.push_back(o.label);
        }
        const uint32_t l = removable[static_cast<size_t>(
            rng.UniformInt(0, static_cast<int>(removable.size()) - 1))];
        all[l] = 0;
        removal.push_back(l);
      }
      for (int k = 0; k < n; ++k) {
        if (k < placed_end) {
          const uint32_t count = static_cast<uint32_t>(k / s) + 1;
          for (uint32_t l = 1; l <= num_labels; ++l) present[l] = l <= count ? 1 : 0;
        } else if (k < removal_start) {
          for (uint32_t l = 1; l <= num_labels; ++l) present[l] = 1;
        } else {
          const size_t removed = std::min<size_t>(num_labels, (k - removal_start) / s + 1);
          for (uint32_t l = 1; l <= num_labels; ++l) present[l] = 1;
          for (size_t i = 0; i < removed; ++i) present[removal[i]] = 0;
        }
        frames.push_back(FrameWith(full, present));
        if (k >= placed_end && k < sweep_end) {
          AddOccluder(p, params, k - placed_end, s, num_labels + 1, &frames.back());
        }
      }
      break;
    }
  }
  for (int k = 0; k < n; ++k) Jitter(params, seed, k, &frames[static_cast<size_t>(k)].camera_pose);
  return frames;
}

}  // namespace clutterseg::synth
