#include "clutterseg/drivers/openni2/openni2_source.h"

#include <OpenNI.h>
#include <dlfcn.h>
#include <link.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include "clutterseg/core/param_check.h"
#include "clutterseg/drivers/oni/oni_reader.h"

namespace clutterseg::drivers {
namespace {

using Clock = std::chrono::steady_clock;

std::mutex g_openni_mutex;
bool g_openni_initialized = false;

std::string ExtendedError() {
  const char* e = openni::OpenNI::getExtendedError();
  return (e != nullptr && e[0] != '\0') ? std::string(e) : std::string("no details");
}

// OpenNI2 dlopen()s its device drivers (libOniFile, libPS1080, ...) in initialize() and
// dlclose()s them in shutdown() or at exit, while threads they started may still be ending
// and objects they allocated are still alive. Marking the loaded drivers RTLD_NODELETE keeps
// their code mapped until the process ends: no thread can run in unmapped code, and
// LeakSanitizer and ThreadSanitizer can still name the drivers in reports at exit (their
// suppression files match these libraries by name).
void PinOpenNI2Drivers() {
  std::vector<std::string> drivers;
  dl_iterate_phdr(
      [](dl_phdr_info* info, size_t, void* data) {
        const char* name = info->dlpi_name;
        if (name != nullptr && std::strstr(name, "/OpenNI2/Drivers/") != nullptr) {
          static_cast<std::vector<std::string>*>(data)->emplace_back(name);
        }
        return 0;
      },
      &drivers);
  for (const std::string& path : drivers) {
    // RTLD_NOLOAD: only promotes the flags of the loaded library. The extra reference is
    // deliberately never closed.
    (void)dlopen(path.c_str(), RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
  }
}

bool LooksLikeFile(const std::string& uri) {
  if (uri.empty()) return false;
  std::error_code ec;
  if (std::filesystem::is_regular_file(uri, ec)) return true;
  const std::string ext = ".oni";
  if (uri.size() >= ext.size()) {
    std::string tail = uri.substr(uri.size() - ext.size());
    std::transform(tail.begin(), tail.end(), tail.begin(),
                   [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
    if (tail == ext) return true;
  }
  return false;
}

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// How long Read() waits for the next depth frame of a recording before it takes the replay
// as stopped (OniFile's lockstep player delivers within milliseconds; a cut file stalls it).
constexpr auto kPlayerStallLimit = std::chrono::seconds(3);

// Intrinsics of a W x H stream with the given fields of view (radians), pixel-centre
// convention (see the class comment).
core::CameraIntrinsics IntrinsicsFromFov(int w, int h, double hfov, double vfov) {
  core::CameraIntrinsics k;
  k.width = w;
  k.height = h;
  k.fx = w / (2.0 * std::tan(hfov / 2.0));
  k.fy = h / (2.0 * std::tan(vfov / 2.0));
  k.cx = w / 2.0 - 0.5;
  k.cy = h / 2.0 - 0.5;
  return k;
}

std::string DescribeFov(double hfov, double vfov) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "%.1f x %.1f deg (%.4g x %.4g rad)", hfov * kRadToDeg,
                vfov * kRadToDeg, hfov, vfov);
  return buf;
}

// The same recording under another spelling of its path ("dir/./name.oni").
std::string ColorPlayerUri(const std::string& path) {
  const std::filesystem::path p(path);
  const std::filesystem::path parent = p.parent_path();
  return ((parent.empty() ? std::filesystem::path(".") : parent / ".") / p.filename()).string();
}

// Bytes per pixel of a NONE-coded node's frames, 0 when the format is not known here.
uint64_t BytesPerPixel(const OniNodeInfo& n) {
  if (n.type == 2) return 2;  // DEPTH_1_MM / DEPTH_100_UM
  if (n.type == 3 && (n.pixel_format < 0 || n.pixel_format == 200)) return 3;  // RGB888
  return 0;
}

// What the replay learnt from our own reading of a recording.
struct RecordingPlan {
  bool has_color{false};
  int64_t frames_in_source{0};  // depth frames the recording holds (declared or found)
  int64_t depth_records{0};     // depth frame records OpenNI2 can deliver
  int64_t color_records{0};
  std::string damage;  // why frames_in_source > depth_records, "" when equal
  size_t unknown_records{0};
  uintmax_t file_bytes{0};  // size of the file when it was checked
};

// Checks a recording with our own parser before OpenNI2 opens it: OniFile accepts some broken
// files and then hangs, delivers nothing, drops frames or replays garbage.
RecordingPlan ValidateRecording(const std::string& path, const core::FrameLimits& limits) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw std::runtime_error("OpenNI2 source: recording '" + path + "' does not exist");
  }
  OniReader reader;
  OniReadLimits read_limits;
  read_limits.frame = limits;
  try {
    reader.Open(path, read_limits);
  } catch (const std::exception& e) {
    throw std::runtime_error("OpenNI2 source: recording '" + path +
                             "' cannot be replayed: " + e.what());
  }
  const OniFileInfo& info = reader.info();
  auto fail = [&](const std::string& why) {
    throw std::runtime_error("OpenNI2 source: recording '" + path + "' cannot be replayed: " + why);
  };
  if (info.version_maintenance < 1) {
    fail("it was written by an old OpenNI 1.x recorder (version " +
         std::to_string(info.version_major) + "." + std::to_string(info.version_minor) + "." +
         std::to_string(info.version_maintenance) + "." + std::to_string(info.version_build) +
         "), which OpenNI2 does not read reliably");
  }
  if (!info.has_end) fail("it was never finalized (no END record)");
  const int depth_index = info.FindNodeIndex(2);
  const int color_index = info.FindNodeIndex(3);
  if (depth_index < 0) fail("it has no depth stream");
  for (size_t i = 0; i < info.nodes.size(); ++i) {
    const OniNodeInfo& n = info.nodes[i];
    if (n.type != 2 && n.type != 3) continue;
    if (!n.has_cropping) {
      fail("stream '" + n.name +
           "' has no xnCropping property, so OpenNI2 would deliver no frames");
    }
    if (n.width == 0) fail("stream '" + n.name + "' has no xnMapOutputMode property");
    if (!n.state_ready || !n.data_begin) fail("stream '" + n.name + "' never starts its data");
    // OniFile reads a seek table of (frames + 1) entries: a count its table does not confirm
    // is refused (it would also size OniFile's allocation).
    const bool declared = n.number_of_frames != std::numeric_limits<uint32_t>::max();
    if (declared && n.seek_table_offset != 0 &&
        uint64_t{n.seek_table_entries} != uint64_t{n.number_of_frames} + 1) {
      fail("stream '" + n.name + "' declares " + std::to_string(n.number_of_frames) +
           " frames but its seek table holds " + std::to_string(n.seek_table_entries) +
           " entries (expected one more than the frames)");
    }
    const uint64_t bpp = BytesPerPixel(n);
    const std::string size = std::to_string(n.width) + "x" + std::to_string(n.height);
    if (const std::optional<std::string> too_large =
            limits.CheckImage(n.width, n.height, bpp == 0 ? 1 : bpp)) {
      fail("stream '" + n.name + "': declared size " + *too_large);
    }
    const uint64_t frame_bytes = uint64_t(n.width) * uint64_t(n.height) * (bpp == 0 ? 1 : bpp);
    // OniFile cuts every frame to oniRequiredFrameSize: smaller than the image, each frame
    // would arrive short (or not at all when it is negative).
    if (const auto it = n.int_properties.find("oniRequiredFrameSize");
        it != n.int_properties.end() && bpp != 0) {
      const int64_t required = it->second;
      if (required < 0 || static_cast<uint64_t>(required) < frame_bytes ||
          static_cast<uint64_t>(required) > limits.max_bytes) {
        fail("stream '" + n.name + "' declares oniRequiredFrameSize = " + std::to_string(required) +
             ", expected " + std::to_string(frame_bytes) + " (" + size + " x " +
             std::to_string(bpp) + " bytes) up to the frame limit of " +
             std::to_string(limits.max_bytes) + " bytes");
      }
    }
    // Raw frames must hold exactly the declared image: a declared size smaller (or larger)
    // than the stored frames would replay them garbled.
    if (n.codec == "NONE" && bpp != 0) {
      int64_t k = 0;
      for (const OniFrameRecord& f : info.frames) {
        if (f.node_index != i) continue;
        ++k;
        if (f.payload_bytes != frame_bytes) {
          fail("frame " + std::to_string(k) + " of stream '" + n.name + "' (record at offset " +
               std::to_string(f.record_offset) + ") holds " + std::to_string(f.payload_bytes) +
               " bytes, but the stream declares " + size + " x " + std::to_string(bpp) + " = " +
               std::to_string(frame_bytes) + " bytes per frame");
        }
      }
    }
  }
  const OniNodeInfo& depth = info.nodes[static_cast<size_t>(depth_index)];
  if (depth.data_records == 0) fail("it holds no depth frames");
  // A field of view no camera has (a corrupted xnFOV) would make every pixel a voxel of its
  // own or every frame a single voxel.
  if (const auto it = depth.general_properties.find("xnFOV");
      it != depth.general_properties.end()) {
    if (it->second.size() < 16) {
      fail("stream '" + depth.name + "' has a malformed xnFOV property of " +
           std::to_string(it->second.size()) + " bytes (expected 16)");
    }
    const core::CameraIntrinsics k =
        IntrinsicsFromFov(depth.width, depth.height, depth.hfov_rad, depth.vfov_rad);
    try {
      k.ValidateOrThrow("intrinsics");
    } catch (const std::invalid_argument& e) {
      fail("stream '" + depth.name + "' has a field of view of " +
           DescribeFov(depth.hfov_rad, depth.vfov_rad) +
           " (xnFOV), which no camera has: " + e.what());
    }
  }
  RecordingPlan plan;
  plan.has_color = color_index >= 0;
  plan.file_bytes = std::filesystem::file_size(path, ec);
  plan.unknown_records = info.unknown_records;
  plan.depth_records = depth.data_records;
  plan.color_records =
      color_index >= 0 ? info.nodes[static_cast<size_t>(color_index)].data_records : 0;
  // The frames the recording holds: its declared count when its seek table confirms it
  // (frame records damaged since then are counted as not delivered), else the records.
  const bool confirmed = depth.number_of_frames != std::numeric_limits<uint32_t>::max() &&
                         depth.seek_table_offset != 0;
  plan.frames_in_source = std::max<int64_t>(confirmed ? depth.number_of_frames : 0,
                                            static_cast<int64_t>(depth.data_records));
  if (plan.frames_in_source > plan.depth_records) {
    plan.damage = "the recording declares " + std::to_string(plan.frames_in_source) +
                  " depth frames but holds " + std::to_string(plan.depth_records) +
                  " readable frame records (damaged records)";
  }
  return plan;
}

}  // namespace

