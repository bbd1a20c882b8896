// clutterseg: the segmentation daemon. Reads frames from a camera, recording, directory or
// the synthetic generator, segments them and publishes the results over LCM.
//
// Exit codes (core/exit_codes.h): 0 ok (signal, --max-frames, end of recording), 1 runtime
// failure, 2 bad command line or configuration, 3 source cannot be opened, 4 LCM unavailable,
// 5 finished but something was not delivered.

#include <signal.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "clutterseg/daemon/daemon.h"
#include "clutterseg/daemon/daemon_config.h"
#include "clutterseg/daemon/heap.h"
#include "clutterseg/daemon/instance_lock.h"
#include "clutterseg/daemon/instance_watch.h"
#include "clutterseg/daemon/lcm_bus.h"
#include "clutterseg/daemon/lcm_log_file.h"
#include "clutterseg/daemon/lcm_url.h"
#include "clutterseg/daemon/log.h"
#include "clutterseg/daemon/realtime.h"
#include "clutterseg/daemon/run_watch.h"
#include "clutterseg/daemon/signal_watcher.h"
#include "clutterseg/daemon/source_factory.h"
#include "clutterseg/daemon/source_params.h"
#include "clutterseg/daemon/systemd_notify.h"
#include "clutterseg/version.h"

namespace clutterseg::daemon {
namespace {

struct CommandLine {
  std::string config_path;
  std::string source;
  std::string speed;
  std::string lcm_url;
  int64_t max_frames{-1};
  std::string png_dir;
  std::string log_level;
  int threads{-1};
  bool loop{false};
  bool print_config{false};
  std::vector<std::string> sets;
  std::vector<std::string> defaults;
};

// Flushes standard output and checks that everything printed reached it (a full device, a
// closed pipe); logs the failure naming `what` and returns false otherwise. A write that failed
// while printing (more than a buffer's worth) left its errno; the caller clears errno first.
bool StdoutWritten(const std::string& what) {
  const int while_printing = errno;
  errno = 0;
  if (std::fflush(stdout) == 0 && std::ferror(stdout) == 0) return true;
  const int error = errno != 0 ? errno : while_printing;
  Log(LogLevel::kError,
      "cannot write " + what + " to standard output: " +
          (error != 0 ? std::string(std::strerror(error)) : std::string("the write failed")));
  return false;
}

// The configuration: built-in defaults, then --default values, then the file, then
// command-line options, then --set overrides. @throws ConfigError.
DaemonConfig BuildConfig(const CommandLine& cl) {
  DaemonConfig base;
  for (const std::string& d : cl.defaults) {
    try {
      ApplyOverride(d, &base);
    } catch (const ConfigError& e) {
      throw ConfigError(std::string("--default: ") + e.what());
    }
  }
  DaemonConfig c = cl.config_path.empty() ? std::move(base) : LoadConfig(cl.config_path, base);
  if (!cl.source.empty()) SetKey("source", cl.source, &c);
  if (!cl.speed.empty()) SetKey("speed", cl.speed, &c);
  if (!cl.lcm_url.empty()) SetKey("lcm.url", cl.lcm_url, &c);
  if (cl.max_frames >= 0) c.capture.max_frames = cl.max_frames;
  if (!cl.png_dir.empty()) c.overlay.png_dir = cl.png_dir;
  if (!cl.log_level.empty()) SetKey("log.level", cl.log_level, &c);
  if (cl.threads >= 0) c.processing.threads = cl.threads;
  if (cl.loop) c.capture.loop = true;
  for (const std::string& s : cl.sets) ApplyOverride(s, &c);
  try {
    c.ValidateOrThrow();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("command line: ") + e.what());
  }
  return c;
}

// How long start-up (opening the LCM URL and the source) may take before the daemon gives up
// on a step that does not return (e.g. a tcpq:// peer that never answers the handshake).
constexpr auto kStartupLimit = std::chrono::seconds(20);

// How long the daemon listens for another daemon of its camera before publishing: a little
// more than one status period (theirs is most likely the default, like ours).
std::chrono::milliseconds InstanceCheckPeriod(double status_period_s) {
  const double s = std::min(5.0, 1.2 * status_period_s + 0.2);
  return std::chrono::milliseconds(static_cast<int64_t>(s * 1000.0));
}

// SIGHUP: re-reads --config (with the command line on top) and applies the segmenter and
// tracker parameters from the next frame. Runs on the signal thread; never throws.
void Reload(const CommandLine& cl, Daemon* daemon) {
  if (cl.config_path.empty()) {
    Log(LogLevel::kWarn, "SIGHUP: no --config file, nothing to reload");
    return;
  }
  try {
    const DaemonConfig fresh = BuildConfig(cl);
    // Everything read before anything is applied: a bad file keeps the current state whole.
    std::optional<core::Extrinsics> extrinsics = LoadExtrinsics(fresh.camera);
    daemon->UpdateSegmenterParams(fresh.segmenter);
    daemon->UpdateTrackerParams(fresh.tracker);
    const std::string frame = extrinsics ? "frame '" + extrinsics->parent_frame + "' (" +
                                               fresh.camera.extrinsics_file + ")"
                                         : "the camera frame";
    const bool moved = daemon->UpdateExtrinsics(std::move(extrinsics));
    Log(LogLevel::kInfo, "SIGHUP: segmenter parameters reloaded from " + cl.config_path +
                             " (applied from the next frame)");
    if (moved) Log(LogLevel::kInfo, "SIGHUP: objects from the next frame in " + frame);
  } catch (const std::exception& e) {
    Log(LogLevel::kError,
        std::string("SIGHUP: reload failed, keeping the current parameters: ") + e.what());
  }
}

int Run(int argc, char** argv) {
  // Signals are taken by a thread of their own from here on (the mask was blocked before
  // main), so a signal during a slow start-up (an LCM handshake, a device) is honoured too.
  signal(SIGPIPE, SIG_IGN);
  std::unique_ptr<SignalWatcher> signals;
  try {
    signals = std::make_unique<SignalWatcher>(BlockDaemonSignals(), kStartupLimit);
  } catch (const std::exception& e) {
    Log(LogLevel::kError, e.what());
    return kExitFailure;
  }

  CommandLine cl;
  CLI::App app{"clutterseg: training-free RGB-D tabletop segmentation daemon (publishes LCM)"};
  app.footer(
      "Exit codes: 0 ok (signal, --max-frames or end of recording), 1 runtime failure, 2 bad "
      "command line or configuration, 3 source cannot be opened, 4 LCM unavailable, 5 "
      "finished but not everything was delivered (named in the last log line).\n"
      "Signals: SIGINT/SIGTERM finish the frames in flight and exit (a second one exits at "
      "once); SIGHUP reloads the segmenter and tracker parameters and the extrinsics from "
      "--config.");
  app.add_option("--config", cl.config_path,
                 "YAML configuration file (see config/clutterseg.yaml)");
  app.add_option("--source", cl.source,
                 "device | device:URI | FILE.oni | DIR (PCD or depth PNG frames) | synthetic");
  app.add_option("--speed", cl.speed, "replay speed of recordings: realtime | max");
  app.add_option("--lcm-url", cl.lcm_url,
                 "LCM URL, e.g. udpm://239.255.76.67:7667?ttl=0, memq://, "
                 "file:///abs/out.lcmlog?mode=w");
  app.add_option("--max-frames", cl.max_frames, "stop after publishing N frames (0 = no limit)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--png-dir", cl.png_dir, "write a label overlay PNG per frame into DIR");
  app.add_option("--threads", cl.threads, "worker threads (0 = number of cores)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--log-level", cl.log_level, "debug | info | warn | error");
  app.add_flag("--loop", cl.loop, "restart recordings at their end");
  app.add_option("--set", cl.sets, "override any config key: --set segmenter.planes.max_planes=4")
      ->type_name("KEY=VALUE");
  app.add_option("--default", cl.defaults,
                 "a default value the --config file may override (--set overrides it): "
                 "--default camera_name=left")
      ->type_name("KEY=VALUE");
  app.add_flag("--print-config", cl.print_config, "print the effective configuration and exit");
  app.set_version_flag("--version", std::string("clutterseg ") + kVersion);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    if (code == 0) return StdoutWritten("the --help or --version text") ? kExitOk : kExitFailure;
    return kExitUsage;
  }

