#pragma once

// Helpers shared by the daemon tests: generated tabletop recordings, child processes, LCM logs and
// private network namespaces.

#include <signal.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <sys/types.h>

#include "clutterseg/core/frame.h"
#include "clutterseg/daemon/lcm_log_file.h"

namespace clutterseg::daemon::testutil {

/// Renders `n` cluttered tabletop frames with the project's own generator (src/synth): one
/// scene per frame (seeds 1..n, 4-8 objects touching, stacked and occluding on a table, with
/// floor and sometimes a wall), 640x480 Kinect intrinsics, depth in millimetres through the
/// structured-light sensor model and registered colour. Needs no downloaded data; the same
/// frames in every run.
std::vector<core::RgbdFrame> TabletopFrames(int n);
/// One still tabletop (TabletopFrames' first scene) in every frame, with fresh sensor noise
/// per frame, as a fixed camera sees it.
std::vector<core::RgbdFrame> StillTabletopFrames(int n);

/// Writes TabletopFrames(frames) as an ONI recording (depth + colour, 30 fps timestamps) with
/// drivers::OniWriter. @throws std::runtime_error when the file cannot be written.
void WriteTabletopOni(const std::string& path, int frames);

/// A child process with its stderr captured.
struct Child {
  pid_t pid{-1};
  int stderr_fd{-1};
};

/// Starts `argv` (argv[0] is a path) with stdout to /dev/null and stderr to a pipe, and
/// $RUNTIME_DIRECTORY set to a scratch directory of this test process (the daemons' lock
/// directory, see lcm.lock_dir).
Child Spawn(const std::vector<std::string>& argv);
/// Waits up to `timeout` for the child; returns its exit code, 128 + signal when killed by a
/// signal, or -1 on timeout (the child is then killed). Appends its stderr to `*err`.
int Wait(Child* child, std::chrono::milliseconds timeout, std::string* err);
/// The command line of the daemon `exe` replaying `recording` in real time in a loop into
/// `url` as camera `camera`, its instance lock in `lock_dir` (lcm.lock_dir).
std::vector<std::string> LoopingDaemonArgv(const std::string& exe, const std::string& recording,
                                           const std::string& url, const std::string& camera,
                                           const std::string& lock_dir);
/// Spawn + Wait.
int Run(const std::vector<std::string>& argv, std::chrono::milliseconds timeout, std::string* err);
/// Appends whatever the running child has written to stderr so far to `*err` without
/// blocking (long runs must drain the pipe or the child blocks on a full pipe).
void Drain(Child* child, std::string* err);

/// Resource use of a running process from /proc/<pid>.
struct ProcSample {
  int64_t rss_kib{-1};  ///< VmRSS of /proc/<pid>/status
  int fds{-1};          ///< entries of /proc/<pid>/fd
  int threads{-1};      ///< entries of /proc/<pid>/task
};
/// True when `pid` currently blocks `sig` (SigBlk of /proc/<pid>/status).
bool SignalBlocked(pid_t pid, int sig);

/// Samples /proc/<pid>; false when the process is gone.
bool SampleProc(pid_t pid, ProcSample* sample);

/// The structure of an LCM event log file as found on disk (the daemon's own scanner, which
/// reads the format without liblcm).
using daemon::LcmLogScan;
using daemon::ScanLcmLog;

/// One event of an LCM log.
struct LogEvent {
  std::string channel;
  std::vector<uint8_t> data;
};
/// Reads every event of an LCM log file with lcm::LogFile.
std::vector<LogEvent> ReadLcmLog(const std::string& path);

/// A private network namespace for multicast tests; deleted by the destructor.
class NetNamespace {
 public:
  /// Creates the namespace (unique name); with `route`, brings lo up and routes 224.0.0.0/4
  /// to it. ok() is false (and why() says why) when not root or `ip netns` fails.
  explicit NetNamespace(bool route);
  ~NetNamespace();
  NetNamespace(const NetNamespace&) = delete;
  NetNamespace& operator=(const NetNamespace&) = delete;
  bool ok() const { return ok_; }
  const std::string& why() const { return why_; }
  const std::string& name() const { return name_; }
  /// `ip netns exec NAME argv...`
  std::vector<std::string> Exec(const std::vector<std::string>& argv) const;

 private:
  std::string name_;
  bool created_{false};
  bool ok_{false};
  std::string why_;
};

/// Hosts of one LAN, each a network namespace with an `eth0` (10.231.0.(i+1)/24, the
/// multicast route 224.0.0.0/4 on it) plugged into one bridge that floods multicast (snooping
/// off, as an unmanaged switch does), itself in a namespace of its own. Deleted by the
/// destructor. ok() is false (and why() says why) when not root or a step fails.
class LanSegment {
 public:
  explicit LanSegment(int hosts);
  ~LanSegment();
  LanSegment(const LanSegment&) = delete;
  LanSegment& operator=(const LanSegment&) = delete;
  bool ok() const { return ok_; }
  const std::string& why() const { return why_; }
  /// The namespace of host `i` (0 .. hosts - 1).
  const NetNamespace& host(int i) const { return *hosts_[static_cast<size_t>(i)]; }

 private:
  NetNamespace bridge_{/*route=*/false};
  std::vector<std::unique_ptr<NetNamespace>> hosts_;
  bool ok_{false};
  std::string why_;
};

/// Waits up to `timeout` until some socket of the namespace `ns` has joined the IPv4
/// multicast `group` (dotted quad), as /proc/net/igmp inside it shows: a subscriber started
/// there is then certain to receive what is sent to the group. False on timeout.
bool WaitForMulticastMember(const NetNamespace& ns, const std::string& group,
                            std::chrono::milliseconds timeout);

}  // namespace clutterseg::daemon::testutil
