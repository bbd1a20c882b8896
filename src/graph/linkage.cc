#include "clutterseg/graph/linkage.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "clutterseg/core/scoped_timer.h"
#include "clutterseg/core/union_find.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace clutterseg::graph {
namespace {

constexpr size_t kNodeGrain = 512;
constexpr double kRadToDeg = 180.0 / std::numbers::pi;
constexpr float kNever = std::numeric_limits<float>::infinity();
constexpr size_t kRowGrain = 32;  // rows per band of the image border pass
// The bridge cut's searches scan at most this many adjacency slots per slot of the graph in
// a frame. Real and synthetic frames need 0.3-21 (mOSD, synthetic rooms and piles); a frame
// of garbage depth (corrupt recording data) needed 2600, 4 s on one thread, before the bound.
constexpr size_t kBridgeWorkPerSlot = 64;
constexpr size_t kVoxelGrain = 2048;

// Union-find forest of the components over the kept edges of a CSR adjacency (`kept` per
// slot): every root is the smallest member of its component.
void JoinKept(const supervoxel::Supervoxels& sv, const std::vector<uint8_t>& kept,
              std::vector<int32_t>* parent) {
  const size_t n = sv.size();
  const auto& off = sv.adjacency_offsets;
  const auto& adj = sv.adjacency;
  parent->resize(n);
  for (size_t i = 0; i < n; ++i) (*parent)[i] = static_cast<int32_t>(i);
  for (size_t i = 0; i < n; ++i) {
    for (uint32_t s = off[i]; s < off[i + 1]; ++s) {
      const uint32_t j = adj[s];
      if (j < i || !kept[s]) continue;
      const int32_t a = core::FindRoot(parent->data(), static_cast<int32_t>(i));
      const int32_t b = core::FindRoot(parent->data(), static_cast<int32_t>(j));
      if (a != b) (*parent)[std::max(a, b)] = std::min(a, b);
    }
  }
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

#if defined(__SSE2__)
// A bit per lane of x and y whose labels differ and are both valid (>= 0).
inline unsigned DifferingValid(__m128i x, __m128i y) {
  const unsigned equal =
      static_cast<unsigned>(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(x, y))));
  const unsigned invalid =
      static_cast<unsigned>(_mm_movemask_ps(_mm_castsi128_ps(_mm_or_si128(x, y))));
  return ~(equal | invalid) & 0xfu;
}
#endif

// For a mask of 8 pairs of four pixels u..u + 3 (bits 0-3: (u + k, u + k + 1), bits 4-7:
// (u + k, u + k + w)): the codes (2 k | direction) of the set bits first, and their count.
constexpr std::array<std::array<uint8_t, 8>, 256> kPairCode = [] {
  std::array<std::array<uint8_t, 8>, 256> t{};
  for (unsigned m = 0; m < 256; ++m) {
    unsigned n = 0;
    for (unsigned k = 0; k < 8; ++k) {
      if ((m >> k) & 1u) t[m][n++] = static_cast<uint8_t>(k < 4 ? 2 * k : 2 * (k - 4) + 1);
    }
  }
  return t;
}();
constexpr std::array<uint8_t, 256> kBitCount = [] {
  std::array<uint8_t, 256> t{};
  for (unsigned m = 0; m < 256; ++m) {
    for (unsigned k = 0; k < 8; ++k) t[m] += static_cast<uint8_t>((m >> k) & 1u);
  }
  return t;
}();

// The CSR slot of edge (lo, hi), lo < hi, in lo's neighbour list, or UINT32_MAX, with the
// slots of recent pairs in a small direct-mapped cache: border pairs repeat the same few
// supervoxel pairs.
class SlotCache {
 public:
  SlotCache(const uint32_t* offsets, const uint32_t* adjacency) : off_(offsets), adj_(adjacency) {
    entries_.fill(Entry{UINT64_MAX, UINT32_MAX});
  }
  uint32_t Slot(uint32_t lo, uint32_t hi) {
    const uint64_t pair = (uint64_t{lo} << 32) | hi;
    Entry& e = entries_[((lo * 31u + hi) * 2654435761u) >> 24];
    if (e.pair != pair) {
      e.pair = pair;
      const uint32_t* first = adj_ + off_[lo];
      const uint32_t* end = adj_ + off_[lo + 1];
      const uint32_t* it = std::lower_bound(first, end, hi);
      e.slot = it != end && *it == hi ? static_cast<uint32_t>(it - adj_) : UINT32_MAX;
    }
    return e.slot;
  }

 private:
  struct Entry {
    uint64_t pair;
    uint32_t slot;
  };
  const uint32_t* off_;
  const uint32_t* adj_;
  std::array<Entry, 256> entries_;
};

// Connections whose normals' cosine exceeds this skip the sanity criterion (2: none does).
double SanityMinCos(const LinkageParams& params) {
  return params.sanity_min_angle_deg > 0.f
             ? std::cos(double{params.sanity_min_angle_deg} / kRadToDeg)
             : 2.0;
}

// The verdict of LCCP's convexity test on one connection.
enum ConnectionClass : uint8_t {
  kConvex = 0,        // convex, or concave below the tolerance (and below crease_min_deg)
  kMildConcave = 1,   // kept: concave within the tolerance, normal angle >= crease_min_deg
  kSharpConcave = 2,  // cut: concave beyond the tolerance
  kSanityCut = 3,     // cut by the sanity criterion
};

