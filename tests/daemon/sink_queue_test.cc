#include "clutterseg/daemon/sink_queue.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/daemon/overlay_writer.h"
#include "tests/testing/test_data.h"

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

// A stop does not wait for a slow consumer: the waiting items are dropped and counted, Pop
// gets none of them, and a Push after it is refused.
TEST(SinkQueue, CloseAndDropWaitingCountsWhatWaited) {
  SinkQueue<std::vector<int>> dut(4);
  for (int i = 0; i < 3; ++i) {
    std::vector<int> item{i};
    ASSERT_TRUE(dut.Push(&item));
  }
  EXPECT_EQ(dut.CloseAndDropWaiting(), 3u);
  EXPECT_EQ(dut.dropped(), 3u);
  EXPECT_TRUE(dut.drained());
  std::vector<int> out;
  EXPECT_FALSE(dut.Pop(&out, milliseconds(1)));
  std::vector<int> late{9};
  EXPECT_FALSE(dut.Push(&late));
}

// The overlay writer at a stop: every frame offered is written or dropped (counted), the
// directory holds exactly the written PNGs and no temporary file, and Finish(true) does not
// write what still waits.
TEST(OverlayWriter, AStopDropsWhatWaitsAndCountsEveryFrame) {
  const std::filesystem::path dir = testing::ScratchDir("overlay_stop");
  OverlayWriterParams params;
  params.png_dir = dir.string();
  params.queue_capacity = 8;
  OverlayWriter dut(params);
  dut.Start();
  constexpr int kFrames = 8;
  for (int i = 0; i < kFrames; ++i) {
    OverlayFrame f;
    f.sequence = static_cast<uint64_t>(i);
    f.labels = core::LabelImage(640, 480);
    f.base = core::ColorImage(640, 480);
    dut.Offer(&f);
  }
  dut.Finish(true);
  EXPECT_EQ(dut.written() + dut.dropped() + dut.failures(), static_cast<uint64_t>(kFrames));
  EXPECT_EQ(dut.failures(), 0u) << dut.last_error();
  uint64_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    EXPECT_EQ(e.path().extension(), ".png") << e.path() << ": only whole PNGs";
    ++files;
  }
  EXPECT_EQ(files, dut.written());
  std::printf("stop with %d overlays offered: %llu written, %llu dropped\n", kFrames,
              static_cast<unsigned long long>(dut.written()),
              static_cast<unsigned long long>(dut.dropped()));
}

}  // namespace
}  // namespace clutterseg::daemon
