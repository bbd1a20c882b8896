#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
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

/// The path of a file:// URL (what comes before its `?`), "" for any other URL.
std::string FileUrlPath(const std::string& url);

/// True (filling `log`) when `url` is a file:// URL that writes a log (mode=w or mode=a).
bool ParseFileLogUrl(const std::string& url, FileLogUrl* log);

/// The log a file:// URL writes, written by the daemon itself in LCM's format (LCM's own
/// file provider buffers its writes and accepts messages it later cannot write: on a full disk
/// it reported every message published while the log held less than half of them).
///
/// At open it (1) refuses a log another process is writing (an exclusive flock on the file; a
/// second daemon would garble it), and (2) for ?mode=a, cuts a torn event off the end of an
/// existing log (a run that was killed mid-event), so that the new events stay readable: LCM
/// readers stop at the first bad event; a log damaged inside (a whole event follows the bad
/// bytes) is refused rather than cut; ?mode=w empties the file. Each Write() puts one whole
/// event into the file with one unbuffered write, or, when the file system refuses part of it
/// (full, over quota, I/O error), cuts the part off again and returns false: the file holds
/// whole events only, and exactly those Write() accepted.
///
/// Thread-safety: one owner thread; Write from one thread at a time; the counters from any
/// thread.
class LcmLogFile {
 public:
  LcmLogFile(const LcmLogFile&) = delete;
  LcmLogFile& operator=(const LcmLogFile&) = delete;

  /// /dev/null is accepted as a log that discards every message (nothing to verify); any
  /// other file that is not a regular file (a FIFO, /dev/full, a directory) is refused.
  /// @throws std::runtime_error naming the file when it is not a regular file, is locked by
  /// another process, is damaged inside (?mode=a) or cannot be opened, emptied or repaired.
  explicit LcmLogFile(const FileLogUrl& log);
  ~LcmLogFile();

  /// Appends one event (`channel`, `size` bytes of `data`, stamped with the wall clock in
  /// microseconds, as LCM stamps it). Returns false, leaving the file as it was, when the file
  /// system does not take all of it; last_error() then says why.
  bool Write(const std::string& channel, const void* data, size_t size);

  const std::string& path() const { return log_.path; }
  /// Bytes cut off a torn end at start-up (0 when the log was whole or new).
  uint64_t repaired_bytes() const { return repaired_bytes_; }
  /// Events found in an appended log before this run.
  uint64_t events_before() const { return events_before_; }
  /// Events this run wrote.
  uint64_t written() const { return written_.load(std::memory_order_relaxed); }
  /// Events this run could not write.
  uint64_t failures() const { return failures_.load(std::memory_order_relaxed); }
  /// Why the last failed Write() failed ("" when none did). Thread-safety: the writing thread,
  /// or after it stopped writing.
  const std::string& last_error() const { return last_error_; }

  /// Reads the file back: "" when it is whole and holds exactly the events this run wrote
  /// after those it found, otherwise what is wrong; also names the events that could not be
  /// written (e.g. the disk filled up) and why. Write() reads the new events back about once
  /// a second as it goes, so that Verify() reads only those of the last second: its time
  /// after a stop does not grow with the log (read whole, a 430 MB log of 70,000 events cost
  /// one stdio read per event between the stop and the exit).
  std::string Verify() const;

 private:
  static constexpr std::chrono::seconds kCheckPeriod{1};
  // Reads back the events written since the last check (the writing thread).
  void CheckWritten();

  FileLogUrl log_;
  int fd_{-1};
  uint64_t repaired_bytes_{0};
  uint64_t events_before_{0};
  uint64_t end_{0};  // bytes of whole events in the file
  int64_t next_event_number_{0};
  bool discard_{false};  // the log is /dev/null: nothing to lock, write or verify
  std::atomic<uint64_t> written_{0};
  std::atomic<uint64_t> failures_{0};
  std::string last_error_;
  // Read back while writing: the file's first checked_end_ bytes hold checked_events_ whole
  // events (those found at open included); what a check found wrong ("" when nothing).
  uint64_t checked_end_{0};
  uint64_t checked_events_{0};
  std::chrono::steady_clock::time_point next_check_{};
  std::string check_problem_;
};

}  // namespace clutterseg::daemon
