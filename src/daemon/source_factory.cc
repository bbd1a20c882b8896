#include "clutterseg/daemon/source_factory.h"

#include <filesystem>
#include <optional>
#include <stdexcept>

#include "clutterseg/config/camera_info.h"
#include "clutterseg/core/text_and_color.h"
#include "clutterseg/daemon/daemon.h"
#include "clutterseg/daemon/log.h"
#include "clutterseg/io/png_io.h"

#ifdef CLUTTERSEG_HAVE_OPENNI2
#include "clutterseg/drivers/openni2/openni2_source.h"
#endif
#ifdef CLUTTERSEG_HAVE_REPLAY
#include "clutterseg/drivers/replay/depth_png_source.h"
#include "clutterseg/drivers/replay/pcd_directory_source.h"
#endif
#ifdef CLUTTERSEG_HAVE_SYNTHETIC_SOURCE
#include "clutterseg/drivers/replay/synthetic_source.h"
#endif

namespace clutterseg::daemon {
namespace {

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool HasPcdFiles(const std::filesystem::path& dir) {
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    if (core::HasExtension(entry.path().filename().string(), ".pcd")) return true;
  }
  return false;
}

[[noreturn, maybe_unused]] void NotBuilt(const std::string& source, const char* what) {
  throw std::invalid_argument("source '" + source + "': " + what +
                              " support is not built into "
                              "this binary");
}

// The intrinsics of camera.intrinsics_file (a ROS camera_info *.yaml / *.yml, else an
// intrinsics JSON), unset when it is "". @throws
// std::invalid_argument naming the key and the file when it cannot be read or is implausible.
std::optional<core::CameraIntrinsics> IntrinsicsOf(const SourceParams& camera) {
  if (camera.intrinsics_file.empty()) return std::nullopt;
  try {
    const std::filesystem::path ext = std::filesystem::path(camera.intrinsics_file).extension();
    core::CameraIntrinsics k = ext == ".yaml" || ext == ".yml"
                                   ? config::ReadCameraInfoYaml(camera.intrinsics_file)
                                   : io::ReadIntrinsicsJson(camera.intrinsics_file);
    k.ValidateOrThrow("camera.intrinsics_file");
    return k;
  } catch (const std::exception& e) {
    throw std::invalid_argument("camera.intrinsics_file = '" + camera.intrinsics_file +
                                "': " + e.what());
  }
}

}  // namespace

SourceKind ClassifySource(const std::string& source) {
  if (source == "device" || source.rfind("device:", 0) == 0) return SourceKind::kDevice;
  if (source == "synthetic") return SourceKind::kSynthetic;
  std::error_code ec;
  if (EndsWith(source, ".oni") || EndsWith(source, ".ONI")) {
    if (std::filesystem::is_directory(source, ec)) {
      throw SourceOpenError("source '" + source + "' is a directory, not an .oni recording");
    }
    return SourceKind::kOniFile;
  }
  if (std::filesystem::is_directory(source, ec)) {
    return HasPcdFiles(source) ? SourceKind::kPcdDirectory : SourceKind::kDepthPngDirectory;
  }
  if (std::filesystem::exists(source, ec)) {
    throw SourceOpenError("source '" + source +
                          "' is a file but not an .oni recording (expected device, "
                          "device:URI, FILE.oni, DIR or synthetic)");
  }
  throw SourceOpenError("source '" + source +
                        "' does not exist (expected device, device:URI, FILE.oni, DIR "
                        "or synthetic)");
}

bool IsFrameStream(const std::string& source) {
  try {
    const SourceKind kind = ClassifySource(source);
    return kind == SourceKind::kDevice || kind == SourceKind::kOniFile ||
           kind == SourceKind::kSynthetic;
  } catch (const std::exception&) {
    return false;
  }
}

