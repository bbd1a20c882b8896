// clutterseg._core: the segmenter, the PCD reader and writer and the evaluation for Python.
// numpy arrays in, plain Python values and numpy arrays out. The Python-facing documentation
// is the docstrings below (help(clutterseg.Segmenter)) and docs/python.md.
//
// Errors: every problem with an argument raises a Python exception that names the argument
// (TypeError for a wrong dtype or type, ValueError for a wrong shape or value, KeyError for an
// unknown parameter key, OSError-like RuntimeError for files). Nothing here aborts on input.

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "clutterseg/config/key_table.h"
#include "clutterseg/config/segmenter_keys.h"
#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/frame_limits.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/eval/metrics.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/pipeline/segmenter.h"
#include "clutterseg/pipeline/stage_times.h"
#include "clutterseg/version.h"

namespace py = pybind11;

namespace clutterseg::python {
namespace {

static_assert(sizeof(core::Vec3f) == 3 * sizeof(float), "Vec3f must be three packed floats");

// ---- argument checks ------------------------------------------------------------------------

std::string ShapeString(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) {
    s += std::to_string(a.shape(i));
    s += (a.ndim() == 1 || i + 1 < a.ndim()) ? (i + 1 < a.ndim() ? ", " : ",") : "";
  }
  return s + ")";
}

std::string DtypeString(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

// `obj` as a numpy array of exactly dtype T (no conversion: a float64 cloud is refused, not
// silently rounded). Any strides are accepted; the reads below follow them.
template <typename T>
py::array RequireArray(const py::handle& obj, const char* name, const char* expected_dtype) {
  if (!py::isinstance<py::array>(obj)) {
    throw py::type_error(std::string(name) + " must be a numpy array of " + expected_dtype +
                         ", got " + py::str(py::type::of(obj)).cast<std::string>());
  }
  py::array a = py::reinterpret_borrow<py::array>(obj);
  if (!a.dtype().is(py::dtype::of<T>())) {
    throw py::type_error(std::string(name) + " must have dtype " + expected_dtype + ", got " +
                         DtypeString(a) + " (convert with .astype(numpy." + expected_dtype + "))");
  }
  return a;
}

// The leading shape of a (..., 3) array with one or two leading dimensions: (N,) or (H, W).
std::vector<py::ssize_t> LeadingShape(const py::array& a, const char* name, const char* what) {
  if ((a.ndim() != 2 && a.ndim() != 3) || a.shape(a.ndim() - 1) != 3) {
    throw py::value_error(std::string(name) + " must have shape " + what + ", got " +
                          ShapeString(a));
  }
  return std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim() - 1);
}

std::string LeadingString(const std::vector<py::ssize_t>& shape) {
  std::string s = "(";
  for (size_t i = 0; i < shape.size(); ++i) {
    s += std::to_string(shape[i]) + (shape.size() == 1 ? "," : (i + 1 < shape.size() ? ", " : ""));
  }
  return s + ")";
}

// Element (i, c) of a (..., 3) array viewed as (n, 3), following its strides.
template <typename T>
class Rows3 {
 public:
  explicit Rows3(const py::array& a)
      : base_(static_cast<const char*>(a.data())),
        contiguous_(a.flags() & py::array::c_style),
        stride_c_(a.strides(a.ndim() - 1)),
        stride_u_(a.ndim() == 3 ? a.strides(1) : a.strides(0)),
        stride_v_(a.ndim() == 3 ? a.strides(0) : 0),
        width_(a.ndim() == 3 ? a.shape(1) : a.shape(0)) {}
  bool contiguous() const { return contiguous_; }
  const T* data() const { return reinterpret_cast<const T*>(base_); }
  T at(py::ssize_t k, int c) const {
    const py::ssize_t v = width_ > 0 ? k / width_ : 0, u = width_ > 0 ? k % width_ : 0;
    T value;
    std::memcpy(&value, base_ + v * stride_v_ + u * stride_u_ + c * stride_c_, sizeof(T));
    return value;
  }

