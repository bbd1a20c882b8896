#include "tests/daemon/daemon_test_util.h"

#include <fcntl.h>
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <thread>

#include <lcm/lcm-cpp.hpp>
#include <sys/wait.h>

#include "clutterseg/core/frame.h"
#include "clutterseg/drivers/oni/oni_writer.h"
#include "clutterseg/synth/renderer.h"
#include "clutterseg/synth/scene.h"
#include "clutterseg/synth/sensor_params.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon::testutil {

namespace {

// Frame i renders scene `scene_seed(i)` with sensor noise seed i + 1.
template <typename SceneSeed>
std::vector<core::RgbdFrame> RenderTabletops(int n, SceneSeed scene_seed) {
  synth::SceneParams scene;
  scene.min_objects = 4;
  scene.max_objects = 8;
  const synth::SensorParams sensor;
  std::vector<core::RgbdFrame> frames(static_cast<size_t>(std::max(n, 0)));
  synth::RenderedFrame rendered;
  for (int i = 0; i < n; ++i) {
    const uint64_t seed = static_cast<uint64_t>(i) + 1;
    synth::RenderScene(synth::GenerateScene(scene, scene_seed(seed)), scene.intrinsics, sensor,
                       seed, &rendered);
    core::RgbdFrame& f = frames[static_cast<size_t>(i)];
    f.intrinsics = rendered.intrinsics;
    f.depth = rendered.depth;
    f.color = rendered.color;
    core::StampReplayFrame(static_cast<uint64_t>(i), 33333, "camera", &f);
  }
  return frames;
}

}  // namespace

std::vector<core::RgbdFrame> TabletopFrames(int n) {
  return RenderTabletops(n, [](uint64_t seed) { return seed; });
}

std::vector<core::RgbdFrame> StillTabletopFrames(int n) {
  return RenderTabletops(n, [](uint64_t) { return uint64_t{1}; });
}

void WriteTabletopOni(const std::string& path, int frames) {
  const std::vector<core::RgbdFrame> images = TabletopFrames(frames);
  drivers::OniWriter writer;
  for (size_t i = 0; i < images.size(); ++i) {
    const core::RgbdFrame& f = images[i];
    if (i == 0) writer.Open(path, f.depth.width, f.depth.height, 30, f.intrinsics, true);
    writer.WriteFrame(f.depth, &f.color, static_cast<int64_t>(i) * 33333);
  }
  writer.Close();
}

std::vector<std::string> LoopingDaemonArgv(const std::string& exe, const std::string& recording,
                                           const std::string& url, const std::string& camera,
                                           const std::string& lock_dir) {
  return {exe,         "--source",
          recording,   "--speed",
          "realtime",  "--loop",
          "--lcm-url", url,
          "--set",     "camera_name=" + camera,
          "--set",     "lcm.lock_dir=" + lock_dir};
}

Child Spawn(const std::vector<std::string>& argv) {
  // The daemons of this test process lock their camera names in a directory of its own
  // (lcm.lock_dir's default starts with $RUNTIME_DIRECTORY), never in the host's.
  static const bool kLockDirSet = [] {
    const auto dir = testing::ScratchDir("daemon_locks");
    return setenv("RUNTIME_DIRECTORY", dir.c_str(), 1) == 0;
  }();
  (void)kLockDirSet;
  int pipefd[2];
  if (pipe2(pipefd, O_CLOEXEC) != 0) return {};
  const pid_t pid = fork();
  if (pid == 0) {
    const int null_fd = open("/dev/null", O_WRONLY);
    dup2(null_fd, STDOUT_FILENO);
    dup2(pipefd[1], STDERR_FILENO);
    // The test runner may have blocked signals; the child starts with a clean mask.
    sigset_t none;
    sigemptyset(&none);
    sigprocmask(SIG_SETMASK, &none, nullptr);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    _exit(127);
  }
  close(pipefd[1]);
  if (pid < 0) {
    close(pipefd[0]);
    return {};
  }
  return {pid, pipefd[0]};
}

int Wait(Child* child, std::chrono::milliseconds timeout, std::string* err) {
  if (child->pid <= 0) return -1;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  int status = 0;
  bool exited = false;
  char buf[4096];
  auto drain = [&](int wait_ms) {
    while (child->stderr_fd >= 0) {
      pollfd pfd{child->stderr_fd, POLLIN, 0};
      if (poll(&pfd, 1, wait_ms) <= 0) return;
      const ssize_t n = read(child->stderr_fd, buf, sizeof(buf));
      if (n <= 0) {
        close(child->stderr_fd);
        child->stderr_fd = -1;
        return;
      }
      err->append(buf, static_cast<size_t>(n));
    }
  };
  while (!exited) {
    drain(0);  // so the child never blocks on a full pipe
    if (waitpid(child->pid, &status, WNOHANG) == child->pid) {
      exited = true;
    } else if (std::chrono::steady_clock::now() > deadline) {
      kill(child->pid, SIGKILL);
      waitpid(child->pid, &status, 0);
      drain(0);
      if (child->stderr_fd >= 0) close(child->stderr_fd);
      child->stderr_fd = -1;
      child->pid = -1;
      return -1;
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  drain(200);
  if (child->stderr_fd >= 0) close(child->stderr_fd);
  child->stderr_fd = -1;
  child->pid = -1;
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}

int Run(const std::vector<std::string>& argv, std::chrono::milliseconds timeout, std::string* err) {
  Child c = Spawn(argv);
  return Wait(&c, timeout, err);
}

void Drain(Child* child, std::string* err) {
  char buf[4096];
  while (child->stderr_fd >= 0) {
    pollfd pfd{child->stderr_fd, POLLIN, 0};
    if (poll(&pfd, 1, 0) <= 0) return;
    const ssize_t n = read(child->stderr_fd, buf, sizeof(buf));
    if (n <= 0) return;  // end of file: Wait() closes the descriptor
    err->append(buf, static_cast<size_t>(n));
  }
}

bool SignalBlocked(pid_t pid, int sig) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("SigBlk:", 0) == 0) {
      const unsigned long long mask = std::strtoull(line.c_str() + 7, nullptr, 16);
      return ((mask >> (sig - 1)) & 1ull) != 0;
    }
  }
  return false;
}