std::unique_ptr<core::FrameSource> MakeSource(const DaemonConfig& config) {
  const std::string& source = config.source;
  const bool max_speed = config.capture.speed == Speed::kMax;
  const SourceParams& camera = config.camera;
  const std::optional<core::CameraIntrinsics> intrinsics = IntrinsicsOf(camera);
  switch (ClassifySource(source)) {
    case SourceKind::kDevice:
    case SourceKind::kOniFile: {
#ifdef CLUTTERSEG_HAVE_OPENNI2
      drivers::OpenNI2SourceOptions o;
      if (source.rfind("device:", 0) == 0) {
        o.uri = source.substr(7);
      } else if (source != "device") {
        o.uri = source;
      }
      o.serial = camera.serial;
      o.width = camera.width;
      o.height = camera.height;
      o.fps = camera.fps;
      o.color = camera.color;
      o.registration = camera.registration;
      o.intrinsics = intrinsics;
      o.replay_speed = max_speed ? -1.0 : 1.0;
      o.loop = config.capture.loop;
      o.camera_name = config.capture.camera_name;
      o.ValidateOrThrow();
      return std::make_unique<drivers::OpenNI2Source>(o);
#else
      NotBuilt(source, "OpenNI2 (device and .oni)");
#endif
    }
    case SourceKind::kPcdDirectory: {
#ifdef CLUTTERSEG_HAVE_REPLAY
      drivers::PcdDirectorySourceOptions o;
      o.path = source;
      if (intrinsics) {
        o.estimate_intrinsics = false;
        o.intrinsics = *intrinsics;
      }
      o.loop = config.capture.loop;
      o.camera_name = config.capture.camera_name;
      o.ValidateOrThrow();
      return std::make_unique<drivers::PcdDirectorySource>(o);
#else
      NotBuilt(source, "PCD directory");
#endif
    }
    case SourceKind::kDepthPngDirectory: {
#ifdef CLUTTERSEG_HAVE_REPLAY
      drivers::DepthPngSourceOptions o;
      o.directory = source;
      o.intrinsics_json = camera.intrinsics_file;
      o.depth_scale_to_mm = camera.depth_scale_mm;
      o.color = camera.color;
      o.loop = config.capture.loop;
      o.camera_name = config.capture.camera_name;
      o.ValidateOrThrow();
      return std::make_unique<drivers::DepthPngSource>(o);
#else
      NotBuilt(source, "depth PNG directory");
#endif
    }
    case SourceKind::kSynthetic: {
#ifdef CLUTTERSEG_HAVE_SYNTHETIC_SOURCE
      drivers::SyntheticSourceOptions o;
      o.loop = config.capture.loop;
      o.real_time = !max_speed;
      o.camera_name = config.capture.camera_name;
      o.ValidateOrThrow();
      return std::make_unique<drivers::SyntheticSource>(o);
#else
      NotBuilt(source, "synthetic scene");
#endif
    }
  }
  throw std::invalid_argument("source '" + source + "': unknown kind");
}

void InitializeSourceDrivers(const DaemonConfig& config) {
#ifdef CLUTTERSEG_HAVE_OPENNI2
  const SourceKind kind = ClassifySource(config.source);
  if (kind == SourceKind::kDevice || kind == SourceKind::kOniFile) {
    // A recording needs only the OniFile driver: without the camera drivers' USB threads the
    // daemon starts and stops faster (their shutdown alone takes 0.25-0.5 s).
    drivers::InitializeOpenNI2(kind == SourceKind::kOniFile
                                   ? drivers::OpenNI2Drivers::kRecordingsOnly
                                   : drivers::OpenNI2Drivers::kAll);
    Log(LogLevel::kDebug, "OpenNI2 loaded from " + drivers::DescribeOpenNI2());
  }
#else
  (void)config;
#endif
}

void ShutdownSourceDrivers() {
#ifdef CLUTTERSEG_HAVE_OPENNI2
  drivers::ShutdownOpenNI2();
#endif
}

}  // namespace clutterseg::daemon
