// Default sanitizer options of every test binary of a sanitizer build (CLUTTERSEG_SANITIZER),
// so that a test behaves the same when run by ctest and when run by hand:
//  - the runtime of the test binary itself reads the options below at start-up (variables
//    set in the environment, e.g. by the asan/tsan test presets, take precedence);
//  - before main(), the same options are exported to the environment unless already set, so
//    that child processes the tests start (the daemon, the tools, helper executables) use the
//    same suppression files.
// The suppression files tests/lsan.supp and tests/tsan.supp are the single source of truth;
// docs/reliability.md explains each entry.
#include <cstdlib>

#ifndef CLUTTERSEG_SOURCE_DIR
#error "CLUTTERSEG_SOURCE_DIR must name the source tree (for the suppression files)"
#endif

namespace {

#if defined(__SANITIZE_ADDRESS__)
constexpr const char* kAsanOptions = "detect_leaks=1:strict_init_order=1";
constexpr const char* kLsanOptions =
    "suppressions=" CLUTTERSEG_SOURCE_DIR "/tests/lsan.supp:print_suppressions=0";
constexpr const char* kUbsanOptions = "print_stacktrace=1:halt_on_error=1";
#endif
#if defined(__SANITIZE_THREAD__)
constexpr const char* kTsanOptions = "suppressions=" CLUTTERSEG_SOURCE_DIR
                                     "/tests/tsan.supp:halt_on_error=1:second_deadlock_stack=1";
#endif

__attribute__((constructor)) void ExportSanitizerOptionsForChildren() {
#if defined(__SANITIZE_ADDRESS__)
  setenv("ASAN_OPTIONS", kAsanOptions, /*overwrite=*/0);
  setenv("LSAN_OPTIONS", kLsanOptions, 0);
  setenv("UBSAN_OPTIONS", kUbsanOptions, 0);
#endif
#if defined(__SANITIZE_THREAD__)
  setenv("TSAN_OPTIONS", kTsanOptions, 0);
#endif
}

}  // namespace

// Hooks the sanitizer runtimes call at start-up (weak in the runtime, overridden here).
#define CLUTTERSEG_SANITIZER_HOOK extern "C" __attribute__((visibility("default"), used))
#if defined(__SANITIZE_ADDRESS__)
CLUTTERSEG_SANITIZER_HOOK const char* __asan_default_options() { return kAsanOptions; }
CLUTTERSEG_SANITIZER_HOOK const char* __lsan_default_options() { return kLsanOptions; }
CLUTTERSEG_SANITIZER_HOOK const char* __ubsan_default_options() { return kUbsanOptions; }
#endif
#if defined(__SANITIZE_THREAD__)
CLUTTERSEG_SANITIZER_HOOK const char* __tsan_default_options() { return kTsanOptions; }
#endif
