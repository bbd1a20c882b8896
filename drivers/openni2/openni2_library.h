#pragma once

#include <string>

namespace clutterseg::drivers {

/// Which OpenNI2 device drivers a process loads. OpenNI2 loads every driver in the directory
/// `OpenNI2/Drivers` beside the libOpenNI2 it was loaded from, once per process.
enum class OpenNI2Drivers {
  /// The system's libOpenNI2 with all its drivers: cameras (PS1080, PSLink) and recordings.
  kAll,
  /// Only the OniFile driver, through the directory CLUTTERSEG_OPENNI2_RECORDINGS_DIR (links to
  /// the system's libOpenNI2 and libOniFile, made by the build). The camera drivers start USB
  /// threads even with no camera attached, and OpenNI::shutdown() waits 0.25-0.5 s for them;
  /// a replay needs none of that. Falls back to kAll when the directory is missing.
  kRecordingsOnly,
};

namespace internal {

/// Loads libOpenNI2 (dlopen) if no earlier call did; the first call decides the drivers for
/// the life of the process. Returns false with `error` set when the library or one of its
/// functions cannot be found. Thread-safe.
bool LoadOpenNI2Library(OpenNI2Drivers drivers, std::string* error);

/// The path libOpenNI2 was loaded from ("" before LoadOpenNI2Library succeeded).
std::string LoadedOpenNI2Library();

/// True when the loaded libOpenNI2 sees only the OniFile driver.
bool OpenNI2LoadedForRecordingsOnly();

}  // namespace internal
}  // namespace clutterseg::drivers