// `sanity_min_cos`: the cosine of params.sanity_min_angle_deg (connections with a larger
// cosine skip the sanity criterion).
ConnectionClass ClassifyConnection(const core::Vec3f& ci, const core::Vec3f& ni,
                                   const core::Vec3f& cj, const core::Vec3f& nj,
                                   const LinkageParams& params, double sanity_min_cos,
                                   float crease_min_deg) {
  double dx = double{ci.x} - cj.x, dy = double{ci.y} - cj.y, dz = double{ci.z} - cj.z;
  const double dlen = std::sqrt(dx * dx + dy * dy + dz * dz);
  if (!(dlen > 0.0)) return kConvex;  // coincident centroids: no evidence of a concavity
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
  const bool concave = convexity < -double{params.convexity_epsilon};
  if (concave && !(normal_angle_deg() < params.concavity_tolerance_deg)) return kSharpConcave;

  if (params.use_sanity_criterion && !(cos_a > sanity_min_cos)) {
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
        if (theta_deg < threshold_deg) return kSanityCut;
      }
    }
  }
  return concave && normal_angle_deg() >= crease_min_deg ? kMildConcave : kConvex;
}

// Patches i and j face each other: (n_i - n_j) . (c_i - c_j) < 0, without tolerance or
// sanity (the sign of the convexity test).
bool FaceEachOther(const PatchFeatures& f, uint32_t i, uint32_t j) {
  const core::Vec3f& ni = f.normal[i];
  const core::Vec3f& nj = f.normal[j];
  const core::Vec3f& ci = f.centroid[i];
  const core::Vec3f& cj = f.centroid[j];
  return (ni.x - nj.x) * (ci.x - cj.x) + (ni.y - nj.y) * (ci.y - cj.y) +
             (ni.z - nj.z) * (ci.z - cj.z) <
         0.f;
}

}  // namespace

bool IsConvexConnection(const core::Vec3f& ci, const core::Vec3f& ni, const core::Vec3f& cj,
                        const core::Vec3f& nj, const LinkageParams& params) {
  return ClassifyConnection(ci, ni, cj, nj, params, SanityMinCos(params), kNever) <= kMildConcave;
}

Linkage::Linkage(const LinkageParams& params, core::ThreadPool* pool)
    : params_((params.ValidateOrThrow(), params)), pool_(pool) {}

