#pragma once

#include <stdexcept>
#include <string>

namespace clutterseg::daemon {

/// Another process on this host holds the lock of the same camera name.
class InstanceLockHeld : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The runtime directory of the per-camera locks when none is configured: $RUNTIME_DIRECTORY
/// (set by systemd for RuntimeDirectory=), else /run/clutterseg when /run is writable (root),
/// else $XDG_RUNTIME_DIR/clutterseg, else /tmp/clutterseg-UID. Thread-safety: reads the
/// environment.
std::string DefaultLockDir();

/// An advisory flock(2) on DIR/CAMERA.lock held for the life of the object (the kernel
/// releases it on any exit, a crash included, so a stale file is harmless). The file holds
/// the holder's pid and host for the message of the next one. Not copyable; movable is not
/// needed. Thread-safety: construct and destroy on one thread.
class InstanceLock {
 public:
  InstanceLock(const InstanceLock&) = delete;
  InstanceLock& operator=(const InstanceLock&) = delete;

  /// Creates `dir` (mode 0755, parents included) when missing and takes the lock of
  /// `camera_name` (sanitised: characters outside [A-Za-z0-9._-] become '_') without waiting.
  /// @throws InstanceLockHeld naming the camera name, the lock file and the holder's pid.
  /// @throws std::runtime_error naming the directory or file when it cannot be created or
  /// opened (e.g. not writable).
  InstanceLock(const std::string& dir, const std::string& camera_name);
  ~InstanceLock();

  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_{-1};
};

}  // namespace clutterseg::daemon
