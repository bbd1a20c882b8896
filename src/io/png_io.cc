#include "clutterseg/io/png_io.h"

#include <libdeflate.h>
#include <png.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>
#include <sys/stat.h>

#include "clutterseg/core/assert.h"
#include "clutterseg/core/file_kind.h"
#include "clutterseg/io/internal/json_file.h"

namespace clutterseg::io {
namespace {

// Largest ancillary chunk (text, ICC profile) libpng may allocate: a compressed text chunk
// must not inflate into gigabytes.
constexpr png_alloc_size_t kMaxChunkBytes = 8u << 20;
// Deflate cannot expand by more than about 1032:1; a declared image larger than this factor
// times the file size is refused before its buffer is allocated.
constexpr size_t kMaxInflateRatio = 1100;

[[noreturn]] void Fail(const std::string& path, const std::string& what) {
  throw std::runtime_error(path + ": " + what);
}

// Carries libpng's error message out of its callbacks (which must not throw).
struct PngError {
  char message[256]{};
  bool too_large{false};  // the declared size exceeds the frame limits
};

void OnPngError(png_structp png, png_const_charp msg) {
  auto* err = static_cast<PngError*>(png_get_error_ptr(png));
  std::snprintf(err->message, sizeof err->message, "%s", msg);
  png_longjmp(png, 1);
}

void OnPngWarning(png_structp /*png*/, png_const_charp /*msg*/) {}

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

const char* ColorTypeName(int color_type) {
  switch (color_type) {
    case PNG_COLOR_TYPE_GRAY:
      return "grey";
    case PNG_COLOR_TYPE_GRAY_ALPHA:
      return "grey+alpha";
    case PNG_COLOR_TYPE_PALETTE:
      return "palette";
    case PNG_COLOR_TYPE_RGB:
      return "RGB";
    case PNG_COLOR_TYPE_RGB_ALPHA:
      return "RGBA";
    default:
      return "unknown colour type";
  }
}

enum class Want { kDepth16, kRgb8 };

struct ReadGuard {
  png_structp png{nullptr};
  png_infop info{nullptr};
  ~ReadGuard() {
    if (png != nullptr) png_destroy_read_struct(&png, info != nullptr ? &info : nullptr, nullptr);
  }
};

// Decodes a PNG into rows of big-endian grey16 (kDepth16) or RGB8 (kRgb8). Returns false with
// `err` filled on failure. Every object with a destructor lives from before setjmp, so the
// longjmp out of libpng skips none.
bool DecodePng(std::FILE* file, size_t file_size, Want want, const core::FrameLimits& limits,
               std::vector<uint8_t>* pixels, int* width_out, int* height_out, PngError* err) {
  ReadGuard g;
  std::vector<png_bytep> rows;
  g.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, err, OnPngError, OnPngWarning);
  if (g.png == nullptr) {
    std::snprintf(err->message, sizeof err->message, "cannot create a PNG reader");
    return false;
  }
  g.info = png_create_info_struct(g.png);
  if (g.info == nullptr) {
    std::snprintf(err->message, sizeof err->message, "cannot create a PNG reader");
    return false;
  }
  if (setjmp(png_jmpbuf(g.png))) return false;

