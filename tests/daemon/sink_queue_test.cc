#include "clutterseg/daemon/sink_queue.h"

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace clutterseg::daemon {
namespace {

using std::chrono::milliseconds;

TEST(SinkQueue, DropsTheOldestWhenFullAndCountsIt) {
  SinkQueue<std::vector<int>> dut(3);
  for (int i = 0; i < 5; ++i) {
    std::vector<int> item{i};
    EXPECT_TRUE(dut.Push(&item));
  }
  EXPECT_EQ(dut.size(), 3u);
  EXPECT_EQ(dut.pushed(), 5u);
  EXPECT_EQ(dut.dropped(), 2u);
  std::vector<int> out;
  for (int expected : {2, 3, 4}) {  // the newest three, oldest first
    ASSERT_TRUE(dut.Pop(&out, milliseconds(0)));
    EXPECT_EQ(out, std::vector<int>{expected});
  }
  EXPECT_FALSE(dut.Pop(&out, milliseconds(1))) << "empty: times out";
}

// A lockstep replay's Push waits for the consumer instead of dropping; past its bound (a
// stalled sink) it drops the oldest as a camera's does, and Close ends the wait.
TEST(SinkQueue, APushWithAWaitTakesTheNextFreeSlotAndDropsOnlyPastItsBound) {
  SinkQueue<std::vector<int>> dut(1);
  std::vector<int> first{1};
  ASSERT_TRUE(dut.Push(&first));
  std::thread consumer([&] {
    std::this_thread::sleep_for(milliseconds(50));
    std::vector<int> out;
    EXPECT_TRUE(dut.Pop(&out, milliseconds(1000)));
    EXPECT_EQ(out, std::vector<int>{1});
  });
  std::vector<int> second{2};
  EXPECT_TRUE(dut.Push(&second, milliseconds(60000)));
  consumer.join();
  EXPECT_EQ(dut.dropped(), 0u) << "the push waited for the consumer's Pop";
  std::vector<int> third{3};
  EXPECT_TRUE(dut.Push(&third, milliseconds(20)));  // nobody pops: dropped after 20 ms
  EXPECT_EQ(dut.dropped(), 1u);
  std::vector<int> out;
  ASSERT_TRUE(dut.Pop(&out, milliseconds(0)));
  EXPECT_EQ(out, std::vector<int>{3});

  std::vector<int> fourth{4};
  ASSERT_TRUE(dut.Push(&fourth));
  std::thread closer([&] {
    std::this_thread::sleep_for(milliseconds(50));
    dut.Close();
  });
  std::vector<int> fifth{5};
  EXPECT_FALSE(dut.Push(&fifth, milliseconds(60000))) << "closed while waiting: not queued";
  closer.join();
}

TEST(SinkQueue, ItemsMoveBySwapSoBuffersAreReused) {
  SinkQueue<std::vector<int>> dut(1);
  std::vector<int> item(1000, 7);
  const int* buffer = item.data();
  dut.Push(&item);
  EXPECT_TRUE(item.empty()) << "the producer gets the slot's (empty) buffers back";
  std::vector<int> out;
  ASSERT_TRUE(dut.Pop(&out, milliseconds(0)));
  EXPECT_EQ(out.data(), buffer) << "the consumer gets the producer's buffer, not a copy";
}

TEST(SinkQueue, CloseLetsTheConsumerDrainThenStop) {
  SinkQueue<int> dut(4);
  int a = 1, b = 2;
  dut.Push(&a);
  dut.Push(&b);
  dut.Close();
  int c = 3;
  EXPECT_FALSE(dut.Push(&c)) << "nothing is queued after Close";
  int out = 0;
  ASSERT_TRUE(dut.Pop(&out, milliseconds(0)));
  EXPECT_EQ(out, 1);
  ASSERT_TRUE(dut.Pop(&out, milliseconds(0)));
  EXPECT_EQ(out, 2);
  EXPECT_TRUE(dut.drained());
  EXPECT_FALSE(dut.Pop(&out, milliseconds(1000))) << "closed and empty: returns at once";
}

TEST(SinkQueue, APushWakesAWaitingConsumer) {
  SinkQueue<int> dut(2);
  int got = 0;
  std::thread consumer([&] { EXPECT_TRUE(dut.Pop(&got, milliseconds(10000))); });
  std::this_thread::sleep_for(milliseconds(20));
  int v = 42;
  dut.Push(&v);
  consumer.join();
  EXPECT_EQ(got, 42);
}

}  // namespace
}  // namespace clutterseg::daemon
