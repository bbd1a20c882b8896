#pragma once

// Command lines and output of the `clutterseg` process, for the tests that run it.

#include <cstdint>
#include <regex>
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

/// The number before `label` in the daemon's final "done: ..." line of `err` (e.g. 42 for
/// "42 published"), -1 when the line or the label is missing.
inline int64_t DoneCount(const std::string& err, const std::string& label) {
  const size_t done = err.rfind("info: done: ");
  if (done == std::string::npos) return -1;
  const std::string line = err.substr(done, err.find('\n', done) - done);
  std::smatch m;
  if (!std::regex_search(line, m, std::regex("(\\d+) " + label))) return -1;
  return std::stoll(m[1]);
}

}  // namespace clutterseg::daemon::testutil
