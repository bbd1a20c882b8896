#include "clutterseg/io/pcd.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <sys/stat.h>

#include "clutterseg/core/assert.h"
#include "clutterseg/io/lzf.h"

namespace clutterseg::io {
namespace {

// Closes a file descriptor (unless released by setting it to -1) when it goes out of scope.
struct FdCloser {
  int fd;
  ~FdCloser() {
    if (fd >= 0) ::close(fd);
  }
};

static_assert(std::endian::native == std::endian::little,
              "PCD binary data is little-endian; a big-endian host needs byte swapping");

// Largest COUNT accepted for one field; far beyond any real PCD (histograms use a few hundred).
constexpr uint64_t kMaxFieldCount = uint64_t{1} << 20;

// Decoding buffers up to this size are kept per thread for reuse.
constexpr uint64_t kMaxCachedScratchBytes = uint64_t{64} << 20;

enum class DataKind { kAscii, kBinary, kBinaryCompressed };

struct Field {
  std::string name;
  int size{0};        // bytes per element: 1, 2, 4 or 8
  char type{0};       // 'F', 'U' or 'I'
  uint64_t count{1};  // elements
  size_t offset{0};   // byte offset inside one packed point
  size_t bytes() const { return static_cast<size_t>(size) * count; }
};

struct Header {
  std::vector<Field> fields;
  size_t point_bytes{0};     // sum of field bytes
  size_t point_elements{0};  // sum of counts (values per ascii line)
  uint64_t width{0};
  uint64_t height{0};
  uint64_t points{0};
  DataKind data{DataKind::kAscii};
  size_t data_offset{0};  // first byte after the DATA line
  int lines{0};           // number of header lines, for ascii line numbers
  int x{-1}, y{-1}, z{-1}, color{-1}, label{-1};
};

[[noreturn]] void Fail(const std::string& name, const std::string& what) {
  throw std::runtime_error(name + ": " + what);
}

[[noreturn]] void FailTooLarge(const std::string& name, const std::string& what) {
  throw core::FrameTooLargeError(name + ": " + what);
}

// A short printable rendering of untrusted text for error messages.
std::string Printable(std::string_view s) {
  constexpr size_t kMax = 40;
  std::string out;
  for (size_t i = 0; i < s.size() && i < kMax; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (s.size() > kMax) out += "...";
  return out;
}

// a * b, or the largest uint64_t when the product overflows.
uint64_t SaturatingMul(uint64_t a, uint64_t b) {
  uint64_t r = 0;
  return __builtin_mul_overflow(a, b, &r) ? std::numeric_limits<uint64_t>::max() : r;
}

bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

void SplitTokens(std::string_view line, std::vector<std::string_view>* tokens) {
  tokens->clear();
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && IsSpace(line[i])) ++i;
    const size_t start = i;
    while (i < line.size() && !IsSpace(line[i])) ++i;
    if (i > start) tokens->push_back(line.substr(start, i - start));
  }
}

bool ParseU64(std::string_view s, uint64_t* value) {
  if (s.empty()) return false;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), *value);
  return ec == std::errc() && end == s.data() + s.size();
}

