#include "clutterseg/pipeline/frame_runner.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/synth/renderer.h"
#include "clutterseg/synth/scene.h"
#include "tests/testing/process_cpu.h"

namespace clutterseg::pipeline {
namespace {

using std::chrono::milliseconds;

// Counts how many Work calls run at once.
struct Concurrency {
  std::atomic<int> now{0};
  std::atomic<int> max{0};
  void Enter() {
    const int n = now.fetch_add(1) + 1;
    int m = max.load();
    while (n > m && !max.compare_exchange_weak(m, n)) {
    }
  }
  void Leave() { now.fetch_sub(1); }
};

FrameRunnerParams Params(int lanes, int threads, DispatchPolicy policy) {
  FrameRunnerParams p;
  p.pipeline_depth = lanes;
  p.threads = threads;
  p.policy = policy;
  return p;
}

TEST(FrameRunner, CompletesInSubmissionOrderWithEachLanesOutput) {
  constexpr int kLanes = 3;
  constexpr uint64_t kItems = 40;
  std::vector<uint64_t> lane_output(kLanes, 0);  // what each lane's Work left
  std::vector<uint64_t> done_order;
  std::vector<int> lanes_used(kLanes, 0);
  std::mutex mutex;
  auto work = [&](const FrameRunner::Lane& lane, uint64_t item) {
    // Uneven work so that later items often finish first.
    std::this_thread::sleep_for(milliseconds((item * 7) % 5));
    lane_output[static_cast<size_t>(lane.index)] = item;
  };
  auto done = [&](const FrameRunner::Lane& lane, uint64_t item, const std::string* error) {
    ASSERT_EQ(error, nullptr);
    // The lane's output is still the item's: the lane waits for its completion.
    EXPECT_EQ(lane_output[static_cast<size_t>(lane.index)], item);
    std::lock_guard<std::mutex> lock(mutex);
    done_order.push_back(item);
    ++lanes_used[static_cast<size_t>(lane.index)];
  };
  FrameRunner dut(SegmenterParams{}, Params(kLanes, 1, DispatchPolicy::kThroughput), work, done);
  ASSERT_EQ(dut.num_lanes(), kLanes);
  for (uint64_t i = 0; i < kItems; ++i) ASSERT_TRUE(dut.Submit(i));
  dut.Drain();
  EXPECT_EQ(dut.completed(), kItems);
  ASSERT_EQ(done_order.size(), kItems);
  for (uint64_t i = 0; i < kItems; ++i) EXPECT_EQ(done_order[i], i);
  for (int l = 0; l < kLanes; ++l) EXPECT_GT(lanes_used[l], 0) << "lane " << l << " idle";
  std::vector<uint64_t> inputs;
  dut.TakeFinishedInputs(&inputs);
  std::sort(inputs.begin(), inputs.end());
  ASSERT_EQ(inputs.size(), kItems);
  for (uint64_t i = 0; i < kItems; ++i) EXPECT_EQ(inputs[i], i);
  inputs.clear();
  dut.TakeFinishedInputs(&inputs);
  EXPECT_TRUE(inputs.empty()) << "each input is handed back once";
}

TEST(FrameRunner, LatencyFirstWaitsForTheBusyLaneUnlessItemsQueueBehind) {
  for (const bool backlog : {false, true}) {
    Concurrency c;
    auto work = [&](const FrameRunner::Lane&, uint64_t) {
      c.Enter();
      std::this_thread::sleep_for(milliseconds(20));
      c.Leave();
    };
    FrameRunner dut(SegmenterParams{}, Params(2, 1, DispatchPolicy::kLatencyFirst), work,
                    [](const FrameRunner::Lane&, uint64_t, const std::string*) {});
    for (uint64_t i = 0; i < 6; ++i) {
      ASSERT_TRUE(dut.Submit(i, [&] { return backlog ? size_t{3} : size_t{0}; }));
    }
    dut.Drain();
    // Alone, an item has the machine to itself; with items waiting the lanes pipeline.
    EXPECT_EQ(c.max.load(), backlog ? 2 : 1) << "backlog " << backlog;
  }
}

using clutterseg::testing::ProcessCpuMs;

// A camera's runner rests the pool once no lane segments and the items done are completed:
// between a camera's frames the pool's idle worker holds no core. Spinning out its time after
// each of the 20 items would use about 40 ms of CPU while the runner waits for the next one.
// Done itself finds the worker awake: its own per-pixel passes (the tracker's) use the pool.
TEST(FrameRunner, LatencyFirstRestsThePoolAfterDone) {
  const auto spin = std::chrono::microseconds(core::ThreadPool::kSpinMicroseconds);
  std::atomic<int> worker_chunks{0}, done_worker_chunks{0};
  double idle_cpu_ms = 0.0;
  core::ThreadPool* pool = nullptr;
  // The caller's chunk waits for the worker's, so the worker runs (and would spin after).
  auto two_chunks = [&](std::atomic<int>* by_worker) {
    std::atomic<bool> worker_ran{false};
    pool->ParallelFor(2, 1, [&](size_t b, size_t) {
      if (b == 1) {
        if (pool->InWorker()) by_worker->fetch_add(1);
        worker_ran.store(true);
        return;
      }
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
      while (!worker_ran.load() && std::chrono::steady_clock::now() < deadline) {
      }
    });
  };
  auto work = [&](const FrameRunner::Lane&, uint64_t) { two_chunks(&worker_chunks); };
  auto done = [&](const FrameRunner::Lane&, uint64_t, const std::string* error) {
    EXPECT_EQ(error, nullptr);
    two_chunks(&done_worker_chunks);
  };
  FrameRunner dut(SegmenterParams{}, Params(1, 2, DispatchPolicy::kLatencyFirst), work, done);
  pool = dut.pool();
  ASSERT_NE(pool, nullptr);
  for (uint64_t i = 0; i < 20; ++i) {
    ASSERT_TRUE(dut.Submit(i, nullptr));
    dut.Drain();
    const double cpu0 = ProcessCpuMs();
    std::this_thread::sleep_for(2 * spin);
    idle_cpu_ms += ProcessCpuMs() - cpu0;
  }
  EXPECT_EQ(worker_chunks.load(), 20) << "the worker took the second chunk of every item";
  EXPECT_EQ(done_worker_chunks.load(), 20) << "and of every Done";
  EXPECT_LT(idle_cpu_ms, 10.0);
}

// Done rests the pool before it hands its frame on (the daemon's RememberAfterPublishing):
// from then on the worker that ran Done's second chunk blocks instead of spinning while Done
// finishes, so a sink woken then finds a core. Without RestIfIdle it would spin for the
// rest of Done (up to kSpinMicroseconds per item: 40 ms of CPU over these 20 items).
TEST(FrameRunner, RestIfIdleStopsTheSpinWhileDoneFinishes) {
  const auto spin = std::chrono::microseconds(core::ThreadPool::kSpinMicroseconds);
  std::atomic<int> done_worker_chunks{0};
  double rest_cpu_ms = 0.0;
  core::ThreadPool* pool = nullptr;
  FrameRunner* runner = nullptr;
  auto work = [](const FrameRunner::Lane&, uint64_t) {};
  auto done = [&](const FrameRunner::Lane&, uint64_t, const std::string* error) {
    EXPECT_EQ(error, nullptr);
    std::atomic<bool> worker_ran{false};
    pool->ParallelFor(2, 1, [&](size_t b, size_t) {
      if (b == 1) {
        if (pool->InWorker()) done_worker_chunks.fetch_add(1);
        worker_ran.store(true);
        return;
      }
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
      while (!worker_ran.load() && std::chrono::steady_clock::now() < deadline) {
      }
    });
    runner->RestIfIdle();
    const double cpu0 = ProcessCpuMs();
    std::this_thread::sleep_for(2 * spin);  // the rest of Done: the worker must not spin
    rest_cpu_ms += ProcessCpuMs() - cpu0;
  };
  FrameRunner dut(SegmenterParams{}, Params(1, 2, DispatchPolicy::kLatencyFirst), work, done);
  runner = &dut;
  pool = dut.pool();
  ASSERT_NE(pool, nullptr);
  for (uint64_t i = 0; i < 20; ++i) {
    ASSERT_TRUE(dut.Submit(i, nullptr));
    dut.Drain();
  }
  EXPECT_EQ(done_worker_chunks.load(), 20) << "the worker took the second chunk of every Done";
  EXPECT_LT(rest_cpu_ms, 10.0);
}

TEST(FrameRunner, AWorkExceptionCompletesItsItemWithTheErrorAndTheRestGoOn) {
  std::vector<std::string> errors;
  std::vector<uint64_t> done_items;
  auto work = [](const FrameRunner::Lane&, uint64_t item) {
    if (item == 2) throw std::runtime_error("frame 2 is broken");
  };
  auto done = [&](const FrameRunner::Lane&, uint64_t item, const std::string* error) {
    done_items.push_back(item);
    errors.push_back(error != nullptr ? *error : "");
  };
  FrameRunner dut(SegmenterParams{}, Params(2, 1, DispatchPolicy::kThroughput), work, done);
  for (uint64_t i = 0; i < 5; ++i) dut.Submit(i);
  dut.Drain();
  ASSERT_EQ(done_items, (std::vector<uint64_t>{0, 1, 2, 3, 4}));
  EXPECT_EQ(errors[2], "frame 2 is broken");
  EXPECT_EQ(errors[1], "");
  EXPECT_EQ(errors[3], "");
}

TEST(FrameRunner, CloseRefusesNewItemsAndFinishesStartedOnes) {
  std::atomic<int> done_count{0};
  FrameRunner dut(
      SegmenterParams{}, Params(1, 1, DispatchPolicy::kThroughput),
      [](const FrameRunner::Lane&, uint64_t) { std::this_thread::sleep_for(milliseconds(30)); },
      [&](const FrameRunner::Lane&, uint64_t, const std::string*) { done_count.fetch_add(1); });
  ASSERT_TRUE(dut.Submit(0));
  // The only lane is busy: this Submit waits until Close releases it.
  std::thread closer([&] {
    std::this_thread::sleep_for(milliseconds(5));
    dut.Close();
  });
  EXPECT_FALSE(dut.Submit(1));
  closer.join();
  dut.Drain();
  EXPECT_EQ(done_count.load(), 1);
  EXPECT_FALSE(dut.Submit(2));
}

TEST(FrameRunner, UpdateParamsValidatesAndReachesEveryLane) {
  std::vector<float> seen(2, 0.f);
  auto work = [&](const FrameRunner::Lane& lane, uint64_t) {
    seen[static_cast<size_t>(lane.index)] =
        lane.segmenter->params().linkage.concavity_tolerance_deg;
    // Long enough that the next item finds this lane busy and takes the other one.
    std::this_thread::sleep_for(milliseconds(20));
  };
  FrameRunner dut(SegmenterParams{}, Params(2, 1, DispatchPolicy::kThroughput), work,
                  [](const FrameRunner::Lane&, uint64_t, const std::string*) {});
  SegmenterParams bad;
  bad.supervoxel.grid.voxel_resolution_m = -1.f;
  EXPECT_THROW(dut.UpdateParams(bad), std::invalid_argument);
  SegmenterParams p;
  p.linkage.concavity_tolerance_deg = 12.f;
  dut.UpdateParams(p);
  // Both lanes run items after the update.
  for (uint64_t i = 0; i < 8; ++i) dut.Submit(i);
  dut.Drain();
  EXPECT_EQ(seen[0], 12.f);
  EXPECT_EQ(seen[1], 12.f);
}

TEST(FrameRunner, RealSegmentationDoesNotDependOnLanesOrThreads) {
  synth::SceneParams sp;
  sp.min_objects = 3;
  sp.max_objects = 5;
  std::vector<core::PointCloud> clouds(4);
  for (size_t i = 0; i < clouds.size(); ++i) {
    const synth::Scene scene = synth::GenerateScene(sp, 100 + i);
    synth::RenderedFrame frame;
    synth::RenderScene(scene, sp.intrinsics, synth::SensorParams{}, 100 + i, &frame);
    synth::ToPointCloud(frame, &clouds[i]);
  }
  auto run = [&](int lanes, int threads, DispatchPolicy policy) {
    std::vector<std::vector<uint32_t>> labels(clouds.size());
    std::vector<std::vector<uint32_t>> lane_labels(static_cast<size_t>(lanes));
    auto work = [&](const FrameRunner::Lane& lane, uint64_t item) {
      lane.segmenter->Process(clouds[item], sp.intrinsics, lane.result);
      lane_labels[static_cast<size_t>(lane.index)] = lane.result->labels.data;
    };
    auto done = [&](const FrameRunner::Lane& lane, uint64_t item, const std::string* error) {
      ASSERT_EQ(error, nullptr) << *error;
      labels[item] = lane_labels[static_cast<size_t>(lane.index)];
    };
    FrameRunner dut(SegmenterParams{}, Params(lanes, threads, policy), work, done);
    for (uint64_t i = 0; i < clouds.size(); ++i) dut.Submit(i);
    dut.Drain();
    return labels;
  };
  const auto reference = run(1, 1, DispatchPolicy::kThroughput);
  for (const auto& r : reference) {
    EXPECT_GT(*std::max_element(r.begin(), r.end()), 0u) << "objects found";
  }
  EXPECT_EQ(run(2, 2, DispatchPolicy::kThroughput), reference);
  EXPECT_EQ(run(2, 2, DispatchPolicy::kLatencyFirst), reference);
  EXPECT_EQ(run(3, 1, DispatchPolicy::kThroughput), reference);
}

TEST(FrameRunnerParams, ValidationNamesTheKey) {
  FrameRunnerParams p;
  p.pipeline_depth = 0;
  try {
    p.ValidateOrThrow();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("processing.pipeline_depth = 0 is invalid"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace clutterseg::pipeline
