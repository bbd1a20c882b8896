#include "clutterseg/core/frame.h"

#include <chrono>

namespace clutterseg::core {

int64_t SteadyClockMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

int64_t SystemClockMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void StampReplayFrame(uint64_t sequence, int64_t frame_period_us, const std::string& camera_name,
                      RgbdFrame* frame) {
  frame->utime = static_cast<int64_t>(sequence) * frame_period_us;
  frame->sequence = sequence;
  frame->receive_utime = SteadyClockMicros();
  frame->camera_name = camera_name;
}

}  // namespace clutterseg::core
