// libFuzzer target for the PNG readers. They read from a path only, so each input is written
// to an anonymous in-memory file (memfd) and read back through /proc/self/fd. Any input must
// either decode into an image of consistent size or throw std::runtime_error.

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "clutterseg/io/png_io.h"
#include "tests/fuzz/fuzz_check.h"
#include "tests/fuzz/memfd_input.h"

namespace {

template <typename Image>
void CheckImage(const Image& image) {
  CLUTTERSEG_FUZZ_CHECK(image.width > 0 && image.height > 0);
  CLUTTERSEG_FUZZ_CHECK(image.width <= 16384 && image.height <= 16384);
  CLUTTERSEG_FUZZ_CHECK(static_cast<size_t>(image.width) * static_cast<size_t>(image.height) ==
                        image.data.size());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = clutterseg::fuzz::MemfdPath(data, size);
  try {
    CheckImage(clutterseg::io::ReadDepthPng(path, 1.0));
  } catch (const std::runtime_error&) {
  }
  try {
    CheckImage(clutterseg::io::ReadDepthPng(path, 0.2));
  } catch (const std::runtime_error&) {
  }
  try {
    CheckImage(clutterseg::io::ReadColorPng(path));
  } catch (const std::runtime_error&) {
  }
  return 0;
}
