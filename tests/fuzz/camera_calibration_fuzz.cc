// libFuzzer target for the camera calibration readers a user hands the daemon and the tools:
// the ROS camera_info YAML of camera.intrinsics_file (config::ReadCameraInfoYaml), the
// intrinsics JSON of depth-PNG directories (io::ReadIntrinsicsJson), and the extrinsics of
// camera.extrinsics_file (io::ReadExtrinsicsJson, config::ReadExtrinsicsYaml). All read a
// path, so the input goes through a memfd. Each either returns a calibration a camera can
// have (intrinsics that pass CameraIntrinsics::ValidateOrThrow; extrinsics with a finite
// pose within range, a unit quaternion and a parent frame: Extrinsics::Problem is empty) or
// throws std::runtime_error (config::ConfigError is one); any other exception, a crash or a
// sanitizer report is a finding.

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "clutterseg/config/camera_info.h"
#include "clutterseg/config/extrinsics.h"
#include "clutterseg/core/extrinsics.h"
#include "clutterseg/io/extrinsics_json.h"
#include "clutterseg/io/png_io.h"
#include "tests/fuzz/fuzz_check.h"
#include "tests/fuzz/memfd_input.h"

namespace {

template <typename Read>
void Check(const char* what, Read read) {
  clutterseg::core::CameraIntrinsics k;
  try {
    k = read();
  } catch (const std::runtime_error&) {
    return;  // refused, with a message
  }
  try {
    k.ValidateOrThrow();
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "%s returned intrinsics no camera has: %s\n", what, e.what());
    std::abort();
  }
}

template <typename Read>
void CheckExtrinsics(const char* what, Read read) {
  clutterseg::core::Extrinsics e;
  try {
    e = read();
  } catch (const std::runtime_error&) {
    return;  // refused, with a message
  }
  const std::string problem = e.Problem("translation", "rotation", "parent frame");
  if (!problem.empty()) {
    std::fprintf(stderr, "%s returned a pose no camera has: %s\n", what, problem.c_str());
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = clutterseg::fuzz::MemfdPath(data, size);
  Check("ReadCameraInfoYaml", [&] { return clutterseg::config::ReadCameraInfoYaml(path); });
  Check("ReadIntrinsicsJson", [&] { return clutterseg::io::ReadIntrinsicsJson(path); });
  CheckExtrinsics("ReadExtrinsicsJson", [&] { return clutterseg::io::ReadExtrinsicsJson(path); });
  CheckExtrinsics("ReadExtrinsicsYaml",
                  [&] { return clutterseg::config::ReadExtrinsicsYaml(path); });
  return 0;
}
