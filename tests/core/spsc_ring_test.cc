#include "clutterseg/core/spsc_ring.h"

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <random>
#include <set>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/frame_pool.h"

namespace clutterseg::core {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

struct Item {
  uint64_t seq{0};
  std::array<uint64_t, 7> payload{};
};

void Fill(uint64_t seq, Item* item) {
  item->seq = seq;
  for (size_t i = 0; i < item->payload.size(); ++i) item->payload[i] = seq * 1000003u + i;
}

bool Intact(const Item& item) {
  for (size_t i = 0; i < item.payload.size(); ++i) {
    if (item.payload[i] != item.seq * 1000003u + i) return false;
  }
  return true;
}

void Push(SpscRing<Item>* ring, uint64_t seq) {
  Fill(seq, ring->acquire());
  ring->push();
}

uint64_t PopSeq(SpscRing<Item>* ring) {
  Item* item = ring->try_pop();
  EXPECT_NE(item, nullptr);
  if (item == nullptr) return UINT64_MAX;
  const uint64_t seq = item->seq;
  ring->release(item);
  return seq;
}

TEST(SpscRing, DeliversInPushOrder) {
  SpscRing<Item> dut(4);
  for (uint64_t i = 0; i < 3; ++i) Push(&dut, i);
  EXPECT_EQ(dut.size(), 3u);
  for (uint64_t i = 0; i < 3; ++i) EXPECT_EQ(PopSeq(&dut), i);
  EXPECT_EQ(dut.try_pop(), nullptr);
  EXPECT_EQ(dut.pushed(), 3u);
  EXPECT_EQ(dut.popped(), 3u);
  EXPECT_EQ(dut.dropped(), 0u);
}

TEST(SpscRing, FullQueueDropsOldestAndCounts) {
  SpscRing<Item> dut(3);
  std::vector<bool> dropped;
  for (uint64_t i = 0; i < 7; ++i) {
    Fill(i, dut.acquire());
    dropped.push_back(dut.push());
  }
  EXPECT_EQ(dropped, (std::vector<bool>{false, false, false, true, true, true, true}));
  EXPECT_EQ(dut.size(), 3u);
  EXPECT_EQ(dut.dropped(), 4u);
  // The newest three survive, oldest first.
  EXPECT_EQ(PopSeq(&dut), 4u);
  EXPECT_EQ(PopSeq(&dut), 5u);
  EXPECT_EQ(PopSeq(&dut), 6u);
  EXPECT_EQ(dut.pushed(), dut.popped() + dut.dropped() + dut.size());
}

TEST(SpscRing, AcquireReturnsTheSameSlotUntilPush) {
  SpscRing<Item> dut(2);
  Item* a = dut.acquire();
  EXPECT_EQ(dut.acquire(), a);
  dut.push();
  EXPECT_NE(dut.acquire(), a);
}

TEST(SpscRing, ReusesAFixedSetOfSlots) {
  // capacity + 1 + max_consumer_held slots, whatever the traffic.
  SpscRing<Item> dut(3, 2);
  std::set<const Item*> seen;
  for (uint64_t i = 0; i < 1000; ++i) {
    Item* slot = dut.acquire();
    seen.insert(slot);
    Fill(i, slot);
    dut.push();
    if (i % 3 == 0) {
      Item* a = dut.try_pop();
      Item* b = dut.try_pop();
      ASSERT_NE(a, nullptr);
      seen.insert(a);
      if (b != nullptr) dut.release(b);  // release out of order
      dut.release(a);
    }
  }
  EXPECT_LE(seen.size(), 6u);
  EXPECT_EQ(dut.pushed(), dut.popped() + dut.dropped() + dut.size());
}

TEST(SpscRing, ConsumerHeldSlotsAreNeverHandedToTheProducer) {
  SpscRing<Item> dut(1, 2);
  Push(&dut, 0);
  Item* held0 = dut.try_pop();
  Push(&dut, 1);
  Item* held1 = dut.try_pop();
  ASSERT_NE(held0, nullptr);
  ASSERT_NE(held1, nullptr);
  for (uint64_t i = 2; i < 50; ++i) {
    Item* slot = dut.acquire();
    EXPECT_NE(slot, held0);
    EXPECT_NE(slot, held1);
    Fill(i, slot);
    dut.push();
  }
  EXPECT_EQ(held0->seq, 0u);
  EXPECT_EQ(held1->seq, 1u);
  EXPECT_TRUE(Intact(*held0));
  EXPECT_TRUE(Intact(*held1));
  dut.release(held0);
  dut.release(held1);
  EXPECT_EQ(PopSeq(&dut), 49u);
  EXPECT_EQ(dut.dropped(), 47u);
}

TEST(SpscRing, CloseDrainsThenReportsEnd) {
  SpscRing<Item> dut(4);
  Push(&dut, 10);
  Push(&dut, 11);
  dut.close();
  EXPECT_TRUE(dut.closed());
  EXPECT_FALSE(dut.drained());
  for (uint64_t expected : {10u, 11u}) {
    Item* item = dut.wait_pop_for(seconds(5));
    ASSERT_NE(item, nullptr);
    EXPECT_EQ(item->seq, expected);
    dut.release(item);
  }
  EXPECT_TRUE(dut.drained());
  EXPECT_EQ(dut.wait_pop_for(seconds(60)), nullptr);  // returns at once: closed and empty
}

TEST(SpscRing, WaitPopTimesOutWhenEmpty) {
  SpscRing<Item> dut(2);
  EXPECT_EQ(dut.wait_pop_for(milliseconds(20)), nullptr);
  EXPECT_EQ(dut.popped(), 0u);
}

TEST(SpscRing, WaitPopWakesOnPushFromAnotherThread) {
  SpscRing<Item> dut(2);
  std::thread producer([&dut] {
    std::this_thread::sleep_for(milliseconds(20));
    Push(&dut, 42);
  });
  Item* item = dut.wait_pop_for(seconds(30));
  producer.join();
  ASSERT_NE(item, nullptr);
  EXPECT_EQ(item->seq, 42u);
  dut.release(item);
}

TEST(SpscRing, WaitNotFullWakesWhenTheConsumerPops) {
  SpscRing<Item> dut(1);
  Push(&dut, 0);
  EXPECT_FALSE(dut.wait_not_full_for(milliseconds(10)));
  std::thread consumer([&dut] {
    std::this_thread::sleep_for(milliseconds(20));
    Item* item = dut.wait_pop_for(seconds(30));
    if (item != nullptr) dut.release(item);
  });
  EXPECT_TRUE(dut.wait_not_full_for(seconds(30)));
  consumer.join();
  EXPECT_EQ(dut.dropped(), 0u);
}

TEST(SpscRingDeathTest, MisuseAborts) {
  EXPECT_DEATH(
      {
        SpscRing<Item> dut(4, 1);
        Push(&dut, 0);
        Push(&dut, 1);
        dut.try_pop();
        dut.try_pop();  // a second slot while max_consumer_held = 1
      },
      "max_consumer_held");
  EXPECT_DEATH(
      {
        SpscRing<Item> dut(4, 1);
        Item foreign;
        dut.release(&foreign);
      },
      "invariant failed");
  EXPECT_DEATH(
      {
        SpscRing<Item> dut(4, 1);
        dut.push();  // nothing acquired
      },
      "without acquire");
}

TEST(FramePool, ReservesFrameBuffers) {
  FramePoolParams params;
  params.capacity = 2;
  params.width = 64;
  params.height = 48;
  auto dut = MakeFrameQueue(params);
  RgbdFrame* frame = dut->acquire();
  EXPECT_GE(frame->depth.data.capacity(), 64u * 48u);
  EXPECT_GE(frame->color.data.capacity(), 64u * 48u);
  const auto* depth_buffer = frame->depth.data.data();
  frame->depth.Reset(64, 48, 7);
  EXPECT_EQ(frame->depth.data.data(), depth_buffer);  // no reallocation
}

struct StressCase {
  size_t capacity;
  size_t held;
  uint64_t items;
  uint32_t producer_yield_mask{1023};  // the producer yields when (rng() & mask) == 0
  uint32_t consumer_yield_mask{255};
};

// Producer and consumer run flat out with random pauses on both sides, so the queue is
// alternately empty and full. Checks no duplicate, order, integrity and the counters.
void RunStress(const StressCase& c) {
  SpscRing<Item> dut(c.capacity, c.held);
  std::atomic<bool> producer_done{false};
  std::thread producer([&] {
    std::mt19937 rng(1234);
    for (uint64_t i = 0; i < c.items; ++i) {
      Fill(i, dut.acquire());
      dut.push();
      if ((rng() & c.producer_yield_mask) == 0) std::this_thread::yield();
    }
    dut.close();
    producer_done.store(true);
  });

  std::mt19937 rng(99);
  uint64_t received = 0;
  uint64_t last = 0;
  bool first = true;
  bool in_order = true;
  bool intact = true;
  std::vector<Item*> held;
  for (;;) {
    Item* item = dut.wait_pop_for(seconds(10));
    if (item == nullptr) {
      if (dut.drained()) break;
      continue;
    }
    if (!first && item->seq <= last) in_order = false;
    if (!Intact(*item)) intact = false;
    first = false;
    last = item->seq;
    ++received;
    held.push_back(item);
    if (held.size() == c.held || (rng() & 7) == 0) {
      // Check again after the producer had time to run: a slot still held must not change.
      for (Item* h : held) {
        if (!Intact(*h)) intact = false;
      }
      while (!held.empty()) {
        dut.release(held.back());  // newest first: out of order on purpose
        held.pop_back();
      }
    }
    if ((rng() & c.consumer_yield_mask) == 0) std::this_thread::yield();
  }
  for (Item* h : held) dut.release(h);
  producer.join();

  EXPECT_TRUE(producer_done.load());
  EXPECT_TRUE(in_order) << "an item was delivered twice or out of order";
  EXPECT_TRUE(intact) << "a slot's contents were overwritten while the consumer held it";
  EXPECT_EQ(last, c.items - 1) << "the newest item must never be dropped";
  EXPECT_EQ(dut.pushed(), c.items);
  EXPECT_EQ(dut.popped(), received);
  EXPECT_EQ(dut.size(), 0u);
  EXPECT_EQ(dut.pushed(), dut.popped() + dut.dropped() + dut.size());
  std::printf("capacity %zu held %zu: %llu pushed, %llu popped, %llu dropped\n", c.capacity, c.held,
              static_cast<unsigned long long>(dut.pushed()),
              static_cast<unsigned long long>(dut.popped()),
              static_cast<unsigned long long>(dut.dropped()));
}

#if defined(__SANITIZE_THREAD__)
constexpr uint64_t kStressItems = 1'000'000;
#else
constexpr uint64_t kStressItems = 3'000'000;
#endif

TEST(SpscRingStress, CapacityOne) { RunStress({1, 1, kStressItems}); }
TEST(SpscRingStress, CapacityFourHoldingTwo) { RunStress({4, 2, kStressItems}); }
TEST(SpscRingStress, CapacitySixtyFour) { RunStress({64, 3, kStressItems}); }
// A slow producer: the consumer keeps finding the queue empty and sleeping.
TEST(SpscRingStress, SlowProducer) { RunStress({2, 1, kStressItems / 4, 3, 0xffffffffu}); }

}  // namespace
}  // namespace clutterseg::core
