#pragma once

#include <string>

namespace clutterseg::daemon {

/// Verbosity of the daemon's stderr log.
enum class LogLevel { kDebug, kInfo, kWarn, kError };
const char* ToString(LogLevel level);

/// Sets the minimum level written by Log (process-wide; default info). Thread-safe.
void SetLogLevel(LogLevel level);
/// True when messages of `level` are written.
bool LogEnabled(LogLevel level);
/// Writes one line "clutterseg: <level>: <message>" to stderr when `level` is enabled.
/// Thread-safe (one fprintf per line).
void Log(LogLevel level, const std::string& message);

}  // namespace clutterseg::daemon
