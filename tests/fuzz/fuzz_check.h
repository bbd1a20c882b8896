#pragma once

// Invariant checks shared by the fuzz targets: a violated invariant aborts with a message so
// that libFuzzer records the input as a crash.

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <typeinfo>

#define CLUTTERSEG_FUZZ_CHECK(cond)                                                              \
  do {                                                                                           \
    if (!(cond)) {                                                                               \
      std::fprintf(stderr, "fuzz invariant violated at %s:%d: %s\n", __FILE__, __LINE__, #cond); \
      std::abort();                                                                              \
    }                                                                                            \
  } while (0)

namespace clutterseg::fuzz {

/// The contract of a reader of user files: `read()` either returns a value that `check`
/// accepts (check aborts through CLUTTERSEG_FUZZ_CHECK when it does not) or throws `Refusal`
/// (a message naming the problem). Any other exception aborts, naming `what` and the type.
/// A new parser's target is then a few lines:
///
///     extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
///       const std::string path = clutterseg::fuzz::MemfdPath(data, size);
///       clutterseg::fuzz::ReadOrRefuse("ReadThing", [&] { return ReadThing(path); },
///                                      [](const Thing& t) { CLUTTERSEG_FUZZ_CHECK(t.ok()); });
///       return 0;
///     }
template <typename Refusal = std::runtime_error, typename Read, typename Check>
void ReadOrRefuse(const char* what, Read&& read, Check&& check) {
  try {
    check(read());
  } catch (const Refusal&) {
    // refused with a message
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s threw %s (not a refusal): %s\n", what, typeid(e).name(), e.what());
    std::abort();
  }
}

}  // namespace clutterseg::fuzz