  DaemonConfig cfg;
  try {
    cfg = BuildConfig(cl);
  } catch (const ConfigError& e) {
    Log(LogLevel::kError, std::string("configuration: ") + e.what());
    return kExitUsage;
  }
  if (cl.print_config) {
    const std::string yaml = ConfigToYaml(cfg);
    errno = 0;
    std::fputs(yaml.c_str(), stdout);
    return StdoutWritten("the configuration (--print-config)") ? kExitOk : kExitFailure;
  }
  SetLogLevel(cfg.log_level);
  // Before the threads that allocate (LCM, capture, lanes) start.
  if (std::string problem; !PrepareHeap(cfg.heap, &problem)) {
    Log(LogLevel::kWarn, "processing.prefault_heap_mb: " + problem + "; running without it");
  }

  const std::string lcm_url = ResolveLcmUrl(cfg.lcm.url);
  if (const std::string why = CheckLcmUrl(lcm_url); !why.empty()) {
    Log(LogLevel::kError, "configuration: lcm.url = '" + lcm_url + "'" +
                              (cfg.lcm.url.empty() ? " (from LCM_DEFAULT_URL)" : "") + ": " + why);
    return kExitUsage;
  }
  // One daemon per camera name on this host, even when two start together: a lock taken
  // before anything is published and held until exit (the bus watch below finds other hosts).
  // Only on a transport other processes can hear: memq:// and file:// publish nowhere shared.
  std::unique_ptr<InstanceLock> instance_lock;
  if (cfg.lcm.check_instances && IsNetworkBus(lcm_url)) {
    const std::string dir = cfg.lcm.lock_dir.empty() ? DefaultLockDir() : cfg.lcm.lock_dir;
    try {
      instance_lock = std::make_unique<InstanceLock>(dir, cfg.capture.camera_name);
    } catch (const InstanceLockHeld& e) {
      Log(LogLevel::kError, std::string("configuration: ") + e.what() +
                                "; give each daemon its own camera_name (or set "
                                "lcm.check_instances: false)");
      return kExitUsage;
    } catch (const std::exception& e) {
      Log(LogLevel::kError, std::string("configuration: lcm.lock_dir = '") + dir +
                                "': " + e.what() + "; set lcm.lock_dir to a writable directory");
      return kExitUsage;
    }
  }
  // A file:// log is written by the bus itself: locked, emptied or (?mode=a) its torn end cut.
  std::unique_ptr<LcmBus> bus;
  signals->Step("opening LCM URL '" + lcm_url + "'", kExitLcmUnavailable);
  try {
    bus = std::make_unique<LcmBus>(lcm_url);
  } catch (const LcmUnavailableError& e) {
    Log(LogLevel::kError, e.what());
    return kExitLcmUnavailable;
  }
  if (const LcmLogFile* log = bus->log_file(); log != nullptr && log->repaired_bytes() > 0) {
    Log(LogLevel::kWarn, "LCM log " + log->path() + ": cut a torn last event (" +
                             std::to_string(log->repaired_bytes()) +
                             " bytes) left by an earlier run; appending after event " +
                             std::to_string(log->events_before()));
  }