// Reads the header; validates every key and the field layout. Does not look at the data.
Header ParseHeader(const char* text, size_t size, const std::string& name,
                   const ReadLimits& limits) {
  Header h;
  bool seen_version = false, seen_fields = false, seen_size = false, seen_type = false,
       seen_count = false, seen_width = false, seen_height = false, seen_viewpoint = false,
       seen_points = false, seen_data = false;
  std::string version;
  std::vector<std::string_view> tok;
  std::vector<std::string_view> names, sizes, types, counts;
  size_t pos = 0;
  int line_no = 0;
  while (!seen_data) {
    if (pos >= size) {
      Fail(name, line_no == 0 ? "not a PCD file (no header)" : "header ends without a DATA line");
    }
    if (pos >= limits.max_header_bytes) {
      Fail(name, "header is longer than the limit of " + std::to_string(limits.max_header_bytes) +
                     " bytes (no DATA line found)");
    }
    // Never scan past the header limit, however long the line.
    const size_t scan_end = limits.max_header_bytes >= size ? size : limits.max_header_bytes + 1;
    const char* nl = static_cast<const char*>(std::memchr(text + pos, '\n', scan_end - pos));
    if (nl == nullptr && scan_end < size) {
      Fail(name, "header is longer than the limit of " + std::to_string(limits.max_header_bytes) +
                     " bytes (no DATA line found)");
    }
    const size_t end = nl != nullptr ? static_cast<size_t>(nl - text) : size;
    const std::string_view line(text + pos, end - pos);
    pos = nl != nullptr ? end + 1 : size;
    ++line_no;
    SplitTokens(line, &tok);
    if (tok.empty() || tok[0][0] == '#') continue;
    const std::string_view key = tok[0];
    const std::string where = " on header line " + std::to_string(line_no);
    auto once = [&](bool* seen) {
      if (*seen) Fail(name, "duplicate header key '" + std::string(key) + "'" + where);
      *seen = true;
    };
    auto one_value = [&]() {
      if (tok.size() != 2) {
        Fail(name, "header key '" + std::string(key) + "' needs exactly one value" + where);
      }
      return tok[1];
    };
    auto unsigned_value = [&]() {
      const std::string_view v = one_value();
      uint64_t n = 0;
      if (!ParseU64(v, &n)) {
        Fail(name,
             std::string(key) + " '" + Printable(v) + "' is not a non-negative integer" + where);
      }
      return n;
    };
    auto list = [&](std::vector<std::string_view>* out) {
      if (tok.size() < 2) Fail(name, "header key '" + std::string(key) + "' has no values" + where);
      out->assign(tok.begin() + 1, tok.end());
    };
    if (key == "VERSION") {
      once(&seen_version);
      version = std::string(one_value());
      if (version != "0.7" && version != ".7" && version != "0.6" && version != ".6" &&
          version != "0.5" && version != ".5") {
        Fail(name, "unsupported VERSION '" + Printable(version) + "' (expected 0.5, 0.6 or 0.7)");
      }
    } else if (key == "FIELDS" || key == "COLUMNS") {
      once(&seen_fields);
      list(&names);
    } else if (key == "SIZE") {
      once(&seen_size);
      list(&sizes);
    } else if (key == "TYPE") {
      once(&seen_type);
      list(&types);
    } else if (key == "COUNT") {
      once(&seen_count);
      list(&counts);
    } else if (key == "WIDTH") {
      once(&seen_width);
      h.width = unsigned_value();
    } else if (key == "HEIGHT") {
      once(&seen_height);
      h.height = unsigned_value();
    } else if (key == "POINTS") {
      once(&seen_points);
      h.points = unsigned_value();
    } else if (key == "VIEWPOINT") {
      once(&seen_viewpoint);
      if (tok.size() != 8) Fail(name, "VIEWPOINT needs 7 values" + where);
    } else if (key == "DATA") {
      once(&seen_data);
      const std::string_view v = one_value();
      if (v == "ascii") {
        h.data = DataKind::kAscii;
      } else if (v == "binary") {
        h.data = DataKind::kBinary;
      } else if (v == "binary_compressed") {
        h.data = DataKind::kBinaryCompressed;
      } else {
        Fail(name, "unknown DATA encoding '" + Printable(v) +
                       "' (expected ascii, binary or binary_compressed)");
      }
    } else {
      Fail(name, "unknown header key '" + Printable(key) + "'" + where);
    }
  }
  h.data_offset = pos;
  h.lines = line_no;

  // Field layout.
  if (!seen_fields) Fail(name, "header has no FIELDS");
  if (!seen_size) Fail(name, "header has no SIZE");
  if (!seen_type) Fail(name, "header has no TYPE");
  auto check_len = [&](const char* key, const std::vector<std::string_view>& v) {
    if (v.size() != names.size()) {
      Fail(name, std::string(key) + " has " + std::to_string(v.size()) +
                     " entries but FIELDS has " + std::to_string(names.size()));
    }
  };
  check_len("SIZE", sizes);
  check_len("TYPE", types);
  if (seen_count) check_len("COUNT", counts);
  for (size_t i = 0; i < names.size(); ++i) {
    Field f;
    f.name = std::string(names[i]);
    uint64_t field_size = 0;
    if (!ParseU64(sizes[i], &field_size) ||
        (field_size != 1 && field_size != 2 && field_size != 4 && field_size != 8)) {
      Fail(name, "unsupported SIZE '" + Printable(sizes[i]) + "' for field '" + Printable(f.name) +
                     "' (expected 1, 2, 4 or 8)");
    }
    f.size = static_cast<int>(field_size);
    if (types[i] != "F" && types[i] != "U" && types[i] != "I") {
      Fail(name, "unsupported TYPE '" + Printable(types[i]) + "' for field '" + Printable(f.name) +
                     "' (expected F, U or I)");
    }
    f.type = types[i][0];
    if (f.type == 'F' && f.size != 4 && f.size != 8) {
      Fail(name, "unsupported floating-point SIZE " + std::to_string(f.size) + " for field '" +
                     Printable(f.name) + "' (expected 4 or 8)");
    }
    if (seen_count) {
      if (!ParseU64(counts[i], &f.count) || f.count == 0 || f.count > kMaxFieldCount) {
        Fail(name,
             "invalid COUNT '" + Printable(counts[i]) + "' for field '" + Printable(f.name) + "'");
      }
    }
    f.offset = h.point_bytes;
    h.point_bytes += f.bytes();
    h.point_elements += f.count;
    h.fields.push_back(std::move(f));
  }

  // Known fields.
  for (size_t i = 0; i < h.fields.size(); ++i) {
    const Field& f = h.fields[i];
    if (f.name == "_") continue;
    for (size_t j = 0; j < i; ++j) {
      if (h.fields[j].name == f.name) Fail(name, "duplicate field '" + Printable(f.name) + "'");
    }
    const std::string desc =
        std::string(1, f.type) + std::to_string(f.size) + " with COUNT " + std::to_string(f.count);
    const int index = static_cast<int>(i);
    if (f.name == "x" || f.name == "y" || f.name == "z") {
      if (f.type != 'F' || f.count != 1) {
        Fail(name, "field '" + f.name + "' must be F4 or F8 with COUNT 1, got " + desc);
      }
      (f.name == "x" ? h.x : f.name == "y" ? h.y : h.z) = index;
    } else if (f.name == "rgb" || f.name == "rgba") {
      if (f.size != 4 || f.count != 1) {
        Fail(name, "field '" + f.name + "' must be 4 bytes with COUNT 1, got " + desc);
      }
      if (h.color < 0) h.color = index;
    } else if (f.name == "label") {
      if (f.type == 'F' || f.count != 1) {
        Fail(name, "field 'label' must be an integer with COUNT 1, got " + desc);
      }
      h.label = index;
    }
  }
  if (h.x < 0 || h.y < 0 || h.z < 0) Fail(name, "header has no x, y and z fields");

  // Sizes.
  const bool v05 = version == "0.5" || version == ".5";
  if (!seen_points) {
    if (!seen_width || !seen_height) Fail(name, "header has no POINTS");
    if (__builtin_mul_overflow(h.width, h.height, &h.points)) Fail(name, "WIDTH*HEIGHT overflows");
  }
  if (!seen_width) {
    if (!v05) Fail(name, "header has no WIDTH");
    h.width = h.points;
  }
  if (!seen_height) {
    if (!v05) Fail(name, "header has no HEIGHT");
    h.height = 1;
  }
  if (h.points > limits.max_points) {
    FailTooLarge(name, "POINTS " + std::to_string(h.points) + " exceeds the limit of " +
                           std::to_string(limits.max_points));
  }
  uint64_t wh = 0;
  if (__builtin_mul_overflow(h.width, h.height, &wh) || wh != h.points) {
    Fail(name, "WIDTH*HEIGHT (" + std::to_string(h.width) + "*" + std::to_string(h.height) +
                   ") does not equal POINTS (" + std::to_string(h.points) + ")");
  }
  constexpr uint64_t kMaxDim = std::numeric_limits<int>::max();
  if (h.width > kMaxDim || h.height > kMaxDim) {
    Fail(name, "WIDTH or HEIGHT is too large");
  }
  // The frame limits every reader and writer shares: an organized cloud is an image.
  const std::optional<std::string> too_large =
      h.height > 1 ? limits.CheckImage(static_cast<int64_t>(h.width),
                                       static_cast<int64_t>(h.height), h.point_bytes)
                   : limits.CheckPoints(h.points, h.point_bytes);
  if (too_large) FailTooLarge(name, "declared size " + *too_large);
  return h;
}

