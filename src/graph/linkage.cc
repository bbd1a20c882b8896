#include "clutterseg/graph/linkage.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "clutterseg/core/scoped_timer.h"

namespace clutterseg::graph {
namespace {

constexpr size_t kNodeGrain = 512;
constexpr double kRadToDeg = 180.0 / std::numbers::pi;

int32_t Find(std::vector<int32_t>& parent, int32_t x) {
  int32_t root = x;
  while (parent[root] != root) root = parent[root];
  while (parent[x] != root) {
    const int32_t next = parent[x];
    parent[x] = root;
    x = next;
  }
  return root;
}

void CheckAdjacency(const supervoxel::Supervoxels& sv) {
  const size_t n = sv.size();
  if (sv.adjacency_offsets.size() != n + 1 || sv.adjacency_offsets.front() != 0 ||
      sv.adjacency_offsets.back() != sv.adjacency.size()) {
    throw std::runtime_error("Linkage: adjacency_offsets has " +
                             std::to_string(sv.adjacency_offsets.size()) + " entries for " +
                             std::to_string(n) + " supervoxels and " +
                             std::to_string(sv.adjacency.size()) + " slots");
  }
  for (size_t i = 0; i < n; ++i) {
    if (sv.adjacency_offsets[i] > sv.adjacency_offsets[i + 1]) {
      throw std::runtime_error("Linkage: adjacency_offsets not monotone at supervoxel " +
                               std::to_string(i));
    }
  }
}

}  // namespace

bool IsConvexConnection(const core::Vec3f& ci, const core::Vec3f& ni, const core::Vec3f& cj,
                        const core::Vec3f& nj, const LinkageParams& params) {
  double dx = double{ci.x} - cj.x, dy = double{ci.y} - cj.y, dz = double{ci.z} - cj.z;
  const double dlen = std::sqrt(dx * dx + dy * dy + dz * dz);
  if (!(dlen > 0.0)) return true;  // coincident centroids: no evidence of a concavity
  dx /= dlen;
  dy /= dlen;
  dz /= dlen;
  const double cos_a =
      std::clamp(double{ni.x} * nj.x + double{ni.y} * nj.y + double{ni.z} * nj.z, -1.0, 1.0);
  // The normal angle is needed only for concave connections and for the sanity threshold.
  double angle_deg = -1.0;
  auto normal_angle_deg = [&]() {
    if (angle_deg < 0.0) angle_deg = std::acos(static_cast<float>(cos_a)) * kRadToDeg;
    return angle_deg;
  };

  // Convexity: (n_i - n_j) . d >= -epsilon, or a concavity shallower than the tolerance.
  const double convexity =
      (double{ni.x} - nj.x) * dx + (double{ni.y} - nj.y) * dy + (double{ni.z} - nj.z) * dz;
  if (convexity < -double{params.convexity_epsilon} &&
      !(normal_angle_deg() < params.concavity_tolerance_deg)) {
    return false;
  }

  if (params.use_sanity_criterion) {
    // s = n_i x n_j; theta = min(angle(d, s), angle(d, -s)); cut when theta is below
    // 60 / (1 + exp(-0.25 (a - 25))) degrees. That threshold never exceeds 60 degrees, so
    // connections with theta >= 60 (cos theta <= 0.5) pass without evaluating it.
    const double sx = double{ni.y} * nj.z - double{ni.z} * nj.y;
    const double sy = double{ni.z} * nj.x - double{ni.x} * nj.z;
    const double sz = double{ni.x} * nj.y - double{ni.y} * nj.x;
    const double slen = std::sqrt(sx * sx + sy * sy + sz * sz);
    if (slen > 1e-12) {
      const double c = std::min(1.0, std::fabs(sx * dx + sy * dy + sz * dz) / slen);
      if (c > 0.5) {
        const double theta_deg = std::acos(c) * kRadToDeg;
        const double threshold_deg = 60.0 / (1.0 + std::exp(-0.25 * (normal_angle_deg() - 25.0)));
        if (theta_deg < threshold_deg) return false;
      }
    }
  }
  return true;
}

Linkage::Linkage(const LinkageParams& params, core::ThreadPool* pool)
    : params_((params.ValidateOrThrow(), params)), pool_(pool) {}

void Linkage::Compute(const supervoxel::Supervoxels& sv, const PatchFeatures& f,
                      LinkageResult* out) {
  const core::ScopedTimer timer(&out->time_ms);
  const size_t n = sv.size();
  if (f.size() != n || f.normal.size() != n || f.type.size() != n) {
    throw std::runtime_error("Linkage: features have " + std::to_string(f.size()) +
                             " entries for " + std::to_string(n) + " supervoxels");
  }
  out->filtered_type.resize(n);
  out->segment.resize(n);
  out->segment_size.clear();
  out->num_segments = 0;
  const size_t slots = sv.adjacency.size();
  out->edge_convex.assign(slots, 0);
  out->edge_kept.assign(slots, 0);
  if (n == 0) return;
  CheckAdjacency(sv);
  const auto& off = sv.adjacency_offsets;
  const auto& adj = sv.adjacency;

  // Reverse slot of every CSR slot (the adjacency must be symmetric and sorted).
  reverse_slot_.resize(slots);
  auto run = [&](const auto& fn) { core::ForChunks(pool_, n, kNodeGrain, fn); };
  run([&](size_t i0, size_t i1) {
    for (size_t i = i0; i < i1; ++i) {
      for (uint32_t s = off[i]; s < off[i + 1]; ++s) {
        const uint32_t j = adj[s];
        if (j >= n || j == i) {
          reverse_slot_[s] = UINT32_MAX;
          continue;
        }
        const auto first = adj.begin() + off[j];
        const auto last = adj.begin() + off[j + 1];
        const auto it = std::lower_bound(first, last, static_cast<uint32_t>(i));
        reverse_slot_[s] =
            (it != last && *it == i) ? static_cast<uint32_t>(it - adj.begin()) : UINT32_MAX;
      }
    }
  });
  for (size_t s = 0; s < slots; ++s) {
    if (reverse_slot_[s] == UINT32_MAX) {
      throw std::runtime_error("Linkage: adjacency slot " + std::to_string(s) +
                               " is a self loop, out of range or has no reverse entry");
    }
  }

  // Local area linkage: majority filter on the patch types.
  run([&](size_t i0, size_t i1) {
    for (size_t i = i0; i < i1; ++i) {
      PatchType t = f.type[i];
      if (params_.use_type_filter) {
        const uint32_t deg = off[i + 1] - off[i];
        uint32_t planar = 0;
        for (uint32_t s = off[i]; s < off[i + 1]; ++s) {
          planar += f.type[adj[s]] == PatchType::kPlanar ? 1u : 0u;
        }
        if (2 * planar > deg) {
          t = PatchType::kPlanar;
        } else if (2 * (deg - planar) > deg) {
          t = PatchType::kNonPlanar;
        }
      }
      out->filtered_type[i] = t;
    }
  });

  // Convexity per undirected edge, mirrored to the reverse slot.
  convex_raw_.assign(slots, 0);
  run([&](size_t i0, size_t i1) {
    for (size_t i = i0; i < i1; ++i) {
      for (uint32_t s = off[i]; s < off[i + 1]; ++s) {
        const uint32_t j = adj[s];
        if (j < i) continue;
        const uint8_t c =
            IsConvexConnection(f.centroid[i], f.normal[i], f.centroid[j], f.normal[j], params_) ? 1
                                                                                                : 0;
        convex_raw_[s] = c;
        convex_raw_[reverse_slot_[s]] = c;
      }
    }
  });

  // Extended convexity: count common neighbours forming convex triangles.
  if (params_.use_extended_convexity) {
    const uint32_t k_needed = static_cast<uint32_t>(params_.extended_convexity_k);
    run([&](size_t i0, size_t i1) {
      for (size_t i = i0; i < i1; ++i) {
        for (uint32_t s = off[i]; s < off[i + 1]; ++s) {
          const uint32_t j = adj[s];
          if (j < i || !convex_raw_[s]) continue;
          uint32_t count = 0;
          uint32_t a = off[i], b = off[j];
          while (a < off[i + 1] && b < off[j + 1] && count < k_needed) {
            if (adj[a] < adj[b]) {
              ++a;
            } else if (adj[b] < adj[a]) {
              ++b;
            } else {
              if (convex_raw_[a] && convex_raw_[b]) ++count;
              ++a;
              ++b;
            }
          }
          const uint8_t c = count >= k_needed ? 1 : 0;
          out->edge_convex[s] = c;
          out->edge_convex[reverse_slot_[s]] = c;
        }
      }
    });
  } else {
    out->edge_convex = convex_raw_;
  }

  for (size_t i = 0; i < n; ++i) {
    for (uint32_t s = off[i]; s < off[i + 1]; ++s) {
      const uint32_t j = adj[s];
      bool keep = out->edge_convex[s] != 0;
      if (params_.cut_on_type_change && out->filtered_type[i] != out->filtered_type[j]) {
        keep = false;
      }
      out->edge_kept[s] = keep ? 1 : 0;
    }
  }

  // Connected components over kept edges.
  parent_.resize(n);
  for (size_t i = 0; i < n; ++i) parent_[i] = static_cast<int32_t>(i);
  for (size_t i = 0; i < n; ++i) {
    for (uint32_t s = off[i]; s < off[i + 1]; ++s) {
      const uint32_t j = adj[s];
      if (j < i || !out->edge_kept[s]) continue;
      const int32_t a = Find(parent_, static_cast<int32_t>(i));
      const int32_t b = Find(parent_, static_cast<int32_t>(j));
      if (a != b) parent_[std::max(a, b)] = std::min(a, b);  // root = smallest member
    }
  }
  // With the root always the smallest member, components appear in order of their roots.
  int32_t num = 0;
  for (size_t i = 0; i < n; ++i) {
    const int32_t r = Find(parent_, static_cast<int32_t>(i));
    out->segment[i] = (r == static_cast<int32_t>(i)) ? num++ : out->segment[r];
  }

  // Merge components smaller than min_segment_supervoxels into their largest neighbour.
  if (params_.min_segment_supervoxels > 1 && num > 1) {
    const uint32_t min_size = static_cast<uint32_t>(params_.min_segment_supervoxels);
    // Segments over segments: parent_ and size_ are reused, indexed by segment id.
    parent_.resize(num);
    size_.assign(num, 0);
    for (int32_t s = 0; s < num; ++s) parent_[s] = s;
    for (size_t i = 0; i < n; ++i) ++size_[out->segment[i]];
    // Members of each initial segment, by counting sort (ascending supervoxel id).
    std::vector<uint32_t>& start = member_start_;
    std::vector<uint32_t>& members = members_;
    start.assign(num + 1, 0);
    for (size_t i = 0; i < n; ++i) ++start[out->segment[i] + 1];
    for (int32_t s = 0; s < num; ++s) start[s + 1] += start[s];
    members.resize(n);
    fill_.assign(start.begin(), start.end() - 1);
    for (size_t i = 0; i < n; ++i) members[fill_[out->segment[i]]++] = static_cast<uint32_t>(i);
    for (int32_t s = 0; s < num; ++s) {
      const int32_t r = Find(parent_, s);
      if (size_[r] >= min_size) continue;
      int32_t best = -1;
      for (uint32_t m = start[s]; m < start[s + 1]; ++m) {
        const uint32_t i = members[m];
        for (uint32_t e = off[i]; e < off[i + 1]; ++e) {
          const int32_t q = Find(parent_, out->segment[adj[e]]);
          if (q == r) continue;
          if (best < 0 || size_[q] > size_[best] || (size_[q] == size_[best] && q < best)) {
            best = q;
          }
        }
      }
      if (best < 0) continue;  // isolated: stays on its own
      parent_[r] = best;
      size_[best] += size_[r];
    }
    // Renumber in order of the smallest supervoxel of each merged segment.
    new_id_.assign(num, -1);  // merged root -> new id
    int32_t next = 0;
    for (size_t i = 0; i < n; ++i) {
      const int32_t r = Find(parent_, out->segment[i]);
      if (new_id_[r] < 0) new_id_[r] = next++;
      out->segment[i] = new_id_[r];
    }
    num = next;
  }

  out->num_segments = num;
  out->segment_size.assign(num, 0);
  for (size_t i = 0; i < n; ++i) ++out->segment_size[out->segment[i]];
}

}  // namespace clutterseg::graph
