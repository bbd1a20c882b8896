#include "clutterseg/drivers/oni/oni_writer.h"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <vector>

#include "clutterseg/core/frame_limits.h"
#include "clutterseg/drivers/oni/oni_format.h"

namespace clutterseg::drivers {
namespace {

using internal::OniNodeType;
using internal::OniRecordType;

static_assert(sizeof(core::Rgb8) == 3, "RGB888 frames are written straight from Rgb8 pixels");

// Little-endian byte builder for record fields.
class Bytes {
 public:
  void U8(uint8_t v) { data_.push_back(v); }
  void U16(uint16_t v) { Le(v, 2); }
  void U32(uint32_t v) { Le(v, 4); }
  void U64(uint64_t v) { Le(v, 8); }
  void F64(double v) { U64(std::bit_cast<uint64_t>(v)); }
  void Raw(const void* p, size_t n) {
    const auto* b = static_cast<const uint8_t*>(p);
    data_.insert(data_.end(), b, b + n);
  }
  void Str(const std::string& s) {
    U32(static_cast<uint32_t>(s.size() + 1));
    Raw(s.data(), s.size());
    U8(0);
  }
  const std::vector<uint8_t>& data() const { return data_; }
  size_t size() const { return data_.size(); }
  void Clear() { data_.clear(); }

 private:
  void Le(uint64_t v, int n) {
    for (int i = 0; i < n; ++i) data_.push_back(static_cast<uint8_t>(v >> (8 * i)));
  }
  std::vector<uint8_t> data_;
};

struct Node {
  uint32_t id{0};
  std::string name;
  OniNodeType type{OniNodeType::kDepth};
  uint64_t added_offset{0};  // offset of NODE_ADDED
  uint64_t added_size{0};    // its fieldsSize (rewritten in place with the same size)
  uint64_t last_data_offset{0};
  uint32_t bytes_per_pixel{2};
  std::vector<uint64_t> timestamps;
  std::vector<uint64_t> data_offsets;
  uint64_t seek_table_offset{0};
};

}  // namespace

struct OniWriter::Impl {
  std::string path;
  std::FILE* file{nullptr};
  int width{0};
  int height{0};
  int fps{0};
  double hfov{0.0};
  double vfov{0.0};
  bool with_color{false};
  std::vector<Node> nodes;
  uint64_t last_timestamp{0};
  int frames{0};
  std::vector<uint8_t> swap_buffer;  // only used on big-endian hosts

  [[noreturn]] void Fail(const std::string& what) const {
    throw std::runtime_error("ONI writer: " + path + ": " + what);
  }
  void FailIo(const char* what) const {
    Fail(std::string(what) + " failed: " + std::strerror(errno));
  }

  uint64_t Tell() const {
    const off_t pos = ftello(file);
    if (pos < 0) FailIo("ftell");
    return static_cast<uint64_t>(pos);
  }
  void Seek(uint64_t pos) const {
    if (fseeko(file, static_cast<off_t>(pos), SEEK_SET) != 0) FailIo("seek");
  }
  void Write(const void* p, size_t n) const {
    if (n != 0 && std::fwrite(p, 1, n, file) != n) FailIo("write");
  }

  // Writes one record: 28-byte header + `fields` + `payload_size` bytes that the caller writes
  // right after. Returns the record's offset.
  uint64_t WriteRecord(OniRecordType type, uint32_t node_id, const Bytes& fields,
                       uint64_t payload_size, uint64_t undo_pos) const {
    const uint64_t offset = Tell();
    Bytes h;
    h.U32(internal::kOniRecordMagic);
    h.U32(static_cast<uint32_t>(type));
    h.U32(node_id);
    h.U32(static_cast<uint32_t>(internal::kOniRecordHeaderSize + fields.size()));
    h.U32(static_cast<uint32_t>(payload_size));
    h.U64(undo_pos);
    Write(h.data().data(), h.size());
    Write(fields.data().data(), fields.size());
    return offset;
  }

  void WriteFileHeader(uint64_t max_timestamp, uint32_t max_node_id) const {
    Bytes h;
    h.Raw(internal::kOniMagic, 4);
    h.U8(1);   // major
    h.U8(0);   // minor
    h.U16(1);  // maintenance
    h.U32(0);  // build
    h.U64(max_timestamp);
    h.U32(max_node_id);
    Write(h.data().data(), h.size());
  }

