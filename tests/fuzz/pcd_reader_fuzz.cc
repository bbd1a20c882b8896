// libFuzzer target for the PCD reader: any input either parses into a consistent cloud or
// throws std::runtime_error. The reusing overload is exercised with a cloud that persists
// across inputs, as the daemon's PCD directory source does.

#include <cstddef>
#include <cstdint>
#include <stdexcept>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/io/pcd.h"
#include "tests/fuzz/fuzz_check.h"

namespace {

void CheckCloud(const clutterseg::core::PointCloud& cloud) {
  CLUTTERSEG_FUZZ_CHECK(cloud.width >= 0 && cloud.height >= 0);
  CLUTTERSEG_FUZZ_CHECK(static_cast<size_t>(cloud.width) * static_cast<size_t>(cloud.height) ==
                        cloud.xyz.size());
  CLUTTERSEG_FUZZ_CHECK(cloud.rgba.empty() || cloud.rgba.size() == cloud.xyz.size());
  CLUTTERSEG_FUZZ_CHECK(cloud.label.empty() || cloud.label.size() == cloud.xyz.size());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // Small limits keep allocations bounded; the reader must enforce them before allocating.
  clutterseg::io::ReadLimits limits;
  limits.max_points = 1u << 20;
  limits.max_header_bytes = 4096;
  try {
    const clutterseg::core::PointCloud cloud =
        clutterseg::io::ReadPcdFromMemory(data, size, "fuzz.pcd", limits);
    CheckCloud(cloud);
  } catch (const std::runtime_error&) {
  }
  static clutterseg::core::PointCloud reused;
  try {
    clutterseg::io::ReadPcdFromMemory(data, size, "fuzz.pcd", limits, &reused);
    CheckCloud(reused);
  } catch (const std::runtime_error&) {
  }
  return 0;
}