void OpenNI2SourceOptions::ValidateOrThrow() const {
  const core::ParamCheck check("camera");
  check.Require(uri.empty() || serial.empty(), "serial", serial, "either a URI or a serial");
  check.InRange("width", width, 1, 4096, "px");
  check.InRange("height", height, 1, 4096, "px");
  check.InRange("fps", fps, 1, 1000);
  check.Require(replay_speed == -1.0 || (replay_speed > 0.0 && replay_speed <= 1000.0),
                "replay_speed", replay_speed, "-1 (lockstep) or a speed factor in (0, 1000]");
  limits.ValidateOrThrow("limits");
  if (intrinsics) intrinsics->ValidateOrThrow("camera.intrinsics");
}

void InitializeOpenNI2(OpenNI2Drivers drivers) {
  std::lock_guard<std::mutex> lock(g_openni_mutex);
  if (g_openni_initialized) return;
  std::string error;
  if (!internal::LoadOpenNI2Library(drivers, &error)) {
    throw std::runtime_error("OpenNI2 initialization failed: " + error);
  }
  const openni::Status rc = openni::OpenNI::initialize();
  if (rc != openni::STATUS_OK) {
    throw std::runtime_error("OpenNI2 initialization failed (status " +
                             std::to_string(static_cast<int>(rc)) + "): " + ExtendedError());
  }
  PinOpenNI2Drivers();
  g_openni_initialized = true;
}

std::string DescribeOpenNI2() {
  const std::string path = internal::LoadedOpenNI2Library();
  if (path.empty()) return path;
  return path +
         (internal::OpenNI2LoadedForRecordingsOnly() ? " (OniFile driver only)" : " (all drivers)");
}

void ShutdownOpenNI2() {
  std::lock_guard<std::mutex> lock(g_openni_mutex);
  if (!g_openni_initialized) return;
  openni::OpenNI::shutdown();
  g_openni_initialized = false;
}