  Bytes NodeAddedFields(const Node& n, uint32_t frame_count, uint64_t min_ts, uint64_t max_ts,
                        uint64_t seek_table_pos) const {
    Bytes f;
    f.Str(n.name);
    f.U32(static_cast<uint32_t>(n.type));
    f.Raw("NONE", 4);
    f.U32(frame_count);
    f.U64(min_ts);
    f.U64(max_ts);
    f.U64(seek_table_pos);
    return f;
  }

  void IntProperty(const Node& n, const char* name, uint64_t value) const {
    Bytes f;
    f.Str(name);
    f.U32(8);
    f.U64(value);
    WriteRecord(OniRecordType::kIntProperty, n.id, f, 0, 0);
  }
  void GeneralProperty(const Node& n, const char* name, const Bytes& value) const {
    Bytes f;
    f.Str(name);
    f.U32(static_cast<uint32_t>(value.size()));
    f.Raw(value.data().data(), value.size());
    WriteRecord(OniRecordType::kGeneralProperty, n.id, f, 0, 0);
  }

  void WriteNode(Node* n) const {
    const Bytes added = NodeAddedFields(*n, std::numeric_limits<uint32_t>::max(), 0,
                                        std::numeric_limits<uint64_t>::max(), 0);
    n->added_offset = WriteRecord(OniRecordType::kNodeAdded, n->id, added, 0, 0);
    n->added_size = internal::kOniRecordHeaderSize + added.size();
    const bool depth = n->type == OniNodeType::kDepth;
    IntProperty(*n, "oniRequiredFrameSize",
                static_cast<uint64_t>(width) * static_cast<uint64_t>(height) * n->bytes_per_pixel);
    if (depth) IntProperty(*n, "xnDeviceMaxDepth", 10000);
    Bytes mode;
    mode.U32(static_cast<uint32_t>(width));
    mode.U32(static_cast<uint32_t>(height));
    mode.U32(static_cast<uint32_t>(fps));
    GeneralProperty(*n, "xnMapOutputMode", mode);
    IntProperty(*n, "oniPixelFormat",
                depth ? internal::kOniPixelFormatDepth1Mm : internal::kOniPixelFormatRgb888);
    Bytes fov;
    fov.F64(hfov);
    fov.F64(vfov);
    GeneralProperty(*n, "xnFOV", fov);
    Bytes cropping;  // disabled cropping; OniFile delivers no frames without this property
    cropping.U32(0);
    cropping.U16(0);
    cropping.U16(0);
    cropping.U16(0);
    cropping.U16(0);
    GeneralProperty(*n, "xnCropping", cropping);
    IntProperty(*n, "xnMirror", 0);
  }

  void WritePixels(const void* p, size_t count, size_t bytes_per_value) {
    if constexpr (std::endian::native == std::endian::little) {
      Write(p, count * bytes_per_value);
    } else {
      swap_buffer.resize(count * bytes_per_value);
      const auto* src = static_cast<const uint8_t*>(p);
      for (size_t i = 0; i < count; ++i) {
        for (size_t b = 0; b < bytes_per_value; ++b) {
          swap_buffer[i * bytes_per_value + b] = src[i * bytes_per_value + bytes_per_value - 1 - b];
        }
      }
      Write(swap_buffer.data(), swap_buffer.size());
    }
  }

