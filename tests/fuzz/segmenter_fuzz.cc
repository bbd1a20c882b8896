// libFuzzer target for the segmenter on arbitrary small depth frames. Input layout: bytes 0-1
// give the width (1..320), bytes 2-3 the height (1..240), byte 4 the focal length (a scale of
// the Kinect's), the rest are little-endian uint16 depths in millimetres, repeated cyclically
// to fill the image (no depth bytes: every pixel invalid). The result must be consistent:
// labels within 0..objects.size(), object ids 1..n in order, point counts matching the label
// image, every object field finite.

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/types.h"
#include "clutterseg/pipeline/segmenter.h"
#include "tests/fuzz/fuzz_check.h"

namespace {

bool Finite(const clutterseg::core::Vec3f& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace clutterseg;
  if (size < 5) return 0;
  const int width = 1 + (data[0] | (data[1] << 8)) % 320;
  const int height = 1 + (data[2] | (data[3] << 8)) % 240;
  const double focal_scale = 0.25 + data[4] / 64.0;  // 0.25 .. 4.2
  const uint8_t* depth_bytes = data + 5;
  const size_t num_depths = (size - 5) / 2;

  core::DepthImage depth(width, height, 0);
  if (num_depths > 0) {
    for (size_t i = 0; i < depth.data.size(); ++i) {
      const size_t k = i % num_depths;
      depth.data[i] = static_cast<uint16_t>(depth_bytes[2 * k] | (depth_bytes[2 * k + 1] << 8));
    }
  }
  core::CameraIntrinsics intrinsics = core::DefaultKinectIntrinsics().Scaled(width, height);
  intrinsics.fx *= focal_scale;
  intrinsics.fy *= focal_scale;
  core::PointCloud cloud;
  core::DepthToPointCloud(depth, intrinsics, nullptr, &cloud);

  pipeline::Segmenter segmenter(pipeline::SegmenterParams{});
  pipeline::SegmentationResult result;
  segmenter.Process(cloud, intrinsics, &result);

  CLUTTERSEG_FUZZ_CHECK(result.width == width && result.height == height);
  CLUTTERSEG_FUZZ_CHECK(result.labels.width == width && result.labels.height == height);
  CLUTTERSEG_FUZZ_CHECK(result.labels.data.size() == depth.data.size());
  const size_t num_objects = result.objects.size();
  std::vector<uint32_t> counts(num_objects + 1, 0);
  for (size_t i = 0; i < result.labels.data.size(); ++i) {
    const uint32_t label = result.labels.data[i];
    CLUTTERSEG_FUZZ_CHECK(label <= num_objects);
    ++counts[label];
    if (label != 0) CLUTTERSEG_FUZZ_CHECK(core::IsValid(cloud.xyz[i]));
  }
  for (size_t k = 0; k < num_objects; ++k) {
    const pipeline::Object& o = result.objects[k];
    CLUTTERSEG_FUZZ_CHECK(o.id == k + 1);
    CLUTTERSEG_FUZZ_CHECK(o.num_points == counts[k + 1]);
    CLUTTERSEG_FUZZ_CHECK(o.num_points > 0);
    CLUTTERSEG_FUZZ_CHECK(Finite(o.centroid) && Finite(o.aabb_min) && Finite(o.aabb_max));
    CLUTTERSEG_FUZZ_CHECK(Finite(o.obb_center) && Finite(o.obb_extents));
    CLUTTERSEG_FUZZ_CHECK(Finite(o.obb_axes[0]) && Finite(o.obb_axes[1]) && Finite(o.obb_axes[2]));
    CLUTTERSEG_FUZZ_CHECK(std::isfinite(o.confidence) && o.confidence >= 0.f &&
                          o.confidence <= 1.f);
    CLUTTERSEG_FUZZ_CHECK(o.pixel_min_u >= 0 && o.pixel_min_u <= o.pixel_max_u &&
                          o.pixel_max_u < width);
    CLUTTERSEG_FUZZ_CHECK(o.pixel_min_v >= 0 && o.pixel_min_v <= o.pixel_max_v &&
                          o.pixel_max_v < height);
  }
  for (const pipeline::Plane& p : result.planes) {
    CLUTTERSEG_FUZZ_CHECK(Finite(p.normal) && std::isfinite(p.d) && std::isfinite(p.area_m2));
  }
  return 0;
}