struct OpenNI2Source::Impl {
  // Device events arrive on OpenNI2 threads: record them in atomics only.
  class StateListener final : public openni::OpenNI::DeviceStateChangedListener {
   public:
    explicit StateListener(Impl* owner) : owner_(owner) {}
    void onDeviceStateChanged(const openni::DeviceInfo* info, openni::DeviceState state) override {
      try {
        if (state == openni::DEVICE_STATE_EOF && owner_->MatchesDevice(info)) {
          owner_->eof_event.store(true);
        } else if (state == openni::DEVICE_STATE_EOF && owner_->MatchesColorDevice(info)) {
          owner_->color_eof_event.store(true);
        }
      } catch (...) {  // nothing may escape into OpenNI2
      }
    }

   private:
    Impl* owner_;
  };
  class DisconnectListener final : public openni::OpenNI::DeviceDisconnectedListener {
   public:
    explicit DisconnectListener(Impl* owner) : owner_(owner) {}
    void onDeviceDisconnected(const openni::DeviceInfo* info) override {
      try {
        if (owner_->MatchesDevice(info)) owner_->disconnected.store(true);
      } catch (...) {
      }
    }

   private:
    Impl* owner_;
  };

  explicit Impl(const OpenNI2SourceOptions& o)
      : options(o), state_listener(this), disconnect_listener(this) {}

  bool MatchesDevice(const openni::DeviceInfo* info) const {
    if (info == nullptr) return false;
    const char* uri = info->getUri();
    return uri != nullptr && device_uri_set.load() && device_uri == uri;
  }
  bool MatchesColorDevice(const openni::DeviceInfo* info) const {
    if (info == nullptr) return false;
    const char* uri = info->getUri();
    return uri != nullptr && device_uri_set.load() && color_device_uri == uri;
  }

  const OpenNI2SourceOptions options;
  StateListener state_listener;
  DisconnectListener disconnect_listener;
  bool listeners_added{false};
  core::SourceCounters counters;  // over every Open()

  openni::Device device;
  // A recording's colour is read through a second player of the same file, opened under
  // another spelling of its path (ColorPlayerUri) so that its EOF event can be told apart.
  openni::Device color_device;
  openni::VideoStream depth_stream;
  openni::VideoStream color_stream;
  openni::VideoStream* streams[2]{nullptr, nullptr};
  int stream_count{0};
  bool depth_created{false};
  bool color_created{false};
  bool streams_running{false};
  Clock::time_point stopped_at{};

  std::string device_uri;        // written before device_uri_set, then read-only
  std::string color_device_uri;  // likewise
  std::atomic<bool> device_uri_set{false};
  std::atomic<bool> eof_event{false};
  std::atomic<bool> color_eof_event{false};
  std::atomic<bool> disconnected{false};
  std::atomic<bool> stop_requested{false};

  bool open{false};
  bool file{false};
  bool with_color{false};
  bool registered{false};
  bool fov_from_device{true};
  bool calibrated{false};  // options.intrinsics replaced the field of view's
  bool end_reached{false};
  uint64_t sequence{0};
  core::CameraIntrinsics intr;
  openni::PixelFormat depth_format{openni::PIXEL_FORMAT_DEPTH_1_MM};
  std::string description;
  std::string error;

  // Recording accounting (file only): what our reader found, and what this pass read.
  RecordingPlan plan;
  int64_t depth_read_pass{0};  // depth frames OpenNI2 delivered in this pass
  int64_t color_read_pass{0};
  int last_depth_index{0};

  // Pairing: a depth frame waiting for its colour, a colour frame waiting for its depth, and
  // the next frame to deliver (its colour attached or not).
  int64_t pair_tolerance_us{16667};
  openni::VideoFrameRef pending_depth;
  bool have_pending{false};
  Clock::time_point pending_deadline{};  // when a waiting depth stops waiting for colour
  openni::VideoFrameRef held_color;
  bool have_held_color{false};
  openni::VideoFrameRef out_depth;
  openni::VideoFrameRef out_color;
  bool have_out{false};
  bool out_with_color{false};
  openni::VideoFrameRef incoming;

  // Pacing of a recording replayed at a speed > 0 (OpenNI2 itself runs in lockstep).
  bool pace{false};
  bool pace_base_set{false};
  int64_t pace_ts0{0};
  int64_t pace_last_ts{0};  // timestamp of the frame paced last
  // Whether Read() is waiting for the player's next depth frame, and since when (the time
  // spent in Read(), not the consumer's time between reads, is what counts as a stall).
  bool waiting_for_depth{false};
  Clock::time_point depth_wait_start{};
  Clock::time_point pace_t0{};
  Clock::time_point pace_last_due{};  // when the frame paced last was due

  [[noreturn]] void Fail(const std::string& what) {
    const std::string msg = "OpenNI2 source '" + Name() + "': " + what;
    Teardown();
    throw std::runtime_error(msg);
  }

  std::string Name() const {
    if (!options.serial.empty()) return "serial " + options.serial;
    return options.uri.empty() ? std::string("first device") : options.uri;
  }

  // Live devices only: OpenNI2 keeps listing recordings opened earlier in the process, and
  // ANY_DEVICE would happily open one of those.
  static std::vector<std::string> LiveDeviceUris() {
    openni::Array<openni::DeviceInfo> list;
    openni::OpenNI::enumerateDevices(&list);
    std::vector<std::string> uris;
    for (int i = 0; i < list.getSize(); ++i) {
      const char* uri = list[i].getUri();
      if (uri != nullptr && !LooksLikeFile(uri)) uris.emplace_back(uri);
    }
    return uris;
  }

