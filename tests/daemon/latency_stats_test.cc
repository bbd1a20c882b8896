#include "clutterseg/daemon/latency_stats.h"

#include <gtest/gtest.h>

namespace clutterseg::daemon {
namespace {

TEST(LatencyWindow, NearestRankPercentilesThenReset) {
  LatencyWindow dut(1000);
  for (int i = 1; i <= 100; ++i) dut.Add(static_cast<double>(i));
  const LatencySummary s = dut.TakeSummary();
  EXPECT_EQ(s.count, 100u);
  EXPECT_EQ(s.p50_ms, 50.0);
  EXPECT_EQ(s.p99_ms, 99.0);
  EXPECT_EQ(s.max_ms, 100.0);
  const LatencySummary empty = dut.TakeSummary();
  EXPECT_EQ(empty.count, 0u);
  EXPECT_EQ(empty.p99_ms, 0.0);
}

TEST(LatencyWindow, KeepsTheNewestSamplesWhenFull) {
  LatencyWindow dut(10);
  for (int i = 0; i < 25; ++i) dut.Add(i < 15 ? 1000.0 : static_cast<double>(i));
  const LatencySummary s = dut.TakeSummary();
  EXPECT_EQ(s.count, 10u);
  EXPECT_EQ(s.max_ms, 24.0);
  EXPECT_EQ(s.p50_ms, 19.0);
}

}  // namespace
}  // namespace clutterseg::daemon