template <typename T>
inline T Load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

// Copies a float field (F4 or F8) of n points into dst[i * dst_stride].
void GatherFloat(const Field& f, const uint8_t* base, size_t stride, size_t n, float* dst,
                 size_t dst_stride) {
  if (f.size == 4) {
    for (size_t i = 0; i < n; ++i) dst[i * dst_stride] = Load<float>(base + i * stride);
  } else {
    for (size_t i = 0; i < n; ++i) {
      dst[i * dst_stride] = static_cast<float>(Load<double>(base + i * stride));
    }
  }
}

template <typename T>
void GatherIntAs(const uint8_t* base, size_t stride, size_t n, uint32_t* dst) {
  for (size_t i = 0; i < n; ++i) dst[i] = static_cast<uint32_t>(Load<T>(base + i * stride));
}

// Copies an integer field (or the bits of an F4 field, as for packed rgb) as uint32.
void GatherU32(const Field& f, const uint8_t* base, size_t stride, size_t n, uint32_t* dst) {
  const bool sign = f.type == 'I';
  switch (f.size) {
    case 1:
      sign ? GatherIntAs<int8_t>(base, stride, n, dst) : GatherIntAs<uint8_t>(base, stride, n, dst);
      break;
    case 2:
      sign ? GatherIntAs<int16_t>(base, stride, n, dst)
           : GatherIntAs<uint16_t>(base, stride, n, dst);
      break;
    case 4:
      // F4 (packed rgb) is reinterpreted bit for bit, like U4; a field stored contiguously
      // (binary_compressed) is a plain copy.
      if (stride == 4) {
        std::memcpy(dst, base, 4 * n);
      } else {
        sign ? GatherIntAs<int32_t>(base, stride, n, dst)
             : GatherIntAs<uint32_t>(base, stride, n, dst);
      }
      break;
    default:
      sign ? GatherIntAs<int64_t>(base, stride, n, dst)
           : GatherIntAs<uint64_t>(base, stride, n, dst);
      break;
  }
}