  void OpenLiveDevice() {
    if (internal::OpenNI2LoadedForRecordingsOnly()) {
      Fail(
          "cannot open a live device: this process loaded OpenNI2 for recordings only, "
          "without the camera drivers");
    }
    if (!options.serial.empty()) {
      const std::vector<std::string> uris = LiveDeviceUris();
      std::string seen;
      for (const std::string& uri : uris) {
        openni::Device candidate;
        if (candidate.open(uri.c_str()) != openni::STATUS_OK) continue;
        char serial[128] = {0};
        int size = sizeof(serial) - 1;
        const bool got = candidate.getProperty(openni::DEVICE_PROPERTY_SERIAL_NUMBER, serial,
                                               &size) == openni::STATUS_OK;
        candidate.close();
        if (!got) continue;
        serial[std::min<int>(std::max(size, 0), static_cast<int>(sizeof(serial)) - 1)] = '\0';
        if (options.serial == serial) {
          if (device.open(uri.c_str()) != openni::STATUS_OK) {
            Fail("cannot open device " + uri + ": " + ExtendedError());
          }
          return;
        }
        if (!seen.empty()) seen += ", ";
        seen += serial;
      }
      Fail("no device with serial '" + options.serial + "' (" + std::to_string(uris.size()) +
           " device(s) found" + (seen.empty() ? std::string() : ": " + seen) + ")");
    }
    std::string uri = options.uri;
    if (uri.empty()) {
      const std::vector<std::string> uris = LiveDeviceUris();
      if (uris.empty()) Fail("no OpenNI2 device is connected");
      uri = uris.front();
    }
    if (device.open(uri.c_str()) != openni::STATUS_OK) {
      Fail("cannot open device " + uri + ": " + ExtendedError());
    }
  }

  // Picks the closest mode of `sensor` with the given format (exact size and rate preferred).
  void SetLiveMode(openni::VideoStream* stream, openni::SensorType sensor,
                   openni::PixelFormat format, const char* what) {
    const openni::SensorInfo* info = device.getSensorInfo(sensor);
    if (info == nullptr) Fail(std::string("device has no ") + what + " sensor");
    const openni::Array<openni::VideoMode>& modes = info->getSupportedVideoModes();
    std::ostringstream listing;
    for (int i = 0; i < modes.getSize(); ++i) {
      const openni::VideoMode& m = modes[i];
      listing << " " << m.getResolutionX() << "x" << m.getResolutionY() << "@" << m.getFps() << "/"
              << static_cast<int>(m.getPixelFormat());
      if (m.getPixelFormat() == format && m.getResolutionX() == options.width &&
          m.getResolutionY() == options.height && m.getFps() == options.fps) {
        if (stream->setVideoMode(m) != openni::STATUS_OK) {
          Fail(std::string("cannot set the ") + what + " video mode: " + ExtendedError());
        }
        return;
      }
    }
    Fail(std::string("the ") + what + " sensor has no mode " + std::to_string(options.width) + "x" +
         std::to_string(options.height) + "@" + std::to_string(options.fps) + " in pixel format " +
         std::to_string(static_cast<int>(format)) + "; supported:" + listing.str());
  }

  void ComputeIntrinsics(const openni::VideoMode& mode) {
    const int w = mode.getResolutionX();
    const int h = mode.getResolutionY();
    if (const std::optional<std::string> too_large = options.limits.CheckImage(w, h, 2)) {
      Fail("the depth stream's size " + *too_large);
    }
    if (options.intrinsics) {
      const core::CameraIntrinsics& k = *options.intrinsics;
      if (static_cast<int64_t>(k.width) * h != static_cast<int64_t>(k.height) * w) {
        Fail("the calibrated intrinsics are for " + std::to_string(k.width) + "x" +
             std::to_string(k.height) + " px, another aspect ratio than the depth stream's " +
             std::to_string(w) + "x" + std::to_string(h));
      }
      intr = k.Scaled(w, h);
      calibrated = true;
      return;
    }
    // Depth registered to colour is in the colour camera's image: its field of view is the
    // colour stream's (as openni2_camera does), not the depth sensor's.
    openni::VideoStream& fov_stream = registered ? color_stream : depth_stream;
    const double hfov = fov_stream.getHorizontalFieldOfView();
    const double vfov = fov_stream.getVerticalFieldOfView();
    if (hfov == 0.0 && vfov == 0.0) {
      // No field of view reported (a recording without xnFOV, some drivers).
      intr = core::DefaultKinectIntrinsics().Scaled(w, h);
      fov_from_device = false;
      return;
    }
    intr = IntrinsicsFromFov(w, h, hfov, vfov);
    fov_from_device = true;
    try {
      intr.ValidateOrThrow("intrinsics");
    } catch (const std::invalid_argument& e) {
      Fail("the depth stream reports a field of view of " + DescribeFov(hfov, vfov) +
           ", which no camera has: " + e.what());
    }
  }