 private:
  const char* base_;
  bool contiguous_;
  py::ssize_t stride_c_, stride_u_, stride_v_, width_;
};

// Intrinsics from None (the Kinect / Xtion defaults), an Intrinsics or a dict with fx, fy,
// cx, cy and optionally width, height (default: `default_width` x `default_height`).
core::CameraIntrinsics ToIntrinsics(const py::handle& obj, int default_width, int default_height) {
  if (obj.is_none()) return core::DefaultKinectIntrinsics();
  core::CameraIntrinsics k;
  if (py::isinstance<core::CameraIntrinsics>(obj)) {
    k = obj.cast<core::CameraIntrinsics>();
  } else if (py::isinstance<py::dict>(obj)) {
    const py::dict d = py::reinterpret_borrow<py::dict>(obj);
    for (const auto& item : d) {
      const std::string key = py::str(item.first).cast<std::string>();
      if (key != "fx" && key != "fy" && key != "cx" && key != "cy" && key != "width" &&
          key != "height") {
        throw py::key_error("intrinsics: unknown key '" + key +
                            "' (expected fx, fy, cx, cy in pixels, optionally width, height)");
      }
    }
    for (const char* key : {"fx", "fy", "cx", "cy"}) {
      if (!d.contains(key)) {
        throw py::key_error(std::string("intrinsics: missing '") + key +
                            "' (fx, fy, cx, cy in pixels are required)");
      }
    }
    try {
      k.fx = d["fx"].cast<double>();
      k.fy = d["fy"].cast<double>();
      k.cx = d["cx"].cast<double>();
      k.cy = d["cy"].cast<double>();
      k.width = d.contains("width") ? d["width"].cast<int>() : default_width;
      k.height = d.contains("height") ? d["height"].cast<int>() : default_height;
    } catch (const py::cast_error&) {
      throw py::type_error("intrinsics: fx, fy, cx, cy must be numbers, width, height integers");
    }
  } else {
    throw py::type_error("intrinsics must be None, a clutterseg.Intrinsics or a dict, got " +
                         py::str(py::type::of(obj)).cast<std::string>());
  }
  k.ValidateOrThrow("intrinsics");
  return k;
}

// Packs `n` colours (uint8 (..., 3), any strides) into 0xAARRGGBB, reusing `rgba`'s storage.
void PackColors(const py::array& colors, size_t n, std::vector<uint32_t>* rgba) {
  rgba->resize(n);
  const Rows3<uint8_t> c(colors);
  if (c.contiguous() && n > 0 && std::endian::native == std::endian::little) {
    // Four bytes r g b (next r) at a time, little-endian: byte-swapped and shifted they are
    // 0x00RRGGBB (the same value as PackRgba, a third of its time on a 640x480 frame).
    const uint8_t* rgb = c.data();
    uint32_t* out = rgba->data();
    for (size_t k = 0; k + 1 < n; ++k) {
      uint32_t w;
      std::memcpy(&w, rgb + 3 * k, sizeof(w));
      out[k] = 0xFF000000u | (__builtin_bswap32(w) >> 8);
    }
    out[n - 1] = core::PackRgba(core::Rgb8{rgb[3 * n - 3], rgb[3 * n - 2], rgb[3 * n - 1]});
    return;
  }
  for (size_t k = 0; k < n; ++k) {
    const auto i = static_cast<py::ssize_t>(k);
    (*rgba)[k] = core::PackRgba(core::Rgb8{c.at(i, 0), c.at(i, 1), c.at(i, 2)});
  }
}

// Copies `points` (float32 (H, W, 3) or (N, 3)) and `colors` (uint8, same leading shape, or
// None) into `cloud`, reusing its storage. Call without the GIL only while the arrays are
// referenced.
void FillCloud(const py::array& points, const std::optional<py::array>& colors,
               core::PointCloud* cloud) {
  const bool organized = points.ndim() == 3;
  cloud->width = static_cast<int>(organized ? points.shape(1) : points.shape(0));
  cloud->height = static_cast<int>(organized ? points.shape(0) : 1);
  const size_t n = static_cast<size_t>(cloud->width) * static_cast<size_t>(cloud->height);
  cloud->xyz.resize(n);
  const Rows3<float> p(points);
  if (p.contiguous()) {
    std::memcpy(static_cast<void*>(cloud->xyz.data()), p.data(), n * sizeof(core::Vec3f));
  } else {
    for (size_t k = 0; k < n; ++k) {
      const auto i = static_cast<py::ssize_t>(k);
      cloud->xyz[k] = core::Vec3f{p.at(i, 0), p.at(i, 1), p.at(i, 2)};
    }
  }
  cloud->label.clear();
  if (colors) {
    PackColors(*colors, n, &cloud->rgba);
  } else {
    cloud->rgba.clear();
  }
}

// What the segmenter reads: C-contiguous float32 points are viewed where they are (no copy);
// other strides are copied into `cloud` (reused), as colours always are (packed into rgba).
// Call without the GIL only while the arrays are referenced.
core::PointCloudView ViewOrFill(const py::array& points, const std::optional<py::array>& colors,
                                core::PointCloud* cloud) {
  const Rows3<float> p(points);
  const bool viewable =
      p.contiguous() && reinterpret_cast<uintptr_t>(p.data()) % alignof(core::Vec3f) == 0;
  if (!viewable) {
    FillCloud(points, colors, cloud);
    return core::PointCloudView(*cloud);
  }
  core::PointCloudView view;
  view.width = static_cast<int>(points.ndim() == 3 ? points.shape(1) : points.shape(0));
  view.height = static_cast<int>(points.ndim() == 3 ? points.shape(0) : 1);
  const size_t n = static_cast<size_t>(view.width) * static_cast<size_t>(view.height);
  view.xyz = std::span<const core::Vec3f>(reinterpret_cast<const core::Vec3f*>(p.data()), n);
  if (colors) {
    PackColors(*colors, n, &cloud->rgba);
    view.rgba = cloud->rgba;
  }
  return view;  // `cloud`'s points are left as they are: not read
}

// Checks points (and colours) for a segment() or write_pcd() call.
void CheckCloudArrays(const py::handle& points_obj, const py::handle& colors_obj, py::array* points,
                      std::optional<py::array>* colors) {
  *points = RequireArray<float>(points_obj, "points", "float32");
  const std::vector<py::ssize_t> lead =
      LeadingShape(*points, "points", "(H, W, 3) (organized) or (N, 3) (unorganized)");
  const core::FrameLimits limits;
  const auto problem =
      points->ndim() == 3
          ? limits.CheckImage(points->shape(1), points->shape(0), sizeof(core::Vec3f))
          : limits.CheckPoints(static_cast<uint64_t>(points->shape(0)), sizeof(core::Vec3f));
  if (problem) throw py::value_error("points: " + *problem);
  if (colors_obj.is_none()) {
    colors->reset();
    return;
  }
  *colors = RequireArray<uint8_t>(colors_obj, "colors", "uint8");
  if ((*colors)->ndim() != points->ndim() || (*colors)->shape((*colors)->ndim() - 1) != 3 ||
      !std::equal(lead.begin(), lead.end(), (*colors)->shape())) {
    throw py::value_error("colors must have shape " + LeadingString(lead) + " + (3,) like points " +
                          ShapeString(*points) + ", got " + ShapeString(**colors));
  }
}

// A numpy array that owns `data` (moved in, no copy), with `shape`.
template <typename T>
py::array OwningArray(std::vector<T>&& data, std::vector<py::ssize_t> shape) {
  auto* owned = new std::vector<T>(std::move(data));
  py::capsule free_when_done(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(std::move(shape), owned->data(), free_when_done);
}

py::array Vec3(const core::Vec3f& v) {
  py::array_t<double> a(3);
  auto m = a.mutable_unchecked<1>();
  m(0) = v.x;
  m(1) = v.y;
  m(2) = v.z;
  return a;
}

// Raises FileNotFoundError naming `what` when `path` is not a readable file.
void RequireFile(const std::string& path, const char* what) {
  if (::access(path.c_str(), R_OK) != 0) {
    const int err = errno;
    PyErr_SetObject(
        err == ENOENT ? PyExc_FileNotFoundError : PyExc_OSError,
        py::str(std::string(what) + ": cannot read '" + path + "': " + std::strerror(err)).ptr());
    throw py::error_already_set();
  }
}

// A Vec3f field of `t` as a numpy float64 (3,), for the bindings' properties.
template <typename T, core::Vec3f T::*kField>
py::array VecField(const T& t) {
  return Vec3(t.*kField);
}

// ---- the segmentation result ----------------------------------------------------------------

/// What Segmenter.segment returns (a snapshot; the next call does not change it): the
/// segmenter's result with its labels handed over to a numpy array.
struct Result {
  py::array labels;
  py::dict times;
  pipeline::SegmentationResult r;  // without its labels
};

// Takes what the segmenter produced out of `r` (the label buffer is handed over, no copy; the
// segmenter grows a new one on its next call; the rest is small and copied). Runs under the
// segmenter's mutex, without the GIL: `r` is the segmenter's and the next frame overwrites it.
pipeline::SegmentationResult TakeResult(pipeline::SegmentationResult* r) {
  std::vector<uint32_t> labels = std::move(r->labels.data);
  r->labels.data.clear();
  pipeline::SegmentationResult out = *r;
  out.labels.data = std::move(labels);
  return out;
}

// The Python result of a taken result; needs the GIL.
Result ToResult(pipeline::SegmentationResult&& r, std::vector<py::ssize_t> label_shape) {
  Result out;
  out.labels = OwningArray(std::move(r.labels.data), std::move(label_shape));
  for (size_t i = 0; i < pipeline::kNumStages; ++i) {
    out.times[py::str(std::string(pipeline::StageTable()[i].name))] = r.times.ms[i];
  }
  out.times["total"] = r.times.total_ms;
  out.r = std::move(r);
  return out;
}

// ---- the segmenter --------------------------------------------------------------------------

// A Python value as the text the key table parses.
std::string ValueText(const std::string& key, const py::handle& value) {
  if (py::isinstance<py::bool_>(value)) return value.cast<bool>() ? "true" : "false";
  if (py::isinstance<py::int_>(value)) return py::str(value).cast<std::string>();
  if (py::isinstance<py::float_>(value)) return py::repr(value).cast<std::string>();
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  // numpy scalars and other numbers
  if (py::hasattr(value, "item")) return ValueText(key, value.attr("item")());
  throw py::type_error("segmenter key '" + key + "' takes a bool, int, float or str, got " +
                       py::str(py::type::of(value)).cast<std::string>());
}

// Flattens {"supervoxel": {"seed_resolution_m": 0.02}} and "supervoxel.seed_resolution_m"
// into (dotted key, value) pairs.
void Flatten(const std::string& prefix, const py::dict& d,
             std::vector<std::pair<std::string, py::object>>* out) {
  for (const auto& item : d) {
    if (!py::isinstance<py::str>(item.first)) {
      throw py::type_error("segmenter keys must be strings, got " +
                           py::repr(item.first).cast<std::string>());
    }
    std::string key = prefix + item.first.cast<std::string>();
    if (key.rfind("segmenter.", 0) == 0) key = key.substr(10);
    if (py::isinstance<py::dict>(item.second)) {
      Flatten(key + ".", py::reinterpret_borrow<py::dict>(item.second), out);
    } else {
      out->emplace_back(key, py::reinterpret_borrow<py::object>(item.second));
    }
  }
}

class PySegmenter {
 public:
  PySegmenter(const py::object& config, int threads, const py::kwargs& overrides) {
    if (threads < 0 || threads > 256) {
      throw py::value_error("threads = " + std::to_string(threads) +
                            " is invalid: expected 0 (all cores) .. 256");
    }
    if (!config.is_none()) {
      const std::string path = py::str(config).cast<std::string>();
      RequireFile(path, "config");
      config::LoadSegmenterParams(path, &params_);  // ConfigError -> ValueError
    }
    std::vector<std::pair<std::string, py::object>> flat;
    Flatten("", overrides, &flat);
    const auto& table = config::SegmenterKeyTable();
    for (const auto& [key, value] : flat) {
      const std::string full = "segmenter." + key;
      const auto& paths = table.paths();
      if (std::find(paths.begin(), paths.end(), full) == paths.end()) {
        try {
          table.Set(full, "", "Segmenter", &params_);
        } catch (const config::ConfigError& e) {
          throw py::key_error(e.what());
        }
      }
      table.Set(full, ValueText(key, value), "Segmenter", &params_);
    }
    params_.ValidateOrThrow();  // std::invalid_argument naming the key -> ValueError
    if (threads != 1) pool_ = std::make_unique<core::ThreadPool>(threads);
    segmenter_ = std::make_unique<pipeline::Segmenter>(params_, pool_.get());
  }

  Result Segment(const py::object& points_obj, const py::object& colors_obj,
                 const py::object& intrinsics_obj) {
    py::array points;
    std::optional<py::array> colors;
    CheckCloudArrays(points_obj, colors_obj, &points, &colors);
    std::vector<py::ssize_t> lead(points.shape(), points.shape() + points.ndim() - 1);
    const bool organized = points.ndim() == 3 && points.shape(0) > 1;
    const core::CameraIntrinsics given =
        ToIntrinsics(intrinsics_obj, organized ? static_cast<int>(points.shape(1)) : 640,
                     organized ? static_cast<int>(points.shape(0)) : 480);
    pipeline::SegmentationResult taken;
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> lock(mutex_);
      const core::PointCloudView view = ViewOrFill(points, colors, &cloud_);
      segmenter_->Process(view, core::IntrinsicsForCloud(given, view), &result_);
      if (pool_) pool_->Rest();
      taken = TakeResult(&result_);
    }
    return ToResult(std::move(taken), std::move(lead));
  }

  Result SegmentDepth(const py::object& depth_obj, const py::object& intrinsics_obj,
                      const py::object& colors_obj) {
    const py::array depth = RequireArray<uint16_t>(depth_obj, "depth_mm", "uint16");
    if (depth.ndim() != 2) {
      throw py::value_error("depth_mm must have shape (H, W), got " + ShapeString(depth));
    }
    const int h = static_cast<int>(depth.shape(0)), w = static_cast<int>(depth.shape(1));
    if (const auto problem = core::FrameLimits{}.CheckImage(w, h, sizeof(uint16_t))) {
      throw py::value_error("depth_mm: " + *problem);
    }
    if (intrinsics_obj.is_none()) {
      throw py::value_error("intrinsics are required to back-project depth_mm");
    }
    const core::CameraIntrinsics k = ToIntrinsics(intrinsics_obj, w, h);
    if (k.width != w || k.height != h) {
      throw py::value_error("intrinsics are for " + std::to_string(k.width) + "x" +
                            std::to_string(k.height) + " px but depth_mm is " + std::to_string(w) +
                            "x" + std::to_string(h) + " (use Intrinsics.scaled(width, height))");
    }
    std::optional<py::array> colors;
    pipeline::SegmentationResult taken;
    if (!colors_obj.is_none()) {
      colors = RequireArray<uint8_t>(colors_obj, "colors", "uint8");
      if (colors->ndim() != 3 || colors->shape(0) != h || colors->shape(1) != w ||
          colors->shape(2) != 3) {
        throw py::value_error("colors must have shape (" + std::to_string(h) + ", " +
                              std::to_string(w) + ", 3) like depth_mm, got " +
                              ShapeString(*colors));
      }
    }
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> lock(mutex_);
      depth_.Reset(w, h);
      const auto d = depth.unchecked<uint16_t, 2>();
      for (int v = 0; v < h; ++v) {
        for (int u = 0; u < w; ++u) depth_.at(u, v) = d(v, u);
      }
      if (colors) {
        color_.Reset(w, h);
        const auto c = colors->unchecked<uint8_t, 3>();
        for (int v = 0; v < h; ++v) {
          for (int u = 0; u < w; ++u)
            color_.at(u, v) = core::Rgb8{c(v, u, 0), c(v, u, 1), c(v, u, 2)};
        }
      }
      segmenter_->ProcessDepth(depth_, colors ? &color_ : nullptr, k, &result_);
      if (pool_) pool_->Rest();
      taken = TakeResult(&result_);
    }
    return ToResult(std::move(taken), {h, w});
  }

