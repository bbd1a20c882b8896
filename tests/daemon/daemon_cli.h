#pragma once

// Command lines and output of the `clutterseg` process, for the tests that run it.

#include <string>
#include <vector>

namespace clutterseg::daemon::testutil {

/// The daemon (`exe`) replaying `source` in lockstep (--speed max) to the LCM URL `url`, then
/// `extra` arguments.
inline std::vector<std::string> ReplayArgs(const std::string& exe, const std::string& source,
                                           const std::string& url,
                                           const std::vector<std::string>& extra = {}) {
  std::vector<std::string> argv = {exe, "--source", source, "--speed", "max", "--lcm-url", url};
  argv.insert(argv.end(), extra.begin(), extra.end());
  return argv;
}

/// The last non-empty line of `text` (e.g. the daemon's final log line), without its newline.
inline std::string LastLine(const std::string& text) {
  const size_t end = text.find_last_not_of('\n');
  if (end == std::string::npos) return {};
  const size_t start = text.rfind('\n', end);
  const size_t from = start == std::string::npos ? 0 : start + 1;
  return text.substr(from, end - from + 1);
}

}  // namespace clutterseg::daemon::testutil