  void OpenImpl() {
    InitializeOpenNI2();
    file = options.serial.empty() && LooksLikeFile(options.uri);
    if (file) {
      plan = ValidateRecording(options.uri, options.limits);
      counters.SetFramesInSource(plan.frames_in_source);
    } else {
      plan = RecordingPlan{};
    }

    if (file) {
      if (device.open(options.uri.c_str()) != openni::STATUS_OK) {
        Fail("OpenNI2 cannot open the recording: " + ExtendedError());
      }
    } else {
      OpenLiveDevice();
    }
    device_uri = device.getDeviceInfo().getUri();
    with_color = options.color && (file ? plan.has_color : device.hasSensor(openni::SENSOR_COLOR));
    if (file && with_color) {
      const std::string uri = ColorPlayerUri(options.uri);
      if (color_device.open(uri.c_str()) != openni::STATUS_OK) {
        Fail("OpenNI2 cannot open the recording's colour: " + ExtendedError());
      }
      color_device_uri = color_device.getDeviceInfo().getUri();
    }
    device_uri_set.store(true);
    if (openni::OpenNI::addDeviceStateChangedListener(&state_listener) == openni::STATUS_OK &&
        openni::OpenNI::addDeviceDisconnectedListener(&disconnect_listener) == openni::STATUS_OK) {
      listeners_added = true;
    }

    if (file) {
      for (openni::Device* d : {&device, &color_device}) {
        if (!d->isValid()) continue;
        openni::PlaybackControl* playback = d->getPlaybackControl();
        if (playback == nullptr) Fail("the recording has no playback control");
        playback->setRepeatEnabled(options.loop);
        // Always lockstep: OpenNI2's free-running player drops frames the consumer misses
        // (all of them when timestamps are equal); a speed > 0 is paced in Read().
        playback->setSpeed(-1.0f);
      }
      pace = options.replay_speed > 0;
    }

    if (depth_stream.create(device, openni::SENSOR_DEPTH) != openni::STATUS_OK) {
      Fail("cannot create the depth stream: " + ExtendedError());
    }
    depth_created = true;
    if (with_color) {
      if (color_stream.create(file ? color_device : device, openni::SENSOR_COLOR) !=
          openni::STATUS_OK) {
        Fail("cannot create the colour stream: " + ExtendedError());
      }
      color_created = true;
    }

    if (!file) {
      SetLiveMode(&depth_stream, openni::SENSOR_DEPTH, openni::PIXEL_FORMAT_DEPTH_1_MM, "depth");
      depth_stream.setMirroringEnabled(false);
      if (with_color) {
        SetLiveMode(&color_stream, openni::SENSOR_COLOR, openni::PIXEL_FORMAT_RGB888, "colour");
        color_stream.setMirroringEnabled(false);
        device.setDepthColorSyncEnabled(true);
        if (options.registration &&
            device.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR)) {
          registered = device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR) ==
                       openni::STATUS_OK;
        }
      }
    }

    const openni::VideoMode depth_mode = depth_stream.getVideoMode();
    depth_format = depth_mode.getPixelFormat();
    if (depth_format != openni::PIXEL_FORMAT_DEPTH_1_MM &&
        depth_format != openni::PIXEL_FORMAT_DEPTH_100_UM) {
      Fail("depth pixel format " + std::to_string(static_cast<int>(depth_format)) +
           " is not DEPTH_1_MM or DEPTH_100_UM");
    }
    if (with_color && color_stream.getVideoMode().getPixelFormat() != openni::PIXEL_FORMAT_RGB888) {
      Fail("colour pixel format " +
           std::to_string(static_cast<int>(color_stream.getVideoMode().getPixelFormat())) +
           " is not RGB888");
    }
    ComputeIntrinsics(depth_mode);
    const int fps = depth_mode.getFps();
    pair_tolerance_us = fps > 0 && fps <= 1000 ? 500000 / fps : 16667;

    if (depth_stream.start() != openni::STATUS_OK) {
      Fail("cannot start the depth stream: " + ExtendedError());
    }
    streams_running = true;
    streams[0] = &depth_stream;
    stream_count = 1;
    if (with_color) {
      if (color_stream.start() != openni::STATUS_OK) {
        Fail("cannot start the colour stream: " + ExtendedError());
      }
      streams[1] = &color_stream;
      stream_count = 2;
    }

    std::ostringstream os;
    os << (file ? "oni:" : "openni2:") << (file ? options.uri : device_uri);
    if (!file && !options.serial.empty()) os << " serial " << options.serial;
    os << " (" << depth_mode.getResolutionX() << "x" << depth_mode.getResolutionY();
    if (!file) os << "@" << depth_mode.getFps();
    os << (with_color ? " depth+color" : " depth");
    if (registered) os << " registered";
    if (file) {
      os << ", " << plan.frames_in_source << " frames";
      if (!plan.damage.empty()) os << " (" << plan.depth_records << " readable)";
      os << ", speed ";
      if (options.replay_speed < 0) {
        os << "lockstep";
      } else {
        os << options.replay_speed;
      }
      if (options.loop) os << ", loop";
    }
    if (calibrated) {
      os << ", calibrated intrinsics";
    } else if (!fov_from_device) {
      os << ", no FOV: default intrinsics";
    }
    os << ")";
    description = os.str();
    open = true;
  }

  void StopStreams() {
    if (!streams_running) return;
    if (depth_created) depth_stream.stop();
    if (color_created) color_stream.stop();
    streams_running = false;
    stopped_at = Clock::now();
  }

  void ReleaseFrames() {
    pending_depth.release();
    held_color.release();
    out_depth.release();
    out_color.release();
    incoming.release();
    have_pending = have_held_color = have_out = out_with_color = false;
  }

  // Stops, waits out OpenNI2's teardown races, destroys and closes. Never throws.
  void Teardown() {
    const bool was_running = streams_running;
    StopStreams();
    if (depth_created || color_created) {
      // OniFile's player thread (and DummyDevice's stream thread) may still touch the streams
      // right after stop(): destroying them at once crashes sometimes.
      const auto settle = std::chrono::milliseconds(file ? 50 : 150);
      const auto since = Clock::now() - stopped_at;
      if (was_running || since < settle) {
        std::this_thread::sleep_for(settle - std::min<Clock::duration>(since, settle));
      }
    }
    ReleaseFrames();
    if (color_created) color_stream.destroy();
    if (depth_created) depth_stream.destroy();
    color_created = depth_created = false;
    streams[0] = streams[1] = nullptr;
    stream_count = 0;
    if (listeners_added) {
      openni::OpenNI::removeDeviceStateChangedListener(&state_listener);
      openni::OpenNI::removeDeviceDisconnectedListener(&disconnect_listener);
      listeners_added = false;
    }
    if (device.isValid()) device.close();
    if (color_device.isValid()) color_device.close();
    device_uri_set.store(false);
    open = false;
  }

  // Rows of `f` whose `row_bytes` lie inside the frame's data (all of them for a sound frame).
  static int CompleteRows(const openni::VideoFrameRef& f, int row_bytes) {
    const int stride = f.getStrideInBytes();
    const int size = f.getDataSize();
    if (f.getData() == nullptr || stride < row_bytes || size < row_bytes || row_bytes <= 0) {
      return 0;
    }
    return std::min(f.getHeight(), 1 + (size - row_bytes) / stride);
  }

  // Why a delivered frame cannot be used (too large, or its data shorter than its image);
  // std::nullopt for a sound frame.
  std::optional<std::string> FrameProblem(const openni::VideoFrameRef& f, int bytes_per_pixel,
                                          core::SkipReason* reason) const {
    const int w = f.getWidth();
    const int h = f.getHeight();
    if (const std::optional<std::string> too_large =
            options.limits.CheckImage(w, h, static_cast<uint64_t>(bytes_per_pixel))) {
      *reason = core::SkipReason::kTooLarge;
      return "its size " + *too_large;
    }
    if (CompleteRows(f, w * bytes_per_pixel) < h) {
      *reason = core::SkipReason::kSizeMismatch;
      return "its data of " + std::to_string(f.getDataSize()) + " bytes (stride " +
             std::to_string(f.getStrideInBytes()) + ") is shorter than its " + std::to_string(w) +
             "x" + std::to_string(h) + " image";
    }
    return std::nullopt;
  }

  void CopyDepth(const openni::VideoFrameRef& f, core::DepthImage* out) const {
    const int w = f.getWidth();
    const int h = f.getHeight();
    out->width = w;
    out->height = h;
    out->data.resize(static_cast<size_t>(w) * h);
    const auto* base = static_cast<const uint8_t*>(f.getData());
    const int stride = f.getStrideInBytes();
    const int rows = CompleteRows(f, w * static_cast<int>(sizeof(uint16_t)));
    // FrameProblem() refused short frames; never read past the data regardless.
    std::fill(out->data.begin() + static_cast<std::ptrdiff_t>(rows) * w, out->data.end(),
              uint16_t{0});
    for (int v = 0; v < rows; ++v) {
      const auto* row = reinterpret_cast<const uint16_t*>(base + static_cast<size_t>(v) * stride);
      uint16_t* dst = out->data.data() + static_cast<size_t>(v) * w;
      if (depth_format == openni::PIXEL_FORMAT_DEPTH_100_UM) {
        for (int u = 0; u < w; ++u) dst[u] = static_cast<uint16_t>((row[u] + 5) / 10);
      } else {
        std::memcpy(dst, row, static_cast<size_t>(w) * sizeof(uint16_t));
      }
    }
  }

  static void CopyColor(const openni::VideoFrameRef& f, core::ColorImage* out) {
    const int w = f.getWidth();
    const int h = f.getHeight();
    out->width = w;
    out->height = h;
    out->data.resize(static_cast<size_t>(w) * h);
    const auto* base = static_cast<const uint8_t*>(f.getData());
    const int stride = f.getStrideInBytes();
    const int rows = CompleteRows(f, w * 3);
    std::fill(out->data.begin() + static_cast<std::ptrdiff_t>(rows) * w, out->data.end(),
              core::Rgb8{});
    for (int v = 0; v < rows; ++v) {
      std::memcpy(out->data.data() + static_cast<size_t>(v) * w,
                  base + static_cast<size_t>(v) * stride, static_cast<size_t>(w) * 3);
    }
  }

  std::string FrameName(const char* what, const openni::VideoFrameRef& f) const {
    return Name() + ": " + what + " frame " + std::to_string(f.getFrameIndex()) + " (timestamp " +
           std::to_string(f.getTimestamp()) + " us)";
  }

  // Delivers `out_depth` (with `out_color` when attached) into `frame`.
  void Emit(core::RgbdFrame* frame) {
    frame->receive_utime = core::SteadyClockMicros();
    frame->utime = static_cast<int64_t>(out_depth.getTimestamp());
    frame->sequence = sequence++;
    frame->camera_name = options.camera_name;
    CopyDepth(out_depth, &frame->depth);
    frame->intrinsics = intr;
    if (frame->depth.width != intr.width || frame->depth.height != intr.height) {
      frame->intrinsics = intr.Scaled(frame->depth.width, frame->depth.height);
    }
    bool attached = false;
    if (out_with_color && out_color.getWidth() == frame->depth.width &&
        out_color.getHeight() == frame->depth.height) {
      CopyColor(out_color, &frame->color);
      attached = true;
    } else {
      if (out_with_color) counters.ColorUnmatched();  // another size than the depth
      frame->color.Reset(0, 0);
    }
    const bool empty = std::none_of(frame->depth.data.begin(), frame->depth.data.end(),
                                    [](uint16_t d) { return d != 0; });
    counters.Delivered(empty, with_color && !attached);
    out_depth.release();
    out_color.release();
    have_out = out_with_color = false;
  }

  // Makes `pending_depth` the next frame to deliver, with `held_color` when `with`.
  void ReleasePending(bool with) {
    out_depth = pending_depth;
    pending_depth.release();
    have_pending = false;
    out_with_color = with;
    if (with) {
      out_color = held_color;
      held_color.release();
      have_held_color = false;
    }
    have_out = true;
  }

  // Pairs the waiting depth and colour frames when they belong together: timestamps within
  // half a frame period (frame ids are no guide: each stream numbers its own frames, and a
  // dropped colour frame shifts them). Colour older than the depth is dropped (its depth came
  // and went); colour newer than it means the depth's own colour is missing: the depth goes
  // alone and the colour waits for the next depth.
  void TryPair() {
    if (!have_pending || !have_held_color || have_out) return;
    const int64_t dt = static_cast<int64_t>(held_color.getTimestamp()) -
                       static_cast<int64_t>(pending_depth.getTimestamp());
    if (dt <= pair_tolerance_us && dt >= -pair_tolerance_us) {
      ReleasePending(true);
    } else if (dt < 0) {
      held_color.release();
      have_held_color = false;
      counters.ColorUnmatched();
    } else {
      ReleasePending(false);
    }
  }

  // Ends one pass over a recording: frames it holds that were neither delivered nor skipped
  // are counted as not delivered.
  void FinishPass(const std::string& stalled = "") {
    if (!file) return;
    const int64_t missing_records = plan.frames_in_source - plan.depth_records;
    if (missing_records > 0) {
      counters.Skipped(core::SkipReason::kNotDelivered, options.uri + ": " + plan.damage,
                       static_cast<uint64_t>(missing_records));
    }
    const int64_t undelivered = plan.depth_records - depth_read_pass;
    if (undelivered > 0) {
      std::string why = options.uri + ": OpenNI2 delivered " + std::to_string(depth_read_pass) +
                        " of the recording's " + std::to_string(plan.depth_records) +
                        " depth frame records";
      if (!stalled.empty()) {
        why += " (" + stalled + ")";
      } else if (plan.unknown_records > 0) {
        why += " (the recording holds " + std::to_string(plan.unknown_records) +
               " damaged records of unknown type; OpenNI2 loses the frame after each)";
      }
      counters.Skipped(core::SkipReason::kNotDelivered, why, static_cast<uint64_t>(undelivered));
    }
    counters.PassCompleted();
    depth_read_pass = 0;
    color_read_pass = 0;
  }

  // The lockstep player delivers the next depth frame within milliseconds; when it delivers
  // none for kPlayerStallLimit (the file was cut or replaced while it was replayed, or OniFile
  // stopped on a record it cannot read), the pass ends and the frames it did not deliver are
  // counted, also when looping (the next pass would stop at the same place).
  core::ReadStatus PlayerStalled() {
    std::error_code ec;
    const uintmax_t bytes = std::filesystem::file_size(options.uri, ec);
    std::string why =
        "no frame for " + std::to_string(std::chrono::seconds(kPlayerStallLimit).count()) + " s";
    if (ec) {
      why += "; the recording is gone: " + ec.message();
    } else if (bytes != plan.file_bytes) {
      why += "; the recording changed while it was replayed: " + std::to_string(bytes) +
             " bytes, " + std::to_string(plan.file_bytes) + " when it was opened";
    }
    error = options.uri + ": the replay stopped: " + why;
    return EndOfStream(why);
  }

  core::ReadStatus EndOfStream(const std::string& stalled = "") {
    if (!end_reached) {
      end_reached = true;
      FinishPass(stalled);
      StopStreams();  // ends the player's busy loop at EOF
    }
    return core::ReadStatus::kEndOfStream;
  }

  // A depth frame arrived in `incoming`.
  void OnDepth() {
    waiting_for_depth = false;
    if (file && options.loop && plan.depth_records > 0 &&
        (depth_read_pass >= plan.depth_records || incoming.getFrameIndex() <= last_depth_index)) {
      FinishPass();  // the player rewound
    }
    last_depth_index = incoming.getFrameIndex();
    ++depth_read_pass;
    core::SkipReason reason{};
    if (const std::optional<std::string> problem = FrameProblem(incoming, 2, &reason)) {
      counters.Skipped(reason, FrameName("depth", incoming) + ": " + *problem);
      incoming.release();
      return;
    }
    if (!with_color) {
      out_depth = incoming;
      incoming.release();
      have_out = true;
      out_with_color = false;
      return;
    }
    // A depth still waiting for colour goes alone: its colour is missing or late.
    if (have_pending) ReleasePending(false);
    pending_depth = incoming;
    incoming.release();
    have_pending = true;
    // A live camera's colour comes within a frame period; a recording's next record comes at
    // once unless the player is at its end (or starved of CPU).
    const auto wait =
        file ? std::chrono::milliseconds(2000)
             : std::chrono::milliseconds(std::max<int64_t>(50, 4 * pair_tolerance_us / 1000));
    pending_deadline = Clock::now() + wait;
  }

  void OnColor() {
    if (file && plan.color_records > 0 && color_read_pass >= plan.color_records) {
      color_read_pass = 0;
    }
    ++color_read_pass;
    core::SkipReason reason{};
    if (FrameProblem(incoming, 3, &reason)) {
      counters.ColorUnmatched();
      incoming.release();
      return;
    }
    if (have_held_color) counters.ColorUnmatched();  // replaced before any depth matched it
    held_color = incoming;
    incoming.release();
    have_held_color = true;
  }

  // Delivers the frame in `out_depth` when it is due (a recording at a speed > 0 is paced
  // on its timestamps); kOk once delivered, kTimeout when the read's time ran out first,
  // nullopt after a short wait (call again).
  std::optional<core::ReadStatus> DeliverWhenDue(int remaining_ms, core::RgbdFrame* frame) {
    if (pace) {
      // The recorded rate (scaled by the speed), relative to the first frame; a clock that
      // goes back from the previous frame (a rewind: each pass starts at the first frame's
      // time again) or jumps ahead by more than 2 s starts a new base.
      const auto now = Clock::now();
      const auto ts = static_cast<int64_t>(out_depth.getTimestamp());
      if (!pace_base_set) {
        pace_base_set = true;
        pace_ts0 = ts;
        pace_t0 = now;
      } else if (ts < pace_last_ts) {
        // The next pass starts one frame period after the last frame of this one was due, as
        // a camera's next frame would (not at once: two frames back to back).
        pace_ts0 = ts;
        pace_t0 =
            std::max(now, pace_last_due + std::chrono::microseconds(static_cast<int64_t>(
                                              2.0 * pair_tolerance_us / options.replay_speed)));
      }
      pace_last_ts = ts;
      const auto due = pace_t0 + std::chrono::microseconds(static_cast<int64_t>(
                                     static_cast<double>(ts - pace_ts0) / options.replay_speed));
      pace_last_due = due;
      if (due - now > std::chrono::seconds(2)) {
        pace_ts0 = ts;
        pace_t0 = now;
      } else if (due > now) {
        if (remaining_ms <= 0) return core::ReadStatus::kTimeout;
        std::this_thread::sleep_for(std::min<Clock::duration>(
            {due - now, std::chrono::milliseconds(remaining_ms), std::chrono::milliseconds(20)}));
        return std::nullopt;
      }
    }
    Emit(frame);
    return core::ReadStatus::kOk;
  }

  core::ReadStatus ReadFailed(const std::string& what, openni::Status rc) {
    error = what + " (status " + std::to_string(static_cast<int>(rc)) + "): " + ExtendedError();
    if (!file) {
      StopStreams();
      ReleaseFrames();
      return core::ReadStatus::kDisconnected;
    }
    return core::ReadStatus::kError;
  }

  int RemainingMs(Clock::time_point deadline) const {
    return static_cast<int>(
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count());
  }

  // A recording: depth and colour come from two lockstep players of the same file (OpenNI2's
  // single player drops a stream's frames while the other stream has none, e.g. around
  // missing colour records). Each depth frame is read first, then colour frames until one
  // matches it, is newer than it, or there is no more colour.
  core::ReadStatus ReadFile(int timeout_ms, core::RgbdFrame* frame) {
    const auto deadline = Clock::now() + std::chrono::milliseconds(std::max(timeout_ms, 0));
    while (true) {
      if (stop_requested.load()) return core::ReadStatus::kTimeout;
      const int remaining = RemainingMs(deadline);
      TryPair();
      if (have_out) {
        if (const std::optional<core::ReadStatus> s = DeliverWhenDue(remaining, frame)) return *s;
        continue;
      }
      // Short slices keep RequestStop() responsive.
      const int slice = std::clamp(remaining, 0, 50);
      int ready = -1;
      if (have_pending) {
        const bool no_more_color =
            !options.loop && plan.color_records > 0 && color_read_pass >= plan.color_records;
        if (no_more_color) {
          ReleasePending(false);
          continue;
        }
        const bool eof_before_wait = color_eof_event.load();
        openni::VideoStream* streams_color[1] = {&color_stream};
        const openni::Status rc = openni::OpenNI::waitForAnyStream(streams_color, 1, &ready, slice);
        if (rc == openni::STATUS_TIME_OUT) {
          if (eof_before_wait || Clock::now() >= pending_deadline) {
            ReleasePending(false);  // the colour player has nothing more for this depth
            continue;
          }
          if (remaining <= 0) return core::ReadStatus::kTimeout;
          continue;
        }
        if (rc != openni::STATUS_OK) return ReadFailed("waiting for colour failed", rc);
        if (color_stream.readFrame(&incoming) != openni::STATUS_OK || !incoming.isValid()) {
          return ReadFailed("reading a colour frame failed", openni::STATUS_ERROR);
        }
        OnColor();
        continue;
      }
      if (!options.loop && depth_read_pass >= plan.depth_records) return EndOfStream();
      if (pace && pace_base_set && !waiting_for_depth) {
        // Paced: the next frame is taken from the players a quarter period before it is due,
        // not as soon as the last one was delivered. Taking a frame sets the players decoding
        // the one after it (2-3 ms of CPU for a 640x480 RGB-D pair); that work then falls in
        // the idle end of a frame period, as a camera's frame arrives at its time, instead of
        // at the start of the last frame's segmentation.
        const auto take_at = pace_last_due + std::chrono::microseconds(static_cast<int64_t>(
                                                 1.5 * pair_tolerance_us / options.replay_speed));
        const auto now = Clock::now();
        if (now < take_at) {
          if (remaining <= 0) return core::ReadStatus::kTimeout;
          std::this_thread::sleep_for(
              std::min<Clock::duration>({take_at - now, std::chrono::milliseconds(remaining),
                                         std::chrono::milliseconds(20)}));
          continue;
        }
      }
      const bool eof_before_wait = eof_event.load();
      if (!waiting_for_depth) {
        waiting_for_depth = true;
        depth_wait_start = Clock::now();
      }
      openni::VideoStream* streams_depth[1] = {&depth_stream};
      const openni::Status rc = openni::OpenNI::waitForAnyStream(streams_depth, 1, &ready, slice);
      if (rc == openni::STATUS_TIME_OUT) {
        if (!options.loop && eof_before_wait) return EndOfStream();
        if (Clock::now() - depth_wait_start > kPlayerStallLimit) return PlayerStalled();
        if (remaining <= 0) return core::ReadStatus::kTimeout;
        continue;
      }
      if (rc != openni::STATUS_OK) return ReadFailed("waiting for depth failed", rc);
      if (depth_stream.readFrame(&incoming) != openni::STATUS_OK || !incoming.isValid()) {
        return ReadFailed("reading a depth frame failed", openni::STATUS_ERROR);
      }
      OnDepth();
    }
  }

  // A live camera: depth and colour arrive on their own; each depth waits a little for its
  // colour.
  core::ReadStatus ReadLive(int timeout_ms, core::RgbdFrame* frame) {
    const auto deadline = Clock::now() + std::chrono::milliseconds(std::max(timeout_ms, 0));
    while (true) {
      if (disconnected.load()) {
        error = "device " + device_uri + " was disconnected";
        StopStreams();
        ReleaseFrames();
        return core::ReadStatus::kDisconnected;
      }
      if (stop_requested.load()) return core::ReadStatus::kTimeout;
      const int remaining = RemainingMs(deadline);
      TryPair();
      if (have_out) {
        if (const std::optional<core::ReadStatus> s = DeliverWhenDue(remaining, frame)) return *s;
        continue;
      }
      // Short slices keep RequestStop() and device events responsive.
      const int slice = std::clamp(remaining, 0, 50);
      int ready = -1;
      const openni::Status rc =
          openni::OpenNI::waitForAnyStream(streams, stream_count, &ready, slice);
      if (rc == openni::STATUS_TIME_OUT) {
        if (have_pending && Clock::now() >= pending_deadline) {
          ReleasePending(false);  // nothing arrived for a while: its colour is not coming
          continue;
        }
        if (remaining <= 0) return core::ReadStatus::kTimeout;
        continue;
      }
      if (rc != openni::STATUS_OK || ready < 0 || ready >= stream_count) {
        return ReadFailed("waiting for frames failed", rc);
      }
      if (streams[ready]->readFrame(&incoming) != openni::STATUS_OK || !incoming.isValid()) {
        return ReadFailed("reading a frame failed", openni::STATUS_ERROR);
      }
      if (ready == 0) {
        OnDepth();
      } else {
        OnColor();
      }
    }
  }

  core::ReadStatus ReadImpl(int timeout_ms, core::RgbdFrame* frame) {
    if (!open) {
      error = "Read() on a closed source";
      return core::ReadStatus::kError;
    }
    if (end_reached) return core::ReadStatus::kEndOfStream;
    return file ? ReadFile(timeout_ms, frame) : ReadLive(timeout_ms, frame);
  }
};