  void Finalize() {
    uint64_t max_ts = 0;
    for (Node& n : nodes) {
      if (!n.timestamps.empty()) max_ts = std::max(max_ts, n.timestamps.back());
      Bytes none;
      WriteRecord(OniRecordType::kNodeRemoved, n.id, none, 0, n.added_offset);
      const uint64_t entries = n.timestamps.size() + 1;
      n.seek_table_offset = WriteRecord(OniRecordType::kSeekTable, n.id, none,
                                        entries * internal::kOniSeekEntrySize, 0);
      Bytes table;
      table.U64(0);
      table.U32(0);
      table.U64(0);
      for (size_t i = 0; i < n.timestamps.size(); ++i) {
        table.U64(n.timestamps[i]);
        table.U32(0);
        table.U64(n.data_offsets[i]);
      }
      Write(table.data().data(), table.size());
    }
    Bytes none;
    WriteRecord(OniRecordType::kEnd, 0, none, 0, 0);
    for (const Node& n : nodes) {
      const uint64_t first = n.timestamps.empty() ? 0 : n.timestamps.front();
      const uint64_t last = n.timestamps.empty() ? 0 : n.timestamps.back();
      const Bytes added = NodeAddedFields(n, static_cast<uint32_t>(n.timestamps.size()), first,
                                          last, n.seek_table_offset);
      Seek(n.added_offset);
      WriteRecord(OniRecordType::kNodeAdded, n.id, added, 0, 0);
    }
    Seek(0);
    WriteFileHeader(max_ts, static_cast<uint32_t>(nodes.size()));
  }
};

OniWriter::OniWriter() : impl_(std::make_unique<Impl>()) {}

OniWriter::~OniWriter() {
  try {
    Close();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
  } catch (...) {
    std::fprintf(stderr, "ONI writer: unknown error while closing %s\n", impl_->path.c_str());
  }
}

void OniWriter::Open(const std::string& path, int width, int height, int fps,
                     const core::CameraIntrinsics& intrinsics, bool with_color) {
  Impl& m = *impl_;
  if (m.file != nullptr) m.Fail("Open() called while " + m.path + " is still open");
  m = Impl{};
  m.path = path;
  // OniFile buffers at most 1600x1200x3 bytes per frame (kOniFileMaxFrameBytes), which is
  // also within core::FrameLimits, so OniReader reads back what is written here.
  if (width <= 0 || height <= 0 || width > 1600 || height > 1200 ||
      core::FrameLimits{}.CheckImage(width, height, 3)) {
    m.Fail("resolution " + std::to_string(width) + "x" + std::to_string(height) +
           " is outside 1x1 .. 1600x1200");
  }
  if (fps <= 0 || fps > 1000) m.Fail("fps = " + std::to_string(fps) + " is outside 1..1000");
  if (!(intrinsics.fx > 0.0) || !(intrinsics.fy > 0.0) || !std::isfinite(intrinsics.fx) ||
      !std::isfinite(intrinsics.fy)) {
    m.Fail("intrinsics need positive focal lengths, got " + intrinsics.ToString());
  }
  m.width = width;
  m.height = height;
  m.fps = fps;
  m.with_color = with_color;
  // The intrinsics may have been given for another resolution of the same sensor.
  const double fx = intrinsics.width > 0 ? intrinsics.fx * width / intrinsics.width : intrinsics.fx;
  const double fy =
      intrinsics.height > 0 ? intrinsics.fy * height / intrinsics.height : intrinsics.fy;
  m.hfov = 2.0 * std::atan(width / (2.0 * fx));
  m.vfov = 2.0 * std::atan(height / (2.0 * fy));
  // Readers refuse a field of view no camera has (CameraIntrinsics::ValidateOrThrow): so
  // does the writer.
  core::CameraIntrinsics stored;
  stored.width = width;
  stored.height = height;
  stored.fx = fx;
  stored.fy = fy;
  stored.cx = width / 2.0 - 0.5;
  stored.cy = height / 2.0 - 0.5;
  try {
    stored.ValidateOrThrow("intrinsics");
  } catch (const std::invalid_argument& e) {
    m.Fail(std::string("implausible field of view: ") + e.what());
  }

  m.file = std::fopen(path.c_str(), "w+b");
  if (m.file == nullptr) m.FailIo("open for writing");
  try {
    Node depth;
    depth.id = 1;
    depth.name = "Depth";
    depth.type = OniNodeType::kDepth;
    depth.bytes_per_pixel = 2;
    m.nodes.push_back(depth);
    if (with_color) {
      Node image;
      image.id = 2;
      image.name = "Image";
      image.type = OniNodeType::kImage;
      image.bytes_per_pixel = 3;
      m.nodes.push_back(image);
    }
    // Until Close() patches it, the header claims no maximum timestamp (as OpenNI2 does).
    m.WriteFileHeader(std::numeric_limits<uint64_t>::max(), static_cast<uint32_t>(m.nodes.size()));
    for (Node& n : m.nodes) m.WriteNode(&n);
    Bytes data_begin;
    data_begin.U32(std::numeric_limits<uint32_t>::max());
    data_begin.U64(std::numeric_limits<uint64_t>::max());
    Bytes none;
    for (const Node& n : m.nodes) {
      m.WriteRecord(OniRecordType::kNodeStateReady, n.id, none, 0, 0);
      m.WriteRecord(OniRecordType::kNodeDataBegin, n.id, data_begin, 0, 0);
    }
  } catch (...) {
    std::fclose(m.file);
    m.file = nullptr;
    throw;
  }
}

void OniWriter::WriteFrame(const core::DepthImage& depth, const core::ColorImage* color,
                           int64_t timestamp_us) {
  Impl& m = *impl_;
  if (m.file == nullptr) m.Fail("WriteFrame() called on a closed writer");
  if (depth.width != m.width || depth.height != m.height ||
      depth.data.size() != static_cast<size_t>(m.width) * m.height) {
    m.Fail("depth frame is " + std::to_string(depth.width) + "x" + std::to_string(depth.height) +
           ", the file was opened for " + std::to_string(m.width) + "x" + std::to_string(m.height));
  }
  if (m.with_color) {
    if (color == nullptr) m.Fail("the file was opened with colour but the frame has none");
    if (color->width != m.width || color->height != m.height ||
        color->data.size() != depth.data.size()) {
      m.Fail("colour frame is " + std::to_string(color->width) + "x" +
             std::to_string(color->height) + ", expected the depth size");
    }
  }
  if (timestamp_us < 0) m.Fail("negative timestamp " + std::to_string(timestamp_us));
  const auto ts = static_cast<uint64_t>(timestamp_us);
  if (m.frames > 0 && ts < m.last_timestamp) {
    m.Fail("timestamp " + std::to_string(ts) + " us is before the previous one (" +
           std::to_string(m.last_timestamp) + " us)");
  }
  if (m.frames == std::numeric_limits<int>::max() - 1) m.Fail("too many frames");

  for (Node& n : m.nodes) {
    if (n.type != OniNodeType::kDepth && color == nullptr) continue;  // WriteDepthOnlyFrame
    // Each stream numbers its own frames, as openni::Recorder does.
    const auto frame_id = static_cast<uint32_t>(n.timestamps.size() + 1);
    Bytes fields;
    fields.U64(ts);
    fields.U32(frame_id);
    const size_t pixels = depth.data.size();
    const uint64_t offset = m.WriteRecord(OniRecordType::kNewData, n.id, fields,
                                          pixels * n.bytes_per_pixel, n.last_data_offset);
    if (n.type == OniNodeType::kDepth) {
      m.WritePixels(depth.data.data(), pixels, 2);
    } else {
      m.Write(color->data.data(), pixels * 3);  // bytes, no byte order
    }
    n.last_data_offset = offset;
    n.timestamps.push_back(ts);
    n.data_offsets.push_back(offset);
  }
  m.last_timestamp = ts;
  ++m.frames;
}

void OniWriter::WriteDepthOnlyFrame(const core::DepthImage& depth, int64_t timestamp_us) {
  Impl& m = *impl_;
  if (!m.with_color) {
    WriteFrame(depth, nullptr, timestamp_us);
    return;
  }
  // WriteFrame() checks everything but the colour, which it then leaves out.
  m.with_color = false;
  try {
    WriteFrame(depth, nullptr, timestamp_us);
  } catch (...) {
    m.with_color = true;
    throw;
  }
  m.with_color = true;
}

void OniWriter::Close() {
  Impl& m = *impl_;
  if (m.file == nullptr) return;
  std::string error;
  try {
    m.Finalize();
  } catch (const std::exception& e) {
    error = e.what();
  }
  if (std::fclose(m.file) != 0 && error.empty()) {
    error = "ONI writer: " + m.path + ": close failed: " + std::strerror(errno);
  }
  m.file = nullptr;
  if (!error.empty()) throw std::runtime_error(error);
}

bool OniWriter::is_open() const { return impl_->file != nullptr; }
int OniWriter::frames_written() const { return impl_->frames; }
const std::string& OniWriter::path() const { return impl_->path; }

}  // namespace clutterseg::drivers
