#pragma once

#include <cstdint>
#include <string>

namespace clutterseg::daemon {

/// The structure of an LCM event log file as found on disk (LCM's format: per event a
/// big-endian sync word 0xEDA1DA01, event number, utime, channel and data lengths, then the
/// channel and the data), read without liblcm and without loading the file into memory.
struct LcmLogScan {
  uint64_t events{0};
  uint64_t file_bytes{0};
  uint64_t parsed_bytes{0};  ///< bytes covered by complete events, from the start
  bool complete{false};      ///< every byte belongs to a complete event
  std::string problem;       ///< what is wrong when not complete
};

/// Scans `path`. A file that cannot be opened gives complete = false and a problem.
LcmLogScan ScanLcmLog(const std::string& path);

/// A file:// LCM URL taken apart: the log's path and whether LCM appends (?mode=a).
struct FileLogUrl {
  std::string path;
  bool append{false};
};

/// True (filling `log`) when `url` is a file:// URL that writes a log (mode=w or mode=a).
bool ParseFileLogUrl(const std::string& url, FileLogUrl* log);

/// The daemon's hold on the log a file:// URL writes: taken before LCM opens the file, it
/// (1) refuses a log another process is writing (an exclusive flock on the file; a second
/// daemon would garble it), and (2) for ?mode=a, cuts a torn event off the end of an
/// existing log (a run that was killed mid-event), so that the new events stay readable: LCM
/// readers stop at the first bad event. After the run, Verify() checks that the file holds
/// every event the transport accepted.
///
/// Thread-safety: one owner thread.
class LcmLogFileGuard {
 public:
  LcmLogFileGuard(const LcmLogFileGuard&) = delete;
  LcmLogFileGuard& operator=(const LcmLogFileGuard&) = delete;

  /// /dev/null is accepted as a log that discards every message (nothing to verify); any
  /// other file that is not a regular file (a FIFO, /dev/full, a directory) is refused.
  /// @throws std::runtime_error naming the file when it is not a regular file, is locked by
  /// another process or cannot be opened or repaired.
  explicit LcmLogFileGuard(const FileLogUrl& log);
  ~LcmLogFileGuard();

  /// Bytes cut off a torn end at start-up (0 when the log was whole or new).
  uint64_t repaired_bytes() const { return repaired_bytes_; }
  /// Events found in an appended log before this run.
  uint64_t events_before() const { return events_before_; }

  /// After LCM closed the log: "" when it is whole and holds at least `published` events of
  /// this run (every message the transport accepted), otherwise what is missing (e.g. the
  /// disk filled up: LCM buffers its writes and accepts messages it later cannot write).
  std::string Verify(uint64_t published) const;

 private:
  FileLogUrl log_;
  int fd_{-1};
  uint64_t repaired_bytes_{0};
  uint64_t events_before_{0};
  bool discard_{false};  // the log is /dev/null: nothing to lock or verify
};

}  // namespace clutterseg::daemon
