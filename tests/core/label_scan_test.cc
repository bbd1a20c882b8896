// The per-pixel passes' building blocks: ForEachLabelled visits every pixel labelled in either
// image (and skips blocks of background), CountInChunks adds per-chunk counts into the same
// totals with or without a pool.
#include "clutterseg/core/label_scan.h"

#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"

namespace clutterseg::core {
namespace {

TEST(ForEachLabelled, VisitsEveryPixelLabelledInEitherImageAndSkipsBackgroundBlocks) {
  // 8 blocks of eight and a tail of 5: labels in a only, in b only, in both, at the tail.
  constexpr size_t n = 8 * 8 + 5;
  std::vector<uint32_t> a(n, 0u), b(n, 0u);
  a[3] = 1;           // block 0
  b[17] = 2;          // block 2
  a[40] = b[41] = 3;  // block 5
  a[n - 1] = 4;       // tail
  std::vector<int> visits(n, 0);
  ForEachLabelled(a.data(), b.data(), n, [&](size_t i) { ++visits[i]; });
  for (size_t i = 0; i < n; ++i) {
    const bool labelled = (a[i] | b[i]) != 0;
    if (labelled) {
      EXPECT_EQ(visits[i], 1) << i;
    }
    EXPECT_LE(visits[i], 1) << i;
  }
  // Blocks 1, 3, 4, 6 and 7 are background in both: none of their pixels is visited.
  for (const size_t block : {1u, 3u, 4u, 6u, 7u}) {
    for (size_t i = block * 8; i < block * 8 + 8; ++i) EXPECT_EQ(visits[i], 0) << i;
  }
}

TEST(CountInChunks, AddsUpToTheSerialCountWhateverThePool) {
  constexpr size_t n = 100003, bins = 7, grain = 1000;
  std::vector<uint32_t> expected(bins, 1u);  // the output is not zeroed: counts add to it
  for (size_t i = 0; i < n; ++i) ++expected[(i * i) % bins];
  std::vector<uint32_t> scratch, out;
  const auto count = [&](ThreadPool* pool) {
    out.assign(bins, 1u);
    CountInChunks(pool, n, grain, bins, &scratch, out.data(),
                  [&](size_t b, size_t e, uint32_t* table) {
                    for (size_t i = b; i < e; ++i) ++table[(i * i) % bins];
                  });
  };
  count(nullptr);
  EXPECT_EQ(out, expected);
  EXPECT_EQ(scratch.size(), ThreadPool::NumChunks(n, grain) * bins);
  for (const int threads : {1, 2, 3}) {
    ThreadPool pool(threads);
    count(&pool);
    EXPECT_EQ(out, expected) << threads;
  }
}

TEST(AllZero8, IsTrueOnlyWhenAllEightLabelsAreZero) {
  // At every offset of a longer array (any alignment), and with each of the eight set.
  std::vector<uint32_t> a(24, 0u);
  for (size_t o = 0; o + 8 <= a.size(); ++o) EXPECT_TRUE(AllZero8(a.data() + o)) << o;
  for (size_t j = 0; j < 8; ++j) {
    a[3 + j] = 1u << (4 * j);
    EXPECT_FALSE(AllZero8(a.data() + 3)) << j;
    EXPECT_TRUE(AllZero8(a.data() + 4 + j)) << j;  // the set label just before the block
    a[3 + j] = 0;
  }
}

TEST(RenumberInFirstPixelOrder, NumbersLabelsByTheirFirstPixelAndKeepsBackground) {
  // Labels 5, 2 and 7 first seen in that order; 3 is unused; 0 stays 0.
  std::vector<uint32_t> labels = {0, 5, 5, 2, 0, 7, 2, 5, 0};
  std::vector<uint32_t> scratch;
  EXPECT_EQ(RenumberInFirstPixelOrder(&labels, 7, &scratch), 3u);
  EXPECT_EQ(labels, (std::vector<uint32_t>{0, 1, 1, 2, 0, 3, 2, 1, 0}));
  // Already in order: unchanged; the scratch is reused.
  EXPECT_EQ(RenumberInFirstPixelOrder(&labels, 3, &scratch), 3u);
  EXPECT_EQ(labels, (std::vector<uint32_t>{0, 1, 1, 2, 0, 3, 2, 1, 0}));
  std::vector<uint32_t> empty(4, 0u);
  EXPECT_EQ(RenumberInFirstPixelOrder(&empty, 0, &scratch), 0u);
}

}  // namespace
}  // namespace clutterseg::core
