#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace clutterseg::geometry {

/// Nearest-neighbour queries over a set of points in two or three dimensions: nanoflann's k-d
/// tree (its splitting rule, metric and result sets) behind a thin wrapper that keeps every
/// buffer, the tree's nodes included, between builds, so rebuilding it for each frame
/// allocates nothing once the largest frame has been seen. The neighbourhoods of clouds
/// without an image grid (unorganized clouds) come from here.
///
/// Distances are Euclidean in the given coordinates; queries return squared distances. Ties
/// are broken by the tree's traversal, which depends only on the points and their order, so
/// results are deterministic.
///
/// Thread-safety: Build must not run concurrently with anything else on the instance; the
/// const queries may run concurrently from any number of threads. Complexity: Build
/// O(n log n); a query O(log n) for a few neighbours.
class NeighborIndex {
 public:
  /// At most this many neighbours per Nearest() call.
  static constexpr size_t kMaxNeighbors = 32;

  NeighborIndex();
  ~NeighborIndex();
  NeighborIndex(const NeighborIndex&) = delete;
  NeighborIndex& operator=(const NeighborIndex&) = delete;

  /// Indexes `n` points of `dim` (2 or 3) coordinates each, point i at
  /// `coords[i * dim .. i * dim + dim)`. The coordinates are copied. Non-finite coordinates are
  /// not allowed (filter them first).
  /// @throws std::invalid_argument when dim is not 2 or 3.
  void Build(const float* coords, size_t n, int dim);

  size_t size() const;
  int dim() const;
  /// Coordinates of indexed point `i` (dim() floats).
  const float* point(size_t i) const;

  /// The min(k, size(), kMaxNeighbors) points nearest to `query` (dim() floats), nearest first:
  /// their indices (0-based, in Build order) and squared distances. Returns the count.
  size_t Nearest(const float* query, size_t k, uint32_t* index, float* dist2) const;

  /// Every point closer than `radius` to `query`, in no particular order but the same
  /// for the same input, as (index, squared distance) into `out`, which is cleared first and
  /// keeps its capacity. Returns the count.
  size_t WithinRadius(const float* query, float radius,
                      std::vector<std::pair<uint32_t, float>>* out) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clutterseg::geometry
