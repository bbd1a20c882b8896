#include "clutterseg/drivers/oni/oni_reader.h"

#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "clutterseg/drivers/oni/oni_format.h"

namespace clutterseg::drivers {
namespace {

using internal::OniRecordType;

// Random access to the bytes of a file or buffer; Read() is only called within size().
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  virtual uint64_t size() const = 0;
  virtual void Read(uint64_t offset, void* dst, size_t n) = 0;
};

class MemorySource final : public ByteSource {
 public:
  MemorySource(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  uint64_t size() const override { return size_; }
  void Read(uint64_t offset, void* dst, size_t n) override {
    if (n != 0) std::memcpy(dst, data_ + offset, n);
  }

 private:
  const uint8_t* data_;
  size_t size_;
};

class FileSource final : public ByteSource {
 public:
  explicit FileSource(const std::string& path) : path_(path) {
    file_ = std::fopen(path.c_str(), "rb");
    if (file_ == nullptr) {
      throw std::runtime_error("ONI reader: " + path + ": cannot open: " + std::strerror(errno));
    }
    if (fseeko(file_, 0, SEEK_END) != 0 || (size_ = ftello(file_)) < 0) {
      const std::string err = std::strerror(errno);
      std::fclose(file_);
      throw std::runtime_error("ONI reader: " + path + ": cannot determine size: " + err);
    }
  }
  ~FileSource() override { std::fclose(file_); }
  FileSource(const FileSource&) = delete;
  FileSource& operator=(const FileSource&) = delete;
  uint64_t size() const override { return static_cast<uint64_t>(size_); }
  void Read(uint64_t offset, void* dst, size_t n) override {
    if (fseeko(file_, static_cast<off_t>(offset), SEEK_SET) != 0 ||
        std::fread(dst, 1, n, file_) != n) {
      throw std::runtime_error("ONI reader: " + path_ + ": read of " + std::to_string(n) +
                               " bytes at offset " + std::to_string(offset) + " failed");
    }
  }

 private:
  std::string path_;
  std::FILE* file_{nullptr};
  off_t size_{0};
};

// Bounded little-endian cursor over a record's fields.
class Cursor {
 public:
  Cursor(const std::vector<uint8_t>& bytes, const std::string& where)
      : bytes_(bytes), where_(where) {}
  uint64_t Le(int n) {
    Need(static_cast<size_t>(n));
    uint64_t v = 0;
    for (int i = 0; i < n; ++i) v |= uint64_t{bytes_[pos_ + i]} << (8 * i);
    pos_ += static_cast<size_t>(n);
    return v;
  }
  uint32_t U32() { return static_cast<uint32_t>(Le(4)); }
  uint64_t U64() { return Le(8); }
  std::vector<uint8_t> Bytes(size_t n) {
    Need(n);
    std::vector<uint8_t> out(bytes_.begin() + static_cast<std::ptrdiff_t>(pos_),
                             bytes_.begin() + static_cast<std::ptrdiff_t>(pos_ + n));
    pos_ += n;
    return out;
  }
  std::string Str(uint32_t max_len) {
    const uint32_t len = U32();
    if (len == 0 || len > max_len) {
      throw std::runtime_error(where_ + ": string length " + std::to_string(len) +
                               " is outside 1.." + std::to_string(max_len));
    }
    const std::vector<uint8_t> b = Bytes(len);
    if (b.back() != 0) throw std::runtime_error(where_ + ": string is not NUL-terminated");
    return std::string(b.begin(), b.end() - 1).c_str();  // stop at an embedded NUL
  }
  size_t remaining() const { return bytes_.size() - pos_; }