OpenNI2Source::OpenNI2Source(const OpenNI2SourceOptions& options) {
  options.ValidateOrThrow();
  impl_ = std::make_unique<Impl>(options);
}

OpenNI2Source::~OpenNI2Source() { Close(); }

void OpenNI2Source::Open() {
  Close();
  Impl& m = *impl_;
  m.eof_event = false;
  m.color_eof_event = false;
  m.color_device_uri.clear();
  m.disconnected = false;
  m.stop_requested = false;
  m.end_reached = false;
  m.depth_read_pass = 0;
  m.color_read_pass = 0;
  m.last_depth_index = 0;
  m.sequence = 0;
  m.registered = false;
  m.calibrated = false;
  m.pace = false;
  m.pace_base_set = false;
  m.waiting_for_depth = false;
  m.error.clear();
  try {
    m.OpenImpl();
  } catch (...) {
    m.Teardown();
    throw;
  }
}

core::ReadStatus OpenNI2Source::Read(int timeout_ms, core::RgbdFrame* frame) {
  try {
    return impl_->ReadImpl(timeout_ms, frame);
  } catch (const std::exception& e) {
    impl_->error = e.what();
    return core::ReadStatus::kError;
  }
}

void OpenNI2Source::Close() {
  if (impl_ && (impl_->open || impl_->device.isValid() || impl_->color_device.isValid() ||
                impl_->depth_created)) {
    impl_->Teardown();
  }
}

bool OpenNI2Source::IsLive() const { return !impl_->file || impl_->options.replay_speed > 0; }

std::string OpenNI2Source::Describe() const {
  if (impl_->open) return impl_->description;
  return "openni2:" + impl_->Name() + " (closed)";
}

std::string OpenNI2Source::last_error() const { return impl_->error; }

void OpenNI2Source::RequestStop() { impl_->stop_requested.store(true); }

core::SourceReport OpenNI2Source::report() const { return impl_->counters.Snapshot(); }

bool OpenNI2Source::is_file() const { return impl_->file; }

int OpenNI2Source::number_of_frames() const {
  return impl_->file ? static_cast<int>(impl_->plan.frames_in_source) : -1;
}

core::CameraIntrinsics OpenNI2Source::intrinsics() const { return impl_->intr; }

}  // namespace clutterseg::drivers
