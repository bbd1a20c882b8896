#include "clutterseg/geometry/neighbor_index.h"

#include <algorithm>
#include <array>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include <nanoflann.hpp>

namespace clutterseg::geometry {
namespace {

// The points as nanoflann's dataset adaptor sees them.
template <int kDim>
struct Points {
  const float* data{nullptr};
  size_t n{0};
  size_t kdtree_get_point_count() const { return n; }
  float kdtree_get_pt(uint32_t i, size_t d) const {
    return data[static_cast<size_t>(i) * kDim + d];
  }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

// nanoflann's node pool interface (allocate, free_all) over blocks that are kept: free_all
// rewinds instead of freeing, so a rebuild reuses the memory of the last one.
class NodeArena {
 public:
  template <typename T>
  T* allocate(size_t count = 1) {
    static_assert(alignof(T) <= kAlign);
    const size_t bytes = (sizeof(T) * count + kAlign - 1) & ~(kAlign - 1);
    if (block_ < blocks_.size() && used_ + bytes > kBlockBytes) {
      ++block_;
      used_ = 0;
    }
    if (block_ == blocks_.size()) {
      if (bytes > kBlockBytes) throw std::length_error("NeighborIndex: node larger than a block");
      blocks_.push_back(std::make_unique<Block>());
      used_ = 0;
    }
    T* p = reinterpret_cast<T*>(blocks_[block_]->bytes + used_);
    used_ += bytes;
    usedMemory += static_cast<uint32_t>(bytes);
    return p;
  }
  void free_all() {
    block_ = 0;
    used_ = 0;
    usedMemory = 0;
  }
  // Read by nanoflann's usedMemory(); kept for its interface.
  uint32_t usedMemory{0};
  uint32_t wastedMemory{0};