void AllocateOutputs(const Header& h, core::PointCloud* cloud) {
  cloud->width = static_cast<int>(h.width);
  cloud->height = static_cast<int>(h.height);
  cloud->xyz.resize(h.points);
  // Every element is overwritten by the decoder; resize() keeps storage reused across calls.
  if (h.color >= 0) {
    cloud->rgba.resize(h.points);
  } else {
    cloud->rgba.clear();
  }
  if (h.label >= 0) {
    cloud->label.resize(h.points);
  } else {
    cloud->label.clear();
  }
}

// Packed "rgb" carries no alpha; report it opaque.
void FixRgbAlpha(const Header& h, core::PointCloud* cloud) {
  if (h.color >= 0 && h.fields[h.color].name == "rgb") {
    for (uint32_t& c : cloud->rgba) c |= 0xff000000u;
  }
}

// Extracts all known fields; field f of point i is at planes[f] + i * strides[f].
void GatherAll(const Header& h, const std::vector<const uint8_t*>& planes,
               const std::vector<size_t>& strides, core::PointCloud* cloud) {
  const size_t n = h.points;
  if (n == 0) return;
  if (h.fields[h.x].size == 4 && h.fields[h.y].size == 4 && h.fields[h.z].size == 4) {
    // Common case in one pass, writing the output sequentially.
    const uint8_t* px = planes[h.x];
    const uint8_t* py = planes[h.y];
    const uint8_t* pz = planes[h.z];
    const size_t sx = strides[h.x];
    const size_t sy = strides[h.y];
    const size_t sz = strides[h.z];
    core::Vec3f* out = cloud->xyz.data();
    if (sx == 4 && sy == 4 && sz == 4) {
      // Contiguous planes (binary_compressed): constant strides the compiler can vectorise.
      for (size_t i = 0; i < n; ++i) {
        out[i] =
            core::Vec3f{Load<float>(px + 4 * i), Load<float>(py + 4 * i), Load<float>(pz + 4 * i)};
      }
    } else {
      for (size_t i = 0; i < n; ++i) {
        out[i] = core::Vec3f{Load<float>(px + i * sx), Load<float>(py + i * sy),
                             Load<float>(pz + i * sz)};
      }
    }
  } else {
    float* xyz = &cloud->xyz[0].x;
    GatherFloat(h.fields[h.x], planes[h.x], strides[h.x], n, xyz + 0, 3);
    GatherFloat(h.fields[h.y], planes[h.y], strides[h.y], n, xyz + 1, 3);
    GatherFloat(h.fields[h.z], planes[h.z], strides[h.z], n, xyz + 2, 3);
  }
  if (h.color >= 0) {
    GatherU32(h.fields[h.color], planes[h.color], strides[h.color], n, cloud->rgba.data());
  }
  if (h.label >= 0) {
    GatherU32(h.fields[h.label], planes[h.label], strides[h.label], n, cloud->label.data());
  }
}

