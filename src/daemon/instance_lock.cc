#include "clutterseg/daemon/instance_lock.h"

#include <fcntl.h>
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
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
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

bool UrlNeedsInstanceLock(const std::string& url) {
  for (const char* scheme : {"udpm://", "mpudpm://", "tcpq://"}) {
    if (url.rfind(scheme, 0) == 0) return true;
  }
  return false;
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
    // The holder writes its pid just after it took the lock: give it a moment to.
    for (int i = 0; err == EWOULDBLOCK && holder.empty() && i < 50; ++i) {
      if (i > 0) std::this_thread::sleep_for(std::chrono::milliseconds(10));
      holder = ReadHolder(fd_);
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
  if (ftruncate(fd_, 0) == 0) {
    [[maybe_unused]] const ssize_t n = pwrite(fd_, line.data(), line.size(), 0);
  }
}

InstanceLock::~InstanceLock() {
  if (fd_ >= 0) close(fd_);  // releases the lock
}

}  // namespace clutterseg::daemon
