#pragma once

// For fuzz targets whose parser reads a path only: the input is written to one anonymous
// in-memory file (memfd) per process, read back through /proc/self/fd/N.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include <sys/mman.h>

#include "tests/fuzz/fuzz_check.h"

namespace clutterseg::fuzz {

/// Replaces the memfd's contents with `data` and returns a path that reads them.
inline std::string MemfdPath(const uint8_t* data, size_t size) {
  static const int fd = memfd_create("clutterseg_fuzz_input", 0);
  CLUTTERSEG_FUZZ_CHECK(fd >= 0);
  CLUTTERSEG_FUZZ_CHECK(ftruncate(fd, 0) == 0);
  size_t written = 0;
  while (written < size) {
    const ssize_t n = pwrite(fd, data + written, size - written, static_cast<off_t>(written));
    CLUTTERSEG_FUZZ_CHECK(n > 0);
    written += static_cast<size_t>(n);
  }
  return "/proc/self/fd/" + std::to_string(fd);
}

}  // namespace clutterseg::fuzz
