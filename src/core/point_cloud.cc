#include "core/point_cloud.h"

#include <sstream>
#include <stdexcept>

namespace clutterseg::core {

size_t PointCloud::CountValid() const {
  size_t n = 0;
  for (const Vec3f& p : xyz) n += IsValid(p) ? 1 : 0;
  return n;
}

void CameraIntrinsics::ValidateOrThrow() const {
  auto fail = [](const char* key, double value, const char* want) {
    std::ostringstream os;
    os << "camera intrinsics: " << key << " = " << value << " is invalid (" << want << ")";
    throw std::invalid_argument(os.str());
  };
  if (width <= 0 || width > 16384) fail("width", width, "expected 1..16384 px");
  if (height <= 0 || height > 16384) fail("height", height, "expected 1..16384 px");
  if (!(fx > 0.0 && fx < 1e6)) fail("fx", fx, "expected a positive focal length in px");
  if (!(fy > 0.0 && fy < 1e6)) fail("fy", fy, "expected a positive focal length in px");
  if (!std::isfinite(cx)) fail("cx", cx, "expected a finite principal point");
  if (!std::isfinite(cy)) fail("cy", cy, "expected a finite principal point");
}

CameraIntrinsics CameraIntrinsics::Scaled(int new_width, int new_height) const {
  CameraIntrinsics k = *this;
  const double sx = static_cast<double>(new_width) / width;
  const double sy = static_cast<double>(new_height) / height;
  k.width = new_width;
  k.height = new_height;
  k.fx = fx * sx;
  k.fy = fy * sy;
  k.cx = (cx + 0.5) * sx - 0.5;
  k.cy = (cy + 0.5) * sy - 0.5;
  return k;
}

std::string CameraIntrinsics::ToString() const {
  std::ostringstream os;
  os << width << "x" << height << " fx=" << fx << " fy=" << fy << " cx=" << cx << " cy=" << cy;
  return os.str();
}

void DepthToPointCloud(const DepthImage& depth, const CameraIntrinsics& k, const ColorImage* color,
                       PointCloud* cloud, float min_m, float max_m) {
  const int w = depth.width;
  const int h = depth.height;
  cloud->width = w;
  cloud->height = h;
  cloud->xyz.resize(depth.size());
  cloud->label.clear();
  const bool with_color = color != nullptr && color->width == w && color->height == h;
  if (with_color) {
    cloud->rgba.resize(depth.size());
  } else {
    cloud->rgba.clear();
  }
  const float ifx = static_cast<float>(1.0 / k.fx);
  const float ify = static_cast<float>(1.0 / k.fy);
  const float cx = static_cast<float>(k.cx);
  const float cy = static_cast<float>(k.cy);
  for (int v = 0; v < h; ++v) {
    const size_t row = static_cast<size_t>(v) * w;
    const float yf = (static_cast<float>(v) - cy) * ify;
    for (int u = 0; u < w; ++u) {
      const size_t i = row + u;
      const float z = depth.data[i] * 0.001f;
      Vec3f& p = cloud->xyz[i];
      if (depth.data[i] == 0 || z < min_m || z > max_m) {
        p = Vec3f{kInvalidDepth, kInvalidDepth, kInvalidDepth};
      } else {
        p = Vec3f{(static_cast<float>(u) - cx) * ifx * z, yf * z, z};
      }
      if (with_color) cloud->rgba[i] = PackRgba(color->data[i]);
    }
  }
}

}  // namespace clutterseg::core