void DecodeBinary(const Header& h, const uint8_t* data, size_t available, const std::string& name,
                  core::PointCloud* cloud) {
  const uint64_t need = SaturatingMul(h.points, h.point_bytes);
  if (need > available) {
    Fail(name, "truncated binary data: " + std::to_string(h.points) + " points of " +
                   std::to_string(h.point_bytes) + " bytes need " + std::to_string(need) +
                   " bytes, file has " + std::to_string(available));
  }
  AllocateOutputs(h, cloud);
  std::vector<const uint8_t*> planes(h.fields.size());
  std::vector<size_t> strides(h.fields.size(), h.point_bytes);
  for (size_t f = 0; f < h.fields.size(); ++f) planes[f] = data + h.fields[f].offset;
  GatherAll(h, planes, strides, cloud);
}

void DecodeCompressed(const Header& h, const uint8_t* data, size_t available,
                      const std::string& name, core::PointCloud* cloud) {
  if (available < 8) Fail(name, "truncated binary_compressed data: missing the two size words");
  const uint64_t compressed = Load<uint32_t>(data);
  const uint64_t uncompressed = Load<uint32_t>(data + 4);
  const uint64_t expected = SaturatingMul(h.points, h.point_bytes);
  if (uncompressed != expected) {
    Fail(name, "binary_compressed declares " + std::to_string(uncompressed) +
                   " uncompressed bytes but POINTS*point size is " + std::to_string(expected));
  }
  if (compressed > available - 8) {
    Fail(name, "truncated binary_compressed data: header declares " + std::to_string(compressed) +
                   " compressed bytes, file has " + std::to_string(available - 8));
  }
  if (uncompressed > compressed * kLzfMaxExpansion) {
    Fail(name, "binary_compressed declares " + std::to_string(uncompressed) +
                   " uncompressed bytes, more than " + std::to_string(compressed) +
                   " compressed bytes can hold");
  }
  // Frames are decoded into a per-thread scratch buffer: a fresh multi-megabyte allocation
  // costs more in page faults than the decoding itself. Unusually large clouds use a
  // temporary buffer so that the thread does not keep it.
  thread_local std::vector<uint8_t> scratch;
  std::vector<uint8_t> large;
  std::vector<uint8_t>& raw = uncompressed <= kMaxCachedScratchBytes ? scratch : large;
  if (raw.size() < uncompressed) raw.resize(uncompressed);
  size_t produced = 0;
  try {
    produced = LzfDecompress(data + 8, compressed, raw.data(), uncompressed);
  } catch (const std::runtime_error& e) {
    Fail(name, e.what());
  }
  if (produced != uncompressed) {
    Fail(name, "LZF stream decodes to " + std::to_string(produced) + " bytes, expected " +
                   std::to_string(uncompressed));
  }
  AllocateOutputs(h, cloud);
  std::vector<const uint8_t*> planes(h.fields.size());
  std::vector<size_t> strides(h.fields.size());
  for (size_t f = 0; f < h.fields.size(); ++f) {
    planes[f] = raw.data() + h.fields[f].offset * h.points;
    strides[f] = h.fields[f].bytes();
  }
  GatherAll(h, planes, strides, cloud);
}

template <typename T>
bool ParseNumber(std::string_view s, T* value) {
  if (!s.empty() && s[0] == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), *value);
  return ec == std::errc() && end == s.data() + s.size();
}

bool ParseAsciiFloat(const Field& f, std::string_view s, float* out) {
  if (f.size == 4) return ParseNumber(s, out);
  double d = 0.0;
  if (!ParseNumber(s, &d)) return false;
  *out = static_cast<float>(d);
  return true;
}

bool ParseAsciiU32(const Field& f, std::string_view s, uint32_t* out) {
  if (f.type == 'F') {
    // Packed colour: PCL writes the bits as an unsigned integer; accept a float too.
    uint32_t bits = 0;
    if (ParseNumber(s, &bits)) {
      *out = bits;
      return true;
    }
    float v = 0.f;
    if (!ParseNumber(s, &v)) return false;
    *out = std::bit_cast<uint32_t>(v);
    return true;
  }
  if (f.type == 'U') {
    uint64_t v = 0;
    if (!ParseNumber(s, &v)) return false;
    *out = static_cast<uint32_t>(v);
    return true;
  }
  int64_t v = 0;
  if (!ParseNumber(s, &v)) return false;
  *out = static_cast<uint32_t>(v);
  return true;
}