 private:
  static constexpr size_t kAlign = 16;
  static constexpr size_t kBlockBytes = size_t{1} << 16;
  struct Block {
    alignas(kAlign) unsigned char bytes[kBlockBytes];
  };
  std::vector<std::unique_ptr<Block>> blocks_;
  size_t block_{0};
  size_t used_{0};
};

// nanoflann's KDTreeSingleIndexAdaptor with the node pool above: the tree building of
// nanoflann's KDTreeBaseClass (middle split, leaf bounding boxes) and its search, with the
// nodes taken from a NodeArena (the base class reaches the pool through `obj.pool`, which
// finds this class's member first).
template <int kDim>
class Tree : public nanoflann::KDTreeBaseClass<Tree<kDim>,
                                               nanoflann::L2_Simple_Adaptor<float, Points<kDim>>,
                                               Points<kDim>, kDim, uint32_t> {
 public:
  using Base =
      nanoflann::KDTreeBaseClass<Tree<kDim>, nanoflann::L2_Simple_Adaptor<float, Points<kDim>>,
                                 Points<kDim>, kDim, uint32_t>;
  using Node = typename Base::Node;
  using Dists = std::array<float, kDim>;

  explicit Tree(const Points<kDim>& points) : dataset(points), distance(points) {
    this->root_node = nullptr;
    this->m_leaf_max_size = kLeafSize;
    this->dim = kDim;
    this->m_size = 0;
    this->m_size_at_index_build = 0;
  }

  void Build() {
    const size_t n = dataset.n;
    this->m_size = n;
    this->m_size_at_index_build = n;
    this->vAcc.resize(n);
    std::iota(this->vAcc.begin(), this->vAcc.end(), 0u);
    this->freeIndex(*this);
    this->m_size_at_index_build = n;
    if (n == 0) return;
    for (int d = 0; d < kDim; ++d) {
      this->root_bbox[d].low = this->root_bbox[d].high = dataset.kdtree_get_pt(0, d);
    }
    for (size_t i = 1; i < n; ++i) {
      for (int d = 0; d < kDim; ++d) {
        const float v = dataset.kdtree_get_pt(static_cast<uint32_t>(i), d);
        this->root_bbox[d].low = std::min(this->root_bbox[d].low, v);
        this->root_bbox[d].high = std::max(this->root_bbox[d].high, v);
      }
    }
    this->root_node = this->divideTree(*this, 0, n, this->root_bbox);
  }

  template <class ResultSet>
  void Find(ResultSet& result, const float* query) const {
    if (this->root_node == nullptr) return;
    Dists dists{};
    const float mindist = this->computeInitialDistances(*this, query, dists);
    SearchLevel(result, query, this->root_node, mindist, dists);
  }

  const Points<kDim>& dataset;  // names read by the base class
  nanoflann::L2_Simple_Adaptor<float, Points<kDim>> distance;
  NodeArena pool;

 private:
  static constexpr size_t kLeafSize = 16;

  // nanoflann's exact search (KDTreeSingleIndexAdaptor::searchLevel, eps = 0).
  template <class ResultSet>
  bool SearchLevel(ResultSet& result, const float* query, const Node* node, float mindist,
                   Dists& dists) const {
    if (node->child1 == nullptr && node->child2 == nullptr) {
      const float worst = result.worstDist();
      for (size_t i = node->node_type.lr.left; i < node->node_type.lr.right; ++i) {
        const uint32_t idx = this->vAcc[i];
        const float d = distance.evalMetric(query, idx, kDim);
        if (d < worst && !result.addPoint(d, idx)) return false;
      }
      return true;
    }
    const int feat = node->node_type.sub.divfeat;
    const float val = query[feat];
    const float diff1 = val - node->node_type.sub.divlow;
    const float diff2 = val - node->node_type.sub.divhigh;
    const Node* best;
    const Node* other;
    float cut;
    if (diff1 + diff2 < 0) {
      best = node->child1;
      other = node->child2;
      cut = distance.accum_dist(val, node->node_type.sub.divhigh, feat);
    } else {
      best = node->child2;
      other = node->child1;
      cut = distance.accum_dist(val, node->node_type.sub.divlow, feat);
    }
    if (!SearchLevel(result, query, best, mindist, dists)) return false;
    const float saved = dists[feat];
    mindist = mindist + cut - saved;
    dists[feat] = cut;
    if (mindist <= result.worstDist() && !SearchLevel(result, query, other, mindist, dists)) {
      return false;
    }
    dists[feat] = saved;
    return true;
  }
};

}  // namespace

struct NeighborIndex::Impl {
  int dim{3};
  std::vector<float> coords;
  Points<2> points2;
  Points<3> points3;
  Tree<2> tree2{points2};
  Tree<3> tree3{points3};
};

NeighborIndex::NeighborIndex() : impl_(std::make_unique<Impl>()) {}

NeighborIndex::~NeighborIndex() = default;

void NeighborIndex::Build(const float* coords, size_t n, int dim) {
  if (dim != 2 && dim != 3) {
    throw std::invalid_argument("NeighborIndex: dimension " + std::to_string(dim) +
                                " (expected 2 or 3)");
  }
  Impl& m = *impl_;
  m.dim = dim;
  m.coords.assign(coords, coords + n * static_cast<size_t>(dim));
  m.points2 = Points<2>{m.coords.data(), dim == 2 ? n : 0};
  m.points3 = Points<3>{m.coords.data(), dim == 3 ? n : 0};
  m.tree2.Build();
  m.tree3.Build();
}

size_t NeighborIndex::size() const { return impl_->coords.size() / impl_->dim; }

int NeighborIndex::dim() const { return impl_->dim; }

const float* NeighborIndex::point(size_t i) const {
  return impl_->coords.data() + i * static_cast<size_t>(impl_->dim);
}

size_t NeighborIndex::Nearest(const float* query, size_t k, uint32_t* index, float* dist2) const {
  k = std::min({k, size(), kMaxNeighbors});
  if (k == 0) return 0;
  nanoflann::KNNResultSet<float, uint32_t, size_t> result(k);
  result.init(index, dist2);
  if (impl_->dim == 2) {
    impl_->tree2.Find(result, query);
  } else {
    impl_->tree3.Find(result, query);
  }
  return result.size();
}

size_t NeighborIndex::WithinRadius(const float* query, float radius,
                                   std::vector<std::pair<uint32_t, float>>* out) const {
  nanoflann::RadiusResultSet<float, uint32_t> result(radius * radius, *out);
  if (size() == 0) return 0;
  if (impl_->dim == 2) {
    impl_->tree2.Find(result, query);
  } else {
    impl_->tree3.Find(result, query);
  }
  return out->size();
}

}  // namespace clutterseg::geometry
