#pragma once

namespace clutterseg::core {

/// The root of element `x` in a forest of parent links (`parent[r] == r` at a root), halving
/// the path from `x` on the way. The root does not depend on how paths were compressed, so
/// callers keep their own rule for which root a union keeps (the deterministic choice is
/// theirs). `Index` is a signed or unsigned integer type; `x` must be a valid index.
///
/// Thread-safety: writes `parent`; not safe on a forest shared between threads.
template <typename Index>
Index FindRoot(Index* parent, Index x) {
  while (parent[x] != x) {
    parent[x] = parent[parent[x]];
    x = parent[x];
  }
  return x;
}

}  // namespace clutterseg::core
