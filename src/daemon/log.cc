#include "clutterseg/daemon/log.h"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <mutex>

#include <sys/stat.h>

namespace clutterseg::daemon {
namespace {

std::atomic<int> g_level{static_cast<int>(LogLevel::kInfo)};

// True when stderr is the stream systemd connected to the journal: $JOURNAL_STREAM names
// its device and inode ("dev:ino"), as sd_journal_stream_fd documents.
bool StderrIsJournal() {
  const char* env = std::getenv("JOURNAL_STREAM");
  if (env == nullptr) return false;
  unsigned long long dev = 0, ino = 0;
  if (std::sscanf(env, "%llu:%llu", &dev, &ino) != 2) return false;
  struct stat st {};
  if (fstat(STDERR_FILENO, &st) != 0) return false;
  return static_cast<unsigned long long>(st.st_dev) == dev &&
         static_cast<unsigned long long>(st.st_ino) == ino;
}

bool Journal() {
  static const bool journal = StderrIsJournal();
  return journal;
}

// The syslog priority journald reads from a "<N>" line prefix (sd-daemon.h's SD_ERR etc.).
int Priority(LogLevel level) {
  switch (level) {
    case LogLevel::kDebug:
      return 7;
    case LogLevel::kInfo:
      return 6;
    case LogLevel::kWarn:
      return 4;
    case LogLevel::kError:
      return 3;
  }
  return 6;
}

}  // namespace

const char* ToString(LogLevel level) {
  switch (level) {
    case LogLevel::kDebug:
      return "debug";
    case LogLevel::kInfo:
      return "info";
    case LogLevel::kWarn:
      return "warn";
    case LogLevel::kError:
      return "error";
  }
  return "info";
}

void SetLogLevel(LogLevel level) { g_level.store(static_cast<int>(level)); }

bool LogEnabled(LogLevel level) { return static_cast<int>(level) >= g_level.load(); }

bool LogToJournal() { return Journal(); }

void Log(LogLevel level, const std::string& message) {
  if (!LogEnabled(level)) return;
  if (Journal()) {
    std::fprintf(stderr, "<%d>%s: %s\n", Priority(level), ToString(level), message.c_str());
  } else {
    std::fprintf(stderr, "clutterseg: %s: %s\n", ToString(level), message.c_str());
  }
}

void LogStatusLine(const std::string& line) {
  if (!LogEnabled(LogLevel::kInfo)) return;
  if (Journal()) {
    // One line a minute: the journal keeps a day of them in a few hundred kB.
    static std::mutex mutex;
    static std::chrono::steady_clock::time_point last{};
    const auto now = std::chrono::steady_clock::now();
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (last != std::chrono::steady_clock::time_point{} && now - last < std::chrono::minutes(1)) {
        return;
      }
      last = now;
    }
    std::fprintf(stderr, "<6>%s\n", line.c_str());
  } else {
    std::fprintf(stderr, "clutterseg: %s\n", line.c_str());
  }
}

}  // namespace clutterseg::daemon
