#pragma once

#include <chrono>
#include <string>
#include <vector>

namespace clutterseg::testing {

/// What a child process did.
struct ProcessResult {
  int exit_code{-1};      ///< exit status, 128 + signal when killed by a signal
  bool timed_out{false};  ///< it outlived the timeout and was killed (a hang)
  std::string out;        ///< everything it wrote to stdout
  std::string err;        ///< everything it wrote to stderr
  long max_rss_kib{0};    ///< its peak resident set size (wait4's ru_maxrss)
};

/// Runs `argv` (argv[0] is the executable's path) with stdin from /dev/null, collects its
/// output and waits at most `timeout` (then kills it and sets timed_out).
ProcessResult RunProcess(const std::vector<std::string>& argv, std::chrono::seconds timeout);

/// This process's peak resident set size so far, KiB (getrusage's ru_maxrss).
long PeakRssKib();

}  // namespace clutterseg::testing
