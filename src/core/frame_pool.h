#pragma once

#include <cstddef>
#include <memory>

#include "clutterseg/core/frame.h"
#include "clutterseg/core/spsc_ring.h"

namespace clutterseg::core {

/// The queue between the capture thread and processing: a drop-oldest SpscRing over a pool
/// of preallocated RgbdFrames (see SpscRing for the threading contract).
using FrameQueue = SpscRing<RgbdFrame>;

/// Sizes of the frame pool behind a FrameQueue.
struct FramePoolParams {
  size_t capacity{4};           ///< frames that may wait for processing (>= 1)
  size_t max_consumer_held{1};  ///< frames processing may hold at once (>= 1)
  int width{640};               ///< expected depth (and colour) width, pixels
  int height{480};              ///< expected depth (and colour) height, pixels
  bool with_color{true};        ///< reserve colour buffers too
};

/// Reserves a frame's image buffers for `width` x `height` so that filling it later does
/// not allocate.
inline void ReserveFrame(int width, int height, bool with_color, RgbdFrame* frame) {
  const size_t n = static_cast<size_t>(width) * static_cast<size_t>(height);
  frame->depth.data.reserve(n);
  if (with_color) frame->color.data.reserve(n);
}

/// Builds a FrameQueue whose `capacity + 1 + max_consumer_held` frames are reserved up
/// front. Sources that deliver another size reallocate once, then reuse.
inline std::unique_ptr<FrameQueue> MakeFrameQueue(const FramePoolParams& params) {
  return std::make_unique<FrameQueue>(
      params.capacity, params.max_consumer_held, [&params](RgbdFrame* frame) {
        ReserveFrame(params.width, params.height, params.with_color, frame);
      });
}

}  // namespace clutterseg::core
