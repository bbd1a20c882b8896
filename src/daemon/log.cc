#include "clutterseg/daemon/log.h"

#include <atomic>
#include <cstdio>

namespace clutterseg::daemon {
namespace {
std::atomic<int> g_level{static_cast<int>(config::LogLevel::kInfo)};
}  // namespace

void SetLogLevel(config::LogLevel level) { g_level.store(static_cast<int>(level)); }

bool LogEnabled(config::LogLevel level) { return static_cast<int>(level) >= g_level.load(); }

void Log(config::LogLevel level, const std::string& message) {
  if (!LogEnabled(level)) return;
  std::fprintf(stderr, "clutterseg: %s: %s\n", config::ToString(level), message.c_str());
}

}  // namespace clutterseg::daemon