  py::dict Params() const {
    py::dict d;
    const auto& table = config::SegmenterKeyTable();
    for (const std::string& path : table.paths()) {
      d[py::str(path.substr(10))] = py::str(table.Get(path, params_));
    }
    return d;
  }

  int threads() const { return pool_ ? pool_->num_threads() : 1; }

 private:
  pipeline::SegmenterParams params_;
  std::unique_ptr<core::ThreadPool> pool_;
  std::unique_ptr<pipeline::Segmenter> segmenter_;
  std::mutex mutex_;  // one frame at a time; guards the buffers below
  core::PointCloud cloud_;
  core::DepthImage depth_;
  core::ColorImage color_;
  pipeline::SegmentationResult result_;
};

// ---- PCD ------------------------------------------------------------------------------------

/// What read_pcd returns.
struct Cloud {
  py::array points;
  py::object colors;  // uint8 array or None
  py::object labels;  // uint32 array or None
  bool organized{false};
};

Cloud ReadPcd(const std::string& path) {
  RequireFile(path, "path");
  core::PointCloud c;
  {
    py::gil_scoped_release release;
    io::ReadPcd(path, io::ReadLimits{}, &c);
  }
  std::vector<py::ssize_t> lead;
  if (c.organized()) {
    lead = {c.height, c.width};
  } else {
    lead = {static_cast<py::ssize_t>(c.size())};
  }
  Cloud out;
  out.organized = c.organized();
  std::vector<py::ssize_t> shape3 = lead;
  shape3.push_back(3);
  std::vector<float> xyz(c.size() * 3);
  if (!c.xyz.empty()) std::memcpy(xyz.data(), c.xyz.data(), xyz.size() * sizeof(float));
  out.points = OwningArray(std::move(xyz), shape3);
  out.colors = py::none();
  out.labels = py::none();
  if (c.has_color()) {
    std::vector<uint8_t> rgb(c.size() * 3);
    for (size_t k = 0; k < c.size(); ++k) {
      const core::Rgb8 px = core::UnpackRgba(c.rgba[k]);
      rgb[3 * k] = px.r;
      rgb[3 * k + 1] = px.g;
      rgb[3 * k + 2] = px.b;
    }
    out.colors = OwningArray(std::move(rgb), shape3);
  }
  if (c.has_label()) out.labels = OwningArray(std::move(c.label), lead);
  return out;
}

