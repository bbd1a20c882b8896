#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "clutterseg/core/thread_pool.h"
#include "clutterseg/pipeline/segmentation_result.h"
#include "clutterseg/pipeline/segmenter.h"
#include "clutterseg/pipeline/segmenter_params.h"

namespace clutterseg::pipeline {

/// How FrameRunner::Submit chooses when and where an item starts.
enum class DispatchPolicy {
  /// Lowest latency (a camera): the lowest free lane (its buffers are warm); while another
  /// lane is segmenting, the item waits for that lane, which then has the pool to itself and
  /// finishes sooner, unless more items wait behind it (then the lanes pipeline to keep up).
  /// Once no lane is segmenting and the items done are completed, the pool rests
  /// (ThreadPool::Rest), so the threads Done woke find a core; Done itself finds the pool's
  /// workers awake for its own passes.
  kLatencyFirst,
  /// Highest throughput (files, benchmarks): any free lane, at once.
  kThroughput,
};

/// Parameters of the runner. YAML section `processing` (daemon configuration).
struct FrameRunnerParams {
  static constexpr std::string_view kSection = "processing";

  int pipeline_depth{2};  ///< lanes: frames segmented at once, each by its own Segmenter (1..8)
  int threads{0};         ///< threads of the pool the lanes share; 0 = cores, 1 = no pool
  DispatchPolicy policy{DispatchPolicy::kLatencyFirst};  ///< set by the program, not in YAML

  /// @throws std::invalid_argument naming the key (`processing.<field>`) and value.
  void ValidateOrThrow() const;
};

/// Segments a stream of items on `pipeline_depth` lanes, each a thread with its own
/// Segmenter, all sharing one ThreadPool, and completes them in submission order: the runner
/// of the daemon, clutterseg-segment and clutterseg-bench.
///
/// An item is an opaque number (a frame pointer, a file index). `Work` does what a lane does
/// with it (typically segment it with lane.segmenter into lane.result, and fill the caller's
/// own per-lane buffers, indexed by lane.index); `Done` then sees the items in the order they
/// were submitted, one call at a time, each while its lane's outputs are still intact, and the
/// lane takes its next item only afterwards. While one lane segments it fans its stages out
/// over the whole pool; while several do, each runs inline (ThreadPool::ActiveCaller): the
/// output is the same either way.
///
/// Thread-safety: Submit, TakeFinishedInputs, Drain and Close from one submitting thread;
/// UpdateParams, completed() and num_lanes() from any thread. Work runs on the lane threads,
/// Done on whichever lane thread completes the next item in order (never two at once).
/// Neither may throw out: an exception from Work completes its item with the error text, one
/// from Done is recorded in done_error().
class FrameRunner {
 public:
  FrameRunner(const FrameRunner&) = delete;
  FrameRunner& operator=(const FrameRunner&) = delete;

  /// What Work and Done see of a lane.
  struct Lane {
    int index{0};                         ///< 0 .. num_lanes() - 1
    Segmenter* segmenter{nullptr};        ///< built from the current params
    SegmentationResult* result{nullptr};  ///< the lane's result buffer (reused)
  };
  using Work = std::function<void(const Lane& lane, uint64_t item)>;
  /// `error` is null when Work returned normally.
  using Done = std::function<void(const Lane& lane, uint64_t item, const std::string* error)>;

  /// Starts the lanes (and the pool). @throws std::invalid_argument when a params struct is
  /// invalid.
  FrameRunner(const SegmenterParams& segmenter, const FrameRunnerParams& params, Work work,
              Done done);
  /// Closes, lets every started item complete, joins the lanes.
  ~FrameRunner();

  int num_lanes() const;
  /// The pool the lanes share (null with threads = 1), e.g. for the caller's own loops.
  core::ThreadPool* pool();

  /// Starts `item` on a lane as the policy allows, waiting until then. `backlog` (latency
  /// first only; may be empty) tells how many further items wait behind this one and is read
  /// again while waiting. Returns false, without starting it, once Close() was called.
  bool Submit(uint64_t item, const std::function<size_t()>& backlog = {});
  /// Moves into `items` the items whose Work has returned since the last call (their inputs
  /// are no longer read; their Done may still be pending).
  void TakeFinishedInputs(std::vector<uint64_t>* items);
  /// Waits until every started item is complete (its Done has returned).
  void Drain();
  /// Refuses further items; a Submit waiting for a lane returns false. Started items
  /// complete.
  void Close();
  /// Segmenter parameters for the following items: each lane rebuilds its Segmenter before
  /// its next item. @throws std::invalid_argument when invalid (the current ones stay).
  void UpdateParams(const SegmenterParams& params);
  /// Calls `fn` with every lane in turn on the calling thread, e.g. to warm up their
  /// buffers; waits for the items in flight first. Submitting thread only.
  void ForEachLane(const std::function<void(const Lane&)>& fn);

  /// From Done, before it hands its frame to a thread that sinks it: under
  /// DispatchPolicy::kLatencyFirst, when no lane is segmenting, the pool's idle workers stop
  /// spinning now (core::ThreadPool::Rest) rather than when Done returns, so that the woken
  /// sink gets a core while Done finishes what only the next frame needs (run without the
  /// pool). Does nothing otherwise.
  void RestIfIdle();

  /// Items completed so far.
  uint64_t completed() const;
  /// The first exception message thrown out of Done, empty when none.
  std::string done_error() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clutterseg::pipeline