void DecodeAscii(const Header& h, const char* text, size_t available, const std::string& name,
                 core::PointCloud* cloud) {
  // Every value takes at least one character and one separator.
  const uint64_t min_bytes = SaturatingMul(SaturatingMul(h.points, h.point_elements), 2);
  if (min_bytes > uint64_t{available} + 1) {
    Fail(name, "truncated ascii data: " + std::to_string(available) + " bytes cannot hold " +
                   std::to_string(h.points) + " points");
  }
  AllocateOutputs(h, cloud);
  // Token index of each known field inside a line.
  std::vector<size_t> first_token(h.fields.size());
  for (size_t f = 0, t = 0; f < h.fields.size(); ++f) {
    first_token[f] = t;
    t += h.fields[f].count;
  }
  std::vector<std::string_view> tok;
  size_t pos = 0;
  int line_no = h.lines;
  size_t i = 0;
  while (i < h.points) {
    if (pos >= available) {
      Fail(name, "truncated ascii data: found " + std::to_string(i) + " of " +
                     std::to_string(h.points) + " points");
    }
    const char* nl = static_cast<const char*>(std::memchr(text + pos, '\n', available - pos));
    const size_t end = nl != nullptr ? static_cast<size_t>(nl - text) : available;
    const std::string_view line(text + pos, end - pos);
    pos = nl != nullptr ? end + 1 : available;
    ++line_no;
    SplitTokens(line, &tok);
    if (tok.empty()) continue;
    const std::string where = " on line " + std::to_string(line_no);
    if (tok.size() != h.point_elements) {
      Fail(name, "line " + std::to_string(line_no) + " has " + std::to_string(tok.size()) +
                     " values, expected " + std::to_string(h.point_elements));
    }
    auto bad = [&](int f) {
      Fail(name, "bad value '" + Printable(tok[first_token[f]]) + "' for field '" +
                     h.fields[f].name + "'" + where);
    };
    core::Vec3f& p = cloud->xyz[i];
    if (!ParseAsciiFloat(h.fields[h.x], tok[first_token[h.x]], &p.x)) bad(h.x);
    if (!ParseAsciiFloat(h.fields[h.y], tok[first_token[h.y]], &p.y)) bad(h.y);
    if (!ParseAsciiFloat(h.fields[h.z], tok[first_token[h.z]], &p.z)) bad(h.z);
    if (h.color >= 0 &&
        !ParseAsciiU32(h.fields[h.color], tok[first_token[h.color]], &cloud->rgba[i])) {
      bad(h.color);
    }
    if (h.label >= 0 &&
        !ParseAsciiU32(h.fields[h.label], tok[first_token[h.label]], &cloud->label[i])) {
      bad(h.label);
    }
    ++i;
  }
}

// A file can hold at most a header and `max_bytes` of data.
void CheckFileSize(const std::string& name, uint64_t size, const ReadLimits& limits) {
  if (size - std::min<uint64_t>(size, limits.max_header_bytes) > limits.max_bytes) {
    FailTooLarge(name, "the file of " + std::to_string(size) +
                           " bytes exceeds the frame limit of " + std::to_string(limits.max_bytes) +
                           " bytes of data plus a " + std::to_string(limits.max_header_bytes) +
                           "-byte header");
  }
}

// Reads a whole regular file into `cached` (reused per thread) or, when larger than
// kMaxCachedScratchBytes, into `large`. Returns the bytes. A plain read, not mmap: a file
// truncated by another process while it is read must give an error, not SIGBUS.
std::string_view ReadWholeFile(const std::string& path, const ReadLimits& limits,
                               std::vector<char>* cached, std::vector<char>* large) {
  // O_NONBLOCK: a FIFO must not block the open (it is refused just below).
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) Fail(path, std::string("cannot open: ") + std::strerror(errno));
  const FdCloser closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) Fail(path, std::string("cannot stat: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) Fail(path, "not a regular file (a FIFO, device or directory)");
  const size_t size = static_cast<size_t>(st.st_size);
  if (size == 0) Fail(path, "empty file");
  CheckFileSize(path, size, limits);
  std::vector<char>* buffer = size <= kMaxCachedScratchBytes ? cached : large;
  if (buffer->size() < size) buffer->resize(size);
  size_t got = 0;
  while (got < size) {
    const ssize_t n = ::read(fd, buffer->data() + got, size - got);
    if (n < 0) {
      if (errno == EINTR) continue;
      Fail(path, std::string("read error: ") + std::strerror(errno));
    }
    if (n == 0) break;  // the file shrank since fstat; the decoder reports the truncation
    got += static_cast<size_t>(n);
  }
  return std::string_view(buffer->data(), got);
}

void AppendU32(uint32_t v, std::string* out) {
  char buf[4];
  std::memcpy(buf, &v, 4);
  out->append(buf, 4);
}

void AppendFloatText(float v, std::string* out) {
  char buf[64];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  CLUTTERSEG_DEMAND(ec == std::errc());
  out->append(buf, end);
}

void AppendUintText(uint32_t v, std::string* out) {
  char buf[16];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  CLUTTERSEG_DEMAND(ec == std::errc());
  out->append(buf, end);
}

}  // namespace