  png_init_io(g.png, file);
  // libpng's own size limits are lifted to PNG's maximum so that the frame limits below
  // give the message; nothing is allocated for the image before they are checked.
  png_set_user_limits(g.png, 0x7fffffffu, 0x7fffffffu);
  png_set_chunk_malloc_max(g.png, kMaxChunkBytes);
  png_read_info(g.png, g.info);
  png_uint_32 width = 0;
  png_uint_32 height = 0;
  int bit_depth = 0;
  int color_type = 0;
  png_get_IHDR(g.png, g.info, &width, &height, &bit_depth, &color_type, nullptr, nullptr, nullptr);
  if (const std::optional<std::string> too_large =
          limits.CheckImage(width, height, want == Want::kDepth16 ? 2 : 3)) {
    std::snprintf(err->message, sizeof err->message, "declared size %s", too_large->c_str());
    err->too_large = true;
    return false;
  }
  const size_t raw_bytes = (png_get_rowbytes(g.png, g.info) + 1) * size_t{height};
  if (raw_bytes > file_size * kMaxInflateRatio) {
    std::snprintf(err->message, sizeof err->message,
                  "declares a %ux%u image, more than the file's %zu bytes can hold", width, height,
                  file_size);
    return false;
  }
  if (want == Want::kDepth16) {
    if (bit_depth != 16 || color_type != PNG_COLOR_TYPE_GRAY) {
      std::snprintf(err->message, sizeof err->message,
                    "expected a 16-bit single-channel grey depth PNG, got %d-bit %s", bit_depth,
                    ColorTypeName(color_type));
      return false;
    }
  } else {
    if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(g.png);
    if (color_type == PNG_COLOR_TYPE_GRAY && bit_depth < 8) png_set_expand_gray_1_2_4_to_8(g.png);
    if (bit_depth == 16) png_set_strip_16(g.png);
    if ((color_type & PNG_COLOR_MASK_ALPHA) != 0) png_set_strip_alpha(g.png);
    if (color_type == PNG_COLOR_TYPE_GRAY || color_type == PNG_COLOR_TYPE_GRAY_ALPHA) {
      png_set_gray_to_rgb(g.png);
    }
  }
  png_set_interlace_handling(g.png);
  png_read_update_info(g.png, g.info);
  const size_t row_bytes = png_get_rowbytes(g.png, g.info);
  const size_t want_bytes = size_t{width} * (want == Want::kDepth16 ? 2 : 3);
  if (row_bytes != want_bytes) {
    std::snprintf(err->message, sizeof err->message,
                  "unexpected row size %zu after conversion (expected %zu)", row_bytes, want_bytes);
    return false;
  }
  pixels->resize(row_bytes * height);
  rows.resize(height);
  for (png_uint_32 v = 0; v < height; ++v) rows[v] = pixels->data() + row_bytes * v;
  png_read_image(g.png, rows.data());
  png_read_end(g.png, nullptr);
  *width_out = static_cast<int>(width);
  *height_out = static_cast<int>(height);
  return true;
}

// Writing. PNG's container is a signature and three chunks (IHDR, one IDAT holding the zlib
// stream of the filtered rows, IEND), each with its CRC-32; libdeflate compresses the stream
// and computes the CRCs. On a 640x480 RGB frame its level 1 with the Sub filter writes in
// about a quarter of the time zlib's level 1 took (through libpng), and a smaller file.
constexpr uint8_t kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
constexpr int kPngColorGrey = 0;
constexpr int kPngColorRgb = 2;
constexpr uint8_t kPngFilterSub = 1;

void PutU32(uint32_t v, uint8_t* out) {
  out[0] = static_cast<uint8_t>(v >> 24);
  out[1] = static_cast<uint8_t>(v >> 16);
  out[2] = static_cast<uint8_t>(v >> 8);
  out[3] = static_cast<uint8_t>(v);
}

// Appends a chunk: length, type, data, CRC-32 of type and data.
void AppendChunk(const char type[4], const uint8_t* data, size_t size, std::vector<uint8_t>* out) {
  const size_t at = out->size();
  out->resize(at + 12 + size);
  uint8_t* p = out->data() + at;
  PutU32(static_cast<uint32_t>(size), p);
  std::memcpy(p + 4, type, 4);
  if (size > 0) std::memcpy(p + 8, data, size);
  PutU32(static_cast<uint32_t>(libdeflate_crc32(0, p + 4, size + 4)), p + 8 + size);
}

// The Sub filter of one row of `row_bytes` bytes with `bpp` bytes per pixel: each byte minus
// the byte of the pixel to its left; `out` gets the filter type and the filtered bytes.
void FilterSub(const uint8_t* row, size_t row_bytes, size_t bpp, uint8_t* out) {
  out[0] = kPngFilterSub;
  const size_t first = std::min(bpp, row_bytes);
  std::memcpy(out + 1, row, first);
  for (size_t i = first; i < row_bytes; ++i)
    out[1 + i] = static_cast<uint8_t>(row[i] - row[i - bpp]);
}

FilePtr OpenForRead(const std::string& path, size_t* size) {
  // A FIFO would block fopen() until a writer comes: refused before it is opened.
  if (core::IsNonRegularFile(path)) {
    Fail(path, "not a regular file (a FIFO, device or directory)");
  }
  FilePtr f(std::fopen(path.c_str(), "rb"));
  if (f == nullptr) Fail(path, std::string("cannot open: ") + std::strerror(errno));
  if (std::fseek(f.get(), 0, SEEK_END) != 0) Fail(path, "cannot seek (not a regular file?)");
  const long end = std::ftell(f.get());
  if (end < 0) Fail(path, "cannot determine the file size");
  if (end == 0) Fail(path, "empty file");
  std::rewind(f.get());
  *size = static_cast<size_t>(end);
  return f;
}

void ReadPngFile(const std::string& path, Want want, const core::FrameLimits& limits,
                 std::vector<uint8_t>* pixels, int* width, int* height) {
  size_t size = 0;
  FilePtr f = OpenForRead(path, &size);
  PngError err;
  if (!DecodePng(f.get(), size, want, limits, pixels, width, height, &err)) {
    if (err.too_large) throw core::FrameTooLargeError(path + ": " + err.message);
    Fail(path, err.message[0] != '\0' ? err.message : "cannot decode PNG");
  }
}

void CheckWritable(const std::string& path, int width, int height, uint64_t bytes_per_pixel,
                   const core::FrameLimits& limits) {
  if (width <= 0 || height <= 0) Fail(path, "cannot write an empty image");
  if (const std::optional<std::string> too_large =
          limits.CheckImage(width, height, bytes_per_pixel)) {
    throw core::FrameTooLargeError(path + ": cannot write an image: size " + *too_large);
  }
}

using Json = nlohmann::json;
using internal::FindNumber;
using internal::ParseJsonFile;

int ToDimension(const std::string& path, const char* key, double v) {
  if (!(v >= 1.0 && v <= 16384.0) || std::floor(v) != v) {
    Fail(path, std::string("key '") + key + "' = " + std::to_string(v) +
                   " is not an image size in 1..16384");
  }
  return static_cast<int>(v);
}

// Reads a 3x3 camera matrix given as 9 numbers (row- or column-major) or as 3 rows.
void ReadCameraMatrix(const std::string& path, const char* key, const Json& m,
                      core::CameraIntrinsics* k) {
  double a[9];
  bool nested = false;
  if (m.is_array() && m.size() == 9) {
    for (int i = 0; i < 9; ++i) {
      if (!m[i].is_number()) Fail(path, std::string("'") + key + "' has a non-number");
      a[i] = m[i].get<double>();
    }
  } else if (m.is_array() && m.size() == 3) {
    nested = true;
    for (int r = 0; r < 3; ++r) {
      const Json& row = m[r];
      if (!row.is_array() || row.size() != 3) {
        Fail(path, std::string("'") + key + "' must be 9 numbers or 3 rows of 3");
      }
      for (int c = 0; c < 3; ++c) {
        if (!row[c].is_number()) Fail(path, std::string("'") + key + "' has a non-number");
        a[3 * r + c] = row[c].get<double>();
      }
    }
  } else {
    Fail(path, std::string("'") + key + "' must be 9 numbers or 3 rows of 3");
  }
  // Row-major K = [fx 0 cx; 0 fy cy; 0 0 1]; the flat column-major form (Open3D's) has cx, cy
  // at indices 6 and 7.
  const bool row_major = a[3] == 0.0 && a[6] == 0.0 && a[7] == 0.0 && a[8] == 1.0;
  const bool col_major = !nested && a[1] == 0.0 && a[2] == 0.0 && a[5] == 0.0 && a[8] == 1.0;
  if (row_major) {
    k->fx = a[0];
    k->fy = a[4];
    k->cx = a[2];
    k->cy = a[5];
  } else if (col_major) {
    k->fx = a[0];
    k->fy = a[4];
    k->cx = a[6];
    k->cy = a[7];
  } else {
    Fail(path, std::string("'") + key + "' is not a pinhole camera matrix");
  }
}

}  // namespace

