#include "clutterseg/daemon/lcm_log_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <vector>

#include <sys/file.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/uio.h>

namespace clutterseg::daemon {
namespace {

constexpr uint32_t kSync = 0xEDA1DA01u;
constexpr size_t kHeader = 4 + 8 + 8 + 4 + 4;

void PutBe(uint64_t value, int bytes, unsigned char* out) {
  for (int i = 0; i < bytes; ++i) {
    out[i] = static_cast<unsigned char>(value >> (8 * (bytes - 1 - i)));
  }
}

uint32_t Be32(const unsigned char* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | uint32_t{p[3]};
}

// The first byte after `from` where a whole event starts (a sync word and a header whose
// channel and data lie within the file's `size` bytes), or -1. Reads `fd` in 1 MiB windows.
int64_t FindWholeEventAfter(int fd, uint64_t from, uint64_t size) {
  constexpr size_t kWindow = size_t{1} << 20;
  std::vector<unsigned char> buf(kWindow + kHeader);
  for (uint64_t base = from; base + kHeader <= size; base += kWindow) {
    const size_t want = static_cast<size_t>(std::min<uint64_t>(kWindow + kHeader, size - base));
    const ssize_t got = pread(fd, buf.data(), want, static_cast<off_t>(base));
    if (got < static_cast<ssize_t>(kHeader)) return -1;
    for (size_t i = 0; i + kHeader <= static_cast<size_t>(got) && i < kWindow; ++i) {
      if (Be32(&buf[i]) != kSync) continue;
      const uint32_t channel = Be32(&buf[i + 20]);
      const uint64_t end = base + i + kHeader + channel + Be32(&buf[i + 24]);
      if (channel > 0 && channel <= 1024 && end <= size) return static_cast<int64_t>(base + i);
    }
  }
  return -1;
}

// Scans the events of `fd` from byte `pos` (the start of an event) up to `file_bytes`: one
// pread of each event's header, the channel and data skipped (not read). `events` counts the
// events from `pos`; `parsed_bytes` is the end of the last whole one (absolute).
LcmLogScan ScanFrom(int fd, uint64_t pos, uint64_t file_bytes) {
  LcmLogScan scan;
  scan.file_bytes = file_bytes;
  scan.parsed_bytes = pos;
  unsigned char header[kHeader];
  for (;;) {
    if (pos == file_bytes) {
      scan.complete = true;
      break;
    }
    ssize_t got = 0;
    do {
      got = pread(fd, header, kHeader, static_cast<off_t>(pos));
    } while (got < 0 && errno == EINTR);
    if (got < 0) {
      scan.problem = "unreadable at byte " + std::to_string(pos) + ": " + std::strerror(errno);
      break;
    }
    if (got < static_cast<ssize_t>(kHeader) || pos + kHeader > file_bytes) {
      scan.problem = "truncated event header at byte " + std::to_string(pos);
      break;
    }
    if (Be32(header) != kSync) {
      scan.problem = "no sync word at byte " + std::to_string(pos);
      break;
    }
    const uint64_t end = pos + kHeader + Be32(header + 20) + Be32(header + 24);
    if (end > file_bytes) {
      scan.problem = "truncated event at byte " + std::to_string(pos) + " (needs " +
                     std::to_string(end - pos) + " bytes, " + std::to_string(file_bytes - pos) +
                     " left)";
      break;
    }
    pos = end;
    scan.parsed_bytes = pos;
    ++scan.events;
  }
  return scan;
}

// Scans the log at `path` from byte `from` (the start of an event, 0 = the whole log).
LcmLogScan ScanPathFrom(const std::string& path, uint64_t from) {
  LcmLogScan scan;
  // O_NONBLOCK: a FIFO must not block the open (it is refused just below).
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    scan.problem = "cannot open " + path + ": " + std::strerror(errno);
    return scan;
  }
  struct stat st {};
  if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    scan.problem = "not a regular file (a FIFO, device or directory)";
  } else if (static_cast<uint64_t>(st.st_size) < from) {
    scan.problem = "it is " + std::to_string(st.st_size) + " bytes, shorter than the " +
                   std::to_string(from) + " already read back";
  } else {
    scan = ScanFrom(fd, from, static_cast<uint64_t>(st.st_size));
  }
  close(fd);
  return scan;
}

}  // namespace

