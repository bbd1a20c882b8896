#include "clutterseg/pipeline/refine.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>

#include "clutterseg/core/scoped_timer.h"
#include "clutterseg/core/union_find.h"

namespace clutterseg::pipeline {
namespace {

constexpr size_t kPixelGrain = 32768;
constexpr size_t kCandidateGrain = 1024;
// Neighbours of a reclaim candidate in an unorganized cloud.
constexpr size_t kReclaimNeighbors = 8;
// Area of a compact flat patch from the two largest eigenvalues of its points' covariance:
// area = k sqrt(l1 l2), k = 4 pi for a disc, 12 for a square, 12.47 for a regular hexagon
// (supervoxels are compact cells between those).
constexpr double kPatchAreaFactor = 12.4;

// Calls f(first, second, count) for each run of equal keys of `sorted_keys`, keys being pairs
// (first << 32 | second) sorted ascending: each pair once, with how often it occurs.
template <class F>
void ForEachPairRun(const std::vector<uint64_t>& sorted_keys, F&& f) {
  for (size_t a = 0; a < sorted_keys.size();) {
    size_t b = a;
    while (b < sorted_keys.size() && sorted_keys[b] == sorted_keys[a]) ++b;
    f(static_cast<int32_t>(sorted_keys[a] >> 32),
      static_cast<int32_t>(sorted_keys[a] & 0xffffffffu), static_cast<uint32_t>(b - a));
    a = b;
  }
}

// Vessel rims (Refiner::CutVesselRims).
constexpr size_t kVesselMinWalls = 5;          // wall patches to fit a circle to
constexpr double kVesselWallAcross = 0.7;      // a wall's normal across the support's, at least
constexpr size_t kVesselHypothesisWalls = 48;  // walls paired for circles, at most
constexpr double kVesselMinPairTurn = 0.25;    // |n_a - n_b|^2 of a pair: 29 degrees apart
constexpr double kVesselMinTolerance = 0.006;  // metres
constexpr double kVesselMaxMeanNormal = 0.9;   // the fitting walls' mean normal, at most
constexpr double kVesselSameSurfaceCos = 0.8;  // a cut continues to normals within 37 degrees
constexpr double kVesselMinCutPoints = 50.0;   // smaller cuts are left alone
constexpr uint8_t kRimFits = 1;
constexpr uint8_t kRimCut = 2;

// Coordinates across a unit normal u: two unit vectors that make (e1, e2, u) right-handed.
struct AcrossBasis {
  double e1[3], e2[3];
  explicit AcrossBasis(const core::Vec3f& uf) {
    const double u[3] = {uf.x, uf.y, uf.z};
    // The axis least aligned with u, crossed with it.
    const int a = std::abs(u[0]) <= std::abs(u[1]) && std::abs(u[0]) <= std::abs(u[2])
                      ? 0
                      : (std::abs(u[1]) <= std::abs(u[2]) ? 1 : 2);
    const double ax[3] = {a == 0 ? 1.0 : 0.0, a == 1 ? 1.0 : 0.0, a == 2 ? 1.0 : 0.0};
    e1[0] = u[1] * ax[2] - u[2] * ax[1];
    e1[1] = u[2] * ax[0] - u[0] * ax[2];
    e1[2] = u[0] * ax[1] - u[1] * ax[0];
    const double l = std::sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
    for (double& v : e1) v /= l;
    e2[0] = u[1] * e1[2] - u[2] * e1[1];
    e2[1] = u[2] * e1[0] - u[0] * e1[2];
    e2[2] = u[0] * e1[1] - u[1] * e1[0];
  }
  std::pair<double, double> Across(const core::Vec3f& v) const {
    return {v.x * e1[0] + v.y * e1[1] + v.z * e1[2], v.x * e2[0] + v.y * e2[1] + v.z * e2[2]};
  }
};

}  // namespace

int32_t Refiner::Find(int32_t x) { return core::FindRoot(parent_.data(), x); }

void Refiner::Union(int32_t a, int32_t b) {
  a = Find(a);
  b = Find(b);
  if (a == b) return;
  if (a < b) std::swap(a, b);
  parent_[a] = b;  // the smaller id is the root: deterministic
}

uint32_t Refiner::KeepLargestGroups(uint32_t cap) {
  // The `cap` largest labelled groups (ties: the lower label), relabelled 1..cap in their
  // label order; the others become background.
  capped_order_.clear();
  for (const auto& [first, g] : group_order_) {
    if (group_label_[g] != 0) capped_order_.emplace_back(group_points_[g], group_label_[g], g);
  }
  std::nth_element(capped_order_.begin(), capped_order_.begin() + cap, capped_order_.end(),
                   [](const auto& a, const auto& b) {
                     return std::get<0>(a) != std::get<0>(b) ? std::get<0>(a) > std::get<0>(b)
                                                             : std::get<1>(a) < std::get<1>(b);
                   });
  for (size_t k = cap; k < capped_order_.size(); ++k)
    group_label_[std::get<2>(capped_order_[k])] = 0;
  uint32_t next = 0;
  for (const auto& [first, g] : group_order_) {
    if (group_label_[g] != 0) group_label_[g] = ++next;
  }
  return next;
}

bool Refiner::KeepGroup(const optimize::PlaneLabeling& planes, int32_t g) const {
  const ObjectParams& params = params_;
  if (group_points_[g] < static_cast<uint64_t>(params.min_object_points)) return false;
  if (params.below_support_margin_m <= 0.f) return true;
  // Segments below a support surface (the table's edge faces and legs, things under the
  // table) are not objects on it. Support normals point to the camera, so "below" is a
  // negative signed distance.
  const double inv = 1.0 / static_cast<double>(group_points_[g]);
  const core::Vec3f& c = group_centroid_[g];
  for (size_t p = 0; p < planes.planes.size(); ++p) {
    if (!support_[p]) continue;
    const core::Vec3f& nrm = planes.planes[p].normal;
    const double dist = (nrm.x * c.x + nrm.y * c.y + nrm.z * c.z) * inv + planes.planes[p].d;
    if (dist < -params.below_support_margin_m) return false;
  }
  return true;
}

void Refiner::SumGroups(const supervoxel::Supervoxels& sv, const graph::PatchFeatures& features) {
  const size_t n = sv.size();
  group_points_.assign(n, 0);
  group_centroid_.assign(n, core::Vec3f{});
  for (size_t i = 0; i < n; ++i) {
    if (background_[i]) continue;
    const int32_t g = Find(static_cast<int32_t>(i));
    const float w = static_cast<float>(sv.num_points[i]);
    group_points_[g] += sv.num_points[i];
    group_centroid_[g].x += w * features.centroid[i].x;
    group_centroid_[g].y += w * features.centroid[i].y;
    group_centroid_[g].z += w * features.centroid[i].z;
  }
}

void Refiner::MergeSmallGroups(const supervoxel::Supervoxels& sv) {
  // Every adjacency of a small group to another foreground group, as a key (small group,
  // other group); after sorting, each run is one pair and its length their adjacencies.
  const size_t n = sv.size();
  const uint64_t min_points = static_cast<uint64_t>(params_.min_object_points);
  pair_keys_.clear();
  for (size_t i = 0; i < n; ++i) {
    if (background_[i]) continue;
    const int32_t g = Find(static_cast<int32_t>(i));
    if (group_points_[g] >= min_points) continue;
    for (uint32_t s = sv.adjacency_offsets[i]; s < sv.adjacency_offsets[i + 1]; ++s) {
      const uint32_t j = sv.adjacency[s];
      if (background_[j]) continue;
      const int32_t h = Find(static_cast<int32_t>(j));
      if (h != g) pair_keys_.push_back(uint64_t{static_cast<uint32_t>(g)} << 32 | uint32_t(h));
    }
  }
  std::sort(pair_keys_.begin(), pair_keys_.end());
  // Best neighbour per small group: most shared adjacencies, then the larger group. The
  // merges are decided on the groups before any of them, then applied.
  merge_into_.clear();
  uint32_t best_count = 0;
  ForEachPairRun(pair_keys_, [&](int32_t g, int32_t h, uint32_t count) {
    if (merge_into_.empty() || merge_into_.back().first != g) {
      merge_into_.emplace_back(g, h);
      best_count = count;
    } else if (count > best_count ||
               (count == best_count &&
                group_points_[h] > group_points_[merge_into_.back().second])) {
      merge_into_.back().second = h;
      best_count = count;
    }
  });
  for (const auto& [g, h] : merge_into_) Union(g, h);
}

void Refiner::MergeContainerInsides(const supervoxel::Supervoxels& sv,
                                    const graph::PatchFeatures& features,
                                    const optimize::PlaneLabeling& planes) {
  const ObjectParams& params = params_;
  const size_t n = sv.size();
  // Per group root, sums over its patches (w = points, p = centroid, n = normal): w, w n,
  // w p, w n n^T, w p p^T and w n p^T.
  group_fit_sums_.assign(n, FitSums{});
  for (size_t i = 0; i < n; ++i) {
    if (background_[i]) continue;
    FitSums& a = group_fit_sums_[Find(static_cast<int32_t>(i))];
    const double w = sv.num_points[i];
    const core::Vec3f& pf = features.centroid[i];
    const core::Vec3f& nf = features.normal[i];
    const double p[3] = {pf.x, pf.y, pf.z};
    const double nr[3] = {nf.x, nf.y, nf.z};
    a.w += w;
    for (int k = 0; k < 3; ++k) {
      a.n[k] += w * nr[k];
      a.p[k] += w * p[k];
      for (int l = 0; l < 3; ++l) {
        a.nn[k][l] += w * nr[k] * nr[l];
        a.pp[k][l] += w * p[k] * p[l];
        a.np[k][l] += w * nr[k] * p[l];
      }
    }
  }
  // Each group with a support plane below it (the support nearest its centroid on the
  // camera's side, a table rather than a wall behind it) is fitted with a vertical axis
  // through c and a radius r: least squares of c - r n = p across the support's normal u
  // (every vector projected onto the plane normal to u), which holds exactly for the walls of
  // a cylinder or a sphere. With W = sum w, N, P the projected sums and S_nn, S_pn, S_pp the
  // sums of the projected products: r = (P . N / W - S_pn) / (S_nn - |N|^2 / W),
  // c = (P + r N) / W. Normals that barely vary across u (a flat face, a table-like top)
  // leave r undetermined: such a group is neither.
  group_fit_.assign(n, ContainerFit{});
  container_roots_.clear();
  for (size_t g = 0; g < n; ++g) {
    const FitSums& a = group_fit_sums_[g];
    const double w = a.w;
    if (!(w > 0.0) || group_points_[g] < static_cast<uint64_t>(params.min_object_points)) continue;
    const int32_t support =
        SupportBelow(planes, group_centroid_[g], 1.0 / static_cast<double>(group_points_[g]));
    if (support < 0) continue;
    const core::Vec3f& uf = planes.planes[support].normal;
    const double u[3] = {uf.x, uf.y, uf.z};
    auto quad = [&](const double(&m)[3][3]) {  // u^T m u
      double q = 0.0;
      for (int k = 0; k < 3; ++k)
        for (int l = 0; l < 3; ++l) q += u[k] * m[k][l] * u[l];
      return q;
    };
    const double s_nn = a.nn[0][0] + a.nn[1][1] + a.nn[2][2] - quad(a.nn);
    const double s_pp = a.pp[0][0] + a.pp[1][1] + a.pp[2][2] - quad(a.pp);
    const double s_pn = a.np[0][0] + a.np[1][1] + a.np[2][2] - quad(a.np);
    const double nu = a.n[0] * u[0] + a.n[1] * u[1] + a.n[2] * u[2];
    const double pu = a.p[0] * u[0] + a.p[1] * u[1] + a.p[2] * u[2];
    double np_[3], pp_[3];
    for (int k = 0; k < 3; ++k) {
      np_[k] = a.n[k] - nu * u[k];
      pp_[k] = a.p[k] - pu * u[k];
    }
    const double nn_sq = np_[0] * np_[0] + np_[1] * np_[1] + np_[2] * np_[2];
    const double spread = s_nn - nn_sq / w;
    if (!(spread > 0.02 * w)) continue;
    const double pn = pp_[0] * np_[0] + pp_[1] * np_[1] + pp_[2] * np_[2];
    const double r = (pn / w - s_pn) / spread;
    const double ar = std::abs(r);
    if (ar < params.container_min_radius_m || ar > params.container_max_radius_m) continue;
    double c[3];
    for (int k = 0; k < 3; ++k) c[k] = (pp_[k] + r * np_[k]) / w;
    // Residual: sum w |c - r n - p|^2 over the projected vectors.
    const double cc = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
    const double cn = c[0] * np_[0] + c[1] * np_[1] + c[2] * np_[2];
    const double cp = c[0] * pp_[0] + c[1] * pp_[1] + c[2] * pp_[2];
    const double e = w * cc + r * r * s_nn + s_pp - 2.0 * r * cn - 2.0 * cp + 2.0 * r * s_pn;
    const double rms = std::sqrt(std::max(0.0, e) / w);
    if (rms > params.container_max_fit_rms_rel * ar) continue;
    ContainerFit& f = group_fit_[g];
    f.center = {c[0], c[1], c[2]};
    f.radius = r;
    f.height = pu / w;
    f.support = support;
    container_roots_.push_back(static_cast<int32_t>(g));
  }
  // Each concave group (r > 0) picks the convex one (r < 0) over the same support whose axis
  // is nearest its own, relative to the larger radius; decided on the groups before any
  // merge, then applied.
  merge_into_.clear();
  for (const int32_t g : container_roots_) {
    const ContainerFit& in = group_fit_[g];
    if (in.radius <= 0.0) continue;
    int32_t best = -1;
    double best_rel = params.container_max_axis_offset_rel;
    for (const int32_t h : container_roots_) {
      const ContainerFit& out = group_fit_[h];
      if (out.radius >= 0.0 || out.support != in.support) continue;
      const double r_in = in.radius, r_out = -out.radius, r_max = std::max(r_in, r_out);
      if (std::abs(r_in - r_out) > params.container_max_radius_diff_rel * r_max) continue;
      // The mean heights of the two walls' points lie within a vessel's height, taken as two
      // radii.
      if (std::abs(in.height - out.height) > 2.0 * r_max) continue;
      const double dx = in.center[0] - out.center[0], dy = in.center[1] - out.center[1],
                   dz = in.center[2] - out.center[2];
      const double rel = std::sqrt(dx * dx + dy * dy + dz * dz) / r_max;
      if (rel <= best_rel) {
        best_rel = rel;
        best = h;
      }
    }
    if (best >= 0) merge_into_.emplace_back(g, best);
  }
  for (const auto& [g, h] : merge_into_) Union(g, h);
}

int32_t Refiner::SupportBelow(const optimize::PlaneLabeling& planes, const core::Vec3f& sum,
                              double inv) const {
  int32_t support = -1;
  double support_dist = 0.0;
  for (size_t p = 0; p < planes.planes.size(); ++p) {
    if (!support_[p]) continue;
    const core::Vec3f& nrm = planes.planes[p].normal;
    const double dist = (nrm.x * sum.x + nrm.y * sum.y + nrm.z * sum.z) * inv + planes.planes[p].d;
    if (dist > 0.0 && (support < 0 || dist < support_dist)) {
      support = static_cast<int32_t>(p);
      support_dist = dist;
    }
  }
  return support;
}

void Refiner::CutVesselRims(const supervoxel::Supervoxels& sv, const graph::PatchFeatures& features,
                            const optimize::PlaneLabeling& planes) {
  const ObjectParams& params = params_;
  const size_t n = sv.size();
  // Members of each group, ordered by group (a counting sort on the roots).
  rim_root_.assign(n, -1);
  rim_offsets_.assign(n + 1, 0);
  for (size_t i = 0; i < n; ++i) {
    if (background_[i]) continue;
    rim_root_[i] = Find(static_cast<int32_t>(i));
    ++rim_offsets_[static_cast<size_t>(rim_root_[i]) + 1];
  }
  for (size_t g = 0; g < n; ++g) rim_offsets_[g + 1] += rim_offsets_[g];
  rim_members_.resize(rim_offsets_[n]);
  rim_fill_.assign(rim_offsets_.begin(), rim_offsets_.end() - 1);
  for (size_t i = 0; i < n; ++i) {
    if (rim_root_[i] >= 0)
      rim_members_[rim_fill_[static_cast<size_t>(rim_root_[i])]++] = static_cast<uint32_t>(i);
  }
  rim_cut_.assign(n, 0);
  rim_cut_group_.assign(n, 0);
  bool any = false;
  for (size_t g = 0; g < n; ++g) {
    const uint32_t b = rim_offsets_[g], e = rim_offsets_[g + 1];
    if (e - b < kVesselMinWalls) continue;
    double w_all = 0.0;
    core::Vec3f sum{0.f, 0.f, 0.f};
    for (uint32_t m = b; m < e; ++m) {
      const uint32_t i = rim_members_[m];
      const float w = static_cast<float>(sv.num_points[i]);
      w_all += w;
      sum.x += w * features.centroid[i].x;
      sum.y += w * features.centroid[i].y;
      sum.z += w * features.centroid[i].z;
    }
    if (w_all < params.min_object_points) continue;
    const int32_t support = SupportBelow(planes, sum, 1.0 / w_all);
    if (support < 0) continue;
    const AcrossBasis basis(planes.planes[static_cast<size_t>(support)].normal);
    // Walls: members whose normal lies mostly across the support's normal, as (x, y) and the
    // unit normal (nx, ny) across it, their points and the member.
    rim_walls_.clear();
    double w_wall = 0.0;
    for (uint32_t m = b; m < e; ++m) {
      const uint32_t i = rim_members_[m];
      const auto [nx, ny] = basis.Across(features.normal[i]);
      const double nl = std::hypot(nx, ny);
      if (nl < kVesselWallAcross) continue;
      const auto [x, y] = basis.Across(features.centroid[i]);
      rim_walls_.push_back({x, y, nx / nl, ny / nl, static_cast<double>(sv.num_points[i]), i});
      w_wall += sv.num_points[i];
    }
    if (rim_walls_.size() < kVesselMinWalls) continue;
    // Every pair of walls (of at most kVesselHypothesisWalls, evenly spaced) whose normals
    // differ enough fixes a circle: p_a + r n_a = p_b + r n_b. The circle most walls fit wins.
    const double min_r = params.container_min_radius_m, max_r = params.container_max_radius_m;
    const auto tolerance = [&](double r) {
      return std::max(double{params.vessel_fit_tolerance_rel} * r, kVesselMinTolerance);
    };
    const auto fits = [&](const VesselWall& k, double r, double cx, double cy) {
      const double ex = k.x + r * k.nx - cx, ey = k.y + r * k.ny - cy;
      const double tol = tolerance(r);
      return ex * ex + ey * ey <= tol * tol;
    };
    const size_t walls = rim_walls_.size();
    const size_t step = (walls + kVesselHypothesisWalls - 1) / kVesselHypothesisWalls;
    double best_w = 0.0, best_r = 0.0, best_cx = 0.0, best_cy = 0.0;
    for (size_t i = 0; i < walls; i += step) {
      const VesselWall& wa = rim_walls_[i];
      for (size_t j = i + step; j < walls; j += step) {
        const VesselWall& wb = rim_walls_[j];
        const double dx = wb.nx - wa.nx, dy = wb.ny - wa.ny;
        const double dd = dx * dx + dy * dy;
        if (dd < kVesselMinPairTurn) continue;
        const double r = ((wa.x - wb.x) * dx + (wa.y - wb.y) * dy) / dd;
        if (r < min_r || r > max_r) continue;
        const double cx = 0.5 * (wa.x + r * wa.nx + wb.x + r * wb.nx);
        const double cy = 0.5 * (wa.y + r * wa.ny + wb.y + r * wb.ny);
        double w = 0.0;
        for (const VesselWall& k : rim_walls_) w += fits(k, r, cx, cy) ? k.w : 0.0;
        if (w > best_w) {
          best_w = w;
          best_r = r;
          best_cx = cx;
          best_cy = cy;
        }
      }
    }
    if (!(best_w >= double{params.vessel_min_inlier_share} * w_wall)) continue;
    // Least squares of c = p + r n on the fitting walls (as in MergeContainerInsides), which
    // must face the axis from around it: their mean normal is short.
    double sw = 0.0, snp = 0.0, N[2] = {0.0, 0.0}, P[2] = {0.0, 0.0};
    size_t count = 0;
    for (const VesselWall& k : rim_walls_) {
      if (!fits(k, best_r, best_cx, best_cy)) continue;
      ++count;
      sw += k.w;
      N[0] += k.w * k.nx;
      N[1] += k.w * k.ny;
      P[0] += k.w * k.x;
      P[1] += k.w * k.y;
      snp += k.w * (k.nx * k.x + k.ny * k.y);
    }
    const double nn = N[0] * N[0] + N[1] * N[1];
    if (count < kVesselMinWalls || std::sqrt(nn) > kVesselMaxMeanNormal * sw) continue;
    const double r = ((N[0] * P[0] + N[1] * P[1]) / sw - snp) / (sw - nn / sw);
    if (r < min_r || r > max_r) continue;
    const double cx = (P[0] + r * N[0]) / sw, cy = (P[1] + r * N[1]) / sw;
    for (const VesselWall& k : rim_walls_) {
      if (fits(k, r, cx, cy)) rim_cut_[k.member] = kRimFits;
    }
    // Cut: the members beyond the rim's reach that do not fit, then the members of the same
    // surface adjacent to them (normals within kVesselSameSurfaceCos) that do not fit.
    const double reach = r + std::max(double{params.vessel_rim_cut_margin_rel} * r, 0.01);
    double cut_w = 0.0;
    stack_.clear();
    for (uint32_t m = b; m < e; ++m) {
      const uint32_t i = rim_members_[m];
      const auto [x, y] = basis.Across(features.centroid[i]);
      if (rim_cut_[i] == kRimFits || std::hypot(x - cx, y - cy) <= reach) continue;
      rim_cut_[i] = kRimCut;
      stack_.push_back(i);
    }
    while (!stack_.empty()) {
      const uint32_t s0 = stack_.back();
      stack_.pop_back();
      cut_w += sv.num_points[s0];
      const core::Vec3f& n0 = features.normal[s0];
      for (uint32_t k = sv.adjacency_offsets[s0]; k < sv.adjacency_offsets[s0 + 1]; ++k) {
        const uint32_t t = sv.adjacency[k];
        if (rim_root_[t] != static_cast<int32_t>(g) || rim_cut_[t] != 0) continue;
        const core::Vec3f& n1 = features.normal[t];
        if (n0.x * n1.x + n0.y * n1.y + n0.z * n1.z < kVesselSameSurfaceCos) continue;
        rim_cut_[t] = kRimCut;
        stack_.push_back(t);
      }
    }
    const bool cut = cut_w >= kVesselMinCutPoints;
    for (uint32_t m = b; m < e; ++m) {
      uint8_t& c = rim_cut_[rim_members_[m]];
      c = cut && c == kRimCut ? kRimCut : 0;
    }
    if (!cut) continue;
    rim_cut_group_[g] = 1;
    any = true;
  }
  if (!any) return;
  // Re-form the groups that were cut: the members that stay are one group as before, those
  // cut off form the pieces they connect into among themselves.
  for (size_t g = 0; g < n; ++g) {
    if (!rim_cut_group_[g]) continue;
    for (uint32_t m = rim_offsets_[g]; m < rim_offsets_[g + 1]; ++m) {
      parent_[rim_members_[m]] = static_cast<int32_t>(rim_members_[m]);
    }
  }
  for (size_t g = 0; g < n; ++g) {
    if (!rim_cut_group_[g]) continue;
    int32_t keep = -1;
    for (uint32_t m = rim_offsets_[g]; m < rim_offsets_[g + 1]; ++m) {
      const uint32_t i = rim_members_[m];
      if (rim_cut_[i] != kRimCut) {
        if (keep < 0) keep = static_cast<int32_t>(i);
        Union(keep, static_cast<int32_t>(i));
        continue;
      }
      for (uint32_t k = sv.adjacency_offsets[i]; k < sv.adjacency_offsets[i + 1]; ++k) {
        const uint32_t t = sv.adjacency[k];
        if (rim_root_[t] == static_cast<int32_t>(g) && rim_cut_[t] == kRimCut) {
          Union(static_cast<int32_t>(i), static_cast<int32_t>(t));
        }
      }
    }
  }
}

void Refiner::MarkTouchingTaken(const supervoxel::Supervoxels& sv,
                                const geometry::PlanarRegions& support_first) {
  // A supervoxel touches the taken pixels when one of its pixels has a taken 4-neighbour;
  // supervoxels already marked (touching, or kSkip) are not looked at again. Per word of a row,
  // the pixels with a taken 4-neighbour are the row's taken bits shifted by one either way (with
  // the bit carried from the next word) and the taken bits of the rows above and below. Taken
  // pixels were invalid in the cloud the supervoxels grew in and carry none: only the pixels
  // next to the taken ones are visited.
  const size_t w = static_cast<size_t>(sv.width), h = static_cast<size_t>(sv.height);
  const size_t words = support_first.taken_words_per_row;
  const size_t rows = words == 0 ? 0 : support_first.taken_bits.size() / words;
  const uint64_t* const bits = support_first.taken_bits.data();
  const auto word = [&](size_t v, size_t k) -> uint64_t {
    return v < rows && k < words ? bits[v * words + k] : 0u;
  };
  const int32_t* const pixel = sv.pixel_label.data();
  for (size_t v = 0; v < h; ++v) {
    for (size_t k = 0; k < words && k * 64 < w; ++k) {
      const uint64_t here = word(v, k);
      const uint64_t left = (here << 1) | (k > 0 ? word(v, k - 1) >> 63 : 0u);  // u - 1 taken
      const uint64_t right = (here >> 1) | (word(v, k + 1) << 63);              // u + 1 taken
      const uint64_t above = v > 0 ? word(v - 1, k) : 0u;
      uint64_t touch = (left | right | above | word(v + 1, k)) & ~here;
      while (touch != 0) {
        const size_t u = k * 64 + static_cast<size_t>(__builtin_ctzll(touch));
        touch &= touch - 1;
        if (u >= w) break;
        const int32_t s = pixel[v * w + u];
        if (s >= 0 && !touches_taken_[s]) touches_taken_[s] = 1;
      }
    }
  }
}

void Refiner::MarkFlatGroups(const supervoxel::Supervoxels& sv,
                             const optimize::PlaneLabeling& planes) {
  // Per support plane, the largest height of a group's supervoxel centroids above it; a
  // group none of whose supervoxels stands more than above_support_distance_m above some
  // support plane lies flat on it (or below it, as the table's front edge does).
  const size_t n = sv.size();
  const float limit = params_.above_support_distance_m;
  for (size_t p = 0; p < planes.planes.size(); ++p) {
    if (!support_[p]) continue;
    const core::Vec3f nrm = planes.planes[p].normal;
    const float d = planes.planes[p].d;
    // Read only at the groups' roots (supervoxels not in the background).
    flat_height_.assign(n, -std::numeric_limits<float>::infinity());
    for (size_t i = 0; i < n; ++i) {
      if (background_[i]) continue;
      const int32_t g = Find(static_cast<int32_t>(i));
      const core::Vec3f& c = sv.centroid[i];
      const float height = nrm.x * c.x + nrm.y * c.y + nrm.z * c.z + d;
      flat_height_[g] = std::max(flat_height_[g], height);
    }
    for (size_t g = 0; g < n; ++g) {
      if (flat_height_[g] <= limit) group_flat_[g] = 1;
    }
  }
}

Refiner::Refiner(const ObjectParams& params, core::ThreadPool* pool)
    : params_((params.ValidateOrThrow(), params)), pool_(pool) {}

void Refiner::Compute(const core::CameraIntrinsics& intrinsics, const core::PointCloud& cloud,
                      const supervoxel::Supervoxels& sv, const graph::PatchFeatures& features,
                      const graph::LinkageResult& link, const optimize::PlaneLabeling& planes,
                      SegmentationResult* result, const geometry::PlanarRegions* support_first) {
  const core::ScopedTimer timer(&result->times[Stage::kRefine]);
  const ObjectParams& params = params_;
  core::ThreadPool* const pool = pool_;
  core::LabelImage* const labels = &result->labels;
  std::vector<Plane>* const out_planes = &result->planes;
  const size_t n = sv.size();
  const size_t num_planes = planes.planes.size();
  const size_t num_pixels = sv.pixel_label.size();
  const bool organized = cloud.organized() && cloud.width == sv.width &&
                         cloud.height == sv.height && cloud.xyz.size() == num_pixels;

  // Support planes are the large ones (table, floor, wall), measured by the metric area of
  // the surface assigned to them. In an organized cloud a pixel at depth z seen at incidence
  // angle t covers z^2 / (fx fy cos t); an unorganized cloud has no pixels (and may be
  // merged from several views), so each patch counts the area of its points' spread. Object
  // faces are small even when they fill much of the image.
  // A plane found on the pixel grid before the supervoxels starts with the area of the points
  // it took, and is a support whatever remains: its region covered the support area.
  plane_area_.resize(num_planes);
  sv_area_.assign(n, 0.0);
  for (size_t p = 0; p < num_planes; ++p) plane_area_[p] = planes.planes[p].fixed_area_m2;
  const double pixel_area = 1.0 / (intrinsics.fx * intrinsics.fy);
  for (size_t i = 0; i < n; ++i) {
    const int32_t p = planes.patch_plane[i];
    if (p < 0) continue;
    if (!organized) {
      const core::Vec3f& l = sv.eigenvalues[i];
      sv_area_[i] =
          kPatchAreaFactor * std::sqrt(std::max(0.0, double{l.x}) * std::max(0.0, double{l.y}));
      plane_area_[p] += sv_area_[i];
      continue;
    }
    const core::Vec3f& c = features.centroid[i];
    const core::Vec3f& nrm = planes.planes[p].normal;
    const double r = std::sqrt(double(c.x) * c.x + double(c.y) * c.y + double(c.z) * c.z);
    if (!(r > 0.0)) continue;
    const double cos_t = std::max(0.2, std::abs((c.x * nrm.x + c.y * nrm.y + c.z * nrm.z) / r));
    sv_area_[i] = sv.num_points[i] * double(c.z) * c.z * pixel_area / cos_t;
    plane_area_[p] += sv_area_[i];
  }
  support_.assign(num_planes, 0);
  out_planes->resize(num_planes);
  for (size_t p = 0; p < num_planes; ++p) {
    const optimize::PlaneModel& pm = planes.planes[p];
    support_[p] = plane_area_[p] >= params.support_min_area_m2 || pm.fixed_points > 0 ? 1 : 0;
    Plane& out = (*out_planes)[p];
    out.id = static_cast<uint32_t>(p);
    out.normal = pm.normal;
    out.d = pm.d;
    out.num_points = pm.num_points + pm.fixed_points;
    out.area_m2 = static_cast<float>(plane_area_[p]);
    out.is_support = support_[p] != 0;
  }

  // Supervoxels on a support plane are background, and their plane is the one their points'
  // heights are measured from (support_plane_[s + 1]; zero for the others, so that reading it
  // needs no branch).
  background_.assign(n, 0);
  support_plane_.assign(n + 1, PlaneEq{});
  for (size_t i = 0; i < n; ++i) {
    const int32_t p = planes.patch_plane[i];
    if (p < 0 || !support_[p]) continue;
    background_[i] = 1;
    const optimize::PlaneModel& pm = planes.planes[p];
    support_plane_[i + 1] = PlaneEq{pm.normal.x, pm.normal.y, pm.normal.z, pm.d};
  }

  // One pass over the points, in bands on the pool, run by run of points of one supervoxel:
  // the first point of every supervoxel in each band (object ids follow the first points),
  // and for support supervoxels how many of their points lie above the support.
  const bool release = params.support_release_fraction > 0.f;
  const bool heights = release || params.support_reclaim_passes > 0;
  const float above = params.above_support_distance_m;
  const size_t num_bands = core::ThreadPool::NumChunks(num_pixels, kPixelGrain);
  if (bands_.size() < num_bands) bands_.resize(num_bands);
  core::ForChunks(pool, num_pixels, kPixelGrain, [&](size_t b, size_t e) {
    Band& band = bands_[b / kPixelGrain];
    band.first.clear();
    band.seen.assign(n, 0);
    band.above.assign(heights ? n : 0, 0);
    const int32_t* const pixel = sv.pixel_label.data();
    const core::Vec3f* const xyz = cloud.xyz.data();
    const uint8_t* const is_support = background_.data();
    uint8_t* const seen = band.seen.data();
    uint32_t* const above_count = band.above.data();
    for (size_t px = b; px < e;) {
      const int32_t s = pixel[px];
      size_t end = px + 1;
      while (end < e && pixel[end] == s) ++end;
      if (s >= 0) {
        if (!seen[s]) {
          seen[s] = 1;
          band.first.emplace_back(static_cast<uint32_t>(s), static_cast<uint32_t>(px));
        }
        if (heights && is_support[s]) {
          const PlaneEq pl = support_plane_[s + 1];
          uint32_t count = 0;
          for (size_t k = px; k < end; ++k) {
            const core::Vec3f q = xyz[k];
            count += pl.nx * q.x + pl.ny * q.y + pl.nz * q.z + pl.d > above ? 1u : 0u;
          }
          above_count[s] += count;
        }
      }
      px = end;
    }
  });
  sv_first_.assign(n, UINT32_MAX);
  for (size_t k = 0; k < num_bands; ++k) {
    for (const auto& [s, px] : bands_[k].first) {
      if (sv_first_[s] == UINT32_MAX) sv_first_[s] = px;
    }
  }
  above_count_.assign(n, 0);
  if (heights) {
    for (size_t k = 0; k < num_bands; ++k) {
      for (size_t i = 0; i < n; ++i) above_count_[i] += bands_[k].above[i];
    }
  }

  // Release: support supervoxels that stand mostly above their plane are foreground.
  released_.assign(n, 0);
  if (release) {
    for (size_t i = 0; i < n; ++i) {
      if (background_[i] && static_cast<double>(above_count_[i]) >=
                                double{params.support_release_fraction} * sv.num_points[i]) {
        background_[i] = 0;
        released_[i] = 1;
      }
    }
  }

  // Group foreground supervoxels: same initial segment and adjacent, or pieces of the same
  // non-support plane that touch with patch normals within plane_merge_max_pair_angle_deg.
  parent_.resize(n);
  std::iota(parent_.begin(), parent_.end(), 0);
  const float min_pair_cos =
      params.plane_merge_max_pair_angle_deg >= 180.f
          ? -2.f
          : static_cast<float>(
                std::cos(double{params.plane_merge_max_pair_angle_deg} * std::numbers::pi / 180.0));
  for (size_t i = 0; i < n; ++i) {
    if (background_[i]) continue;
    const core::Vec3f& ni = features.normal[i];
    for (uint32_t s = sv.adjacency_offsets[i]; s < sv.adjacency_offsets[i + 1]; ++s) {
      const uint32_t j = sv.adjacency[s];
      if (j <= i || background_[j]) continue;
      const bool same_segment = link.segment[i] == link.segment[j];
      const int32_t pi = planes.patch_plane[i];
      const core::Vec3f& nj = features.normal[j];
      const bool same_plane = pi >= 0 && pi == planes.patch_plane[j] &&
                              features.type[i] == graph::PatchType::kPlanar &&
                              features.type[j] == graph::PatchType::kPlanar &&
                              ni.x * nj.x + ni.y * nj.y + ni.z * nj.z >= min_pair_cos;
      if (same_segment || same_plane) Union(static_cast<int32_t>(i), static_cast<int32_t>(j));
    }
  }

  // Pieces of the support that are not on its plane: a group of released supervoxels alone
  // that does not stand clearly above the plane (a piece of the table slightly off the
  // fitted plane), and a group lying flat on a support or below it (support_flat_groups: none
  // of its supervoxels' centroids more than above_support_distance_m above the plane; a piece
  // of the table the plane labelling gave another plane, the table's front edge). Both are
  // background again, unless walled in (below).
  const bool release_low = release && params.support_release_min_height_m > 0.f;
  group_flat_.assign(n, 0);
  if (params.support_flat_groups) MarkFlatGroups(sv, planes);
  if (release_low || params.support_flat_groups) {
    group_unreleased_.assign(n, 0);
    group_height_.assign(n, 0.0);
    group_height_points_.assign(n, 0);
    for (size_t i = 0; i < n; ++i) {
      if (background_[i]) continue;
      const int32_t g = Find(static_cast<int32_t>(i));
      if (!released_[i]) {
        group_unreleased_[g] = 1;
        continue;
      }
      // The heights' sum from the points' mean (the supervoxel's centroid).
      const PlaneEq& pl = support_plane_[i + 1];
      const core::Vec3f& c = sv.centroid[i];
      group_height_[g] += static_cast<double>(sv.num_points[i]) *
                          (double{pl.nx} * c.x + double{pl.ny} * c.y + double{pl.nz} * c.z + pl.d);
      group_height_points_[g] += sv.num_points[i];
    }
    // A group on the support (released alone, or flat) and one of those that is also low.
    auto on_support_group = [&](int32_t g) {
      return group_flat_[g] != 0 || (release && !group_unreleased_[g]);
    };
    auto low_group = [&](int32_t g) {
      return group_flat_[g] != 0 ||
             (release_low && !group_unreleased_[g] &&
              group_height_[g] < double{params.support_release_min_height_m} *
                                     static_cast<double>(group_height_points_[g]));
    };
    // Enclosed: the low groups whose piece of the support (the connected support
    // supervoxels and the groups on the support around them) covers at most
    // support_release_enclosed_max_area_m2 and touches an object: the bottom inside a
    // pot or a bowl, a few millimetres above the table and walled in by it; the table itself
    // is one large piece. component_[s]: the piece of support supervoxel s (-1 for objects);
    // component_object_[c]: the object group piece c shares the most adjacencies with (-1
    // none); group_encloser_[g]: that group for an enclosed group g, else -1.
    group_encloser_.assign(n, -1);
    if (params.support_release_enclosed_max_area_m2 > 0.f) {
      component_.assign(n, -1);
      component_area_.clear();
      component_object_.clear();
      auto on_support = [&](size_t s) {
        return background_[s] || on_support_group(Find(static_cast<int32_t>(s)));
      };
      // A piece next to the pixels the support-first step took is the rest of that large
      // plane: never walled in.
      touches_taken_.assign(n, 0);
      if (support_first != nullptr && !support_first->taken_bits.empty() && organized) {
        // Only the supervoxels of the support's pieces are looked at (kSkip: the others).
        for (size_t s = 0; s < n; ++s) touches_taken_[s] = on_support(s) ? 0 : kSkip;
        MarkTouchingTaken(sv, *support_first);
        for (uint8_t& t : touches_taken_) t = t == kSkip ? 0 : t;
      }
      component_open_.clear();
      pair_keys_.clear();
      for (size_t seed = 0; seed < n; ++seed) {
        if (component_[seed] >= 0 || !on_support(seed)) continue;
        const int32_t c = static_cast<int32_t>(component_area_.size());
        component_area_.push_back(0.0);
        component_open_.push_back(0);
        component_object_.push_back(-1);
        stack_.assign(1, static_cast<uint32_t>(seed));
        component_[seed] = c;
        while (!stack_.empty()) {
          const uint32_t s = stack_.back();
          stack_.pop_back();
          component_area_[c] += sv_area_[s];
          component_open_[c] |= touches_taken_[s];
          for (uint32_t k = sv.adjacency_offsets[s]; k < sv.adjacency_offsets[s + 1]; ++k) {
            const uint32_t t = sv.adjacency[k];
            if (on_support(t)) {
              if (component_[t] < 0) {
                component_[t] = c;
                stack_.push_back(t);
              }
              continue;
            }
            pair_keys_.push_back(uint64_t{static_cast<uint32_t>(c)} << 32 |
                                 static_cast<uint32_t>(Find(static_cast<int32_t>(t))));
          }
        }
      }
      // The object group each piece shares the most adjacencies with (ties: the lower id).
      std::sort(pair_keys_.begin(), pair_keys_.end());
      uint32_t best_count = 0;
      ForEachPairRun(pair_keys_, [&](int32_t c, int32_t h, uint32_t count) {
        if (component_object_[c] < 0 || count > best_count) {
          component_object_[c] = h;
          best_count = count;
        }
      });
      for (size_t i = 0; i < n; ++i) {
        if (background_[i]) continue;
        const int32_t g = Find(static_cast<int32_t>(i));
        if (!on_support_group(g)) continue;
        const int32_t c = component_[i];
        if (component_object_[c] >= 0 && !component_open_[c] &&
            component_area_[c] <= double{params.support_release_enclosed_max_area_m2}) {
          group_encloser_[g] = component_object_[c];
        }
      }
    }
    // The groups are read before any of them changes (a join below moves roots).
    low_root_.assign(n, -1);
    for (size_t i = 0; i < n; ++i) {
      if (background_[i]) continue;
      const int32_t g = Find(static_cast<int32_t>(i));
      if (low_group(g)) low_root_[i] = g;
    }
    for (size_t i = 0; i < n; ++i) {
      const int32_t g = low_root_[i];
      if (g < 0) continue;
      if (group_encloser_[g] < 0) {
        background_[i] = 1;
      } else if (params.container_max_axis_offset_rel > 0.f) {
        // With container insides joined, a low enclosed bottom joins the vessel around it
        // (a higher group, a book lying beside an object, stays an object of its own).
        Union(static_cast<int32_t>(i), group_encloser_[g]);
      }
    }
  }

  // A vessel's inside ends at its rim: what continues it beyond is another object.
  if (params.vessel_rim_cut_margin_rel > 0.f) CutVesselRims(sv, features, planes);
  SumGroups(sv, features);
  if (params.merge_small_groups) {
    MergeSmallGroups(sv);
    SumGroups(sv, features);
  }
  if (params.container_max_axis_offset_rel > 0.f) {
    MergeContainerInsides(sv, features, planes);
    SumGroups(sv, features);
  }

  // Label groups in row-major order of their first point (the first of their supervoxels'
  // first points); drop small ones. The tables below are indexed by supervoxel + 1, so that
  // an invalid point (-1) needs no branch.
  group_first_.assign(n, UINT32_MAX);
  for (size_t i = 0; i < n; ++i) {
    if (background_[i]) continue;
    const int32_t g = Find(static_cast<int32_t>(i));
    group_first_[g] = std::min(group_first_[g], sv_first_[i]);
  }
  group_order_.clear();
  for (size_t g = 0; g < n; ++g) {
    if (group_first_[g] != UINT32_MAX) group_order_.emplace_back(group_first_[g], g);
  }
  std::sort(group_order_.begin(), group_order_.end());
  group_label_.assign(n, 0);
  uint32_t next = 0;
  for (const auto& [first, g] : group_order_) {
    group_label_[g] = KeepGroup(planes, static_cast<int32_t>(g)) ? ++next : 0u;
  }
  result->objects_capped = next > static_cast<uint32_t>(params.max_objects);
  if (result->objects_capped) next = KeepLargestGroups(static_cast<uint32_t>(params.max_objects));
  sv_label_.resize(n + 1);
  sv_label_[0] = 0;
  for (size_t i = 0; i < n; ++i) {
    sv_label_[i + 1] = background_[i] ? 0u : group_label_[Find(static_cast<int32_t>(i))];
  }

  // Reclaim candidates: points above the support in supervoxels that stayed support (not
  // released ones sent back), next to an object. In an unorganized cloud the objects'
  // supervoxels adjacent to them are anchors: their points are the candidates' neighbours.
  const bool reclaim = params.support_reclaim_passes > 0 && next > 0;
  reclaim_from_.assign(n + 1, 0);
  anchor_.assign(n + 1, 0);
  if (reclaim) {
    for (size_t i = 0; i < n; ++i) {
      if (!background_[i] || released_[i] || above_count_[i] == 0) continue;
      for (uint32_t s = sv.adjacency_offsets[i]; s < sv.adjacency_offsets[i + 1]; ++s) {
        const uint32_t j = sv.adjacency[s];
        if (sv_label_[j + 1] == 0) continue;
        reclaim_from_[i + 1] = 1;
        anchor_[j + 1] = organized ? 0 : 1;
      }
    }
  }

  // Second pass: each point takes its supervoxel's label; points of an object that lie on a
  // support plane go back to the background (support_snap_distance_m); reclaim candidates
  // and anchors are listed per band.
  const float snap = params.support_snap_distance_m;
  core::ForChunks(pool, num_pixels, kPixelGrain, [&](size_t b, size_t e) {
    Band& band = bands_[b / kPixelGrain];
    band.candidates.clear();
    band.anchors.clear();
    const int32_t* pixel = sv.pixel_label.data();
    const uint32_t* label = sv_label_.data();
    uint32_t* out = labels->data.data();
    for (size_t px = b; px < e; ++px) out[px] = label[pixel[px] + 1];
    if (snap > 0.f) {
      for (size_t p = 0; p < num_planes; ++p) {
        if (!support_[p]) continue;
        const core::Vec3f nrm = planes.planes[p].normal;
        const float d = planes.planes[p].d;
        for (size_t px = b; px < e; ++px) {
          if (out[px] == 0) continue;
          const core::Vec3f& q = cloud.xyz[px];
          if (std::abs(nrm.x * q.x + nrm.y * q.y + nrm.z * q.z + d) < snap) out[px] = 0;
        }
      }
    }
    if (!reclaim) return;
    for (size_t px = b; px < e;) {
      const int32_t s = pixel[px];
      size_t end = px + 1;
      while (end < e && pixel[end] == s) ++end;
      if (anchor_[s + 1]) {
        for (size_t k = px; k < end; ++k) {
          if (out[k] != 0) band.anchors.push_back(static_cast<uint32_t>(k));
        }
      } else if (reclaim_from_[s + 1]) {
        const PlaneEq pl = support_plane_[s + 1];
        for (size_t k = px; k < end; ++k) {
          const core::Vec3f q = cloud.xyz[k];
          if (pl.nx * q.x + pl.ny * q.y + pl.nz * q.z + pl.d > above) {
            band.candidates.push_back(static_cast<uint32_t>(k));
          }
        }
      }
      px = end;
    }
  });
  if (reclaim) {
    candidates_.clear();
    anchors_.clear();
    for (size_t k = 0; k < num_bands; ++k) {
      candidates_.insert(candidates_.end(), bands_[k].candidates.begin(),
                         bands_[k].candidates.end());
      anchors_.insert(anchors_.end(), bands_[k].anchors.begin(), bands_[k].anchors.end());
    }
    if (organized) {
      ReclaimOrganized(cloud, labels);
    } else {
      ReclaimUnorganized(cloud, labels);
    }
  }
  result->objects.assign(next, Object{});
}

void Refiner::ReclaimOrganized(const core::PointCloud& cloud, core::LabelImage* labels) {
  // Each pass, every candidate next to a labelled pixel (left, right, up, down) takes the
  // label of the one nearest in depth, unless the step exceeds the limit; the labels taken
  // in a pass are written after it, so the order of the candidates does not matter.
  const size_t w = static_cast<size_t>(labels->width), h = static_cast<size_t>(labels->height);
  const float step = params_.support_reclaim_max_step_rel;
  uint32_t* out = labels->data.data();
  const core::Vec3f* xyz = cloud.xyz.data();
  for (int pass = 0; pass < params_.support_reclaim_passes && !candidates_.empty(); ++pass) {
    takes_.clear();
    size_t kept = 0;
    for (const uint32_t px : candidates_) {
      const size_t u = px % w, v = px / w;
      const float z = xyz[px].z;
      const float limit = step * z;
      uint32_t label = 0;
      float best = 0.f;
      auto consider = [&](size_t o) {
        const uint32_t l = out[o];
        if (l == 0) return;
        const float dz = std::abs(xyz[o].z - z);
        if (!(dz <= limit)) return;
        if (label == 0 || dz < best) {
          label = l;
          best = dz;
        }
      };
      if (u > 0) consider(px - 1);
      if (u + 1 < w) consider(px + 1);
      if (v > 0) consider(px - w);
      if (v + 1 < h) consider(px + w);
      if (label != 0) {
        takes_.emplace_back(px, label);
      } else {
        candidates_[kept++] = px;
      }
    }
    if (takes_.empty()) break;
    candidates_.resize(kept);
    for (const auto& [px, label] : takes_) out[px] = label;
  }
}

void Refiner::ReclaimUnorganized(const core::PointCloud& cloud, core::LabelImage* labels) {
  const size_t nc = candidates_.size();
  if (nc == 0 || anchors_.empty()) return;
  // The candidates and anchors in one 3-d index (candidates first); each candidate's nearest
  // neighbours within the step limit, nearest first, found on the pool.
  const size_t total = nc + anchors_.size();
  reclaim_xyz_.resize(3 * total);
  for (size_t k = 0; k < total; ++k) {
    const core::Vec3f& p = cloud.xyz[k < nc ? candidates_[k] : anchors_[k - nc]];
    reclaim_xyz_[3 * k] = p.x;
    reclaim_xyz_[3 * k + 1] = p.y;
    reclaim_xyz_[3 * k + 2] = p.z;
  }
  reclaim_index_.Build(reclaim_xyz_.data(), total, 3);
  constexpr size_t kStride = kReclaimNeighbors + 1;  // the query point finds itself too
  neighbors_.assign(kStride * nc, UINT32_MAX);
  const float step = params_.support_reclaim_max_step_rel;
  core::ForChunks(pool_, nc, kCandidateGrain, [&](size_t b, size_t e) {
    uint32_t index[kStride];
    float dist2[kStride];
    for (size_t c = b; c < e; ++c) {
      const float* q = &reclaim_xyz_[3 * c];
      const size_t found = reclaim_index_.Nearest(q, kStride, index, dist2);
      const float limit = step * q[2];
      uint32_t* dst = &neighbors_[kStride * c];
      for (size_t k = 0; k < found; ++k) {
        if (index[k] == c || !(dist2[k] <= limit * limit)) continue;
        *dst++ = index[k];
      }
    }
  });
  // Labels of the indexed points: candidates start unlabelled. Each pass, an unlabelled
  // candidate takes the label of its nearest labelled neighbour; the labels taken in a pass
  // are written after it.
  uint32_t* out = labels->data.data();
  reclaim_label_.resize(total);
  for (size_t k = 0; k < total; ++k) reclaim_label_[k] = k < nc ? 0u : out[anchors_[k - nc]];
  for (int pass = 0; pass < params_.support_reclaim_passes; ++pass) {
    takes_.clear();
    for (size_t c = 0; c < nc; ++c) {
      if (reclaim_label_[c] != 0) continue;
      const uint32_t* nb = &neighbors_[kStride * c];
      for (size_t k = 0; k < kStride && nb[k] != UINT32_MAX; ++k) {
        const uint32_t l = reclaim_label_[nb[k]];
        if (l == 0) continue;
        takes_.emplace_back(static_cast<uint32_t>(c), l);
        break;
      }
    }
    if (takes_.empty()) break;
    for (const auto& [c, l] : takes_) reclaim_label_[c] = l;
  }
  for (size_t c = 0; c < nc; ++c) {
    if (reclaim_label_[c] != 0) out[candidates_[c]] = reclaim_label_[c];
  }
}

}  // namespace clutterseg::pipeline
