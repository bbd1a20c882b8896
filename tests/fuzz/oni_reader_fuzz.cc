// libFuzzer target for our ONI reader (drivers/oni), which checks every recording before
// OpenNI2 replays it and serves the tools: ParseOni on the bytes, then OniReader on the same
// bytes as a file (through a memfd), reading the frames the way the tools and the replay
// checks do. Any input must either parse or throw std::runtime_error; every indexed payload
// lies inside the input and names an existing node; the file reader indexes exactly what the
// memory parser indexes; a depth or colour frame decodes to its node's declared size or is
// refused with std::runtime_error.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <string>
#include <vector>

#include "clutterseg/core/frame.h"
#include "clutterseg/drivers/oni/oni_reader.h"
#include "tests/fuzz/fuzz_check.h"
#include "tests/fuzz/memfd_input.h"

namespace {

namespace drivers = clutterseg::drivers;

// Frames read per input at most (an input may index thousands of tiny records).
constexpr size_t kMaxFramesRead = 16;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  drivers::OniFileInfo parsed;
  try {
    parsed = drivers::ParseOni(data, size, "fuzz");
  } catch (const std::runtime_error&) {
    return 0;
  }
  for (const drivers::OniFrameRecord& f : parsed.frames) {
    CLUTTERSEG_FUZZ_CHECK(f.payload_offset + f.payload_bytes <= size);
    CLUTTERSEG_FUZZ_CHECK(f.node_index < parsed.nodes.size());
  }

  drivers::OniReader reader;
  try {
    reader.Open(clutterseg::fuzz::MemfdPath(data, size));
  } catch (const std::exception& e) {  // ParseOni took these bytes: the file must parse too
    std::fprintf(stderr, "OniReader::Open refused what ParseOni parsed: %s\n", e.what());
    std::abort();
  }
  const drivers::OniFileInfo& info = reader.info();
  // The same bytes from a file index the same records.
  CLUTTERSEG_FUZZ_CHECK(info.frames.size() == parsed.frames.size());
  CLUTTERSEG_FUZZ_CHECK(info.nodes.size() == parsed.nodes.size());
  clutterseg::core::DepthImage depth;
  clutterseg::core::ColorImage color;
  std::vector<uint8_t> payload;
  for (size_t i = 0; i < std::min(info.frames.size(), kMaxFramesRead); ++i) {
    const drivers::OniFrameRecord& f = info.frames[i];
    const drivers::OniNodeInfo& n = info.nodes[f.node_index];
    try {
      reader.ReadPayload(i, &payload);
      CLUTTERSEG_FUZZ_CHECK(payload.size() == f.payload_bytes);
      if (n.type == 2) {
        reader.ReadDepth(i, &depth);
        CLUTTERSEG_FUZZ_CHECK(depth.width == n.width && depth.height == n.height);
        CLUTTERSEG_FUZZ_CHECK(depth.data.size() == size_t(n.width) * size_t(n.height));
      } else if (n.type == 3) {
        reader.ReadColor(i, &color);
        CLUTTERSEG_FUZZ_CHECK(color.width == n.width && color.height == n.height);
        CLUTTERSEG_FUZZ_CHECK(color.data.size() == size_t(n.width) * size_t(n.height));
      }
    } catch (const std::runtime_error&) {
      // another codec, a size mismatch: refused with a message
    }
  }
  return 0;
}
