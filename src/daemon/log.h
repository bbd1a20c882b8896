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
/// Writes one line "clutterseg: <level>: <message>" to stderr when `level` is enabled. When
/// stderr is systemd's journal stream ($JOURNAL_STREAM), the line starts with the syslog
/// priority instead ("<3>error: ...", "<4>warn: ...", "<6>info: ...", "<7>debug: ..."), so
/// `journalctl -p err` finds the errors. Thread-safe (one fprintf per line).
void Log(LogLevel level, const std::string& message);
/// Writes the periodic status line (info): every call on a terminal, at most one a minute
/// under journald, so that days of running do not fill the journal. Thread-safe.
void LogStatusLine(const std::string& line);
/// True when stderr is systemd's journal stream.
bool LogToJournal();

}  // namespace clutterseg::daemon