 private:
  void Need(size_t n) const {
    if (n > bytes_.size() - pos_) {
      throw std::runtime_error(where_ + ": fields end after " + std::to_string(bytes_.size()) +
                               " bytes, " + std::to_string(n) + " more needed at " +
                               std::to_string(pos_));
    }
  }
  const std::vector<uint8_t>& bytes_;
  size_t pos_{0};
  std::string where_;
};

uint64_t ReadLe(const uint8_t* p, int n) {
  uint64_t v = 0;
  for (int i = 0; i < n; ++i) v |= uint64_t{p[i]} << (8 * i);
  return v;
}

OniFileInfo Parse(ByteSource* src, const std::string& name, const OniReadLimits& limits) {
  const std::string prefix = "ONI reader: " + name;
  const uint64_t size = src->size();
  OniFileInfo info;
  if (size < internal::kOniFileHeaderSize) {
    throw std::runtime_error(prefix + ": " + std::to_string(size) +
                             " bytes is too short for an ONI header");
  }
  uint8_t header[internal::kOniFileHeaderSize];
  src->Read(0, header, sizeof(header));
  if (std::memcmp(header, internal::kOniMagic, 4) != 0) {
    throw std::runtime_error(prefix + ": not an ONI file (no \"NI10\" magic)");
  }
  info.version_major = header[4];
  info.version_minor = header[5];
  info.version_maintenance = static_cast<int>(ReadLe(header + 6, 2));
  info.version_build = static_cast<int>(ReadLe(header + 8, 4));
  info.global_max_timestamp = ReadLe(header + 12, 8);
  info.max_node_id = static_cast<uint32_t>(ReadLe(header + 20, 4));
  const uint64_t version = (uint64_t{static_cast<uint8_t>(info.version_major)} << 56) |
                           (uint64_t{static_cast<uint8_t>(info.version_minor)} << 48) |
                           (uint64_t{static_cast<uint16_t>(info.version_maintenance)} << 32) |
                           static_cast<uint32_t>(info.version_build);
  const uint64_t v1004 = (uint64_t{1} << 56) | 4;
  const uint64_t v1010 = (uint64_t{1} << 56) | (uint64_t{1} << 32);
  if (version < v1004 || version > v1010) {
    std::ostringstream os;
    os << prefix << ": unsupported ONI version " << info.version_major << "." << info.version_minor
       << "." << info.version_maintenance << "." << info.version_build
       << " (supported: 1.0.0.4 .. 1.0.1.0)";
    throw std::runtime_error(os.str());
  }
  const bool new_header = version >= v1010;
  const uint32_t header_size =
      new_header ? internal::kOniRecordHeaderSize : internal::kOniOldRecordHeaderSize;

  auto node_index = [&](uint32_t id, const std::string& where) -> size_t {
    for (size_t i = 0; i < info.nodes.size(); ++i) {
      if (info.nodes[i].id == id) return i;
    }
    throw std::runtime_error(where + ": record for node " + std::to_string(id) +
                             " which was never added");
  };

  uint64_t pos = internal::kOniFileHeaderSize;
  std::vector<uint8_t> fields;
  while (pos < size) {
    const std::string where = prefix + ": record at offset " + std::to_string(pos);
    if (size - pos < header_size) {
      throw std::runtime_error(where + ": truncated record header (" + std::to_string(size - pos) +
                               " bytes left)");
    }
    uint8_t rh[internal::kOniRecordHeaderSize];
    src->Read(pos, rh, header_size);
    const auto magic = static_cast<uint32_t>(ReadLe(rh, 4));
    const auto type = static_cast<uint32_t>(ReadLe(rh + 4, 4));
    const auto node_id = static_cast<uint32_t>(ReadLe(rh + 8, 4));
    const auto fields_size = static_cast<uint32_t>(ReadLe(rh + 12, 4));
    const auto payload_size = static_cast<uint32_t>(ReadLe(rh + 16, 4));
    if (magic != internal::kOniRecordMagic) throw std::runtime_error(where + ": bad record magic");
    if (fields_size < header_size || fields_size > limits.max_fields_bytes) {
      throw std::runtime_error(where + ": fields size " + std::to_string(fields_size) +
                               " is outside " + std::to_string(header_size) + ".." +
                               std::to_string(limits.max_fields_bytes));
    }
    const uint64_t record_size = uint64_t{fields_size} + payload_size;
    if (record_size > size - pos) {
      throw std::runtime_error(where + ": record of " + std::to_string(record_size) +
                               " bytes runs past the end of the file (" + std::to_string(size) +
                               " bytes); the file is truncated");
    }
    fields.resize(fields_size - header_size);
    src->Read(pos + header_size, fields.data(), fields.size());
    Cursor c(fields, where);
    ++info.record_count;
    const auto rtype = static_cast<OniRecordType>(type);
    if (rtype != OniRecordType::kEnd && new_header && node_id > info.max_node_id) {
      throw std::runtime_error(where + ": node id " + std::to_string(node_id) +
                               " exceeds the header's maxNodeId " +
                               std::to_string(info.max_node_id));
    }
    switch (rtype) {
      case OniRecordType::kNodeAdded:
      case OniRecordType::kNodeAdded1005:
      case OniRecordType::kNodeAdded1004: {
        for (const OniNodeInfo& n : info.nodes) {
          if (n.id == node_id && !n.removed) {
            throw std::runtime_error(where + ": node " + std::to_string(node_id) + " added twice");
          }
        }
        if (info.nodes.size() >= limits.max_nodes) {
          throw std::runtime_error(where + ": more than " + std::to_string(limits.max_nodes) +
                                   " nodes");
        }
        OniNodeInfo n;
        n.id = node_id;
        n.node_added_offset = pos;
        n.name = c.Str(limits.max_string_bytes);
        n.type = c.U32();
        const std::vector<uint8_t> codec = c.Bytes(4);
        n.codec.assign(codec.begin(), codec.end());
        if (rtype != OniRecordType::kNodeAdded1004) {
          n.number_of_frames = c.U32();
          n.min_timestamp_us = c.U64();
          n.max_timestamp_us = c.U64();
        }
        if (rtype == OniRecordType::kNodeAdded) {
          n.seek_table_offset = new_header ? c.U64() : c.U32();
        }
        info.nodes.push_back(std::move(n));
        break;
      }
      case OniRecordType::kIntProperty:
      case OniRecordType::kRealProperty:
      case OniRecordType::kStringProperty:
      case OniRecordType::kGeneralProperty: {
        OniNodeInfo& n = info.nodes[node_index(node_id, where)];
        const std::string prop = c.Str(limits.max_string_bytes);
        const uint32_t data_size = c.U32();
        if (data_size > c.remaining()) {
          throw std::runtime_error(where + ": property '" + prop + "' declares " +
                                   std::to_string(data_size) + " bytes, only " +
                                   std::to_string(c.remaining()) + " present");
        }
        if (rtype == OniRecordType::kIntProperty || rtype == OniRecordType::kRealProperty) {
          if (data_size != 8) {
            throw std::runtime_error(where + ": numeric property '" + prop + "' has " +
                                     std::to_string(data_size) + " bytes, expected 8");
          }
          const uint64_t raw = c.U64();
          if (rtype == OniRecordType::kIntProperty) {
            const auto value = static_cast<int64_t>(raw);
            n.int_properties[prop] = value;
            if (prop == "oniPixelFormat") n.pixel_format = value;
          } else {
            n.real_properties[prop] = std::bit_cast<double>(raw);
          }
        } else {
          const std::vector<uint8_t> value = c.Bytes(data_size);
          if (rtype == OniRecordType::kStringProperty) {
            n.string_properties[prop] = std::string(value.begin(), value.end()).c_str();
          } else {
            if (prop == "xnMapOutputMode" && value.size() >= 12) {
              const uint64_t w = ReadLe(value.data(), 4);
              const uint64_t h = ReadLe(value.data() + 4, 4);
              const uint64_t fps = ReadLe(value.data() + 8, 4);
              const std::optional<std::string> too_large =
                  limits.frame.CheckImage(static_cast<int64_t>(w), static_cast<int64_t>(h), 1);
              if (too_large || fps > 10000) {
                throw std::runtime_error(
                    where + ": implausible xnMapOutputMode " + std::to_string(w) + "x" +
                    std::to_string(h) + "@" + std::to_string(fps) +
                    (too_large ? " (" + *too_large + ")" : std::string(" (fps above 10000)")));
              }
              n.width = static_cast<int>(w);
              n.height = static_cast<int>(h);
              n.fps = static_cast<int>(fps);
            } else if (prop == "xnFOV" && value.size() >= 16) {
              n.hfov_rad = std::bit_cast<double>(ReadLe(value.data(), 8));
              n.vfov_rad = std::bit_cast<double>(ReadLe(value.data() + 8, 8));
            } else if (prop == "xnCropping") {
              n.has_cropping = true;
            }
            n.general_properties[prop] = value;
          }
        }
        break;
      }
      case OniRecordType::kNodeStateReady:
        info.nodes[node_index(node_id, where)].state_ready = true;
        break;
      case OniRecordType::kNodeDataBegin:
        info.nodes[node_index(node_id, where)].data_begin = true;
        break;
      case OniRecordType::kNodeRemoved:
        info.nodes[node_index(node_id, where)].removed = true;
        break;
      case OniRecordType::kNewData: {
        const size_t index = node_index(node_id, where);
        OniNodeInfo& n = info.nodes[index];
        OniFrameRecord f;
        f.node_index = index;
        f.timestamp_us = c.U64();
        f.frame_id = c.U32();
        f.record_offset = pos;
        f.payload_offset = pos + fields_size;
        f.payload_bytes = payload_size;
        if (f.frame_id == 0) throw std::runtime_error(where + ": frame id 0 (ids start at 1)");
        if (n.number_of_frames != std::numeric_limits<uint32_t>::max() && n.number_of_frames != 0 &&
            f.frame_id > n.number_of_frames) {
          throw std::runtime_error(where + ": frame id " + std::to_string(f.frame_id) +
                                   " exceeds the node's frame count " +
                                   std::to_string(n.number_of_frames));
        }
        if (f.timestamp_us > info.global_max_timestamp) {
          throw std::runtime_error(where + ": timestamp " + std::to_string(f.timestamp_us) +
                                   " exceeds the header's maximum " +
                                   std::to_string(info.global_max_timestamp));
        }
        if (payload_size > limits.max_frame_bytes) {
          throw std::runtime_error(where + ": frame of " + std::to_string(payload_size) +
                                   " bytes exceeds the limit " +
                                   std::to_string(limits.max_frame_bytes));
        }
        if (info.frames.size() >= limits.max_frame_records) {
          throw std::runtime_error(where + ": more than " +
                                   std::to_string(limits.max_frame_records) + " frame records");
        }
        ++n.data_records;
        info.frames.push_back(f);
        break;
      }
      case OniRecordType::kSeekTable: {
        OniNodeInfo& n = info.nodes[node_index(node_id, where)];
        if (payload_size % internal::kOniSeekEntrySize != 0) {
          throw std::runtime_error(where + ": seek table of " + std::to_string(payload_size) +
                                   " bytes is not a whole number of entries");
        }
        n.seek_table_entries = payload_size / internal::kOniSeekEntrySize;
        break;
      }
      case OniRecordType::kEnd:
        info.has_end = true;
        break;
      default:
        ++info.unknown_records;  // skipped, as OpenNI2 does
        break;
    }
    if (info.has_end) break;
    pos += record_size;
  }
  // A node's seek table is read where its NODE_ADDED says it is (as OpenNI2 does), also when
  // the walk above ended before it (an END record too early).
  for (OniNodeInfo& n : info.nodes) {
    if (n.seek_table_offset == 0 || n.seek_table_entries != 0 || n.seek_table_offset > size ||
        size - n.seek_table_offset < header_size) {
      continue;
    }
    uint8_t rh[internal::kOniRecordHeaderSize];
    src->Read(n.seek_table_offset, rh, header_size);
    const auto fields_size = static_cast<uint32_t>(ReadLe(rh + 12, 4));
    const auto payload_size = static_cast<uint32_t>(ReadLe(rh + 16, 4));
    if (ReadLe(rh, 4) == internal::kOniRecordMagic &&
        ReadLe(rh + 4, 4) == static_cast<uint32_t>(OniRecordType::kSeekTable) &&
        ReadLe(rh + 8, 4) == n.id && fields_size >= header_size &&
        uint64_t{fields_size} + payload_size <= size - n.seek_table_offset &&
        payload_size % internal::kOniSeekEntrySize == 0) {
      n.seek_table_entries = payload_size / internal::kOniSeekEntrySize;
    }
  }
  return info;
}

}  // namespace

const OniNodeInfo* OniFileInfo::FindNode(uint32_t type) const {
  const int i = FindNodeIndex(type);
  return i < 0 ? nullptr : &nodes[static_cast<size_t>(i)];
}

int OniFileInfo::FindNodeIndex(uint32_t type) const {
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (nodes[i].type == type) return static_cast<int>(i);
  }
  return -1;
}

