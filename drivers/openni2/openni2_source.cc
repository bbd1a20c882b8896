#include "clutterseg/drivers/openni2/openni2_source.h"

#include <OpenNI.h>
#include <dlfcn.h>
#include <link.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <mutex>
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

// Checks a recording with our own parser before OpenNI2 opens it: OniFile accepts some broken
// files and then hangs or delivers nothing.
int ValidateRecording(const std::string& path, bool* has_color) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw std::runtime_error("OpenNI2 source: recording '" + path + "' does not exist");
  }
  OniReader reader;
  try {
    reader.Open(path);
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
  const OniNodeInfo* depth = info.FindNode(2);
  if (depth == nullptr) fail("it has no depth stream");
  for (const OniNodeInfo& n : info.nodes) {
    if (n.type != 2 && n.type != 3) continue;
    if (!n.has_cropping) {
      fail("stream '" + n.name +
           "' has no xnCropping property, so OpenNI2 would deliver no frames");
    }
    if (n.width == 0) fail("stream '" + n.name + "' has no xnMapOutputMode property");
    if (!n.state_ready || !n.data_begin) fail("stream '" + n.name + "' never starts its data");
  }
  if (depth->data_records == 0) fail("it holds no depth frames");
  *has_color = info.FindNode(3) != nullptr;
  return static_cast<int>(depth->data_records);
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

  const OpenNI2SourceOptions options;
  StateListener state_listener;
  DisconnectListener disconnect_listener;
  bool listeners_added{false};

  openni::Device device;
  openni::VideoStream depth_stream;
  openni::VideoStream color_stream;
  openni::VideoStream* streams[2]{nullptr, nullptr};
  int stream_count{0};
  bool depth_created{false};
  bool color_created{false};
  bool streams_running{false};
  Clock::time_point stopped_at{};

  std::string device_uri;  // written before device_uri_set, then read-only
  std::atomic<bool> device_uri_set{false};
  std::atomic<bool> eof_event{false};
  std::atomic<bool> disconnected{false};
  std::atomic<bool> stop_requested{false};

  bool open{false};
  bool file{false};
  bool with_color{false};
  bool registered{false};
  bool fov_from_device{true};
  int frame_count{-1};
  int depth_frames_delivered{0};  // since the last rewind
  bool end_reached{false};
  uint64_t sequence{0};
  int last_depth_index{0};
  core::CameraIntrinsics intr;
  openni::PixelFormat depth_format{openni::PIXEL_FORMAT_DEPTH_1_MM};
  std::string description;
  std::string error;

  openni::VideoFrameRef depth_frame;
  openni::VideoFrameRef color_frame;
  bool have_depth{false};
  bool have_color{false};

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
    const double hfov = depth_stream.getHorizontalFieldOfView();
    const double vfov = depth_stream.getVerticalFieldOfView();
    if (hfov > 0.01 && hfov < 3.1 && vfov > 0.01 && vfov < 3.1) {
      intr.width = w;
      intr.height = h;
      intr.fx = w / (2.0 * std::tan(hfov / 2.0));
      intr.fy = h / (2.0 * std::tan(vfov / 2.0));
      intr.cx = w / 2.0 - 0.5;
      intr.cy = h / 2.0 - 0.5;
      fov_from_device = true;
    } else {
      intr = core::DefaultKinectIntrinsics().Scaled(w, h);
      fov_from_device = false;
    }
  }

  void OpenImpl() {
    InitializeOpenNI2();
    file = options.serial.empty() && LooksLikeFile(options.uri);
    bool file_has_color = false;
    if (file) frame_count = ValidateRecording(options.uri, &file_has_color);

    if (file) {
      if (device.open(options.uri.c_str()) != openni::STATUS_OK) {
        Fail("OpenNI2 cannot open the recording: " + ExtendedError());
      }
    } else {
      OpenLiveDevice();
    }
    device_uri = device.getDeviceInfo().getUri();
    device_uri_set.store(true);
    if (openni::OpenNI::addDeviceStateChangedListener(&state_listener) == openni::STATUS_OK &&
        openni::OpenNI::addDeviceDisconnectedListener(&disconnect_listener) == openni::STATUS_OK) {
      listeners_added = true;
    }

    if (file) {
      openni::PlaybackControl* playback = device.getPlaybackControl();
      if (playback == nullptr) Fail("the recording has no playback control");
      playback->setRepeatEnabled(options.loop);
      playback->setSpeed(static_cast<float>(options.replay_speed));
    }

    if (depth_stream.create(device, openni::SENSOR_DEPTH) != openni::STATUS_OK) {
      Fail("cannot create the depth stream: " + ExtendedError());
    }
    depth_created = true;
    with_color = options.color && (file ? file_has_color : device.hasSensor(openni::SENSOR_COLOR));
    if (with_color) {
      if (color_stream.create(device, openni::SENSOR_COLOR) != openni::STATUS_OK) {
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
      os << ", " << frame_count << " frames, speed ";
      if (options.replay_speed < 0) {
        os << "lockstep";
      } else {
        os << options.replay_speed;
      }
      if (options.loop) os << ", loop";
    }
    if (!fov_from_device) os << ", no FOV: default intrinsics";
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
    depth_frame.release();
    color_frame.release();
    have_depth = have_color = false;
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

  void CopyDepth(const openni::VideoFrameRef& f, core::DepthImage* out) const {
    const int w = f.getWidth();
    const int h = f.getHeight();
    out->width = w;
    out->height = h;
    out->data.resize(static_cast<size_t>(w) * h);
    const auto* base = static_cast<const uint8_t*>(f.getData());
    const int stride = f.getStrideInBytes();
    const int rows = CompleteRows(f, w * static_cast<int>(sizeof(uint16_t)));
    // Rows a short frame (a damaged recording) does not carry read as no measurement.
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

  void Emit(core::RgbdFrame* frame) {
    frame->receive_utime = core::SteadyClockMicros();
    frame->utime = static_cast<int64_t>(depth_frame.getTimestamp());
    frame->sequence = sequence++;
    frame->camera_name = options.camera_name;
    CopyDepth(depth_frame, &frame->depth);
    frame->intrinsics = intr;
    if (frame->depth.width != intr.width || frame->depth.height != intr.height) {
      frame->intrinsics = intr.Scaled(frame->depth.width, frame->depth.height);
    }
    if (with_color && have_color && color_frame.getWidth() == frame->depth.width &&
        color_frame.getHeight() == frame->depth.height) {
      CopyColor(color_frame, &frame->color);
    } else {
      frame->color.Reset(0, 0);
    }
    const int index = depth_frame.getFrameIndex();
    if (file && index <= last_depth_index) depth_frames_delivered = 0;  // the player rewound
    last_depth_index = index;
    ++depth_frames_delivered;
    have_depth = have_color = false;
  }

  core::ReadStatus ReadImpl(int timeout_ms, core::RgbdFrame* frame) {
    if (!open) {
      error = "Read() on a closed source";
      return core::ReadStatus::kError;
    }
    if (end_reached) return core::ReadStatus::kEndOfStream;
    const auto deadline = Clock::now() + std::chrono::milliseconds(std::max(timeout_ms, 0));
    while (true) {
      if (disconnected.load()) {
        error = "device " + device_uri + " was disconnected";
        StopStreams();
        return core::ReadStatus::kDisconnected;
      }
      if (stop_requested.load()) return core::ReadStatus::kTimeout;
      if (file && !options.loop && frame_count > 0 && depth_frames_delivered >= frame_count) {
        end_reached = true;
        StopStreams();  // ends the player's busy loop at EOF
        return core::ReadStatus::kEndOfStream;
      }
      const bool eof_before_wait = eof_event.load();
      const auto now = Clock::now();
      const int remaining = static_cast<int>(
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now).count());
      // Short slices keep RequestStop() and device events responsive.
      const int slice = std::clamp(remaining, 0, 50);
      int ready = -1;
      const openni::Status rc =
          openni::OpenNI::waitForAnyStream(streams, stream_count, &ready, slice);
      if (rc == openni::STATUS_TIME_OUT) {
        if (file && !options.loop && eof_before_wait) {
          end_reached = true;
          StopStreams();
          return core::ReadStatus::kEndOfStream;
        }
        if (remaining <= 0) return core::ReadStatus::kTimeout;
        continue;
      }
      if (rc != openni::STATUS_OK || ready < 0 || ready >= stream_count) {
        error = "waiting for frames failed (status " + std::to_string(static_cast<int>(rc)) +
                "): " + ExtendedError();
        if (!file) {
          StopStreams();
          return core::ReadStatus::kDisconnected;
        }
        return core::ReadStatus::kError;
      }
      openni::VideoFrameRef& slot = ready == 0 ? depth_frame : color_frame;
      if (streams[ready]->readFrame(&slot) != openni::STATUS_OK || !slot.isValid()) {
        error = "reading a frame failed: " + ExtendedError();
        if (!file) {
          StopStreams();
          return core::ReadStatus::kDisconnected;
        }
        return core::ReadStatus::kError;
      }
      (ready == 0 ? have_depth : have_color) = true;
      if (!with_color) {
        Emit(frame);
        return core::ReadStatus::kOk;
      }
      if (have_depth && have_color) {
        const int di = depth_frame.getFrameIndex();
        const int ci = color_frame.getFrameIndex();
        if (di == ci) {
          Emit(frame);
          return core::ReadStatus::kOk;
        }
        // Unpaired: keep the newer frame and wait for its partner. A rewind (loop) makes the
        // newer frame the one with the smaller index.
        const bool depth_newer = ready == 0;
        if (depth_newer) {
          have_color = false;
        } else {
          have_depth = false;
        }
      }
      if (remaining <= 0) return core::ReadStatus::kTimeout;
    }
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
  m.disconnected = false;
  m.stop_requested = false;
  m.end_reached = false;
  m.frame_count = -1;
  m.depth_frames_delivered = 0;
  m.last_depth_index = 0;
  m.sequence = 0;
  m.registered = false;
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
  if (impl_ && (impl_->open || impl_->device.isValid() || impl_->depth_created)) {
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

bool OpenNI2Source::is_file() const { return impl_->file; }

int OpenNI2Source::number_of_frames() const { return impl_->file ? impl_->frame_count : -1; }

core::CameraIntrinsics OpenNI2Source::intrinsics() const { return impl_->intr; }

}  // namespace clutterseg::drivers