io::PcdEncoding ParseEncoding(const std::string& e) {
  if (e == "binary") return io::PcdEncoding::kBinary;
  if (e == "binary_compressed") return io::PcdEncoding::kBinaryCompressed;
  if (e == "ascii") return io::PcdEncoding::kAscii;
  throw py::value_error("encoding = '" + e +
                        "' is invalid: expected 'binary', 'binary_compressed' or 'ascii'");
}

void WritePcd(const std::string& path, const py::object& points_obj, const py::object& colors_obj,
              const py::object& labels_obj, const std::string& encoding) {
  const io::PcdEncoding enc = ParseEncoding(encoding);
  py::array points;
  std::optional<py::array> colors;
  CheckCloudArrays(points_obj, colors_obj, &points, &colors);
  const std::vector<py::ssize_t> lead(points.shape(), points.shape() + points.ndim() - 1);
  std::optional<py::array> labels;
  if (!labels_obj.is_none()) {
    labels = RequireArray<uint32_t>(labels_obj, "labels", "uint32");
    if (labels->ndim() != static_cast<py::ssize_t>(lead.size()) ||
        !std::equal(lead.begin(), lead.end(), labels->shape())) {
      throw py::value_error("labels must have shape " + LeadingString(lead) + " like points " +
                            ShapeString(points) + ", got " + ShapeString(*labels));
    }
  }
  py::gil_scoped_release release;
  core::PointCloud c;
  FillCloud(points, colors, &c);
  if (labels) {
    c.label.resize(c.size());
    const auto* base = static_cast<const char*>(labels->data());
    const py::ssize_t s0 = labels->strides(0), s1 = labels->ndim() == 2 ? labels->strides(1) : 0;
    for (int v = 0; v < c.height; ++v) {
      for (int u = 0; u < c.width; ++u) {
        const char* p = labels->ndim() == 2 ? base + v * s0 + u * s1 : base + u * s0;
        std::memcpy(&c.label[static_cast<size_t>(v) * c.width + u], p, sizeof(uint32_t));
      }
    }
  }
  io::WritePcd(path, c, enc);
}

// ---- evaluation -----------------------------------------------------------------------------

