#pragma once

#include <cstdio>
#include <cstdlib>

/// Always-armed invariant check for programming errors: prints the failed condition with its
/// location and aborts. Use for bugs, never for bad input (throw instead).
#define CLUTTERSEG_DEMAND(cond)                                                         \
  do {                                                                                  \
    if (!(cond)) {                                                                      \
      std::fprintf(stderr, "%s:%d: invariant failed: %s\n", __FILE__, __LINE__, #cond); \
      std::abort();                                                                     \
    }                                                                                   \
  } while (0)

#ifdef NDEBUG
#define CLUTTERSEG_ASSERT(cond) \
  do {                          \
  } while (0)
#else
#define CLUTTERSEG_ASSERT(cond) CLUTTERSEG_DEMAND(cond)
#endif
