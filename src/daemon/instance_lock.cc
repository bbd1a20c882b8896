#include "clutterseg/daemon/instance_lock.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <system_error>
#include <thread>

#include <sys/file.h>

#include "clutterseg/daemon/instance_watch.h"

namespace clutterseg::daemon {
namespace {

std::string Sanitise(const std::string& name) {
  std::string out = name.empty() ? std::string("_") : name;
  for (char& c : out) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    if (!ok) c = '_';
  }
  if (out[0] == '.') out[0] = '_';  // no hidden files, no "." or ".."
  return out;
}

std::string Errno(int err) { return std::strerror(err); }

// The holder's "pid host" line, as written by the holder (may be empty while it writes).
std::string ReadHolder(int fd) {
  char buf[256] = {};
  const ssize_t n = pread(fd, buf, sizeof(buf) - 1, 0);
  std::string s = n > 0 ? std::string(buf, static_cast<size_t>(n)) : std::string();
  s = s.substr(0, s.find('\n'));  // the first line: the tail of a longer old one may follow
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

// True when the "pid host" line names a running process (a stale line of an earlier holder,
// which has exited and so released the lock, names none).
bool HolderAlive(const std::string& holder) {
  const long pid = std::strtol(holder.c_str(), nullptr, 10);
  return pid > 0 && (kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM);
}

}  // namespace

std::string DefaultLockDir() {
  if (const char* dir = std::getenv("RUNTIME_DIRECTORY"); dir != nullptr && *dir != '\0') {
    // systemd may list several directories separated by ':'; the first is ours.
    const std::string all = dir;
    return all.substr(0, all.find(':'));
  }
  if (access("/run", W_OK) == 0) return "/run/clutterseg";
  if (const char* xdg = std::getenv("XDG_RUNTIME_DIR"); xdg != nullptr && *xdg == '/') {
    return std::string(xdg) + "/clutterseg";
  }
  return "/tmp/clutterseg-" + std::to_string(getuid());
}

InstanceLock::InstanceLock(const std::string& dir, const std::string& camera_name)
    : path_((std::filesystem::path(dir) / (Sanitise(camera_name) + ".lock")).string()) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    throw std::runtime_error("cannot create the lock directory " + dir + ": " + ec.message());
  }
  fd_ = open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
  if (fd_ < 0) {
    throw std::runtime_error("cannot open the lock file " + path_ + ": " + Errno(errno));
  }
  if (flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    std::string holder;
    // The holder writes its pid just after it took the lock, over what an earlier holder of
    // the file left: give it a moment, and take only the pid of a process that is alive.
    for (int i = 0; err == EWOULDBLOCK && holder.empty() && i < 50; ++i) {
      if (i > 0) std::this_thread::sleep_for(std::chrono::milliseconds(10));
      holder = ReadHolder(fd_);
      if (!HolderAlive(holder)) holder.clear();
    }
    close(fd_);
    fd_ = -1;
    if (err != EWOULDBLOCK) {
      throw std::runtime_error("cannot lock " + path_ + ": " + Errno(err));
    }
    const std::string pid = holder.substr(0, holder.find(' '));
    const std::string host =
        holder.find(' ') == std::string::npos ? std::string() : holder.substr(holder.find(' ') + 1);
    throw InstanceLockHeld("another clutterseg (pid " + (pid.empty() ? "unknown" : pid) +
                           (host.empty() ? "" : " on " + host) + ") already runs camera '" +
                           camera_name + "' on this host: it holds the lock " + path_);
  }
  const ProcessIdentity& me = ThisProcess();
  const std::string line = std::to_string(me.pid) + " " + me.hostname + "\n";
  // Only for the message of a second daemon: a failure to write costs nothing but the pid.
  // Written over the old line, then cut to length, so that a reader never finds it empty.
  if (pwrite(fd_, line.data(), line.size(), 0) == static_cast<ssize_t>(line.size())) {
    [[maybe_unused]] const int rc = ftruncate(fd_, static_cast<off_t>(line.size()));
  }
}

InstanceLock::~InstanceLock() {
  if (fd_ >= 0) close(fd_);  // releases the lock
}

}  // namespace clutterseg::daemon
