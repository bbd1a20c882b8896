// libFuzzer target for what clutterseg-listen, clutterseg-regress and a consumer read from an
// LCM log or the bus: the first input byte picks the parser, the rest is its input. Messages
// go through their bounds check (clutterseg/wire_check.hpp) before decode, as they do there.
//   0: objects_t::decode; 1: status_t::decode; 2: label_image_t::decode, then
//   daemon::DecodeLabelImage (RLE / zlib); 3: daemon::ScanLcmLog on the bytes as a log file.
// decode() returns a negative length (or throws std::length_error) for a malformed message and
// never reads past the input (re-encoding is not required to give the same bytes: lcm-gen
// encodes strings up to their first NUL); DecodeLabelImage gives an image of the declared size
// or throws std::runtime_error; ScanLcmLog never covers more bytes than the
// file has.

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "clutterseg/daemon/lcm_log_file.h"
#include "clutterseg/daemon/messages.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/status_t.hpp"
#include "clutterseg/wire_check.hpp"
#include "tests/fuzz/fuzz_check.h"
#include "tests/fuzz/memfd_input.h"

namespace {

// Decodes `msg` from the bytes; false when the check or the decoder refuses them.
// lcm-gen's decoders throw std::length_error on some malformed strings (a length field of 0),
// which every reader here catches (LcmBus, clutterseg-listen, clutterseg-regress): refused.
template <typename Message>
bool DecodeChecked(const uint8_t* data, size_t size, Message* msg,
                   std::string (*check)(const uint8_t*, size_t)) {
  // What every reader here does first (clutterseg/wire_check.hpp): lcm-gen's decoders size
  // arrays from the message's counts before they look at what follows.
  if (size < 8 || !check(data + 8, size - 8).empty()) return false;
  int used = -1;
  try {
    used = msg->decode(data, 0, static_cast<int>(size));
  } catch (const std::length_error&) {
    return false;
  }
  if (used < 0) return false;
  CLUTTERSEG_FUZZ_CHECK(static_cast<size_t>(used) <= size);
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0 || size > (1u << 24)) return 0;
  const uint8_t which = data[0] % 4;
  ++data;
  --size;
  switch (which) {
    case 0: {
      clutterseg::objects_t msg;
      DecodeChecked(data, size, &msg, clutterseg::wire::CheckObjects);
      break;
    }
    case 1: {
      clutterseg::status_t msg;
      DecodeChecked(data, size, &msg, clutterseg::wire::CheckStatus);
      break;
    }
    case 2: {
      clutterseg::label_image_t msg;
      if (!DecodeChecked(data, size, &msg, clutterseg::wire::CheckLabels)) break;
      clutterseg::core::LabelImage labels;
      try {
        clutterseg::daemon::DecodeLabelImage(msg, &labels);
      } catch (const std::runtime_error&) {
        break;
      }
      CLUTTERSEG_FUZZ_CHECK(labels.width == msg.width && labels.height == msg.height);
      CLUTTERSEG_FUZZ_CHECK(labels.data.size() ==
                            static_cast<size_t>(msg.width) * static_cast<size_t>(msg.height));
      break;
    }
    default: {
      const clutterseg::daemon::LcmLogScan scan =
          clutterseg::daemon::ScanLcmLog(clutterseg::fuzz::MemfdPath(data, size));
      CLUTTERSEG_FUZZ_CHECK(scan.file_bytes == size);
      CLUTTERSEG_FUZZ_CHECK(scan.parsed_bytes <= scan.file_bytes);
      CLUTTERSEG_FUZZ_CHECK(!scan.complete || scan.parsed_bytes == scan.file_bytes);
      break;
    }
  }
  return 0;
}
