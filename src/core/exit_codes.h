#pragma once

namespace clutterseg {

/// The exit codes of every clutterseg program (the daemon, clutterseg-segment, -eval, -synth,
/// -record, -listen, -regress, -bench). Scripts and systemd tell the cases apart by them.
enum ExitCode : int {
  kExitOk = 0,       ///< done: signal, --max-frames, end of input, or nothing to report
  kExitFailure = 1,  ///< a runtime failure: a source or processing error, a bad input file
  kExitUsage = 2,    ///< bad command line or configuration (the message names the key)
  kExitSourceUnavailable = 3,  ///< the frame source or input cannot be opened
  kExitLcmUnavailable = 4,     ///< the LCM URL cannot be opened (e.g. no multicast route)
  /// Finished, but not everything could be delivered: frames the source could not give,
  /// messages the transport refused, outputs that could not be written (counted and named).
  kExitIncomplete = 5,
};

}  // namespace clutterseg
