#pragma once

#include <string>

#include "clutterseg/config/daemon_config.h"

namespace clutterseg::daemon {

/// Sets the minimum level written by Log (process-wide; default info). Thread-safe.
void SetLogLevel(config::LogLevel level);
/// True when messages of `level` are written.
bool LogEnabled(config::LogLevel level);
/// Writes one line "clutterseg: <level>: <message>" to stderr when `level` is enabled.
/// Thread-safe (one fprintf per line).
void Log(config::LogLevel level, const std::string& message);

}  // namespace clutterseg::daemon