LcmLogScan ScanLcmLog(const std::string& path) { return ScanPathFrom(path, 0); }

std::string FileUrlPath(const std::string& url) {
  if (url.rfind("file://", 0) != 0) return "";
  const size_t q = url.find('?', 7);
  return url.substr(7, q == std::string::npos ? std::string::npos : q - 7);
}

bool ParseFileLogUrl(const std::string& url, FileLogUrl* log) {
  if (url.rfind("file://", 0) != 0) return false;
  const size_t q = url.find('?', 7);
  const std::string query = q == std::string::npos ? "" : url.substr(q + 1);
  const bool write = query.find("mode=w") != std::string::npos;
  const bool append = query.find("mode=a") != std::string::npos;
  if (!write && !append) return false;  // read mode: a replay, not a log we write
  log->path = FileUrlPath(url);
  log->append = append;
  return true;
}

LcmLogFile::LcmLogFile(const FileLogUrl& log) : log_(log) {
  // O_NONBLOCK: a FIFO in its place must not block the open; it is refused just below.
  fd_ = open(log.path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NONBLOCK, 0644);
  if (fd_ < 0) {
    throw std::runtime_error("LCM log " + log.path + ": cannot open: " + std::strerror(errno) +
                             " (check the path, that its directory exists and is writable)");
  }
  struct stat st {};
  const bool stat_ok = fstat(fd_, &st) == 0;
  if (stat_ok && S_ISCHR(st.st_mode) && st.st_rdev == makedev(1, 3)) {
    discard_ = true;  // /dev/null: the messages are meant to go nowhere
    return;
  }
  const auto refuse = [this](const std::string& message) {
    close(fd_);
    fd_ = -1;
    throw std::runtime_error("LCM log " + log_.path + message);
  };
  if (!stat_ok || !S_ISREG(st.st_mode)) {
    refuse(
        " is not a regular file (a FIFO, device or directory): the daemon writes logs to "
        "regular files (or /dev/null) only, so that it can verify them");
  }
  if (flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    refuse(err == EWOULDBLOCK ? ": another process is writing it (two writers would garble it); "
                                "give each daemon its own log"
                              : std::string(": cannot lock: ") + std::strerror(err));
  }
  if (!log.append) {
    if (ftruncate(fd_, 0) != 0) refuse(std::string(": cannot empty it: ") + std::strerror(errno));
    next_check_ = std::chrono::steady_clock::now() + kCheckPeriod;
    return;
  }
  const LcmLogScan scan = ScanLcmLog(log.path);
  events_before_ = scan.events;
  next_event_number_ = static_cast<int64_t>(scan.events);
  end_ = scan.parsed_bytes;
  if (!scan.complete && scan.parsed_bytes < scan.file_bytes) {
    // Damage inside the log (a whole event follows the bad bytes) is not a torn end: cutting
    // there would throw away every event after it.
    if (const int64_t next = FindWholeEventAfter(fd_, scan.parsed_bytes + 1, scan.file_bytes);
        next >= 0) {
      refuse(": " + scan.problem + ", but a whole event follows at byte " + std::to_string(next) +
             ": the log is damaged inside, not torn at its end, and appending would cut the " +
             std::to_string(scan.file_bytes - scan.parsed_bytes) +
             " bytes after the damage; move it aside or write a new log (?mode=w)");
    }
    // A torn last event (the previous writer died mid-event): LCM's readers would stop there
    // and never see what this run appends.
    if (ftruncate(fd_, static_cast<off_t>(scan.parsed_bytes)) != 0) {
      refuse(": " + scan.problem + ", and it cannot be repaired: " + std::strerror(errno));
    }
    repaired_bytes_ = scan.file_bytes - scan.parsed_bytes;
  }
  checked_end_ = end_;
  checked_events_ = scan.events;
  next_check_ = std::chrono::steady_clock::now() + kCheckPeriod;
}

LcmLogFile::~LcmLogFile() {
  if (fd_ >= 0) close(fd_);
}