OniFileInfo ParseOni(const uint8_t* data, size_t size, const std::string& name,
                     const OniReadLimits& limits) {
  MemorySource src(data, size);
  return Parse(&src, name, limits);
}

struct OniReader::Impl {
  std::string path;
  std::unique_ptr<FileSource> file;
  OniFileInfo info;
  std::vector<uint8_t> buffer;

  const OniFrameRecord& Frame(size_t index, uint32_t want_type, uint32_t bytes_per_pixel) const {
    if (!file) throw std::runtime_error("ONI reader: no file is open");
    if (index >= info.frames.size()) {
      throw std::runtime_error("ONI reader: " + path + ": frame " + std::to_string(index) +
                               " out of range (" + std::to_string(info.frames.size()) +
                               " records)");
    }
    const OniFrameRecord& f = info.frames[index];
    const OniNodeInfo& n = info.nodes[f.node_index];
    const std::string where = "ONI reader: " + path + ": frame record at offset " +
                              std::to_string(f.record_offset) + " (node '" + n.name + "')";
    if (n.type != want_type) {
      throw std::runtime_error(where + " is of node type " + std::to_string(n.type) +
                               ", expected " + std::to_string(want_type));
    }
    if (n.codec != "NONE") {
      throw std::runtime_error(where + ": codec '" + n.codec +
                               "' is not supported by this reader (only NONE)");
    }
    const uint64_t expected = uint64_t(n.width) * uint64_t(n.height) * bytes_per_pixel;
    if (n.width == 0 || f.payload_bytes != expected) {
      throw std::runtime_error(where + ": payload of " + std::to_string(f.payload_bytes) +
                               " bytes does not match " + std::to_string(n.width) + "x" +
                               std::to_string(n.height) + "x" + std::to_string(bytes_per_pixel));
    }
    return f;
  }
};