  // On a shared bus, listen for another daemon of the same camera while the source opens.
  std::unique_ptr<InstanceWatch> instances;
  const auto check_until =
      std::chrono::steady_clock::now() + InstanceCheckPeriod(cfg.status.period_s);
  if (cfg.lcm.check_instances && IsSharedBus(lcm_url)) {
    try {
      instances = std::make_unique<InstanceWatch>(bus.get(), cfg.lcm.status_channel,
                                                  cfg.capture.camera_name);
    } catch (const std::exception& e) {
      Log(LogLevel::kWarn, std::string("cannot watch for other daemons: ") + e.what());
    }
  }

  std::unique_ptr<core::FrameSource> source;
  signals->Step("opening the source '" + cfg.source + "'", kExitSourceUnavailable);
  try {
    source = MakeSource(cfg);
  } catch (const SourceOpenError& e) {
    Log(LogLevel::kError, std::string("cannot open the source: ") + e.what());
    return kExitSourceUnavailable;
  } catch (const std::invalid_argument& e) {
    Log(LogLevel::kError, std::string("configuration: ") + e.what());
    return kExitUsage;
  }
  try {
    InitializeSourceDrivers(cfg);
  } catch (const std::exception& e) {
    Log(LogLevel::kError, std::string("cannot open the source: ") + e.what());
    return kExitSourceUnavailable;
  }

