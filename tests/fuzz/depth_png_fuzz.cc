// libFuzzer target for the PNG readers. They read from a path only, so each input is written
// to an anonymous in-memory file (memfd) and read back through /proc/self/fd. Any input must
// either decode into an image of consistent size or throw std::runtime_error.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include <sys/mman.h>

#include "clutterseg/io/png_io.h"
#include "tests/fuzz/fuzz_check.h"

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
  static const int fd = memfd_create("clutterseg_png_fuzz", 0);
  CLUTTERSEG_FUZZ_CHECK(fd >= 0);
  CLUTTERSEG_FUZZ_CHECK(ftruncate(fd, 0) == 0);
  size_t written = 0;
  while (written < size) {
    const ssize_t n = pwrite(fd, data + written, size - written, static_cast<off_t>(written));
    CLUTTERSEG_FUZZ_CHECK(n > 0);
    written += static_cast<size_t>(n);
  }
  const std::string path = "/proc/self/fd/" + std::to_string(fd);
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
