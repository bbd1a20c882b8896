#include "clutterseg/optimize/max_flow.h"

#include <algorithm>
#include <limits>

#include "clutterseg/core/assert.h"

namespace clutterseg::optimize {

void MaxFlow::Reset(int num_nodes, int expected_edges) {
  CLUTTERSEG_DEMAND(num_nodes >= 0);
  nodes_.assign(static_cast<size_t>(num_nodes), Node{});
  arcs_.clear();
  if (expected_edges > 0) arcs_.reserve(2 * static_cast<size_t>(expected_edges));
  queue_.assign(static_cast<size_t>(num_nodes) + 1, 0);
  queue_head_ = 0;
  queue_size_ = 0;
  orphans_.clear();
  orphan_head_ = 0;
  flow_ = 0.0;
  time_ = 0;
  solved_ = false;
}

void MaxFlow::AddTerminal(int node, double cap_source, double cap_sink) {
  CLUTTERSEG_DEMAND(node >= 0 && node < num_nodes());
  Node& n = nodes_[node];
  // Split the current residual back into its two parts, add, and keep only the difference;
  // the common part always crosses the cut and is counted in the flow.
  double cs = cap_source, ct = cap_sink;
  if (n.tr_cap > 0.0) {
    cs += n.tr_cap;
  } else {
    ct -= n.tr_cap;
  }
  flow_ += std::min(cs, ct);
  n.tr_cap = cs - ct;
}

void MaxFlow::AddEdge(int i, int j, double cap_ij, double cap_ji) {
  CLUTTERSEG_DEMAND(i >= 0 && i < num_nodes() && j >= 0 && j < num_nodes() && i != j);
  CLUTTERSEG_DEMAND(cap_ij >= 0.0 && cap_ji >= 0.0);
  const int32_t a = static_cast<int32_t>(arcs_.size());
  arcs_.push_back(Arc{j, nodes_[i].first_arc, cap_ij});
  arcs_.push_back(Arc{i, nodes_[j].first_arc, cap_ji});
  nodes_[i].first_arc = a;
  nodes_[j].first_arc = a + 1;
}

void MaxFlow::Activate(int32_t i) {
  Node& n = nodes_[i];
  if (n.in_queue) return;
  n.in_queue = 1;
  queue_[(queue_head_ + queue_size_) % queue_.size()] = i;
  ++queue_size_;
}

int32_t MaxFlow::NextActive() {
  while (queue_size_ > 0) {
    const int32_t i = queue_[queue_head_];
    queue_head_ = (queue_head_ + 1) % queue_.size();
    --queue_size_;
    nodes_[i].in_queue = 0;
    if (nodes_[i].parent != kNone) return i;
  }
  return -1;
}

void MaxFlow::SetOrphan(int32_t i) {
  nodes_[i].parent = kOrphan;
  orphans_.push_back(i);
}

void MaxFlow::Augment(int32_t middle) {
  // Bottleneck along source -> tail(middle) -> head(middle) -> sink.
  double b = arcs_[middle].r_cap;
  int32_t i = arcs_[middle ^ 1].head;
  for (;;) {
    const int32_t a = nodes_[i].parent;
    if (a == kTerminal) break;
    b = std::min(b, arcs_[a ^ 1].r_cap);
    i = arcs_[a].head;
  }
  b = std::min(b, nodes_[i].tr_cap);
  i = arcs_[middle].head;
  for (;;) {
    const int32_t a = nodes_[i].parent;
    if (a == kTerminal) break;
    b = std::min(b, arcs_[a].r_cap);
    i = arcs_[a].head;
  }
  b = std::min(b, -nodes_[i].tr_cap);

  arcs_[middle ^ 1].r_cap += b;
  arcs_[middle].r_cap -= b;
  i = arcs_[middle ^ 1].head;
  for (;;) {
    const int32_t a = nodes_[i].parent;
    if (a == kTerminal) {
      nodes_[i].tr_cap -= b;
      if (nodes_[i].tr_cap <= 0.0) {
        nodes_[i].tr_cap = 0.0;
        SetOrphan(i);
      }
      break;
    }
    arcs_[a].r_cap += b;
    arcs_[a ^ 1].r_cap -= b;
    if (arcs_[a ^ 1].r_cap <= 0.0) {
      arcs_[a ^ 1].r_cap = 0.0;
      SetOrphan(i);
    }
    i = arcs_[a].head;
  }
  i = arcs_[middle].head;
  for (;;) {
    const int32_t a = nodes_[i].parent;
    if (a == kTerminal) {
      nodes_[i].tr_cap += b;
      if (nodes_[i].tr_cap >= 0.0) {
        nodes_[i].tr_cap = 0.0;
        SetOrphan(i);
      }
      break;
    }
    arcs_[a ^ 1].r_cap += b;
    arcs_[a].r_cap -= b;
    if (arcs_[a].r_cap <= 0.0) {
      arcs_[a].r_cap = 0.0;
      SetOrphan(i);
    }
    i = arcs_[a].head;
  }
  flow_ += b;
}

void MaxFlow::ProcessSourceOrphan(int32_t i) {
  constexpr int32_t kInf = std::numeric_limits<int32_t>::max();
  int32_t best_arc = kNone;
  int32_t best_dist = kInf;
  for (int32_t a = nodes_[i].first_arc; a >= 0; a = arcs_[a].next) {
    if (arcs_[a ^ 1].r_cap <= 0.0) continue;
    const int32_t j = arcs_[a].head;
    if (nodes_[j].is_sink || nodes_[j].parent == kNone) continue;
    // Does j trace back to the source?
    int32_t d = 0;
    int32_t k = j;
    for (;;) {
      if (nodes_[k].ts == time_) {
        d += nodes_[k].dist;
        break;
      }
      const int32_t pa = nodes_[k].parent;
      ++d;
      if (pa == kTerminal) {
        nodes_[k].ts = time_;
        nodes_[k].dist = 1;
        break;
      }
      if (pa == kOrphan) {
        d = kInf;
        break;
      }
      k = arcs_[pa].head;
    }
    if (d == kInf) continue;
    if (d < best_dist) {
      best_arc = a;
      best_dist = d;
    }
    for (k = j; nodes_[k].ts != time_; k = arcs_[nodes_[k].parent].head) {
      nodes_[k].ts = time_;
      nodes_[k].dist = d--;
    }
  }
  if (best_arc != kNone) {
    nodes_[i].parent = best_arc;
    nodes_[i].ts = time_;
    nodes_[i].dist = best_dist + 1;
    return;
  }
  // No valid parent: i becomes free; its tree neighbours may regrow into it.
  nodes_[i].ts = 0;
  for (int32_t a = nodes_[i].first_arc; a >= 0; a = arcs_[a].next) {
    const int32_t j = arcs_[a].head;
    Node& nj = nodes_[j];
    if (nj.is_sink || nj.parent == kNone) continue;
    if (arcs_[a ^ 1].r_cap > 0.0) Activate(j);
    if (nj.parent != kTerminal && nj.parent != kOrphan && arcs_[nj.parent].head == i) {
      SetOrphan(j);
    }
  }
  nodes_[i].parent = kNone;
}

void MaxFlow::ProcessSinkOrphan(int32_t i) {
  constexpr int32_t kInf = std::numeric_limits<int32_t>::max();
  int32_t best_arc = kNone;
  int32_t best_dist = kInf;
  for (int32_t a = nodes_[i].first_arc; a >= 0; a = arcs_[a].next) {
    if (arcs_[a].r_cap <= 0.0) continue;
    const int32_t j = arcs_[a].head;
    if (!nodes_[j].is_sink || nodes_[j].parent == kNone) continue;
    int32_t d = 0;
    int32_t k = j;
    for (;;) {
      if (nodes_[k].ts == time_) {
        d += nodes_[k].dist;
        break;
      }
      const int32_t pa = nodes_[k].parent;
      ++d;
      if (pa == kTerminal) {
        nodes_[k].ts = time_;
        nodes_[k].dist = 1;
        break;
      }
      if (pa == kOrphan) {
        d = kInf;
        break;
      }
      k = arcs_[pa].head;
    }
    if (d == kInf) continue;
    if (d < best_dist) {
      best_arc = a;
      best_dist = d;
    }
    for (k = j; nodes_[k].ts != time_; k = arcs_[nodes_[k].parent].head) {
      nodes_[k].ts = time_;
      nodes_[k].dist = d--;
    }
  }
  if (best_arc != kNone) {
    nodes_[i].parent = best_arc;
    nodes_[i].ts = time_;
    nodes_[i].dist = best_dist + 1;
    return;
  }
  nodes_[i].ts = 0;
  for (int32_t a = nodes_[i].first_arc; a >= 0; a = arcs_[a].next) {
    const int32_t j = arcs_[a].head;
    Node& nj = nodes_[j];
    if (!nj.is_sink || nj.parent == kNone) continue;
    if (arcs_[a].r_cap > 0.0) Activate(j);
    if (nj.parent != kTerminal && nj.parent != kOrphan && arcs_[nj.parent].head == i) {
      SetOrphan(j);
    }
  }
  nodes_[i].parent = kNone;
}

double MaxFlow::Solve() {
  CLUTTERSEG_DEMAND(!solved_);
  solved_ = true;
  const int32_t n = num_nodes();
  for (int32_t i = 0; i < n; ++i) {
    Node& node = nodes_[i];
    if (node.tr_cap > 0.0) {
      node.is_sink = 0;
      node.parent = kTerminal;
      node.ts = 0;
      node.dist = 1;
      Activate(i);
    } else if (node.tr_cap < 0.0) {
      node.is_sink = 1;
      node.parent = kTerminal;
      node.ts = 0;
      node.dist = 1;
      Activate(i);
    } else {
      node.parent = kNone;
    }
  }

  int32_t current = -1;
  for (;;) {
    int32_t i = current;
    current = -1;
    if (i < 0 || nodes_[i].parent == kNone) {
      i = NextActive();
      if (i < 0) break;
    }
    // Grow the tree of i until it touches the other tree.
    int32_t middle = -1;
    if (!nodes_[i].is_sink) {
      for (int32_t a = nodes_[i].first_arc; a >= 0; a = arcs_[a].next) {
        if (arcs_[a].r_cap <= 0.0) continue;
        const int32_t j = arcs_[a].head;
        Node& nj = nodes_[j];
        if (nj.parent == kNone) {
          nj.is_sink = 0;
          nj.parent = a ^ 1;
          nj.ts = nodes_[i].ts;
          nj.dist = nodes_[i].dist + 1;
          Activate(j);
        } else if (nj.is_sink) {
          middle = a;
          break;
        } else if (nj.ts <= nodes_[i].ts && nj.dist > nodes_[i].dist) {
          nj.parent = a ^ 1;
          nj.ts = nodes_[i].ts;
          nj.dist = nodes_[i].dist + 1;
        }
      }
    } else {
      for (int32_t a = nodes_[i].first_arc; a >= 0; a = arcs_[a].next) {
        if (arcs_[a ^ 1].r_cap <= 0.0) continue;
        const int32_t j = arcs_[a].head;
        Node& nj = nodes_[j];
        if (nj.parent == kNone) {
          nj.is_sink = 1;
          nj.parent = a ^ 1;
          nj.ts = nodes_[i].ts;
          nj.dist = nodes_[i].dist + 1;
          Activate(j);
        } else if (!nj.is_sink) {
          middle = a ^ 1;
          break;
        } else if (nj.ts <= nodes_[i].ts && nj.dist > nodes_[i].dist) {
          nj.parent = a ^ 1;
          nj.ts = nodes_[i].ts;
          nj.dist = nodes_[i].dist + 1;
        }
      }
    }
    ++time_;
    if (middle < 0) continue;

    // i may still have paths to the other tree: examine it again next.
    current = i;
    Augment(middle);
    while (orphan_head_ < orphans_.size()) {
      const int32_t o = orphans_[orphan_head_++];
      if (nodes_[o].is_sink) {
        ProcessSinkOrphan(o);
      } else {
        ProcessSourceOrphan(o);
      }
    }
    orphans_.clear();
    orphan_head_ = 0;
  }
  return flow_;
}

bool MaxFlow::InSourceSet(int node) const {
  CLUTTERSEG_DEMAND(solved_ && node >= 0 && node < num_nodes());
  return nodes_[node].parent != kNone && !nodes_[node].is_sink;
}

}  // namespace clutterseg::optimize