core::DepthImage ReadDepthPng(const std::string& path, double scale_to_mm,
                              const core::FrameLimits& limits) {
  if (!(scale_to_mm > 0.0 && std::isfinite(scale_to_mm))) {
    throw std::invalid_argument("scale_to_mm = " + std::to_string(scale_to_mm) +
                                " is invalid (expected a positive factor)");
  }
  std::vector<uint8_t> bytes;
  int width = 0;
  int height = 0;
  ReadPngFile(path, Want::kDepth16, limits, &bytes, &width, &height);
  core::DepthImage image(width, height);
  for (size_t i = 0; i < image.data.size(); ++i) {
    const uint32_t raw = (uint32_t{bytes[2 * i]} << 8) | bytes[2 * i + 1];
    if (scale_to_mm == 1.0) {
      image.data[i] = static_cast<uint16_t>(raw);
    } else {
      const double mm = std::round(raw * scale_to_mm);
      image.data[i] = static_cast<uint16_t>(mm > 65535.0 ? 65535.0 : mm);
    }
  }
  return image;
}

core::ColorImage ReadColorPng(const std::string& path, const core::FrameLimits& limits) {
  std::vector<uint8_t> bytes;
  int width = 0;
  int height = 0;
  ReadPngFile(path, Want::kRgb8, limits, &bytes, &width, &height);
  core::ColorImage image(width, height);
  for (size_t i = 0; i < image.data.size(); ++i) {
    image.data[i] = core::Rgb8{bytes[3 * i], bytes[3 * i + 1], bytes[3 * i + 2]};
  }
  return image;
}

