#pragma once

#include <vector>

#include "clutterseg/synth/pose.h"
#include "clutterseg/synth/scene.h"

namespace clutterseg::synth::internal {

/// A primitive with the values the ray caster needs precomputed.
struct PreparedPrimitive {
  PrimitiveKind kind{PrimitiveKind::kBox};
  Pose pose;
  Vec3 half_size;  ///< kBox half extents; others: (radius or r0, r1, half height)
  bool cap_bottom{true};
  bool cap_top{true};
  uint32_t index{0};  ///< index into Scene::primitives
  Vec3 box_half;      ///< half extents of a local-frame box containing the primitive
  bool bounded{true};
  Vec3 bound_center;  ///< world bounding sphere (when bounded)
  double bound_radius{0.0};
};

/// Precomputes one primitive.
PreparedPrimitive Prepare(const Primitive& primitive, uint32_t index);

/// Nearest intersection of the ray `origin + t * dir` (world frame; `dir` need not be unit
/// length) with the primitive for t in (t_min, t_max). On a hit writes t and the outward
/// (geometric, not yet facing the ray) unit normal in the world frame.
bool Intersect(const PreparedPrimitive& p, const Vec3& origin, const Vec3& dir, double t_min,
               double t_max, double* t, Vec3* normal);

/// Conservative pixel rectangle covered by a primitive seen from a pinhole at `eye_pose`
/// (world-from-eye, camera axes): [u0, u1] x [v0, v1], possibly beyond the image. Returns
/// false when the bound straddles the eye plane (the primitive may cover everything).
bool ProjectBound(const PreparedPrimitive& p, const Pose& eye_pose, double fx, double fy, double cx,
                  double cy, double* u0, double* u1, double* v0, double* v1);

/// Primitive indices binned into square tiles of the image of one pinhole eye, CSR layout.
/// Lists are ascending so that the nearest-hit tie breaking is deterministic.
class TileBins {
 public:
  /// Bins `prims` for an image of width x height pixels extended by `margin_px` on every
  /// side; pixels outside the extended image fall back to the full list.
  void Build(const std::vector<PreparedPrimitive>& prims, const Pose& eye_pose, double fx,
             double fy, double cx, double cy, int width, int height, int margin_px);
  /// Candidate primitives (indices into the prepared array) for image position (u, v).
  void Candidates(double u, double v, const uint32_t** begin, const uint32_t** end) const;

 private:
  static constexpr int kTilePx = 16;
  int origin_px_{0};  // pixel coordinate of tile column/row 0 (negative margin)
  int tiles_x_{0};
  int tiles_y_{0};
  std::vector<uint32_t> offsets_;
  std::vector<uint32_t> items_;
  std::vector<uint32_t> all_;
};

}  // namespace clutterseg::synth::internal