  int code = kExitOk;
  std::string error;
  DaemonStats stats;
  SystemdNotifier notifier;
  {
    // processing.realtime_priority: the lanes (started by the Daemon's constructor) inherit P;
    // capture, dispatch, publisher and status (started by Start) P + 1. The source's own
    // threads (started by Open, and by a reopen on the capture thread: ScopedNormalClass) and
    // this thread stay in the normal class.
    const int rt = cfg.realtime.priority;
    bool realtime = rt > 0;
    if (std::string problem; realtime && !SetThreadRealtime(rt, &problem)) {
      Log(LogLevel::kWarn, "processing.realtime_priority = " + std::to_string(rt) + ": " + problem +
                               "; running in the normal scheduling class");
      realtime = false;
    }
    std::unique_ptr<Daemon> daemon;
    try {
      daemon = std::make_unique<Daemon>(cfg, std::move(source), bus.get());
    } catch (const std::invalid_argument& e) {
      Log(LogLevel::kError, std::string("configuration: ") + e.what());
      return kExitUsage;
    }
    const auto back_to_normal = [realtime] {
      if (std::string problem; realtime && !SetThreadRealtime(0, &problem)) {
        Log(LogLevel::kWarn, "cannot return the main thread to the normal class: " + problem);
      }
    };
    back_to_normal();
    try {
      daemon->Open();
    } catch (const SourceOpenError& e) {
      Log(LogLevel::kError, "cannot open the source '" + cfg.source + "': " + e.what());
      daemon.reset();
      ShutdownSourceDrivers();
      return kExitSourceUnavailable;
    }
    if (instances) {
      signals->Step("listening for other daemons on " + cfg.lcm.status_channel, kExitUsage);
      if (const std::string conflict = instances->WaitForConflict(check_until); !conflict.empty()) {
        Log(LogLevel::kError, "configuration: " + conflict +
                                  "; give each daemon its own camera_name (or set "
                                  "lcm.check_instances: false)");
        daemon.reset();
        instances.reset();
        ShutdownSourceDrivers();
        return kExitUsage;
      }
    }
    // From here a stop signal is an orderly stop; before, nothing had been published and the
    // watcher ends the process at once.
    Daemon* running = daemon.get();
    signals->Attach([running] { running->RequestStop(); }, [&cl, running] { Reload(cl, running); });
    if (std::string problem; realtime && !SetThreadRealtime(rt + 1, &problem)) {
      Log(LogLevel::kWarn, "processing.realtime_priority = " + std::to_string(rt) + ": " + problem +
                               "; the capture path runs in the normal class");
    }
    try {
      daemon->Start();
    } catch (const std::invalid_argument& e) {  // e.g. output.png_dir cannot be created
      back_to_normal();
      signals->Detach();
      Log(LogLevel::kError, std::string("configuration: ") + e.what());
      daemon.reset();
      ShutdownSourceDrivers();
      return kExitUsage;
    }
    back_to_normal();
    if (realtime) {
      Log(LogLevel::kInfo, "real-time scheduling: SCHED_FIFO, segmentation at priority " +
                               std::to_string(rt) + ", capture and publishing at " +
                               std::to_string(rt + 1));
    }
    Log(LogLevel::kInfo, "source " + daemon->source_description() + " -> LCM " + bus->url() + " (" +
                             cfg.lcm.objects_channel + ")");
    notifier.Ready("publishing " + daemon->source_description() + " on " + bus->url());
    WaitUntilDone(*signals, IsNetworkBus(lcm_url), &notifier, running);
    daemon->Join();
    signals->Detach();
    code = daemon->exit_code();
    error = daemon->error();
    stats = daemon->stats();
    Log(LogLevel::kInfo,
        Summary(stats, daemon->run_latency()) + (code == kExitOk ? "" : "; error: " + error));
  }
  // Close LCM before the OpenNI2 shutdown, which takes about half a second. A file:// log holds
  // every event once written (unbuffered): read back here, it must hold exactly those.
  const std::string log_problem = bus->log_file() != nullptr ? bus->log_file()->Verify() : "";
  instances.reset();  // it handles messages on the bus
  bus.reset();
  ShutdownSourceDrivers();
  if (code == kExitOk && stats.source.all_empty()) {
    Log(LogLevel::kError, "every one of the " + std::to_string(stats.source.frames_delivered) +
                              " frames the source delivered was empty (no depth measurement): "
                              "check the recording, the depth scale and the intrinsics");
    code = kExitFailure;
  }
  if (code == kExitOk) {
    const std::vector<std::string> missing = Undelivered(stats, log_problem);
    if (!missing.empty()) {
      std::string what;
      for (const std::string& m : missing) what += (what.empty() ? "" : "; ") + m;
      Log(LogLevel::kError, "incomplete: " + what);
      code = kExitIncomplete;
    }
  }
  return code;
}

// Blocks the stop and reload signals before main() (after the shared libraries are loaded and
// initialised), so that a signal sent right after start-up waits for the SignalWatcher in
// Run() instead of killing the process with the default action.
__attribute__((constructor)) void BlockSignalsEarly() { BlockDaemonSignals(); }

}  // namespace
}  // namespace clutterseg::daemon

int main(int argc, char** argv) {
  try {
    return clutterseg::daemon::Run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "clutterseg: fatal: %s\n", e.what());
    return clutterseg::kExitFailure;
  }
}