OniReader::OniReader() : impl_(std::make_unique<Impl>()) {}
OniReader::~OniReader() = default;

void OniReader::Open(const std::string& path, const OniReadLimits& limits) {
  Close();
  auto file = std::make_unique<FileSource>(path);
  OniFileInfo info = Parse(file.get(), path, limits);
  impl_->path = path;
  impl_->info = std::move(info);
  impl_->file = std::move(file);
}

void OniReader::Close() {
  impl_->file.reset();
  impl_->info = OniFileInfo{};
}

const OniFileInfo& OniReader::info() const { return impl_->info; }

void OniReader::ReadDepth(size_t index, core::DepthImage* depth) {
  const OniFrameRecord& f = impl_->Frame(index, 2, 2);
  const OniNodeInfo& n = impl_->info.nodes[f.node_index];
  impl_->buffer.resize(f.payload_bytes);
  impl_->file->Read(f.payload_offset, impl_->buffer.data(), f.payload_bytes);
  depth->Reset(n.width, n.height);
  for (size_t i = 0; i < depth->data.size(); ++i) {
    depth->data[i] = static_cast<uint16_t>(impl_->buffer[2 * i] | (impl_->buffer[2 * i + 1] << 8));
  }
}

void OniReader::ReadColor(size_t index, core::ColorImage* color) {
  const OniFrameRecord& f = impl_->Frame(index, 3, 3);
  const OniNodeInfo& n = impl_->info.nodes[f.node_index];
  impl_->buffer.resize(f.payload_bytes);
  impl_->file->Read(f.payload_offset, impl_->buffer.data(), f.payload_bytes);
  color->Reset(n.width, n.height);
  for (size_t i = 0; i < color->data.size(); ++i) {
    color->data[i] =
        core::Rgb8{impl_->buffer[3 * i], impl_->buffer[3 * i + 1], impl_->buffer[3 * i + 2]};
  }
}

void OniReader::ReadPayload(size_t index, std::vector<uint8_t>* payload) {
  if (!impl_->file) throw std::runtime_error("ONI reader: no file is open");
  if (index >= impl_->info.frames.size()) {
    throw std::runtime_error("ONI reader: " + impl_->path + ": frame " + std::to_string(index) +
                             " out of range");
  }
  const OniFrameRecord& f = impl_->info.frames[index];
  payload->resize(f.payload_bytes);
  impl_->file->Read(f.payload_offset, payload->data(), f.payload_bytes);
}

}  // namespace clutterseg::drivers