void Linkage::Compute(const supervoxel::Supervoxels& sv, const PatchFeatures& f,
                      const LinkageCues& cues, LinkageResult* out) {
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
  const bool crease = params_.crease_min_angle_deg > 0.f;
  const float crease_min_deg = crease ? params_.crease_min_angle_deg : kNever;
  const double sanity_min_cos = SanityMinCos(params_);
  const CueUse use = Use(sv, cues);
  const bool color = use.color;
  const bool prepared = prepared_for_ == &sv;
  prepared_for_ = nullptr;
  // With colour the tolerance may be wider: the colour cut below judges what it lets in.
  LinkageParams convexity_params = params_;
  if (color && params_.color_concavity_tolerance_deg > 0.f) {
    convexity_params.concavity_tolerance_deg = params_.color_concavity_tolerance_deg;
  }
  convex_raw_.resize(slots);
  edge_class_.resize(slots);
  run([&](size_t i0, size_t i1) {
    for (size_t i = i0; i < i1; ++i) {
      for (uint32_t s = off[i]; s < off[i + 1]; ++s) {
        const uint32_t j = adj[s];
        if (j < i) continue;
        const ConnectionClass c =
            ClassifyConnection(f.centroid[i], f.normal[i], f.centroid[j], f.normal[j],
                               convexity_params, sanity_min_cos, crease_min_deg);
        edge_class_[s] = edge_class_[reverse_slot_[s]] = c;
        convex_raw_[s] = convex_raw_[reverse_slot_[s]] = c <= kMildConcave ? 1 : 0;
      }
    }
  });

  // Cues that cut edges the convexity test keeps, judged on the test's verdicts (none reads
  // another's cuts): flags per slot of the lower id, applied afterwards.
  const bool jumps = params_.depth_jump_rel > 0.f;
  const bool image_jumps = use.image_jumps;
  const bool view_jumps = use.view_jumps;
  const bool contact = use.contact;
  const float cos_contact =
      static_cast<float>(std::cos(double{params_.contact_cut_max_angle_deg} / kRadToDeg));
  const auto contact_limit = static_cast<uint32_t>(params_.contact_cut_max_pairs);
  if (contact) contact_cut_.assign(slots, 0);
  if (crease || image_jumps || view_jumps || color || contact) {
    if (image_jumps || contact) CountImageBorderPairs(sv, *cues.cloud);
    if (view_jumps) CountViewBorderPairs(sv, *cues.voxels, *cues.voxel_supervoxel);
    if (color && !prepared) MeanChroma(sv, *cues.cloud);
    const float cos_color =
        static_cast<float>(std::cos(double{params_.color_min_angle_deg} / kRadToDeg));
    const float color_limit2 = params_.color_threshold * params_.color_threshold;
    cue_cut_.assign(slots, 0);
    run([&](size_t i0, size_t i1) {
      for (size_t i = i0; i < i1; ++i) {
        for (uint32_t s = off[i]; s < off[i + 1]; ++s) {
          const uint32_t j = adj[s];
          if (j < i || !convex_raw_[s]) continue;
          bool cut = false;
          if (crease && edge_class_[s] == kMildConcave) {
            // A common neighbour with a sharp concavity to either end: the sorted neighbour
            // lists of i and j, walked together.
            uint32_t a = off[i], b = off[j];
            while (!cut && a < off[i + 1] && b < off[j + 1]) {
              if (adj[a] < adj[b]) {
                ++a;
              } else if (adj[b] < adj[a]) {
                ++b;
              } else {
                cut = edge_class_[a] == kSharpConcave || edge_class_[b] == kSharpConcave;
                ++a;
                ++b;
              }
            }
          }
          if (!cut && jumps && (image_jumps || view_jumps)) {
            const uint32_t pairs = border_pairs_[s];
            cut = pairs >= static_cast<uint32_t>(params_.depth_jump_min_pairs) &&
                  static_cast<float>(jump_pairs_[s]) >=
                      params_.depth_jump_fraction * static_cast<float>(pairs);
          }
          if (!cut && contact && border_pairs_[s] < contact_limit) {
            // A candidate of the contact cut; its diagonal pixel pairs are counted below.
            const core::Vec3f& ni = f.normal[i];
            const core::Vec3f& nj = f.normal[j];
            if (ni.x * nj.x + ni.y * nj.y + ni.z * nj.z >= cos_contact) contact_cut_[s] = 1;
          }
          if (!cut && color) {
            const core::Vec3f& ni = f.normal[i];
            const core::Vec3f& nj = f.normal[j];
            const float cos_a = ni.x * nj.x + ni.y * nj.y + ni.z * nj.z;
            if (cos_a <= cos_color && FaceEachOther(f, static_cast<uint32_t>(i), j)) {
              const float* p = &mean_chroma_[3 * i];
              const float* q = &mean_chroma_[3 * j];
              const float d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                               (p[2] - q[2]) * (p[2] - q[2]);
              cut = d2 > color_limit2;
            }
          }
          cue_cut_[s] = cut ? 1 : 0;
        }
      }
    });
    for (size_t s = 0; s < slots; ++s) {
      if (cue_cut_[s]) convex_raw_[s] = convex_raw_[reverse_slot_[s]] = 0;
    }
    if (contact) CountDiagonalContacts(sv);
  }

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

  if (params_.bridge_max_edges > 0) CutBridges(sv, f, out);
  if (contact) CutContactless(sv, out);

  // Connected components over kept edges.
  JoinKept(sv, out->edge_kept, &parent_);
  // With the root always the smallest member, components appear in order of their roots.
  int32_t num = 0;
  for (size_t i = 0; i < n; ++i) {
    const int32_t r = core::FindRoot(parent_.data(), static_cast<int32_t>(i));
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
      const int32_t r = core::FindRoot(parent_.data(), s);
      if (size_[r] >= min_size) continue;
      int32_t best = -1;
      for (uint32_t m = start[s]; m < start[s + 1]; ++m) {
        const uint32_t i = members[m];
        for (uint32_t e = off[i]; e < off[i + 1]; ++e) {
          const int32_t q = core::FindRoot(parent_.data(), out->segment[adj[e]]);
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
      const int32_t r = core::FindRoot(parent_.data(), out->segment[i]);
      if (new_id_[r] < 0) new_id_[r] = next++;
      out->segment[i] = new_id_[r];
    }
    num = next;
  }

  out->num_segments = num;
  out->segment_size.assign(num, 0);
  for (size_t i = 0; i < n; ++i) ++out->segment_size[out->segment[i]];
}

Linkage::CueUse Linkage::Use(const supervoxel::Supervoxels& sv, const LinkageCues& cues) const {
  CueUse use;
  const bool jumps = params_.depth_jump_rel > 0.f;
  use.image_jumps = jumps && cues.cloud.has_value() && cues.cloud->organized() &&
                    sv.width == cues.cloud->width && sv.height == cues.cloud->height &&
                    sv.pixel_label.size() == cues.cloud->xyz.size();
  use.view_jumps = jumps && !use.image_jumps && cues.voxels != nullptr &&
                   cues.voxel_supervoxel != nullptr &&
                   cues.voxel_supervoxel->size() == cues.voxels->size();
  use.contact = params_.contact_cut_max_pairs > 0 && cues.cloud.has_value() &&
                cues.cloud->organized() && sv.width == cues.cloud->width &&
                sv.height == cues.cloud->height && sv.pixel_label.size() == cues.cloud->xyz.size();
  use.color = params_.color_threshold > 0.f && cues.cloud.has_value() && cues.cloud->has_color() &&
              cues.cloud->rgba.size() == sv.pixel_label.size();
  return use;
}

void Linkage::PrepareCues(const supervoxel::Supervoxels& sv, const LinkageCues& cues) {
  if (Use(sv, cues).color) MeanChroma(sv, *cues.cloud);
  prepared_for_ = &sv;
}

void Linkage::CountImageBorderPairs(const supervoxel::Supervoxels& sv,
                                    const core::PointCloudView& cloud) {
  const size_t slots = sv.adjacency.size();
  border_pairs_.assign(slots, 0);
  jump_pairs_.assign(slots, 0);
  const size_t w = static_cast<size_t>(sv.width), h = static_cast<size_t>(sv.height);
  const size_t num_bands = core::ThreadPool::NumChunks(h, kRowGrain);
  if (band_events_.size() < num_bands) band_events_.resize(num_bands);
  if (band_pairs_.size() < num_bands) band_pairs_.resize(num_bands);
  const int32_t* lab = sv.pixel_label.data();
  const core::Vec3f* xyz = cloud.xyz.data();
  const uint32_t* off = sv.adjacency_offsets.data();
  const uint32_t* adj = sv.adjacency.data();
  const float rel = params_.depth_jump_rel;
  // Per band of rows: one event (slot << 1 | jumped) per pair of 4-neighbour pixels in two
  // supervoxels whose edge the convexity test keeps (pixels of supervoxels whose voxels do
  // not touch, behind an occluding edge, are no pair).
  core::ForChunks(pool_, h, kRowGrain, [&](size_t r0, size_t r1) {
    std::vector<uint32_t>& events = band_events_[r0 / kRowGrain];
    events.clear();
    SlotCache slot_of(off, adj);
    // The depths of border pixels are read out of order: the row two ahead is fetched into
    // the cache while this one is scanned.
    constexpr size_t kLine = 64;
    auto prefetch_row = [&](size_t v) {
      if (v >= h) return;
      const char* first = reinterpret_cast<const char*>(xyz + v * w);
      const char* last = reinterpret_cast<const char*>(xyz + (v + 1) * w);
      for (const char* c = first; c < last; c += kLine) __builtin_prefetch(c);
    };
    prefetch_row(r0);
    prefetch_row(r0 + 1);
    auto visit = [&](size_t p, size_t q) {
      const uint32_t a = static_cast<uint32_t>(lab[p]), b = static_cast<uint32_t>(lab[q]);
      const uint32_t slot = slot_of.Slot(std::min(a, b), std::max(a, b));
      // Only edges the convexity test keeps can be cut.
      if (slot == UINT32_MAX || !convex_raw_[slot]) return;
      const float za = xyz[p].z, zb = xyz[q].z;
      const bool jump = std::fabs(za - zb) > rel * std::min(za, zb);
      events.push_back(slot << 1 | (jump ? 1u : 0u));
    };
    // First the border pixels of the band, as p << 1 | direction (0: (p, p + 1), 1: (p, p + w)):
    // four pixels at a time, a bit per pair whose labels differ and are both valid, written
    // out without a branch (the borders are too dense for branches to predict).
    std::vector<uint32_t>& pairs = band_pairs_[r0 / kRowGrain];
    pairs.resize(2 * (r1 - r0) * w + 8);
    uint32_t* out = pairs.data();
    size_t count = 0;
    for (size_t v = r0; v < r1; ++v) {
      prefetch_row(v + 2);
      const size_t row = v * w;
      const int32_t* here = lab + row;
      const int32_t* below = v + 1 < h ? here + w : nullptr;
      size_t u = 0;
#if defined(__SSE2__)
      for (; u + 5 <= w; u += 4) {
        const __m128i x = _mm_loadu_si128(reinterpret_cast<const __m128i*>(here + u));
        const __m128i r = _mm_loadu_si128(reinterpret_cast<const __m128i*>(here + u + 1));
        unsigned m = DifferingValid(x, r);
        if (below != nullptr) {
          m |= DifferingValid(x, _mm_loadu_si128(reinterpret_cast<const __m128i*>(below + u))) << 4;
        }
        const uint32_t base = static_cast<uint32_t>(row + u) << 1;
        const std::array<uint8_t, 8>& code = kPairCode[m];
        for (int k = 0; k < 8; ++k) out[count + k] = base + code[k];
        count += kBitCount[m];
      }
#endif
      for (; u < w; ++u) {
        const int32_t x = here[u];
        const uint32_t p2 = static_cast<uint32_t>(row + u) << 1;
        if (u + 1 < w && x != here[u + 1] && (x | here[u + 1]) >= 0) out[count++] = p2;
        if (below != nullptr && x != below[u] && (x | below[u]) >= 0) out[count++] = p2 | 1u;
      }
    }
    for (size_t k = 0; k < count; ++k) {
      const size_t p = out[k] >> 1;
      visit(p, (out[k] & 1u) ? p + w : p + 1);
    }
  });
  for (size_t k = 0; k < num_bands; ++k) {
    for (const uint32_t e : band_events_[k]) {
      ++border_pairs_[e >> 1];
      jump_pairs_[e >> 1] += e & 1u;
    }
  }
}

void Linkage::CountDiagonalContacts(const supervoxel::Supervoxels& sv) {
  const size_t n = sv.size();
  const size_t slots = sv.adjacency.size();
  const uint32_t* off = sv.adjacency_offsets.data();
  const uint32_t* adj = sv.adjacency.data();
  contact_node_.assign(n, 0);
  bool any = false;
  for (size_t i = 0; i < n; ++i) {
    for (uint32_t s = off[i]; s < off[i + 1]; ++s) {
      if (contact_cut_[s] == 0) continue;
      contact_node_[i] = contact_node_[adj[s]] = 1;
      any = true;
    }
  }
  if (!any) return;
  // Diagonal pixel pairs ((u, v), (u + 1, v + 1)) and ((u + 1, v), (u, v + 1)) of two
  // candidate supervoxels, per band of rows, as slots of the lower id.
  const size_t w = static_cast<size_t>(sv.width), h = static_cast<size_t>(sv.height);
  const size_t num_bands = core::ThreadPool::NumChunks(h, kRowGrain);
  if (band_events_.size() < num_bands) band_events_.resize(num_bands);
  const int32_t* lab = sv.pixel_label.data();
  const uint8_t* node = contact_node_.data();
  const uint8_t* candidate = contact_cut_.data();
  core::ForChunks(pool_, h, kRowGrain, [&](size_t r0, size_t r1) {
    std::vector<uint32_t>& events = band_events_[r0 / kRowGrain];
    events.clear();
    SlotCache slot_of(off, adj);
    auto visit = [&](int32_t a, int32_t b) {
      if (a == b || (a | b) < 0 || !node[a] || !node[b]) return;
      const auto lo = static_cast<uint32_t>(std::min(a, b));
      const auto hi = static_cast<uint32_t>(std::max(a, b));
      const uint32_t slot = slot_of.Slot(lo, hi);
      if (slot != UINT32_MAX && candidate[slot] != 0) events.push_back(slot);
    };
    for (size_t v = r0; v < std::min(r1, h - 1); ++v) {
      const int32_t* here = lab + v * w;
      const int32_t* below = here + w;
      size_t u = 0;
#if defined(__SSE2__)
      // Four 2 x 2 blocks at a time: most have no diagonal pair of two valid labels that differ.
      for (; u + 5 <= w; u += 4) {
        const auto load = [](const int32_t* p) {
          return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
        };
        const unsigned down = DifferingValid(load(here + u), load(below + u + 1));
        const unsigned up = DifferingValid(load(here + u + 1), load(below + u));
        if ((down | up) == 0) continue;
        for (size_t k = 0; k < 4; ++k) {
          if (down >> k & 1u) visit(here[u + k], below[u + k + 1]);
          if (up >> k & 1u) visit(here[u + k + 1], below[u + k]);
        }
      }
#endif
      for (; u + 1 < w; ++u) {
        visit(here[u], below[u + 1]);
        visit(here[u + 1], below[u]);
      }
    }
  });
  for (size_t k = 0; k < num_bands; ++k) {
    for (const uint32_t slot : band_events_[k]) ++border_pairs_[slot];
  }
  const auto limit = static_cast<uint32_t>(params_.contact_cut_max_pairs);
  for (size_t s = 0; s < slots; ++s) {
    if (contact_cut_[s] != 0 && border_pairs_[s] < limit) contact_cut_[s] = 2;
  }
}

void Linkage::CutContactless(const supervoxel::Supervoxels& sv, LinkageResult* out) {
  const size_t n = sv.size();
  const size_t slots = sv.adjacency.size();
  const uint32_t* off = sv.adjacency_offsets.data();
  const uint32_t* adj = sv.adjacency.data();
  bool any = false;
  for (size_t s = 0; s < slots; ++s) {
    if (contact_cut_[s] != 2) continue;
    out->edge_kept[s] = out->edge_kept[reverse_slot_[s]] = 0;
    any = true;
  }
  if (!any) return;
  // Components over what is kept now; a cut edge whose sides are not both large enough is
  // kept again (all restorations judged on the same components).
  JoinKept(sv, out->edge_kept, &parent_);
  size_.assign(n, 0);
  for (size_t i = 0; i < n; ++i) ++size_[core::FindRoot(parent_.data(), static_cast<int32_t>(i))];
  const auto min_side = static_cast<uint32_t>(params_.contact_cut_min_supervoxels);
  for (size_t i = 0; i < n; ++i) {
    for (uint32_t s = off[i]; s < off[i + 1]; ++s) {
      const uint32_t j = adj[s];
      if (j < i || contact_cut_[s] != 2) continue;
      const int32_t a = core::FindRoot(parent_.data(), static_cast<int32_t>(i));
      const int32_t b = core::FindRoot(parent_.data(), static_cast<int32_t>(j));
      if (a != b && std::min(size_[a], size_[b]) < min_side) {
        out->edge_kept[s] = out->edge_kept[reverse_slot_[s]] = 1;
      }
    }
  }
}

void Linkage::CountViewBorderPairs(const supervoxel::Supervoxels& sv,
                                   const geometry::VoxelGrid& voxels,
                                   const std::vector<int32_t>& voxel_supervoxel) {
  const size_t slots = sv.adjacency.size();
  border_pairs_.assign(slots, 0);
  jump_pairs_.assign(slots, 0);
  const size_t nv = voxels.size();
  const uint32_t* off = sv.adjacency_offsets.data();
  const uint32_t* adj = sv.adjacency.data();
  const float rel = params_.depth_jump_rel;
  // The view neighbours of a voxel: the voxels next to it in view direction (x / z, y / z),
  // as the pixels next to a pixel are. With the single-camera transform the grid's columns
  // of voxels sharing (x, y) are cells of view directions, and the neighbours come from the
  // columns; otherwise from a 2-d tree over the voxels' view directions (within 1.5 voxel
  // widths, for each other supervoxel the voxel nearest in depth).
  const bool columns = voxels.params.use_single_camera_transform;
  size_t num_items = nv;
  if (columns) {
    column_begin_.clear();
    for (size_t v = 0; v < nv; ++v) {
      if (v == 0 || voxels.coord[v].x != voxels.coord[v - 1].x ||
          voxels.coord[v].y != voxels.coord[v - 1].y) {
        column_begin_.push_back(static_cast<uint32_t>(v));
      }
    }
    num_items = column_begin_.size();
    column_begin_.push_back(static_cast<uint32_t>(nv));
  } else {
    view_dir_.resize(2 * nv);
    for (size_t v = 0; v < nv; ++v) {
      const core::Vec3f& c = voxels.centroid[v];
      view_dir_[2 * v] = c.x / c.z;
      view_dir_[2 * v + 1] = c.y / c.z;
    }
    view_index_.Build(view_dir_.data(), nv, 2);
  }
  const size_t num_chunks = core::ThreadPool::NumChunks(num_items, kVoxelGrain);
  if (band_events_.size() < num_chunks) band_events_.resize(num_chunks);
  if (chunk_found_.size() < num_chunks) chunk_found_.resize(num_chunks);
  if (chunk_best_.size() < num_chunks) chunk_best_.resize(num_chunks);
  // Column order is (x, y) lexicographic: the first column at or after (x, y), from `c` on.
  const size_t num_columns = columns ? num_items : 0;
  auto column_at_or_after = [&](size_t c, int32_t x, int32_t y) {
    while (c < num_columns) {
      const geometry::VoxelCoord& k = voxels.coord[column_begin_[c]];
      if (k.x > x || (k.x == x && k.y >= y)) break;
      ++c;
    }
    return c;
  };
  // Border pairs are counted from each voxel's side, so a border is counted from both.
  core::ForChunks(pool_, num_items, kVoxelGrain, [&](size_t b, size_t e) {
    const size_t k = b / kVoxelGrain;
    std::vector<uint32_t>& events = band_events_[k];
    std::vector<std::pair<uint32_t, float>>& found = chunk_found_[k];
    std::vector<std::pair<uint32_t, float>>& best = chunk_best_[k];
    events.clear();
    SlotCache slot_of(off, adj);
    auto evaluate = [&](size_t v) {
      const int32_t a = voxel_supervoxel[v];
      const float z = voxels.centroid[v].z;
      best.clear();
      for (const auto& [u, d2] : found) {
        const int32_t o = voxel_supervoxel[u];
        if (o == a) continue;
        const float dz = voxels.centroid[u].z - z;  // signed
        auto it = std::find_if(best.begin(), best.end(),
                               [o](const auto& x) { return x.first == static_cast<uint32_t>(o); });
        if (it == best.end()) {
          best.emplace_back(static_cast<uint32_t>(o), dz);
        } else if (std::fabs(dz) < std::fabs(it->second)) {
          it->second = dz;
        }
      }
      for (const auto& [o, dz] : best) {
        const uint32_t slot = slot_of.Slot(std::min(static_cast<uint32_t>(a), o),
                                           std::max(static_cast<uint32_t>(a), o));
        if (slot == UINT32_MAX || !convex_raw_[slot]) continue;
        const bool jump = std::fabs(dz) > rel * (z + std::min(0.f, dz));
        events.push_back(slot << 1 | (jump ? 1u : 0u));
      }
    };
    if (!columns) {
      for (size_t v = b; v < e; ++v) {
        const float z = voxels.centroid[v].z;
        view_index_.WithinRadius(&view_dir_[2 * v], 1.5f * voxels.ViewAngleAt(z), &found);
        evaluate(v);
      }
      return;
    }
    // Each voxel's view neighbours in the column grid: in its own column and in the four
    // columns beside it (x - 1, x + 1, y - 1, y + 1), the voxel nearest to it in depth (the
    // surface's continuation, or what lies behind or in front of it); a pair when that voxel
    // is another supervoxel's. Two cursors find the columns of x - 1 and x + 1 (each only
    // moves forward).
    size_t left = 0, right = 0;
    for (size_t c = b; c < e; ++c) {
      const geometry::VoxelCoord& key = voxels.coord[column_begin_[c]];
      size_t near[5];
      size_t num_near = 0;
      near[num_near++] = c;
      auto add_if = [&](size_t r, int32_t x, int32_t y) {
        if (r >= num_columns) return;
        const geometry::VoxelCoord& o = voxels.coord[column_begin_[r]];
        if (o.x == x && o.y == y) near[num_near++] = r;
      };
      left = column_at_or_after(left, key.x - 1, key.y);
      add_if(left, key.x - 1, key.y);
      right = column_at_or_after(right, key.x + 1, key.y);
      add_if(right, key.x + 1, key.y);
      if (c > 0) add_if(c - 1, key.x, key.y - 1);
      add_if(c + 1, key.x, key.y + 1);
      // Most columns lie inside one supervoxel with their neighbours: no pair.
      const int32_t first_owner = voxel_supervoxel[column_begin_[c]];
      bool uniform = true;
      for (size_t m = 0; m < num_near && uniform; ++m) {
        for (uint32_t u = column_begin_[near[m]]; u < column_begin_[near[m] + 1]; ++u) {
          uniform &= voxel_supervoxel[u] == first_owner;
        }
      }
      if (uniform) continue;
      for (uint32_t v = column_begin_[c]; v < column_begin_[c + 1]; ++v) {
        const uint32_t a = static_cast<uint32_t>(voxel_supervoxel[v]);
        const float z = voxels.centroid[v].z;
        for (size_t m = 0; m < num_near; ++m) {
          const size_t r = near[m];
          uint32_t nearest = UINT32_MAX;
          float nearest_dz = 0.f;
          for (uint32_t u = column_begin_[r]; u < column_begin_[r + 1]; ++u) {
            const float dz = voxels.centroid[u].z - z;
            if (u != v && (nearest == UINT32_MAX || std::fabs(dz) < std::fabs(nearest_dz))) {
              nearest = u;
              nearest_dz = dz;
            }
          }
          if (nearest == UINT32_MAX) continue;
          const uint32_t o = static_cast<uint32_t>(voxel_supervoxel[nearest]);
          if (o == a) continue;
          const uint32_t slot = slot_of.Slot(std::min(a, o), std::max(a, o));
          if (slot == UINT32_MAX || !convex_raw_[slot]) continue;
          const bool jump = std::fabs(nearest_dz) > rel * (z + std::min(0.f, nearest_dz));
          events.push_back(slot << 1 | (jump ? 1u : 0u));
        }
      }
    }
  });
  for (size_t k = 0; k < num_chunks; ++k) {
    for (const uint32_t e : band_events_[k]) {
      ++border_pairs_[e >> 1];
      jump_pairs_[e >> 1] += e & 1u;
    }
  }
}

void Linkage::MeanChroma(const supervoxel::Supervoxels& sv, const core::PointCloudView& cloud) {
  const size_t n = sv.size();
  const size_t points = sv.pixel_label.size();
  constexpr size_t kPointGrain = 65536;
  const size_t num_bands = core::ThreadPool::NumChunks(points, kPointGrain);
  if (band_rgb_.size() < num_bands) band_rgb_.resize(num_bands);
  // Integer sums per band, added in any order to the same totals.
  core::ForChunks(pool_, points, kPointGrain, [&](size_t b, size_t e) {
    std::vector<uint32_t>& sums = band_rgb_[b / kPointGrain];
    sums.assign(4 * n, 0);
    for (size_t p = b; p < e; ++p) {
      const int32_t s = sv.pixel_label[p];
      if (s < 0) continue;
      const uint32_t c = cloud.rgba[p];
      uint32_t* t = &sums[4 * static_cast<size_t>(s)];
      t[0] += (c >> 16) & 255u;
      t[1] += (c >> 8) & 255u;
      t[2] += c & 255u;
      t[3] += 1;
    }
  });
  mean_chroma_.assign(3 * n, 0.f);
  for (size_t i = 0; i < n; ++i) {
    uint64_t r = 0, g = 0, bl = 0;
    for (size_t k = 0; k < num_bands; ++k) {
      const uint32_t* t = &band_rgb_[k][4 * i];
      r += t[0];
      g += t[1];
      bl += t[2];
    }
    const double sum = static_cast<double>(r + g + bl);
    if (sum <= 0.0) continue;
    mean_chroma_[3 * i] = static_cast<float>(255.0 * static_cast<double>(r) / sum);
    mean_chroma_[3 * i + 1] = static_cast<float>(255.0 * static_cast<double>(g) / sum);
    mean_chroma_[3 * i + 2] = static_cast<float>(255.0 * static_cast<double>(bl) / sum);
  }
}

bool Linkage::ConcaveSide(uint32_t concave, uint32_t kept) const {
  return static_cast<float>(concave) > params_.bridge_max_concave_share * static_cast<float>(kept);
}

void Linkage::CutBridges(const supervoxel::Supervoxels& sv, const PatchFeatures& f,
                         LinkageResult* out) {
  const size_t n = sv.size();
  const auto& off = sv.adjacency_offsets;
  const auto& adj = sv.adjacency;
  std::vector<uint8_t>& kept = out->edge_kept;
  // Components over the kept edges; a side cut off later gets a new id.
  std::vector<int32_t>& comp = bridge_comp_;
  JoinKept(sv, kept, &comp);
  for (size_t i = 0; i < n; ++i) comp[i] = core::FindRoot(comp.data(), static_cast<int32_t>(i));
  int32_t next_comp = static_cast<int32_t>(n);

  bridge_mark_.assign(n, 0u);
  bridge_from_slot_.resize(n);
  bridge_from_node_.resize(n);
  bridge_flow_.assign(adj.size(), 0);
  uint32_t mark = 0;
  const auto max_flow = static_cast<int>(params_.bridge_max_edges);
  const auto min_side = static_cast<size_t>(params_.bridge_min_supervoxels);
  const float min_cos =
      static_cast<float>(std::cos(double{params_.bridge_max_angle_deg} / kRadToDeg));
  std::vector<uint32_t>& queue = bridge_queue_;
  // Work bound: adjacency slots scanned by the searches, at most kBridgeWorkPerSlot per slot
  // of the graph; candidates after it is spent are not tested (in candidate order, so the
  // output stays deterministic).
  size_t work = 0;
  const size_t work_budget = kBridgeWorkPerSlot * adj.size();

  for (size_t i0 = 0; i0 < n; ++i0) {
    const auto i = static_cast<uint32_t>(i0);
    for (uint32_t s0 = off[i]; s0 < off[i + 1]; ++s0) {
      const uint32_t j = adj[s0];
      // Tested from the crease edges (concave beyond the tolerance) inside a component.
      if (j < i || edge_class_[s0] != kSharpConcave || kept[s0] || comp[i] != comp[j]) continue;
      // Common neighbours joined to both by kept edges are edge-disjoint paths of two edges:
      // more of them than bridge_max_edges settle it without a search.
      int common = 0;
      for (uint32_t sa = off[i], sb = off[j]; sa < off[i + 1] && sb < off[j + 1];) {
        if (adj[sa] < adj[sb]) {
          ++sa;
        } else if (adj[sb] < adj[sa]) {
          ++sb;
        } else {
          common += kept[sa] && kept[sb] ? 1 : 0;
          ++sa;
          ++sb;
        }
      }
      if (common > max_flow) continue;
      if (work > work_budget) return;
      // Augmenting paths from i to j over kept edges of unit capacity in each direction, up to
      // one more than the widest bridge allowed.
      int flow = 0;
      bool reached = false;
      bridge_touched_.clear();
      while (true) {
        ++mark;
        queue.clear();
        queue.push_back(i);
        bridge_mark_[i] = mark;
        reached = false;
        for (size_t q = 0; q < queue.size() && !reached; ++q) {
          const uint32_t a = queue[q];
          work += off[a + 1] - off[a];
          for (uint32_t s = off[a]; s < off[a + 1]; ++s) {
            const uint32_t b = adj[s];
            if (!kept[s] || bridge_flow_[s] > 0 || bridge_mark_[b] == mark) continue;
            bridge_mark_[b] = mark;
            bridge_from_slot_[b] = s;
            bridge_from_node_[b] = a;
            if (b == j) {
              reached = true;
              break;
            }
            queue.push_back(b);
          }
        }
        if (!reached || flow > max_flow) break;
        for (uint32_t b = j; b != i; b = bridge_from_node_[b]) {
          const uint32_t s = bridge_from_slot_[b];
          ++bridge_flow_[s];
          --bridge_flow_[reverse_slot_[s]];
          bridge_touched_.push_back(s);
          bridge_touched_.push_back(reverse_slot_[s]);
        }
        ++flow;
      }
      for (const uint32_t s : bridge_touched_) bridge_flow_[s] = 0;
      if (reached) continue;  // wider than bridge_max_edges
      // The side of i: what the last search reached (marked `mark`). A cut removes every kept
      // edge between its two sides, so the components stay exact and i and j are joined.
      const uint32_t side_i = mark;
      if (queue.size() < min_side) continue;
      // The side of j: its part of the rest, without crossing into i's side.
      const size_t i_size = queue.size();
      ++mark;
      const uint32_t side_j = mark;
      queue.push_back(j);
      bridge_mark_[j] = side_j;
      uint32_t kept_j = 0, concave_j = 0;
      for (size_t q = i_size; q < queue.size(); ++q) {
        const uint32_t a = queue[q];
        work += off[a + 1] - off[a];
        for (uint32_t s = off[a]; s < off[a + 1]; ++s) {
          const uint32_t b = adj[s];
          if (!kept[s] || bridge_mark_[b] == side_i) continue;
          if (b > a) {
            ++kept_j;
            concave_j += FaceEachOther(f, a, b) ? 1u : 0u;
          }
          if (bridge_mark_[b] == side_j) continue;
          bridge_mark_[b] = side_j;
          queue.push_back(b);
        }
      }
      if (queue.size() - i_size < min_side || ConcaveSide(concave_j, kept_j)) continue;
      // Edges between the two sides: the bridge (kept) and the crease (cut); the kept edges
      // inside i's side.
      uint32_t crease = 0, kept_i = 0, concave_i = 0;
      bool sharp = false;
      bridge_cut_.clear();
      for (size_t q = 0; q < i_size; ++q) {
        const uint32_t a = queue[q];
        for (uint32_t s = off[a]; s < off[a + 1]; ++s) {
          const uint32_t b = adj[s];
          if (bridge_mark_[b] == side_i) {
            if (kept[s] && b > a) {
              ++kept_i;
              concave_i += FaceEachOther(f, a, b) ? 1u : 0u;
            }
          } else if (bridge_mark_[b] == side_j) {
            if (kept[s]) {
              bridge_cut_.push_back(s);
              const core::Vec3f& na = f.normal[a];
              const core::Vec3f& nb = f.normal[b];
              sharp = sharp || na.x * nb.x + na.y * nb.y + na.z * nb.z < min_cos;
            } else {
              ++crease;
            }
          }
        }
      }
      if (sharp || ConcaveSide(concave_i, kept_i) ||
          static_cast<float>(crease) <
              params_.bridge_min_crease_ratio * static_cast<float>(bridge_cut_.size())) {
        continue;
      }
      for (const uint32_t s : bridge_cut_) kept[s] = kept[reverse_slot_[s]] = 0;
      const int32_t new_comp = next_comp++;
      for (size_t q = 0; q < i_size; ++q) comp[queue[q]] = new_comp;
    }
  }
}

}  // namespace clutterseg::graph
