// libFuzzer target for the ONI parser: any input must either parse or throw
// std::runtime_error, and every indexed payload must lie inside the input.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>

#include "clutterseg/drivers/oni/oni_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const clutterseg::drivers::OniFileInfo info = clutterseg::drivers::ParseOni(data, size, "fuzz");
    for (const clutterseg::drivers::OniFrameRecord& f : info.frames) {
      if (f.payload_offset + f.payload_bytes > size || f.node_index >= info.nodes.size()) {
        std::abort();
      }
    }
  } catch (const std::runtime_error&) {
  }
  return 0;
}
