#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

namespace clutterseg::core {

/// Pixels per chunk of a per-pixel pass run on a ThreadPool (ForChunks, CountInChunks): a tenth
/// of a 640 x 480 frame, so that two threads share a frame's pass evenly.
inline constexpr size_t kPixelGrain = size_t{1} << 15;

/// Whether the eight labels at `a` are all 0 (one load of 32 bytes, any alignment).
inline bool AllZero8(const uint32_t* a) {
  uint64_t x[4];
  std::memcpy(x, a, sizeof(x));
  return ((x[0] | x[1]) | (x[2] | x[3])) == 0;
}

/// Calls `visit(i)` for every pixel index i < `num` at which label image `a` or `b` is not 0,
/// and possibly at others: the images are read in blocks of eight pixels, and a block that is
/// 0 in both (most of a frame is background in both) is skipped without a call. `visit` must
/// therefore check the labels itself where a pixel of 0 in both matters. `b` may be `a`.
///
/// Thread-safety: reads `a` and `b` only; `visit` may write them at the index it is given.
template <typename Visit>
void ForEachLabelled(const uint32_t* a, const uint32_t* b, size_t num, Visit&& visit) {
  size_t i = 0;
  for (; i + 8 <= num; i += 8) {
    uint64_t x[4], y[4];
    std::memcpy(x, a + i, sizeof(x));
    std::memcpy(y, b + i, sizeof(y));
    if (((x[0] | y[0]) | (x[1] | y[1]) | (x[2] | y[2]) | (x[3] | y[3])) == 0) continue;
    for (size_t j = i; j < i + 8; ++j) visit(j);
  }
  for (; i < num; ++i) visit(i);
}

/// Renumbers the labels 1..`max_label` of `labels` in the order of their first pixel (0 stays
/// 0), using `scratch`; returns the number of labels present. Labels above `max_label` must not
/// occur.
inline uint32_t RenumberInFirstPixelOrder(std::vector<uint32_t>* labels, uint32_t max_label,
                                          std::vector<uint32_t>* scratch) {
  scratch->assign(size_t{max_label} + 1, 0u);
  uint32_t id = 0;
  for (uint32_t& l : *labels) {
    if (l == 0) continue;
    uint32_t& to = (*scratch)[l];
    if (to == 0) to = ++id;
    l = to;
  }
  return id;
}

}  // namespace clutterseg::core