void ReadPcdFromMemory(const void* data, size_t size, const std::string& name,
                       const ReadLimits& limits, core::PointCloud* cloud) {
  if (size == 0) Fail(name, "empty file");
  CheckFileSize(name, size, limits);
  const char* text = static_cast<const char*>(data);
  const Header h = ParseHeader(text, size, name, limits);
  const size_t available = size - h.data_offset;
  const uint8_t* body = static_cast<const uint8_t*>(data) + h.data_offset;
  switch (h.data) {
    case DataKind::kAscii:
      DecodeAscii(h, text + h.data_offset, available, name, cloud);
      break;
    case DataKind::kBinary:
      DecodeBinary(h, body, available, name, cloud);
      break;
    case DataKind::kBinaryCompressed:
      DecodeCompressed(h, body, available, name, cloud);
      break;
  }
  FixRgbAlpha(h, cloud);
}

core::PointCloud ReadPcdFromMemory(const void* data, size_t size, const std::string& name,
                                   const ReadLimits& limits) {
  core::PointCloud cloud;
  ReadPcdFromMemory(data, size, name, limits, &cloud);
  return cloud;
}

void ReadPcd(const std::string& path, const ReadLimits& limits, core::PointCloud* cloud) {
  // The file bytes go to a per-thread buffer, like the decoding scratch (see DecodeCompressed).
  thread_local std::vector<char> file_buffer;
  std::vector<char> large;
  const std::string_view bytes = ReadWholeFile(path, limits, &file_buffer, &large);
  ReadPcdFromMemory(bytes.data(), bytes.size(), path, limits, cloud);
}

core::PointCloud ReadPcd(const std::string& path, const ReadLimits& limits) {
  core::PointCloud cloud;
  ReadPcd(path, limits, &cloud);
  return cloud;
}