PngWriter::PngWriter() : compressor_(libdeflate_alloc_compressor(1)) {
  if (compressor_ == nullptr) throw std::bad_alloc();
}

PngWriter::~PngWriter() { libdeflate_free_compressor(compressor_); }

void PngWriter::WriteColor(const std::string& path, const core::ColorImage& image,
                           const core::FrameLimits& limits) {
  CLUTTERSEG_DEMAND(image.data.size() == static_cast<size_t>(image.width) * image.height);
  CheckWritable(path, image.width, image.height, 3, limits);
  const auto width = static_cast<size_t>(image.width);
  const size_t row_bytes = width * 3;
  filtered_.resize((row_bytes + 1) * static_cast<size_t>(image.height));
  row_.resize(row_bytes);
  for (size_t v = 0; v < static_cast<size_t>(image.height); ++v) {
    const core::Rgb8* in = image.data.data() + v * width;
    for (size_t u = 0; u < width; ++u) {
      row_[3 * u] = in[u].r;
      row_[3 * u + 1] = in[u].g;
      row_[3 * u + 2] = in[u].b;
    }
    FilterSub(row_.data(), row_bytes, 3, filtered_.data() + v * (row_bytes + 1));
  }
  Finish(path, image.width, image.height, 8, kPngColorRgb);
}

void PngWriter::WriteDepth(const std::string& path, const core::DepthImage& image,
                           const core::FrameLimits& limits) {
  CLUTTERSEG_DEMAND(image.data.size() == static_cast<size_t>(image.width) * image.height);
  CheckWritable(path, image.width, image.height, 2, limits);
  const auto width = static_cast<size_t>(image.width);
  const size_t row_bytes = width * 2;
  filtered_.resize((row_bytes + 1) * static_cast<size_t>(image.height));
  row_.resize(row_bytes);
  for (size_t v = 0; v < static_cast<size_t>(image.height); ++v) {
    const uint16_t* in = image.data.data() + v * width;
    for (size_t u = 0; u < width; ++u) {  // big-endian, as PNG requires
      row_[2 * u] = static_cast<uint8_t>(in[u] >> 8);
      row_[2 * u + 1] = static_cast<uint8_t>(in[u] & 0xff);
    }
    FilterSub(row_.data(), row_bytes, 2, filtered_.data() + v * (row_bytes + 1));
  }
  Finish(path, image.width, image.height, 16, kPngColorGrey);
}

void PngWriter::Finish(const std::string& path, int width, int height, int bit_depth,
                       int color_type) {
  const size_t bound = libdeflate_zlib_compress_bound(compressor_, filtered_.size());
  stream_.resize(bound);
  const size_t stream_size = libdeflate_zlib_compress(compressor_, filtered_.data(),
                                                      filtered_.size(), stream_.data(), bound);
  if (stream_size == 0) Fail(path, "cannot write PNG: compression failed");
  uint8_t header[13];
  PutU32(static_cast<uint32_t>(width), header);
  PutU32(static_cast<uint32_t>(height), header + 4);
  header[8] = static_cast<uint8_t>(bit_depth);
  header[9] = static_cast<uint8_t>(color_type);
  header[10] = 0;  // compression method: deflate
  header[11] = 0;  // filter method 0 (a filter type per row)
  header[12] = 0;  // not interlaced
  file_.resize(sizeof kPngSignature);
  std::memcpy(file_.data(), kPngSignature, sizeof kPngSignature);
  AppendChunk("IHDR", header, sizeof header, &file_);
  AppendChunk("IDAT", stream_.data(), stream_size, &file_);
  AppendChunk("IEND", nullptr, 0, &file_);

  // A regular (or new) file is written under a temporary name beside it and renamed into place
  // once whole, so that a reader never finds a truncated PNG under `path` (a full disk leaves
  // nothing); a device such as /dev/null or /dev/full is written directly.
  struct stat st {};
  const bool direct = stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode);
  static std::atomic<uint64_t> temp_counter{0};
  const std::string target = direct ? path
                                    : path + ".tmp." + std::to_string(getpid()) + "." +
                                          std::to_string(temp_counter.fetch_add(1));
  FilePtr f(std::fopen(target.c_str(), direct ? "wb" : "wbx"));  // x: never an existing file
  if (f == nullptr) Fail(path, std::string("cannot open for writing: ") + std::strerror(errno));
  errno = 0;
  const bool written = std::fwrite(file_.data(), 1, file_.size(), f.get()) == file_.size();
  std::FILE* raw = f.release();
  const bool flushed = written && std::ferror(raw) == 0;
  if (std::fclose(raw) != 0 || !flushed) {
    const int err = errno != 0 ? errno : EIO;
    if (!direct) unlink(target.c_str());
    Fail(path, std::string("write failed: ") + std::strerror(err));
  }
  if (!direct && rename(target.c_str(), path.c_str()) != 0) {
    const int err = errno;
    unlink(target.c_str());
    Fail(path, std::string("cannot rename the written file into place: ") + std::strerror(err));
  }
}

