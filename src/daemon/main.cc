// clutterseg: the segmentation daemon. Reads frames from a camera, recording, directory or
// the synthetic generator, segments them and publishes the results over LCM.
//
// Exit codes: 0 ok (signal, --max-frames, end of recording), 1 runtime failure, 2 bad command
// line or configuration, 3 source cannot be opened, 4 LCM unavailable.

#include <poll.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <sys/signalfd.h>

#include "clutterseg/daemon/daemon.h"
#include "clutterseg/daemon/daemon_config.h"
#include "clutterseg/daemon/lcm_bus.h"
#include "clutterseg/daemon/lcm_url.h"
#include "clutterseg/daemon/log.h"
#include "clutterseg/daemon/source_factory.h"

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
};

// The configuration: file (or defaults), then command-line options, then --set overrides.
// @throws ConfigError.
DaemonConfig BuildConfig(const CommandLine& cl) {
  DaemonConfig c = cl.config_path.empty() ? DaemonConfig{} : LoadConfig(cl.config_path);
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

// Waits for the daemon while handling signals from `signal_fd`.
void RunUntilDone(const CommandLine& cl, int signal_fd, Daemon* daemon) {
  bool stopping = false;
  for (;;) {
    pollfd pfd{signal_fd, POLLIN, 0};
    if (poll(&pfd, 1, 20) > 0 && (pfd.revents & POLLIN)) {
      signalfd_siginfo info{};
      if (read(signal_fd, &info, sizeof(info)) == static_cast<ssize_t>(sizeof(info))) {
        const int sig = static_cast<int>(info.ssi_signo);
        if (sig == SIGHUP) {
          if (cl.config_path.empty()) {
            Log(LogLevel::kWarn, "SIGHUP: no --config file, nothing to reload");
          } else {
            try {
              const DaemonConfig fresh = BuildConfig(cl);
              daemon->UpdateSegmenterParams(fresh.segmenter);
              daemon->UpdateTrackerParams(fresh.tracker);
              Log(LogLevel::kInfo, "SIGHUP: segmenter parameters reloaded from " + cl.config_path +
                                       " (applied from the next frame)");
            } catch (const std::exception& e) {
              Log(LogLevel::kError, std::string("SIGHUP: reload failed, keeping the current "
                                                "parameters: ") +
                                        e.what());
            }
          }
        } else if (!stopping) {
          stopping = true;
          Log(LogLevel::kInfo, std::string(strsignal(sig)) + ": stopping");
          daemon->RequestStop();
        } else {
          Log(LogLevel::kError, std::string(strsignal(sig)) + " again: exiting at once");
          std::_Exit(kExitFailure);
        }
      }
    }
    if (daemon->WaitFor(std::chrono::milliseconds(0))) return;
  }
}

// Blocks SIGINT, SIGTERM and SIGHUP in the calling thread (threads created later inherit the
// mask) and returns that set, for the signalfd.
sigset_t BlockDaemonSignals() {
  sigset_t mask;
  sigemptyset(&mask);
  sigaddset(&mask, SIGINT);
  sigaddset(&mask, SIGTERM);
  sigaddset(&mask, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &mask, nullptr);
  return mask;
}

int Run(int argc, char** argv) {
  // Signals are taken through a signalfd: block them before any thread exists so that every
  // thread inherits the mask.
  const sigset_t mask = BlockDaemonSignals();
  signal(SIGPIPE, SIG_IGN);
  const int signal_fd = signalfd(-1, &mask, SFD_CLOEXEC);
  if (signal_fd < 0) {
    std::perror("clutterseg: signalfd");
    return kExitFailure;
  }

  CommandLine cl;
  CLI::App app{"clutterseg: training-free RGB-D tabletop segmentation daemon (publishes LCM)"};
  app.footer(
      "Exit codes: 0 ok (signal, --max-frames or end of recording), 1 runtime failure, 2 bad "
      "command line or configuration, 3 source cannot be opened, 4 LCM unavailable.\n"
      "Signals: SIGINT/SIGTERM finish the frames in flight and exit; SIGHUP reloads the "
      "segmenter parameters from --config.");
  app.add_option("--config", cl.config_path,
                 "YAML configuration file (see config/clutterseg.yaml)");
  app.add_option("--source", cl.source,
                 "device | device:URI | FILE.oni | DIR (PCD or depth PNG frames) | synthetic");
  app.add_option("--speed", cl.speed, "replay speed of recordings: realtime | max");
  app.add_option("--lcm-url", cl.lcm_url,
                 "LCM URL, e.g. udpm://239.255.76.67:7667?ttl=0, memq://, "
                 "file:///abs/out.lcmlog?mode=w");
  app.add_option("--max-frames", cl.max_frames, "stop after publishing N frames (0 = no limit)");
  app.add_option("--png-dir", cl.png_dir, "write a label overlay PNG per frame into DIR");
  app.add_option("--threads", cl.threads, "worker threads (0 = number of cores)");
  app.add_option("--log-level", cl.log_level, "debug | info | warn | error");
  app.add_flag("--loop", cl.loop, "restart recordings at their end");
  app.add_option("--set", cl.sets, "override any config key: --set segmenter.planes.max_planes=4")
      ->type_name("KEY=VALUE");
  app.add_flag("--print-config", cl.print_config, "print the effective configuration and exit");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kExitOk : kExitUsage;
  }

  DaemonConfig cfg;
  try {
    cfg = BuildConfig(cl);
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "clutterseg: configuration error: %s\n", e.what());
    return kExitUsage;
  }
  if (cl.print_config) {
    std::fputs(ConfigToYaml(cfg).c_str(), stdout);
    return kExitOk;
  }
  SetLogLevel(cfg.log_level);

  if (const std::string why = CheckLcmUrl(cfg.lcm.url); !why.empty()) {
    std::fprintf(stderr, "clutterseg: configuration error: lcm.url = '%s': %s\n",
                 cfg.lcm.url.c_str(), why.c_str());
    return kExitUsage;
  }
  std::unique_ptr<LcmBus> bus;
  try {
    bus = std::make_unique<LcmBus>(cfg.lcm.url);
  } catch (const LcmUnavailableError& e) {
    std::fprintf(stderr, "clutterseg: %s\n", e.what());
    return kExitLcmUnavailable;
  }

  std::unique_ptr<core::FrameSource> source;
  try {
    source = MakeSource(cfg);
  } catch (const SourceOpenError& e) {
    std::fprintf(stderr, "clutterseg: cannot open the source: %s\n", e.what());
    return kExitSourceUnavailable;
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "clutterseg: configuration error: %s\n", e.what());
    return kExitUsage;
  }
  try {
    InitializeSourceDrivers(cfg);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "clutterseg: cannot open the source: %s\n", e.what());
    return kExitSourceUnavailable;
  }

  int code = kExitOk;
  {
    std::unique_ptr<Daemon> daemon;
    try {
      daemon = std::make_unique<Daemon>(cfg, std::move(source), bus.get());
    } catch (const std::invalid_argument& e) {
      std::fprintf(stderr, "clutterseg: configuration error: %s\n", e.what());
      return kExitUsage;
    }
    try {
      daemon->Start();
    } catch (const SourceOpenError& e) {
      std::fprintf(stderr, "clutterseg: cannot open the source '%s': %s\n", cfg.source.c_str(),
                   e.what());
      daemon.reset();
      ShutdownSourceDrivers();
      return kExitSourceUnavailable;
    }
    Log(LogLevel::kInfo, "source " + daemon->source_description() + " -> LCM " + bus->url() + " (" +
                             cfg.lcm.objects_channel + ")");
    RunUntilDone(cl, signal_fd, daemon.get());
    daemon->Join();
    code = daemon->exit_code();
    const DaemonStats s = daemon->stats();
    const RunLatency lat = daemon->run_latency();
    char latency[200];
    std::snprintf(latency, sizeof(latency),
                  "; whole run: capture->publish p50 %.1f p99 %.1f max %.1f ms, segment p50 "
                  "%.1f p99 %.1f ms over %llu frames",
                  lat.capture_to_publish_p50_ms, lat.capture_to_publish_p99_ms,
                  lat.capture_to_publish_max_ms, lat.segment_p50_ms, lat.segment_p99_ms,
                  static_cast<unsigned long long>(lat.frames));
    Log(LogLevel::kInfo,
        "done: " + std::to_string(s.frames_captured) + " captured, " +
            std::to_string(s.frames_processed) + " processed, " +
            std::to_string(s.frames_published) + " published, " + std::to_string(s.frames_dropped) +
            " dropped, " + std::to_string(s.publish_failures) + " publish failures" +
            (s.frames_publish_dropped > 0
                 ? ", " + std::to_string(s.frames_publish_dropped) + " dropped before the transport"
                 : "") +
            (s.overlay_failures + s.overlays_dropped > 0
                 ? ", overlays " + std::to_string(s.overlays_written) + " written / " +
                       std::to_string(s.overlays_dropped) + " dropped / " +
                       std::to_string(s.overlay_failures) + " failed"
                 : "") +
            latency + (code == kExitOk ? "" : "; error: " + daemon->error()));
  }
  // Close LCM (a file:// log is flushed and complete) before the OpenNI2 shutdown, which takes
  // about half a second; a second signal that arrives meanwhile stays pending and is ignored.
  bus.reset();
  ShutdownSourceDrivers();
  close(signal_fd);
  return code;
}

// Blocks the stop and reload signals before main() (after the shared libraries are loaded and
// initialised), so that a signal sent right after start-up is taken by the signalfd in Run()
// and ends the daemon in order instead of killing it with the default action.
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