// An integer label array as uint32 (a copy only when its dtype or layout differs).
py::array_t<uint32_t> LabelArray(const py::handle& obj, const char* name) {
  if (!py::isinstance<py::array>(obj)) {
    throw py::type_error(std::string(name) + " must be a numpy array of integers, got " +
                         py::str(py::type::of(obj)).cast<std::string>());
  }
  py::array a = py::reinterpret_borrow<py::array>(obj);
  const char kind = a.dtype().kind();
  if (kind != 'u' && kind != 'i') {
    throw py::type_error(std::string(name) + " must have an integer dtype, got " + DtypeString(a));
  }
  if (kind == 'i' && a.size() > 0 && a.attr("min")().cast<int64_t>() < 0) {
    throw py::value_error(std::string(name) + " holds negative labels");
  }
  if (kind == 'u' && a.itemsize() > 4 && a.size() > 0 &&
      a.attr("max")().cast<uint64_t>() > UINT32_MAX) {
    throw py::value_error(std::string(name) + " holds labels above 2^32 - 1");
  }
  return py::array_t<uint32_t, py::array::c_style | py::array::forcecast>::ensure(a);
}

eval::EvalParams MakeEvalParams(const std::string& convention,
                                const std::vector<uint32_t>& ocid_background,
                                int coverage_percent) {
  eval::EvalParams p;
  p.gt_convention = eval::ParseGtConvention(convention);
  p.ocid_background_labels = ocid_background;
  p.min_coverage_percent = coverage_percent;
  p.ValidateOrThrow();
  return p;
}

eval::FrameMetrics Evaluate(const py::object& gt_obj, const py::object& labels_obj,
                            const py::object& points_obj, const std::string& convention,
                            const std::vector<uint32_t>& ocid_background, int coverage_percent) {
  const eval::EvalParams params = MakeEvalParams(convention, ocid_background, coverage_percent);
  const py::array_t<uint32_t> gt = LabelArray(gt_obj, "gt_labels");
  const py::array_t<uint32_t> pred = LabelArray(labels_obj, "labels");
  const std::vector<py::ssize_t> gshape(gt.shape(), gt.shape() + gt.ndim());
  if (gt.ndim() != pred.ndim() || !std::equal(gshape.begin(), gshape.end(), pred.shape())) {
    throw py::value_error("labels " + ShapeString(pred) + " and gt_labels " + ShapeString(gt) +
                          " must have the same shape");
  }
  const auto n = static_cast<size_t>(gt.size());
  core::PointCloud cloud;
  if (points_obj.is_none()) {
    cloud.xyz.assign(n, core::Vec3f{0.f, 0.f, 1.f});  // every point valid
  } else {
    std::optional<py::array> no_colors;
    py::array points;
    CheckCloudArrays(points_obj, py::none(), &points, &no_colors);
    const auto np = static_cast<size_t>(points.size() / 3);
    if (np != n) {
      throw py::value_error("points " + ShapeString(points) + " must hold one point per label (" +
                            std::to_string(n) + ")");
    }
    FillCloud(points, std::nullopt, &cloud);
  }
  eval::FrameMetrics m;
  py::gil_scoped_release release;
  eval::FrameEvaluator evaluator(params);
  evaluator.Evaluate(cloud.xyz, std::span<const uint32_t>(gt.data(), n),
                     std::span<const uint32_t>(pred.data(), n), &m);
  return m;
}

py::array MapGtLabels(const py::object& gt_obj, const std::string& convention,
                      const std::vector<uint32_t>& ocid_background) {
  const eval::EvalParams params = MakeEvalParams(convention, ocid_background, 10);
  const py::array_t<uint32_t> gt = LabelArray(gt_obj, "gt_labels");
  py::array_t<uint32_t> out(std::vector<py::ssize_t>(gt.shape(), gt.shape() + gt.ndim()));
  const uint32_t* in = gt.data();
  uint32_t* o = out.mutable_data();
  for (py::ssize_t k = 0; k < gt.size(); ++k) o[k] = eval::MapGroundTruthLabel(in[k], params);
  return out;
}

}  // namespace
}  // namespace clutterseg::python

namespace py_cs = clutterseg::python;
using clutterseg::core::CameraIntrinsics;
using clutterseg::eval::FrameMetrics;
using clutterseg::eval::ObjectScore;
using clutterseg::pipeline::Object;
using clutterseg::pipeline::Plane;