bool SampleProc(pid_t pid, ProcSample* sample) {
  const std::filesystem::path dir = "/proc/" + std::to_string(pid);
  std::ifstream status(dir / "status");
  if (!status) return false;
  ProcSample s;
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) s.rss_kib = std::strtoll(line.c_str() + 6, nullptr, 10);
  }
  auto count = [](const std::filesystem::path& d) {
    std::error_code ec;
    int n = 0;
    for (auto it = std::filesystem::directory_iterator(d, ec);
         !ec && it != std::filesystem::directory_iterator(); it.increment(ec)) {
      ++n;
    }
    return ec ? -1 : n;
  };
  s.fds = count(dir / "fd");
  s.threads = count(dir / "task");
  if (s.rss_kib < 0 || s.fds < 0 || s.threads < 0) return false;
  *sample = s;
  return true;
}

std::vector<LogEvent> ReadLcmLog(const std::string& path) {
  std::vector<LogEvent> events;
  lcm::LogFile log(path, "r");
  if (!log.good()) return events;
  while (const lcm::LogEvent* ev = log.readNextEvent()) {
    const auto* p = static_cast<const uint8_t*>(ev->data);
    events.push_back({ev->channel, std::vector<uint8_t>(p, p + ev->datalen)});
  }
  return events;
}

namespace {
int Shell(const std::string& cmd) {
  const int rc = std::system((cmd + " >/dev/null 2>&1").c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}
}  // namespace

NetNamespace::NetNamespace(bool route) {
  static std::atomic<int> counter{0};
  name_ = "clutterseg_test_" + std::to_string(getpid()) + "_" + std::to_string(counter++);
  if (geteuid() != 0) {
    why_ = "needs root to create a network namespace";
    return;
  }
  if (Shell("ip netns add " + name_) != 0) {
    why_ = "'ip netns add' failed (no network namespace support here)";
    return;
  }
  created_ = true;
  if (route) {
    if (Shell("ip -n " + name_ + " link set lo up") != 0 ||
        Shell("ip -n " + name_ + " route add 224.0.0.0/4 dev lo") != 0) {
      why_ = "could not set up lo and the multicast route in the namespace";
      return;
    }
  }
  ok_ = true;
}

NetNamespace::~NetNamespace() {
  if (created_) Shell("ip netns del " + name_);
}

std::vector<std::string> NetNamespace::Exec(const std::vector<std::string>& argv) const {
  std::vector<std::string> out = {"/usr/sbin/ip", "netns", "exec", name_};
  out.insert(out.end(), argv.begin(), argv.end());
  return out;
}

LanSegment::LanSegment(int hosts) {
  if (!bridge_.ok()) {
    why_ = bridge_.why();
    return;
  }
  const std::string lan = bridge_.name();
  if (Shell("ip -n " + lan + " link add br0 type bridge mcast_snooping 0") != 0 ||
      Shell("ip -n " + lan + " link set br0 up") != 0) {
    why_ = "could not create the bridge";
    return;
  }
  for (int i = 0; i < hosts; ++i) {
    hosts_.push_back(std::make_unique<NetNamespace>(/*route=*/false));
    const NetNamespace& h = *hosts_.back();
    if (!h.ok()) {
      why_ = h.why();
      return;
    }
    const std::string port = "port" + std::to_string(i);
    const std::string in_host = "ip -n " + h.name() + " ";
    if (Shell(in_host + "link add eth0 type veth peer name " + port + " netns " + lan) != 0 ||
        Shell("ip -n " + lan + " link set " + port + " master br0 up") != 0 ||
        Shell(in_host + "addr add 10.231.0." + std::to_string(i + 1) + "/24 dev eth0") != 0 ||
        Shell(in_host + "link set eth0 up") != 0 || Shell(in_host + "link set lo up") != 0 ||
        Shell(in_host + "route add 224.0.0.0/4 dev eth0") != 0) {
      why_ = "could not plug host " + std::to_string(i) + " into the bridge";
      return;
    }
  }
  ok_ = true;
}

LanSegment::~LanSegment() = default;  // deleting a namespace deletes its end of each veth

bool WaitForMulticastMember(const NetNamespace& ns, const std::string& group,
                            std::chrono::milliseconds timeout) {
  // /proc/net/igmp lists each joined group as 8 hex digits of the address in host byte order
  // (little-endian here): 239.255.76.67 is 434CFFEF.
  unsigned a = 0, b = 0, c = 0, d = 0;
  if (std::sscanf(group.c_str(), "%u.%u.%u.%u", &a, &b, &c, &d) != 4) return false;
  char hex[9];
  std::snprintf(hex, sizeof(hex), "%02X%02X%02X%02X", d & 0xff, c & 0xff, b & 0xff, a & 0xff);
  const auto until = std::chrono::steady_clock::now() + timeout;
  const std::string cmd = "ip netns exec " + ns.name() + " cat /proc/net/igmp";
  do {
    std::string out;
    if (FILE* f = popen(cmd.c_str(), "r")) {
      char buf[4096];
      size_t n;
      while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0) out.append(buf, n);
      pclose(f);
    }
    if (out.find(hex) != std::string::npos) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  } while (std::chrono::steady_clock::now() < until);
  return false;
}

}  // namespace clutterseg::daemon::testutil
