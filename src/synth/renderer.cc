#include "clutterseg/synth/renderer.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <vector>

#include "clutterseg/core/assert.h"
#include "clutterseg/synth/internal/noise_field.h"
#include "clutterseg/synth/internal/ray_cast.h"
#include "clutterseg/synth/random.h"

namespace clutterseg::synth {
namespace {

using internal::PreparedPrimitive;
using internal::TileBins;

constexpr double kPi = 3.14159265358979323846;
// Rows per ParallelFor chunk (fixed, so chunking never depends on the thread count).
constexpr size_t kRowGrain = 8;
// Extra border (pixels) of the projector's tile grid.
constexpr int kProjectorMarginPx = 160;

// Counter streams of the per-pixel hash.
enum Stream : uint64_t {
  kLateralU = 1,
  kLateralV,
  kDropout,
  kEdgeCluster,
  kColor = 16,  // + channel
};

struct Context {
  const Scene* scene;
  const SensorParams* sensor;
  uint64_t seed;
  int width;
  int height;
  double fx, fy, cx, cy;
  Pose camera;
  Pose projector;
  std::vector<PreparedPrimitive> prims;
  TileBins camera_bins;
  TileBins projector_bins;
  double cos_max_incidence;
  /// Unit-variance spatially correlated axial noise per pixel (empty without axial noise).
  std::vector<float> axial_field;
};

// Nearest hit along origin + t * dir among the candidates; returns the prepared index or -1.
int CastNearest(const Context& ctx, const uint32_t* begin, const uint32_t* end, const Vec3& origin,
                const Vec3& dir, double t_min, double* t_hit, Vec3* normal) {
  double best = std::numeric_limits<double>::infinity();
  int best_index = -1;
  for (const uint32_t* it = begin; it != end; ++it) {
    double t;
    Vec3 n;
    if (internal::Intersect(ctx.prims[*it], origin, dir, t_min, best, &t, &n)) {
      best = t;
      best_index = static_cast<int>(*it);
      *normal = n;
    }
  }
  *t_hit = best;
  return best_index;
}

constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

// Closed convex surfaces (and planes) cannot block the projector ray leaving one of their
// own points that faces the projector.
bool SelfShadowFree(const PreparedPrimitive& p) {
  switch (p.kind) {
    case PrimitiveKind::kBox:
    case PrimitiveKind::kSphere:
    case PrimitiveKind::kPlane:
      return true;
    case PrimitiveKind::kCylinder:
    case PrimitiveKind::kFrustum:
      return p.cap_bottom && p.cap_top;
    case PrimitiveKind::kHemisphereShell:
      return false;
  }
  return false;
}

// True when anything (other than primitive `skip`) blocks the segment from `point` to the
// projector.
bool InProjectorShadow(const Context& ctx, const Vec3& point, uint32_t skip) {
  const Vec3 local = ctx.projector.InverseApply(point);
  const uint32_t* begin;
  const uint32_t* end;
  ctx.projector_bins.Candidates(ctx.fx * local.x / local.z + ctx.cx,
                                ctx.fy * local.y / local.z + ctx.cy, &begin, &end);
  const Vec3 seg = ctx.projector.translation - point;
  for (const uint32_t* it = begin; it != end; ++it) {
    double t;
    Vec3 n;
    if (*it == skip) continue;
    if (internal::Intersect(ctx.prims[*it], point, seg, 1e-6, 1.0, &t, &n)) return true;
  }
  return false;
}

double TextureFactor(SurfaceTexture texture, const Vec3& p) {
  switch (texture) {
    case SurfaceTexture::kPlain:
      return 1.0;
    case SurfaceTexture::kWood: {
      // Wavy rings from nested triangle waves (no trigonometry in the per-pixel path).
      auto tri = [](double x) { return std::abs(2.0 * (x - std::floor(x)) - 1.0); };
      const double grain = tri(p.x * 14.0 + 0.8 * tri(p.y * 1.3 + p.x * 0.4));
      return 0.82 + 0.18 * grain;
    }
    case SurfaceTexture::kTiles: {
      const double tile = 0.3;
      const double fx = p.x / tile - std::floor(p.x / tile);
      const double fy = p.y / tile - std::floor(p.y / tile);
      if (fx < 0.02 || fy < 0.02) return 0.6;  // grout
      const long parity = std::lround(std::floor(p.x / tile) + std::floor(p.y / tile));
      return (parity & 1) != 0 ? 0.88 : 1.0;
    }
  }
  return 1.0;
}

uint8_t ToByte(double v) { return static_cast<uint8_t>(std::clamp(v, 0.0, 255.0) + 0.5); }

// Base random bits of pixel (or cell) `i`: the i-th output of a SplitMix64 stream whose
// start is the (already mixed) noise seed.
uint64_t PixelHash(uint64_t mixed_seed, uint64_t i) {
  return Mix64(mixed_seed + i * 0x9e3779b97f4a7c15ULL);
}

// Random bits of one stream of one pixel, from the pixel's base hash.
uint64_t StreamBits(uint64_t pixel_hash, uint64_t stream) {
  return Mix64(pixel_hash ^ (stream * 0xd6e8feb86659fd93ULL));
}

// Pass 1: geometry. Writes true depth, true label, geometric status and colour.
void RenderGeometryRows(const Context& ctx, int v0, int v1, RenderedFrame* out) {
  const SensorParams& sp = *ctx.sensor;
  const Vec3 light = Normalized(Vec3{0.3, -0.5, 1.0});
  for (int v = v0; v < v1; ++v) {
    for (int u = 0; u < ctx.width; ++u) {
      const size_t i = static_cast<size_t>(v) * ctx.width + u;
      const Vec3 dir = ctx.camera.Rotate({(u - ctx.cx) / ctx.fx, (v - ctx.cy) / ctx.fy, 1.0});
      const uint32_t* begin;
      const uint32_t* end;
      ctx.camera_bins.Candidates(u, v, &begin, &end);
      double t;
      Vec3 n;
      const int hit = CastNearest(ctx, begin, end, ctx.camera.translation, dir, 1e-4, &t, &n);
      double shade[3] = {25.0, 25.0, 30.0};
      if (hit < 0) {
        out->true_depth_m.data[i] = 0.f;
        out->true_label.data[i] = 0;
        out->true_inside.data[i] = 0;
        out->status.data[i] = static_cast<uint8_t>(DepthStatus::kNoSurface);
      } else {
        const PreparedPrimitive& pp = ctx.prims[static_cast<size_t>(hit)];
        const Primitive& prim = ctx.scene->primitives[pp.index];
        const bool inside = Dot(n, dir) > 0.0;  // the outward normal faces away
        if (inside) n = -n;                     // face the camera (inside of shells)
        const Vec3 point = ctx.camera.translation + t * dir;
        // dir has unit z in the camera frame, so t is the depth.
        out->true_depth_m.data[i] = static_cast<float>(t);
        out->true_label.data[i] = prim.label;
        out->true_inside.data[i] = prim.label != 0 && inside ? 1 : 0;
        DepthStatus status = DepthStatus::kValid;
        const double cos_incidence = -Dot(n, dir) / Norm(dir);
        if (t < sp.min_range_m || t > sp.max_range_m) {
          status = DepthStatus::kOutOfRange;
        } else if (cos_incidence < ctx.cos_max_incidence) {
          status = DepthStatus::kGrazing;
        } else if (sp.projector_shadows) {
          const Vec3 to_projector = ctx.projector.translation - point;
          if (Dot(n, to_projector) <= 0.0 ||
              InProjectorShadow(ctx, point + 1e-6 * n,
                                SelfShadowFree(pp) ? static_cast<uint32_t>(hit) : kNone)) {
            status = DepthStatus::kShadow;
          }
        }
        out->status.data[i] = static_cast<uint8_t>(status);
        const double lambert = std::max(0.0, Dot(n, light));
        const double f = TextureFactor(prim.texture, point) * (0.35 + 0.65 * lambert);
        shade[0] = prim.color.r * f;
        shade[1] = prim.color.g * f;
        shade[2] = prim.color.b * f;
      }
      if (sp.color_noise_sigma > 0.0) {
        const uint64_t pixel_hash = PixelHash(ctx.seed, i);
        for (uint64_t c = 0; c < 3; ++c) {
          shade[c] +=
              sp.color_noise_sigma * FastGaussianFromBits(StreamBits(pixel_hash, kColor + c));
        }
      }
      out->color.data[i] = core::Rgb8{ToByte(shade[0]), ToByte(shade[1]), ToByte(shade[2])};
    }
  }
}

int LateralOffset(const Context& ctx, uint64_t pixel_hash, uint64_t stream) {
  const double g = FastGaussianFromBits(StreamBits(pixel_hash, stream));
  return static_cast<int>(std::round(std::clamp(g * ctx.sensor->lateral_sigma_px, -3.0, 3.0)));
}

bool NearDepthEdge(const Context& ctx, const RenderedFrame& f, int u, int v) {
  const float z = f.true_depth_m.at(u, v);
  const float jump = static_cast<float>(ctx.sensor->edge_jump_fraction) * z;
  for (int dv = -1; dv <= 1; ++dv) {
    for (int du = -1; du <= 1; ++du) {
      const int nu = u + du;
      const int nv = v + dv;
      if (nu < 0 || nv < 0 || nu >= ctx.width || nv >= ctx.height) continue;
      const float zn = f.true_depth_m.at(nu, nv);
      if (zn <= 0.f || std::abs(zn - z) > jump) return true;
    }
  }
  return false;
}

// Pass 2: the sensor measurement. Reads pass-1 images only; writes depth and label.
void MeasureRows(const Context& ctx, int v0, int v1, RenderedFrame* out) {
  const SensorParams& sp = *ctx.sensor;
  const double fb = sp.disparity_focal_px * sp.baseline_m;
  const double step = sp.disparity_step_px;
  for (int v = v0; v < v1; ++v) {
    for (int u = 0; u < ctx.width; ++u) {
      const size_t i = static_cast<size_t>(v) * ctx.width + u;
      out->depth.data[i] = 0;
      out->label.data[i] = 0;
      out->inside.data[i] = 0;
      const uint64_t pixel_hash = PixelHash(ctx.seed, i);
      int su = u;
      int sv = v;
      if (sp.lateral_sigma_px > 0.0) {
        su = std::clamp(u + LateralOffset(ctx, pixel_hash, kLateralU), 0, ctx.width - 1);
        sv = std::clamp(v + LateralOffset(ctx, pixel_hash, kLateralV), 0, ctx.height - 1);
      }
      const size_t s = static_cast<size_t>(sv) * ctx.width + su;
      if (out->status.data[s] != static_cast<uint8_t>(DepthStatus::kValid)) continue;
      if (sp.dropout_fraction > 0.0 &&
          ToUnit(StreamBits(pixel_hash, kDropout)) < sp.dropout_fraction) {
        continue;
      }
      if (sp.edge_dropout_probability > 0.0) {
        const uint64_t cell_u = static_cast<uint64_t>(u / sp.edge_cluster_px);
        const uint64_t cell_v = static_cast<uint64_t>(v / sp.edge_cluster_px);
        const uint64_t cell = (cell_v << 32) | cell_u;
        if (ToUnit(StreamBits(PixelHash(ctx.seed, cell), kEdgeCluster)) <
                sp.edge_dropout_probability &&
            NearDepthEdge(ctx, *out, u, v)) {
          continue;
        }
      }
      double z = out->true_depth_m.data[s];
      if (sp.axial_noise || step > 0.0) {
        double disparity = fb / z;
        if (sp.axial_noise) {
          // The Gaussian part plus the quantisation error give the configured total sigma. The
          // Gaussian part is a smooth field over the image (block matching correlates the
          // disparity errors of neighbouring pixels); quantising it makes terraces.
          const double sigma = sp.AxialSigmaM(z);
          const double q = step * z * z / fb;  // quantisation step in depth
          const double sigma_g = std::sqrt(std::max(sigma * sigma - q * q / 12.0, 0.0));
          disparity += sigma_g * fb / (z * z) * ctx.axial_field[i];
        }
        if (step > 0.0) disparity = std::round(disparity / step) * step;
        if (!(disparity > 0.0)) continue;
        z = fb / disparity;
        if (z < sp.min_range_m || z > sp.max_range_m) continue;
      }
      const double mm = std::floor(z * 1000.0 + 0.5);
      if (mm <= 0 || mm > 65535) continue;
      out->depth.data[i] = static_cast<uint16_t>(mm);
      out->label.data[i] = out->true_label.data[s];
      out->inside.data[i] = out->true_inside.data[s];
    }
  }
}

void ParallelRows(core::ThreadPool* pool, int height, const std::function<void(int, int)>& fn) {
  if (pool == nullptr) {
    fn(0, height);
    return;
  }
  pool->ParallelFor(static_cast<size_t>(height), kRowGrain,
                    [&](size_t b, size_t e) { fn(static_cast<int>(b), static_cast<int>(e)); });
}

}  // namespace

void RenderScene(const Scene& scene, const core::CameraIntrinsics& intrinsics,
                 const SensorParams& sensor, uint64_t noise_seed, RenderedFrame* out,
                 core::ThreadPool* pool) {
  CLUTTERSEG_DEMAND(out != nullptr);
  intrinsics.ValidateOrThrow();
  sensor.ValidateOrThrow();
  Context ctx;
  ctx.scene = &scene;
  ctx.sensor = &sensor;
  ctx.seed = Mix64(noise_seed ^ 0x6a09e667f3bcc909ULL);
  ctx.width = intrinsics.width;
  ctx.height = intrinsics.height;
  ctx.fx = intrinsics.fx;
  ctx.fy = intrinsics.fy;
  ctx.cx = intrinsics.cx;
  ctx.cy = intrinsics.cy;
  ctx.camera = scene.camera_pose;
  ctx.projector = scene.camera_pose;
  ctx.projector.translation = scene.camera_pose.Apply({sensor.baseline_m, 0.0, 0.0});
  ctx.cos_max_incidence = std::cos(sensor.max_incidence_deg * kPi / 180.0);
  ctx.prims.reserve(scene.primitives.size());
  for (size_t i = 0; i < scene.primitives.size(); ++i) {
    ctx.prims.push_back(internal::Prepare(scene.primitives[i], static_cast<uint32_t>(i)));
  }
  ctx.camera_bins.Build(ctx.prims, ctx.camera, ctx.fx, ctx.fy, ctx.cx, ctx.cy, ctx.width,
                        ctx.height, 0);
  if (sensor.projector_shadows) {
    ctx.projector_bins.Build(ctx.prims, ctx.projector, ctx.fx, ctx.fy, ctx.cx, ctx.cy, ctx.width,
                             ctx.height, kProjectorMarginPx);
  }

  const int w = ctx.width;
  const int h = ctx.height;
  out->intrinsics = intrinsics;
  out->depth.Reset(w, h, 0);
  out->color.Reset(w, h);
  out->label.Reset(w, h, 0);
  out->true_depth_m.Reset(w, h, 0.f);
  out->true_label.Reset(w, h, 0);
  out->true_inside.Reset(w, h, 0);
  out->inside.Reset(w, h, 0);
  out->status.Reset(w, h, 0);
  if (sensor.axial_noise) {
    internal::CorrelatedGaussianField(ctx.seed, w, h, sensor.axial_noise_correlation_px,
                                      &ctx.axial_field, pool);
  }
  ParallelRows(pool, h, [&](int v0, int v1) { RenderGeometryRows(ctx, v0, v1, out); });
  ParallelRows(pool, h, [&](int v0, int v1) { MeasureRows(ctx, v0, v1, out); });
  // Pixels that were geometrically valid but lost their measurement were dropped.
  for (size_t i = 0; i < out->depth.data.size(); ++i) {
    if (out->depth.data[i] == 0 &&
        out->status.data[i] == static_cast<uint8_t>(DepthStatus::kValid)) {
      out->status.data[i] = static_cast<uint8_t>(DepthStatus::kDropout);
    }
  }
}

void ToPointCloud(const RenderedFrame& frame, core::PointCloud* cloud) {
  CLUTTERSEG_DEMAND(cloud != nullptr);
  core::DepthToPointCloud(frame.depth, frame.intrinsics, &frame.color, cloud);
  cloud->label.assign(frame.label.data.begin(), frame.label.data.end());
}

}  // namespace clutterseg::synth