void WriteColorPng(const std::string& path, const core::ColorImage& image,
                   const core::FrameLimits& limits) {
  PngWriter().WriteColor(path, image, limits);
}

void WriteDepthPng(const std::string& path, const core::DepthImage& image,
                   const core::FrameLimits& limits) {
  PngWriter().WriteDepth(path, image, limits);
}

core::CameraIntrinsics ReadIntrinsicsJson(const std::string& path) {
  const Json doc = internal::ReadJsonFile(path, "an intrinsics file");
  if (!doc.is_object()) Fail(path, "top level is not a JSON object");
  const Json* obj = &doc;
  if (const auto camera = doc.find("camera"); camera != doc.end()) {
    if (!camera->is_object()) Fail(path, "key 'camera' is not an object");
    obj = &*camera;
  }

  core::CameraIntrinsics k;
  const char* matrix_key = nullptr;
  for (const char* key : {"intrinsic_matrix", "K"}) {
    if (obj->contains(key)) {
      matrix_key = key;
      break;
    }
  }
  const std::optional<double> fx = FindNumber(path, *obj, {"fx"});
  const std::optional<double> fy = FindNumber(path, *obj, {"fy"});
  const std::optional<double> cx = FindNumber(path, *obj, {"cx", "x_offset", "ppx"});
  const std::optional<double> cy = FindNumber(path, *obj, {"cy", "y_offset", "ppy"});
  if (matrix_key != nullptr && !fx) {
    ReadCameraMatrix(path, matrix_key, obj->at(matrix_key), &k);
  } else {
    if (!fx) Fail(path, "missing key 'fx'");
    if (!fy) Fail(path, "missing key 'fy'");
    if (!cx) Fail(path, "missing key 'cx'");
    if (!cy) Fail(path, "missing key 'cy'");
    k.fx = *fx;
    k.fy = *fy;
    k.cx = *cx;
    k.cy = *cy;
  }
  if (const auto w = FindNumber(path, *obj, {"width", "img_width", "image_width"})) {
    k.width = ToDimension(path, "width", *w);
  }
  if (const auto h = FindNumber(path, *obj, {"height", "img_height", "image_height"})) {
    k.height = ToDimension(path, "height", *h);
  }
  try {
    k.ValidateOrThrow();
  } catch (const std::invalid_argument& e) {
    Fail(path, e.what());
  }
  return k;
}

core::PointCloud ReadDepthPngCloud(const std::string& depth_png,
                                   const core::CameraIntrinsics& intrinsics,
                                   const std::string& color_png, double scale_to_mm,
                                   const core::FrameLimits& limits) {
  const core::DepthImage depth = ReadDepthPng(depth_png, scale_to_mm, limits);
  if (depth.width != intrinsics.width || depth.height != intrinsics.height) {
    Fail(depth_png, "depth image is " + std::to_string(depth.width) + "x" +
                        std::to_string(depth.height) + " but the intrinsics are for " +
                        std::to_string(intrinsics.width) + "x" + std::to_string(intrinsics.height));
  }
  core::ColorImage color;
  if (!color_png.empty()) {
    color = ReadColorPng(color_png, limits);
    if (color.width != depth.width || color.height != depth.height) {
      Fail(color_png, "colour image is " + std::to_string(color.width) + "x" +
                          std::to_string(color.height) + " but the depth image " + depth_png +
                          " is " + std::to_string(depth.width) + "x" +
                          std::to_string(depth.height));
    }
  }
  core::PointCloud cloud;
  core::DepthToPointCloud(depth, intrinsics, color_png.empty() ? nullptr : &color, &cloud);
  return cloud;
}

}  // namespace clutterseg::io