bool LcmLogFile::Write(const std::string& channel, const void* data, size_t size) {
  if (discard_) {
    written_.fetch_add(1, std::memory_order_relaxed);
    return true;
  }
  unsigned char header[kHeader];
  const auto wall_us = std::chrono::duration_cast<std::chrono::microseconds>(
                           std::chrono::system_clock::now().time_since_epoch())
                           .count();
  PutBe(kSync, 4, header);
  PutBe(static_cast<uint64_t>(next_event_number_), 8, header + 4);
  PutBe(static_cast<uint64_t>(wall_us), 8, header + 12);
  PutBe(channel.size(), 4, header + 20);
  PutBe(size, 4, header + 24);
  iovec parts[3] = {{header, kHeader},
                    {const_cast<char*>(channel.data()), channel.size()},
                    {const_cast<void*>(data), size}};
  const size_t total = kHeader + channel.size() + size;
  size_t done = 0;
  int err = 0;
  while (done < total) {
    // The parts not written yet.
    iovec rest[3];
    int n = 0;
    size_t skip = done;
    for (const iovec& part : parts) {
      if (skip >= part.iov_len) {
        skip -= part.iov_len;
        continue;
      }
      rest[n++] = {static_cast<char*>(part.iov_base) + skip, part.iov_len - skip};
      skip = 0;
    }
    const ssize_t w = pwritev(fd_, rest, n, static_cast<off_t>(end_ + done));
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) {
      err = w < 0 ? errno : ENOSPC;
      break;
    }
    done += static_cast<size_t>(w);
  }
  if (err == 0) {
    end_ += total;
    ++next_event_number_;
    written_.fetch_add(1, std::memory_order_relaxed);
    if (std::chrono::steady_clock::now() >= next_check_) CheckWritten();
    return true;
  }
  // Whole events only: the part that fitted goes again (a full file system has room for
  // less than one event; a later, smaller one may still fit).
  last_error_ = std::strerror(err);
  if (done > 0 && ftruncate(fd_, static_cast<off_t>(end_)) != 0) {
    last_error_ +=
        std::string(", and the partial event cannot be cut off: ") + std::strerror(errno);
  }
  failures_.fetch_add(1, std::memory_order_relaxed);
  return false;
}

void LcmLogFile::CheckWritten() {
  next_check_ = std::chrono::steady_clock::now() + kCheckPeriod;
  if (!check_problem_.empty() || checked_end_ == end_) return;
  const LcmLogScan scan = ScanFrom(fd_, checked_end_, end_);
  if (!scan.complete) {
    check_problem_ = scan.problem + " (read back while writing)";
    return;
  }
  checked_end_ = end_;
  checked_events_ += scan.events;
}

std::string LcmLogFile::Verify() const {
  if (discard_) return {};
  const uint64_t written = written_.load();
  const uint64_t failed = failures_.load();
  std::string problem;
  if (failed > 0) {
    problem = "LCM log " + log_.path + ": " + std::to_string(failed) + " of the " +
              std::to_string(written + failed) + " messages could not be written (" + last_error_ +
              "); it holds the " + std::to_string(written) + " written";
  }
  // The events up to checked_end_ were read back while the run wrote (CheckWritten); only the
  // rest is read here, so that the time this takes at the end does not grow with the run.
  LcmLogScan scan = ScanPathFrom(log_.path, checked_end_);
  if (!check_problem_.empty()) {
    scan.complete = false;
    scan.problem = check_problem_;
    scan.events = 0;
  }
  const uint64_t events = checked_events_ + scan.events;
  const uint64_t ours = events > events_before_ ? events - events_before_ : 0;
  std::string broken;
  if (!scan.complete) {
    broken = "LCM log " + log_.path + " is cut short: " + std::to_string(ours) +
             " whole messages of the " + std::to_string(written) + " written, then " + scan.problem;
  } else if (ours != written) {
    broken = "LCM log " + log_.path + " holds " + std::to_string(ours) + " messages of this run, " +
             std::to_string(written) + " were written (did another process change it?)";
  }
  if (broken.empty()) return problem;
  return problem.empty() ? broken : problem + "; " + broken;
}

}  // namespace clutterseg::daemon
