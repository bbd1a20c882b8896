#include "clutterseg/daemon/lcm_log_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include <sys/file.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>

namespace clutterseg::daemon {
namespace {

constexpr uint32_t kSync = 0xEDA1DA01u;
constexpr size_t kHeader = 4 + 8 + 8 + 4 + 4;

uint32_t Be32(const unsigned char* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | uint32_t{p[3]};
}

}  // namespace

LcmLogScan ScanLcmLog(const std::string& path) {
  LcmLogScan scan;
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) {
    scan.problem = "cannot open " + path + ": " + std::strerror(errno);
    return scan;
  }
  struct stat st {};
  if (fstat(fileno(f), &st) == 0) scan.file_bytes = static_cast<uint64_t>(st.st_size);
  uint64_t pos = 0;
  unsigned char header[kHeader];
  for (;;) {
    const size_t got = std::fread(header, 1, kHeader, f);
    if (got == 0) {
      scan.complete = pos == scan.file_bytes;
      if (!scan.complete) scan.problem = "unreadable at byte " + std::to_string(pos);
      break;
    }
    if (got < kHeader) {
      scan.problem = "truncated event header at byte " + std::to_string(pos);
      break;
    }
    if (Be32(header) != kSync) {
      scan.problem = "no sync word at byte " + std::to_string(pos);
      break;
    }
    const uint64_t end = pos + kHeader + Be32(header + 20) + Be32(header + 24);
    if (end > scan.file_bytes) {
      scan.problem = "truncated event at byte " + std::to_string(pos) + " (needs " +
                     std::to_string(end - pos) + " bytes, " +
                     std::to_string(scan.file_bytes - pos) + " left)";
      break;
    }
    if (std::fseek(f, static_cast<long>(end), SEEK_SET) != 0) {
      scan.problem = "cannot seek to byte " + std::to_string(end);
      break;
    }
    pos = end;
    scan.parsed_bytes = pos;
    ++scan.events;
  }
  std::fclose(f);
  return scan;
}

bool ParseFileLogUrl(const std::string& url, FileLogUrl* log) {
  if (url.rfind("file://", 0) != 0) return false;
  const std::string rest = url.substr(7);
  const size_t q = rest.find('?');
  const std::string query = q == std::string::npos ? "" : rest.substr(q + 1);
  const bool write = query.find("mode=w") != std::string::npos;
  const bool append = query.find("mode=a") != std::string::npos;
  if (!write && !append) return false;  // read mode: a replay, not a log we write
  log->path = rest.substr(0, q);
  log->append = append;
  return true;
}

LcmLogFileGuard::LcmLogFileGuard(const FileLogUrl& log) : log_(log) {
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
  if (!stat_ok || !S_ISREG(st.st_mode)) {
    close(fd_);
    fd_ = -1;
    throw std::runtime_error("LCM log " + log.path +
                             " is not a regular file (a FIFO, device or directory): the daemon "
                             "writes logs to regular files (or /dev/null) only, so that it can "
                             "verify them");
  }
  if (flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    close(fd_);
    fd_ = -1;
    throw std::runtime_error(
        "LCM log " + log.path +
        (err == EWOULDBLOCK ? ": another process is writing it (two writers would garble it); "
                              "give each daemon its own log"
                            : std::string(": cannot lock: ") + std::strerror(err)));
  }
  if (!log.append) return;  // LCM truncates it
  const LcmLogScan scan = ScanLcmLog(log.path);
  events_before_ = scan.events;
  if (!scan.complete && scan.parsed_bytes < scan.file_bytes) {
    // A torn last event (the previous writer died mid-event): LCM's readers would stop there
    // and never see what this run appends.
    if (ftruncate(fd_, static_cast<off_t>(scan.parsed_bytes)) != 0) {
      throw std::runtime_error("LCM log " + log.path + ": " + scan.problem +
                               ", and it cannot be repaired: " + std::strerror(errno));
    }
    repaired_bytes_ = scan.file_bytes - scan.parsed_bytes;
  }
}

LcmLogFileGuard::~LcmLogFileGuard() {
  if (fd_ >= 0) close(fd_);
}

std::string LcmLogFileGuard::Verify(uint64_t published) const {
  if (discard_) return {};
  const LcmLogScan scan = ScanLcmLog(log_.path);
  const uint64_t ours = scan.events > events_before_ ? scan.events - events_before_ : 0;
  if (!scan.complete) {
    return "LCM log " + log_.path + " is cut short (is the disk full?): " + std::to_string(ours) +
           " whole messages of the " + std::to_string(published) + " published, then " +
           scan.problem;
  }
  if (ours < published) {
    return "LCM log " + log_.path + " holds " + std::to_string(ours) + " of the " +
           std::to_string(published) + " messages published (is the disk full?)";
  }
  return {};
}

}  // namespace clutterseg::daemon