namespace {

// Three unit vectors as the rows of a numpy float64 (3, 3) array.
py::array_t<double> Axes(const clutterseg::core::Vec3f (&axes)[3]) {
  py::array_t<double> a({3, 3});
  auto w = a.mutable_unchecked<2>();
  for (int i = 0; i < 3; ++i) {
    w(i, 0) = axes[i].x;
    w(i, 1) = axes[i].y;
    w(i, 2) = axes[i].z;
  }
  return a;
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() =
      "The compiled part of clutterseg: segmentation of RGB-D frames into objects and support "
      "planes (Segmenter), PCD files (read_pcd, write_pcd) and the metrics of clutterseg-eval "
      "(evaluate). All geometry in metres in the camera frame (x right, y down, z forward). "
      "See docs/python.md.";
  m.attr("__version__") = clutterseg::kVersion;
  m.attr("GT_CONVENTIONS") = py::make_tuple("plain", "mosd-parts", "mosd-objects", "ocid");

  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const clutterseg::config::ConfigError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });

  py::class_<CameraIntrinsics>(m, "Intrinsics",
                               "Pinhole intrinsics of a depth camera, in pixels: pixel (u, v) at "
                               "depth z (metres) is the point ((u - cx) z / fx, (v - cy) z / fy, "
                               "z). Wherever intrinsics are taken, a dict {'fx', 'fy', 'cx', "
                               "'cy'[, 'width', 'height']} works too.")
      .def(py::init([](double fx, double fy, double cx, double cy, int width, int height) {
             CameraIntrinsics k{width, height, fx, fy, cx, cy};
             k.ValidateOrThrow("intrinsics");
             return k;
           }),
           py::kw_only(), py::arg("fx") = 525.0, py::arg("fy") = 525.0, py::arg("cx") = 319.5,
           py::arg("cy") = 239.5, py::arg("width") = 640, py::arg("height") = 480,
           "fx, fy: focal lengths in pixels; cx, cy: principal point in pixels; width, height: "
           "image size in pixels. The defaults are those of the Kinect / Xtion data sets "
           "(640x480, fx = fy = 525). Raises ValueError naming the field when the field of view "
           "is not 10..150 degrees or the principal point is far outside the image.")
      .def_readonly("fx", &CameraIntrinsics::fx, "focal length along x, pixels")
      .def_readonly("fy", &CameraIntrinsics::fy, "focal length along y, pixels")
      .def_readonly("cx", &CameraIntrinsics::cx, "principal point x, pixels")
      .def_readonly("cy", &CameraIntrinsics::cy, "principal point y, pixels")
      .def_readonly("width", &CameraIntrinsics::width, "image width, pixels")
      .def_readonly("height", &CameraIntrinsics::height, "image height, pixels")
      .def("scaled", &CameraIntrinsics::Scaled, py::arg("width"), py::arg("height"),
           "The same sensor at another resolution (width x height pixels).")
      .def("__repr__", &CameraIntrinsics::ToString);

  py::class_<Plane>(m, "Plane",
                    "A plane n . p + d = 0 found in the frame (n unit, towards the camera), "
                    "camera frame, metres.")
      .def_readonly("id", &Plane::id, "plane id (Object.support_plane_id refers to it)")
      .def_property_readonly("normal", &py_cs::VecField<Plane, &Plane::normal>,
                             "unit normal n, numpy float64 (3,)")
      .def_readonly("d", &Plane::d, "offset d of n . p + d = 0, metres")
      .def_readonly("num_points", &Plane::num_points, "points assigned to the plane")
      .def_readonly("area_m2", &Plane::area_m2, "area of the surface assigned to it, m^2")
      .def_readonly("is_support", &Plane::is_support,
                    "table / floor / wall: its points are background (label 0)")
      .def("__repr__", [](const Plane& p) {
        std::ostringstream s;
        s << "Plane(id=" << p.id << ", num_points=" << p.num_points
          << ", is_support=" << (p.is_support ? "True" : "False") << ")";
        return s.str();
      });

  py::class_<Object>(m, "Object", "One segmented object. Geometry in metres, camera frame.")
      .def_readonly("id", &Object::id, "the object's value in the label image (>= 1)")
      .def_readonly("num_points", &Object::num_points, "points of the object")
      .def_property_readonly("centroid", &py_cs::VecField<Object, &Object::centroid>,
                             "mean of its points, metres, numpy float64 (3,)")
      .def_property_readonly("aabb_min", &py_cs::VecField<Object, &Object::aabb_min>,
                             "axis-aligned box, lower corner, metres (3,)")
      .def_property_readonly("aabb_max", &py_cs::VecField<Object, &Object::aabb_max>,
                             "axis-aligned box, upper corner, metres (3,)")
      .def_property_readonly("obb_center", &py_cs::VecField<Object, &Object::obb_center>,
                             "oriented box centre, metres (3,)")
      .def_property_readonly(
          "obb_axes", [](const Object& o) { return Axes(o.obb_axes); },
          "oriented box axes, one unit vector per row, largest variance first, "
          "right-handed, numpy float64 (3, 3)")
      .def_property_readonly("obb_extents", &py_cs::VecField<Object, &Object::obb_extents>,
                             "full side lengths along obb_axes, metres (3,)")
      .def_readonly("support_plane_id", &Object::support_plane_id,
                    "id of the Plane it stands on, -1 when none")
      .def_readonly("has_gravity_box", &Object::has_gravity_box,
                    "True when the object has a support plane and so a gravity-aligned box")
      .def_property_readonly("gbox_center", &py_cs::VecField<Object, &Object::gbox_center>,
                             "gravity-aligned box centre, metres (3,)")
      .def_property_readonly(
          "gbox_axes", [](const Object& o) { return Axes(o.gbox_axes); },
          "gravity-aligned box axes, one unit vector per row: the longer side of the minimum-area "
          "footprint, the shorter, and up (the support plane's normal), numpy float64 (3, 3)")
      .def_property_readonly("gbox_extents", &py_cs::VecField<Object, &Object::gbox_extents>,
                             "full side lengths along gbox_axes, metres (3,); the box stands on "
                             "the plane, [2] = height_m")
      .def_readonly("height_m", &Object::height_m,
                    "highest point above the support plane, metres (0 without one)")
      .def_readonly("bottom_m", &Object::bottom_m,
                    "lowest point above the support plane, metres (0 without one)")
      .def_property_readonly(
          "mean_color",
          [](const Object& o) {
            return py::make_tuple(o.mean_color.r, o.mean_color.g, o.mean_color.b);
          },
          "mean colour (r, g, b), 0..255")
      .def_readonly("confidence", &Object::confidence, "0..1")
      .def_property_readonly(
          "pixel_bbox",
          [](const Object& o) {
            return py::make_tuple(o.pixel_min_u, o.pixel_min_v, o.pixel_max_u, o.pixel_max_v);
          },
          "image bounding box (min_u, min_v, max_u, max_v), pixels, inclusive")
      .def("__repr__", [](const Object& o) {
        std::ostringstream s;
        s << "Object(id=" << o.id << ", num_points=" << o.num_points << ", centroid=("
          << o.centroid.x << ", " << o.centroid.y << ", " << o.centroid.z << ") m)";
        return s.str();
      });

  py::class_<py_cs::Result>(m, "SegmentationResult",
                            "The result of one Segmenter call; it is not changed by later calls.")
      .def_readonly("labels", &py_cs::Result::labels,
                    "numpy uint32 array of the input's leading shape ((H, W) or (N,)), the "
                    "input's point order: 0 = support plane / background / invalid point, "
                    "k >= 1 = objects[k - 1]")
      .def_property_readonly(
          "objects", [](const py_cs::Result& x) { return x.r.objects; }, "list of Object, by id")
      .def_property_readonly(
          "planes", [](const py_cs::Result& x) { return x.r.planes; }, "list of Plane")
      .def_readonly("times", &py_cs::Result::times,
                    "wall time of every stage and 'total', milliseconds (dict, stage order)")
      .def_property_readonly(
          "width", [](const py_cs::Result& x) { return x.r.width; },
          "points per row (N when unorganized)")
      .def_property_readonly(
          "height", [](const py_cs::Result& x) { return x.r.height; }, "rows (1 when unorganized)")
      .def_property_readonly("num_supervoxels",
                             [](const py_cs::Result& x) { return x.r.num_supervoxels; })
      .def_property_readonly(
          "num_valid_points", [](const py_cs::Result& x) { return x.r.num_valid_points; },
          "finite points within the depth range (segmenter.points)")
      .def_property_readonly(
          "num_support_first_points",
          [](const py_cs::Result& x) { return x.r.num_support_first_points; },
          "of those, the points the support-first step gave to a large plane")
      .def_property_readonly(
          "supervoxels_capped", [](const py_cs::Result& x) { return x.r.supervoxels_capped; },
          "more seeds than supervoxel.max_supervoxels (some left out)")
      .def_property_readonly(
          "objects_capped", [](const py_cs::Result& x) { return x.r.objects_capped; },
          "more objects than objects.max_objects (the smallest became background)")
      .def("__repr__", [](const py_cs::Result& x) {
        return "SegmentationResult(" + std::to_string(x.r.objects.size()) + " objects, " +
               std::to_string(x.r.planes.size()) + " planes, " + std::to_string(x.r.width) + "x" +
               std::to_string(x.r.height) + ")";
      });

  py::class_<py_cs::PySegmenter>(
      m, "Segmenter",
      "Segments RGB-D frames into objects and support planes with the method of "
      "docs/method.md: the same pipeline, parameters and defaults as clutterseg-segment and "
      "the daemon (same input, same labels, bit for bit).\n\n"
      "Thread-safety: one Segmenter per thread is safe and runs in parallel (the GIL is "
      "released while a frame is segmented). One Segmenter shared by several threads is safe "
      "too, but its calls are serialized by an internal mutex (one frame at a time).")
      .def(py::init<const py::object&, int, const py::kwargs&>(), py::arg("config") = py::none(),
           py::kw_only(), py::arg("threads") = 0,
           "Segmenter(config=None, *, threads=0, **overrides)\n\n"
           "config: path of a YAML configuration file (config/clutterseg.yaml, "
           "/etc/clutterseg/clutterseg.yaml); its 'segmenter:' section is read, other sections "
           "are ignored. None: the built-in defaults (those of config/clutterseg.yaml).\n"
           "threads: threads that work on one frame: 0 = all cores (as clutterseg-segment), 1 "
           "= the calling thread only (use 1 with one Segmenter per thread). The result does "
           "not depend on it.\n"
           "overrides: segmenter parameters over the file, as the configuration keys of "
           "docs/configuration.md under 'segmenter.': dotted, "
           "**{'supervoxel.seed_resolution_m': 0.02}, or nested, supervoxel={'seed_resolution_"
           "m': 0.02}. Units are in the key names (_m metres, _deg degrees, _px pixels, _m2 "
           "square metres). Segmenter.keys() lists them.\n\n"
           "Raises FileNotFoundError (config missing), KeyError (a key that does not exist, "
           "with the nearest one), ValueError (a value of the wrong type or out of range, "
           "naming the key and the valid range), TypeError (a value that is not a bool, int, "
           "float or str).")
      .def("segment", &py_cs::PySegmenter::Segment, py::arg("points"),
           py::arg("colors") = py::none(), py::arg("intrinsics") = py::none(),
           "segment(points, colors=None, intrinsics=None) -> SegmentationResult\n\n"
           "points: numpy float32, (H, W, 3) organized (row-major, pixel (u, v) at [v, u]) or "
           "(N, 3) unorganized; x, y, z in metres in the camera frame (x right, y down, z "
           "forward); NaN marks an invalid point. A C-contiguous array is read in place, "
           "without a copy (do not change it from another thread during the call); other "
           "strides are copied once.\n"
           "colors: numpy uint8 (H, W, 3) or (N, 3), r, g, b, the same leading shape as "
           "points; None: no colour (as a PCD without an rgb field).\n"
           "intrinsics: Intrinsics or dict (pixels) of the camera that took an organized "
           "cloud; None: fx = fy = 525, cx = 319.5, cy = 239.5 for 640x480, scaled to the "
           "cloud's size (as clutterseg-segment). Not used for an unorganized cloud.\n\n"
           "Returns a SegmentationResult whose labels have the leading shape of points. "
           "Raises TypeError (wrong dtype), ValueError (wrong shape, colours not matching, "
           "more than 4096x4096 points, bad intrinsics). The GIL is released meanwhile.")
      .def("segment_depth", &py_cs::PySegmenter::SegmentDepth, py::arg("depth_mm"),
           py::arg("intrinsics"), py::arg("colors") = py::none(),
           "segment_depth(depth_mm, intrinsics, colors=None) -> SegmentationResult\n\n"
           "depth_mm: numpy uint16 (H, W), depth in millimetres along z, 0 = invalid.\n"
           "intrinsics: Intrinsics or dict (pixels) of the depth camera; width and height "
           "must be W and H (a dict without them takes the image's).\n"
           "colors: numpy uint8 (H, W, 3) registered to the depth image, or None.\n\n"
           "Back-projects and segments in one pass: the same labels as segment() of the "
           "back-projected cloud. Labels have shape (H, W). The GIL is released meanwhile.")
      .def_property_readonly("params", &py_cs::PySegmenter::Params,
                             "every segmenter key (without 'segmenter.') and its value as text, "
                             "after the file and the overrides")
      .def_property_readonly("threads", &py_cs::PySegmenter::threads,
                             "threads working on one frame")
      .def_static(
          "keys",
          []() {
            std::vector<std::string> keys;
            for (const std::string& p : clutterseg::config::SegmenterKeyTable().paths()) {
              keys.push_back(p.substr(10));
            }
            return keys;
          },
          "Every segmenter parameter key, in documentation order (docs/configuration.md).");

  py::class_<py_cs::Cloud>(m, "Cloud", "A point cloud read from a PCD file.")
      .def_readonly("points", &py_cs::Cloud::points,
                    "numpy float32 (H, W, 3) when organized, else (N, 3); metres, NaN invalid")
      .def_readonly("colors", &py_cs::Cloud::colors,
                    "numpy uint8 of the same leading shape + (3,), r, g, b; None without colour")
      .def_readonly("labels", &py_cs::Cloud::labels,
                    "numpy uint32 of the leading shape; None without a label field")
      .def_readonly("organized", &py_cs::Cloud::organized, "HEIGHT > 1 in the file")
      .def("__repr__", [](const py_cs::Cloud& c) {
        return "Cloud(points=" + py::str(c.points.attr("shape")).cast<std::string>() +
               ", colors=" + (c.colors.is_none() ? "None" : "uint8") +
               ", labels=" + (c.labels.is_none() ? "None" : "uint32") + ")";
      });

  m.def("read_pcd", &py_cs::ReadPcd, py::arg("path"),
        "read_pcd(path) -> Cloud\n\n"
        "Reads a PCD file (v0.5-0.7; ascii, binary or binary_compressed; fields x y z, "
        "optional rgb / rgba and label). Raises FileNotFoundError, RuntimeError naming the "
        "file for a malformed or too large file. The GIL is released while reading.");
  m.def("write_pcd", &py_cs::WritePcd, py::arg("path"), py::arg("points"),
        py::arg("colors") = py::none(), py::arg("labels") = py::none(),
        py::arg("encoding") = "binary",
        "write_pcd(path, points, colors=None, labels=None, encoding='binary')\n\n"
        "Writes PCD v0.7 with fields x y z rgba label (PCL's PointXYZRGBL), as "
        "clutterseg-segment does. points: float32 (H, W, 3) (organized, kept) or (N, 3), "
        "metres; colors: uint8 (..., 3) or None; labels: uint32 of the leading shape or None "
        "(0); encoding: 'binary', 'binary_compressed' or 'ascii'. Raises RuntimeError naming "
        "the file when it cannot be written completely.");

  py::class_<ObjectScore>(m, "ObjectScore", "Scores of one ground-truth object.")
      .def_readonly("gt_id", &ObjectScore::gt_id, "object id after the convention mapping")
      .def_readonly("size", &ObjectScore::size, "its valid points")
      .def_readonly("best_segment", &ObjectScore::best_segment,
                    "label of the segment of largest IoU, 0 when none overlaps")
      .def_readonly("best_segment_size", &ObjectScore::best_segment_size)
      .def_readonly("intersection", &ObjectScore::intersection)
      .def_readonly("overlap", &ObjectScore::overlap, "IoU with the best segment")
      .def_readonly("tp", &ObjectScore::tp)
      .def_readonly("fp", &ObjectScore::fp)
      .def_readonly("fn", &ObjectScore::fn)
      .def_readonly("covering_segments", &ObjectScore::covering_segments)
      .def_readonly("over_segmented", &ObjectScore::over_segmented)
      .def_readonly("under_segmented", &ObjectScore::under_segmented);

  py::class_<FrameMetrics>(m, "Metrics",
                           "The metrics of one frame (METHOD.md section 7), as clutterseg-eval "
                           "computes them; ratios 0..1.")
      .def_readonly("num_points", &FrameMetrics::num_points)
      .def_readonly("num_valid_points", &FrameMetrics::num_valid_points,
                    "points with finite xyz (all when no points were given)")
      .def_readonly("num_gt_objects", &FrameMetrics::num_gt_objects)
      .def_readonly("num_segments", &FrameMetrics::num_segments)
      .def_readonly("scored", &FrameMetrics::scored, "the frame has ground-truth objects")
      .def_readonly("wov", &FrameMetrics::wov, "weighted overlap WOv")
      .def_readonly("tp", &FrameMetrics::tp, "mean over ground-truth objects of |g ∩ s| / |g|")
      .def_readonly("fp", &FrameMetrics::fp, "mean of |s \\ g| / |s|")
      .def_readonly("fn", &FrameMetrics::fn, "mean of |g \\ s| / |g|")
      .def_readonly("precision", &FrameMetrics::precision, "tp / (tp + fp)")
      .def_readonly("recall", &FrameMetrics::recall, "tp / (tp + fn)")
      .def_readonly("f1", &FrameMetrics::f1, "2 P R / (P + R)")
      .def_readonly("over_segmented", &FrameMetrics::over_segmented)
      .def_readonly("under_segmented", &FrameMetrics::under_segmented)
      .def_readonly("loss_merged", &FrameMetrics::loss_merged,
                    "the part of 1 - wov lost to objects in one segment")
      .def_readonly("loss_split", &FrameMetrics::loss_split,
                    "the part of 1 - wov lost to pieces of an object standing alone")
      .def_readonly("loss_boundary", &FrameMetrics::loss_boundary,
                    "the part of 1 - wov lost to borders between objects")
      .def_readonly("loss_background", &FrameMetrics::loss_background,
                    "the part of 1 - wov lost to borders with the background")
      .def_readonly("objects", &FrameMetrics::objects, "list of ObjectScore, by gt_id")
      .def("__repr__", [](const FrameMetrics& f) {
        char s[160];
        std::snprintf(s, sizeof(s), "Metrics(wov=%.4f, precision=%.4f, recall=%.4f, f1=%.4f)",
                      f.wov, f.precision, f.recall, f.f1);
        return std::string(s);
      });

  m.def("evaluate", &py_cs::Evaluate, py::arg("gt_labels"), py::arg("labels"),
        py::arg("points") = py::none(), py::kw_only(), py::arg("gt_convention") = "plain",
        py::arg("ocid_background") = std::vector<uint32_t>{0, 1, 2},
        py::arg("coverage_percent") = 10,
        "evaluate(gt_labels, labels, points=None, *, gt_convention='plain', "
        "ocid_background=(0, 1, 2), coverage_percent=10) -> Metrics\n\n"
        "Scores predicted labels against ground truth, point by point, exactly as "
        "clutterseg-eval GT PRED --gt-convention ... does.\n"
        "gt_labels: raw ground-truth labels, any non-negative integer array; labels: the "
        "prediction (SegmentationResult.labels), the same shape; points: float32 (..., 3) of "
        "the frame, metres: points with a NaN coordinate count on neither side (clutterseg-eval "
        "takes them from the ground-truth file); None: every point counts.\n"
        "gt_convention: how raw labels map to objects (GT_CONVENTIONS): 'plain' (0 background, "
        "every other label an object), 'mosd-parts' (0..9 background, every label >= 10 its "
        "own object), 'mosd-objects' (0..9 background, object = label // 10), 'ocid' (the "
        "labels of ocid_background are background); see map_gt_labels.\n"
        "coverage_percent: a segment covers an object when it holds at least this percentage "
        "of its points (over/under-segmentation counts), 1..100.");
  m.def("map_gt_labels", &py_cs::MapGtLabels, py::arg("gt_labels"),
        py::arg("gt_convention") = "plain",
        py::arg("ocid_background") = std::vector<uint32_t>{0, 1, 2},
        "map_gt_labels(gt_labels, gt_convention='plain', ocid_background=(0, 1, 2)) -> uint32 "
        "array\n\nThe object id of every raw ground-truth label under a convention (0 = "
        "background), as evaluate() scores them.");
}
