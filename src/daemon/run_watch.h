#pragma once

#include <chrono>
#include <string>
#include <vector>

#include "clutterseg/daemon/daemon.h"
#include "clutterseg/daemon/signal_watcher.h"
#include "clutterseg/daemon/systemd_notify.h"

namespace clutterseg::daemon {

/// How long the pipeline may go without progress once it drains (after a stop signal or the
/// end of a recording: frames in flight finish, the sinks empty their queues, a last status_t
/// is sent) before the process gives up on a sink or device that does not return.
inline constexpr std::chrono::seconds kDrainStallLimit{5};
/// A stop signal on a network transport ends the process within this time even when the
/// transport does not take the last messages (there is no log file to tear by exiting).
inline constexpr std::chrono::milliseconds kNetworkStopLimit{900};

/// Multicast transports (udpm://, mpudpm://), where other processes publish beside us. tcpq
/// is left out: LCM reconnects inside handle(), which can then block on a hub that does not
/// answer.
bool IsSharedBus(const std::string& url);

/// Transports to another process over a socket: the multicast ones and tcpq://.
bool IsNetworkBus(const std::string& url);

/// Waits for `daemon` to finish, feeding systemd's watchdog while frames are published and
/// reporting STATUS=. Once the run drains, ends the process with kExitIncomplete when nothing
/// moves for kDrainStallLimit, or, on a network transport, when a stop signal is not done
/// within kNetworkStopLimit (a message names what was left unpublished). Thread-safety: call
/// from the thread that owns `daemon`.
void WaitUntilDone(const SignalWatcher& signals, bool network_transport, SystemdNotifier* notifier,
                   Daemon* daemon);

/// What the run did not deliver, one phrase each (frames the source could not deliver,
/// refused publishes, frames dropped in front of a slow transport, overlays that could not be
/// written, `log_problem` when not empty); empty when every output is complete. Overlays the
/// writer dropped for lack of CPU or disk bandwidth are like frames the frame queue drops:
/// counted and reported (status_t, the summary line), not a failure.
std::vector<std::string> Undelivered(const DaemonStats& s, const std::string& log_problem);

/// The closing summary line: frame counts, failures and the run's latency percentiles.
std::string Summary(const DaemonStats& s, const RunLatency& lat);

}  // namespace clutterseg::daemon
