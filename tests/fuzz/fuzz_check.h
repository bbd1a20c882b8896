#pragma once

// Invariant checks shared by the fuzz targets: a violated invariant aborts with a message so
// that libFuzzer records the input as a crash.

#include <cstdio>
#include <cstdlib>

#define CLUTTERSEG_FUZZ_CHECK(cond)                                                              \
  do {                                                                                           \
    if (!(cond)) {                                                                               \
      std::fprintf(stderr, "fuzz invariant violated at %s:%d: %s\n", __FILE__, __LINE__, #cond); \
      std::abort();                                                                              \
    }                                                                                            \
  } while (0)