void WritePcd(const std::string& path, const core::PointCloud& cloud, PcdEncoding encoding,
              const core::FrameLimits& limits) {
  const size_t n = cloud.size();
  CLUTTERSEG_DEMAND(cloud.rgba.empty() || cloud.rgba.size() == n);
  CLUTTERSEG_DEMAND(cloud.label.empty() || cloud.label.size() == n);
  size_t width = n;
  size_t height = 1;
  if (cloud.organized()) {
    CLUTTERSEG_DEMAND(cloud.width > 0 &&
                      static_cast<size_t>(cloud.width) * static_cast<size_t>(cloud.height) == n);
    width = static_cast<size_t>(cloud.width);
    height = static_cast<size_t>(cloud.height);
  }
  // Refuse what ReadPcd would refuse under the same limits (20-byte records), before the
  // file is touched.
  constexpr uint64_t kRecordBytes = 20;
  const std::optional<std::string> too_large =
      cloud.organized() ? limits.CheckImage(cloud.width, cloud.height, kRecordBytes)
                        : limits.CheckPoints(n, kRecordBytes);
  if (too_large) FailTooLarge(path, "cannot write a cloud: size " + *too_large);
  // The compressed size words are 32-bit; 21 leaves room for LZF expansion.
  if (n > std::numeric_limits<uint32_t>::max() / 21) {
    Fail(path, "cannot write " + std::to_string(n) + " points: more than a PCD file can hold");
  }
  auto rgba_at = [&](size_t i) { return cloud.rgba.empty() ? 0xff000000u : cloud.rgba[i]; };
  auto label_at = [&](size_t i) { return cloud.label.empty() ? 0u : cloud.label[i]; };

  std::string out;
  out += "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z rgba label\n";
  out += "SIZE 4 4 4 4 4\nTYPE F F F U U\nCOUNT 1 1 1 1 1\n";
  out += "WIDTH " + std::to_string(width) + "\nHEIGHT " + std::to_string(height) + "\n";
  out += "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(n) + "\n";
  const size_t header_bytes = out.size() + 32;  // with the DATA line
  switch (encoding) {
    case PcdEncoding::kAscii: {
      out += "DATA ascii\n";
      out.reserve(out.size() + n * 48);
      for (size_t i = 0; i < n; ++i) {
        const core::Vec3f& p = cloud.xyz[i];
        AppendFloatText(p.x, &out);
        out += ' ';
        AppendFloatText(p.y, &out);
        out += ' ';
        AppendFloatText(p.z, &out);
        out += ' ';
        AppendUintText(rgba_at(i), &out);
        out += ' ';
        AppendUintText(label_at(i), &out);
        out += '\n';
      }
      break;
    }
    case PcdEncoding::kBinary:
      out += "DATA binary\n";
      break;  // the points are written below, in blocks
    case PcdEncoding::kBinaryCompressed: {
      out += "DATA binary_compressed\n";
      // Planar layout: all x, then all y, z, rgba, label.
      std::vector<uint8_t> planes(n * 20);
      uint8_t* px = planes.data();
      uint8_t* py = px + 4 * n;
      uint8_t* pz = py + 4 * n;
      uint8_t* pc = pz + 4 * n;
      uint8_t* pl = pc + 4 * n;
      for (size_t i = 0; i < n; ++i) {
        const uint32_t rgba = rgba_at(i);
        const uint32_t label = label_at(i);
        std::memcpy(px + 4 * i, &cloud.xyz[i].x, 4);
        std::memcpy(py + 4 * i, &cloud.xyz[i].y, 4);
        std::memcpy(pz + 4 * i, &cloud.xyz[i].z, 4);
        std::memcpy(pc + 4 * i, &rgba, 4);
        std::memcpy(pl + 4 * i, &label, 4);
      }
      std::vector<uint8_t> packed;
      LzfCompress(planes.data(), planes.size(), &packed);
      AppendU32(static_cast<uint32_t>(packed.size()), &out);
      AppendU32(static_cast<uint32_t>(planes.size()), &out);
      out.append(reinterpret_cast<const char*>(packed.data()), packed.size());
      break;
    }
  }

  // The reader refuses files of more than a header and `max_bytes` of data (ascii text can
  // be larger than the binary records).
  if (out.size() > header_bytes) {
    if (const std::optional<std::string> data_too_large =
            limits.CheckBytes(out.size() - header_bytes)) {
      FailTooLarge(path, "cannot write the cloud: its data of " + *data_too_large);
    }
  }

  // An existing file is overwritten in place and then cut to length: rewriting its cached
  // pages is cheaper than truncating first, which frees them and allocates fresh ones.
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) Fail(path, std::string("cannot open for writing: ") + std::strerror(errno));
  FdCloser closer{fd};
  size_t total = 0;
  auto write_all = [&](const char* data, size_t size) {
    while (size > 0) {
      const ssize_t w = ::write(fd, data, size);
      if (w < 0) {
        if (errno == EINTR) continue;
        Fail(path, std::string("write failed: ") + std::strerror(errno));
      }
      data += w;
      size -= static_cast<size_t>(w);
      total += static_cast<size_t>(w);
    }
  };
  write_all(out.data(), out.size());
  if (encoding == PcdEncoding::kBinary) {
    // Interleaved records go through a small per-thread block instead of a file-sized
    // string: a fresh multi-megabyte buffer costs more in page faults than the copying.
    constexpr size_t kRecord = 20;
    constexpr size_t kBlockPoints = 16384;
    thread_local std::vector<char> block(kBlockPoints * kRecord);
    const bool has_rgba = !cloud.rgba.empty(), has_label = !cloud.label.empty();
    for (size_t begin = 0; begin < n; begin += kBlockPoints) {
      const size_t end = std::min(n, begin + kBlockPoints);
      char* dst = block.data();
      for (size_t i = begin; i < end; ++i, dst += kRecord) {
        const uint32_t rgba = has_rgba ? cloud.rgba[i] : 0xff000000u;
        const uint32_t label = has_label ? cloud.label[i] : 0u;
        std::memcpy(dst, &cloud.xyz[i], 12);
        std::memcpy(dst + 12, &rgba, 4);
        std::memcpy(dst + 16, &label, 4);
      }
      write_all(block.data(), static_cast<size_t>(dst - block.data()));
    }
  }
  struct stat st {};
  if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) &&
      ::ftruncate(fd, static_cast<off_t>(total)) != 0) {
    Fail(path, std::string("cannot set the file size: ") + std::strerror(errno));
  }
  closer.fd = -1;
  if (::close(fd) != 0) Fail(path, std::string("write failed on close: ") + std::strerror(errno));
}

}  // namespace clutterseg::io
