// clutterseg-record: records an OpenNI2 camera to an .oni file with openni::Recorder, or
// writes an .oni from a directory of PCD files with OniWriter (no camera needed).
//
//   clutterseg-record OUT.oni [--device URI | --serial S] [--frames N] [--seconds S] [--color]
//   clutterseg-record OUT.oni --from-pcd DIR [--fps 30] [--fx F --fy F]
//
// --raw records the camera through OpenNI2Source and OniWriter instead of openni::Recorder:
// uncompressed (about 27 MB/s at 640x480@30 with colour) but every stored depth frame has its
// colour partner (openni::Recorder occasionally loses single frames of one stream).
//
// Exit codes: 0 success, 1 runtime error (no device, unreadable input, I/O), 2 usage.

#include <OpenNI.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>

#include "clutterseg/core/exit_codes.h"
#include "clutterseg/drivers/oni/oni_writer.h"
#include "clutterseg/drivers/openni2/openni2_source.h"
#include "clutterseg/drivers/replay/pcd_directory_source.h"
#include "clutterseg/version.h"

namespace clutterseg::tools {
namespace {

// No camera, or the one asked for cannot be opened: exit 3 (core/exit_codes.h).
struct DeviceUnavailable : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::atomic<bool> g_stop{false};
extern "C" void OnSignal(int /*sig*/) { g_stop.store(true); }

struct Args {
  std::string out;
  std::string device;
  std::string serial;
  int frames{0};
  double seconds{0.0};
  bool color{false};
  bool raw{false};
  std::string from_pcd;
  int fps{30};
  double fx{0.0};
  double fy{0.0};
};

std::string Ext() {
  const char* e = openni::OpenNI::getExtendedError();
  return (e != nullptr && *e != '\0') ? e : "no details";
}

bool IsFileUri(const char* uri) {
  std::error_code ec;
  return std::filesystem::is_regular_file(uri, ec);
}

// Opens the live device by URI, serial or the first one found; throws when there is none.
void OpenDevice(const Args& a, openni::Device* device) {
  openni::Array<openni::DeviceInfo> list;
  openni::OpenNI::enumerateDevices(&list);
  std::vector<std::string> uris;
  for (int i = 0; i < list.getSize(); ++i) {
    if (!IsFileUri(list[i].getUri())) uris.emplace_back(list[i].getUri());
  }
  if (!a.serial.empty()) {
    for (const std::string& uri : uris) {
      openni::Device d;
      if (d.open(uri.c_str()) != openni::STATUS_OK) continue;
      char serial[128] = {0};
      int size = sizeof(serial) - 1;
      const bool ok =
          d.getProperty(openni::DEVICE_PROPERTY_SERIAL_NUMBER, serial, &size) == openni::STATUS_OK;
      d.close();
      if (ok && a.serial == serial) {
        if (device->open(uri.c_str()) != openni::STATUS_OK) {
          throw DeviceUnavailable("cannot open device " + uri + ": " + Ext());
        }
        return;
      }
    }
    throw DeviceUnavailable("no OpenNI2 device with serial '" + a.serial + "' (" +
                            std::to_string(uris.size()) + " device(s) connected)");
  }
  std::string uri = a.device;
  if (uri.empty()) {
    if (uris.empty()) throw DeviceUnavailable("no OpenNI2 device is connected");
    uri = uris.front();
  }
  if (device->open(uri.c_str()) != openni::STATUS_OK) {
    throw DeviceUnavailable("cannot open device '" + uri + "': " + Ext());
  }
}

void SetMode(openni::Device* device, openni::VideoStream* stream, openni::SensorType sensor,
             openni::PixelFormat format, const char* what) {
  const openni::SensorInfo* info = device->getSensorInfo(sensor);
  if (info == nullptr) throw std::runtime_error(std::string("the device has no ") + what);
  const auto& modes = info->getSupportedVideoModes();
  for (int i = 0; i < modes.getSize(); ++i) {
    const openni::VideoMode& m = modes[i];
    if (m.getPixelFormat() == format && m.getResolutionX() == 640 && m.getResolutionY() == 480 &&
        m.getFps() == 30) {
      if (stream->setVideoMode(m) != openni::STATUS_OK) {
        throw std::runtime_error(std::string("cannot set the ") + what + " mode: " + Ext());
      }
      return;
    }
  }
  throw std::runtime_error(std::string("the ") + what + " sensor has no 640x480@30 mode");
}

int RecordLive(const Args& a) {
  drivers::InitializeOpenNI2();
  openni::Device device;
  openni::VideoStream depth;
  openni::VideoStream color;
  openni::Recorder recorder;
  bool depth_ok = false;
  bool color_ok = false;
  int frames = 0;
  auto cleanup = [&] {
    if (recorder.isValid()) {
      recorder.stop();
      recorder.destroy();  // writes the seek tables and END
    }
    if (depth_ok) depth.stop();
    if (color_ok) color.stop();
    std::this_thread::sleep_for(std::chrono::milliseconds(150));  // OpenNI2 teardown race
    if (color_ok) color.destroy();
    if (depth_ok) depth.destroy();
    if (device.isValid()) device.close();
  };
  try {
    OpenDevice(a, &device);
    if (depth.create(device, openni::SENSOR_DEPTH) != openni::STATUS_OK) {
      throw std::runtime_error("cannot create the depth stream: " + Ext());
    }
    depth_ok = true;
    SetMode(&device, &depth, openni::SENSOR_DEPTH, openni::PIXEL_FORMAT_DEPTH_1_MM, "depth");
    depth.setMirroringEnabled(false);
    if (a.color) {
      if (color.create(device, openni::SENSOR_COLOR) != openni::STATUS_OK) {
        throw std::runtime_error("cannot create the colour stream: " + Ext());
      }
      color_ok = true;
      SetMode(&device, &color, openni::SENSOR_COLOR, openni::PIXEL_FORMAT_RGB888, "colour");
      color.setMirroringEnabled(false);
      device.setDepthColorSyncEnabled(true);
      // Registration cannot be applied at replay: record depth already registered to colour.
      if (device.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR)) {
        device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR);
      } else {
        std::fprintf(stderr, "warning: the device cannot register depth to colour\n");
      }
    }
    if (depth.start() != openni::STATUS_OK)
      throw std::runtime_error("cannot start depth: " + Ext());
    if (color_ok && color.start() != openni::STATUS_OK) {
      throw std::runtime_error("cannot start colour: " + Ext());
    }
    if (recorder.create(a.out.c_str()) != openni::STATUS_OK ||
        recorder.attach(depth) != openni::STATUS_OK ||
        (color_ok && recorder.attach(color, false) != openni::STATUS_OK) ||
        recorder.start() != openni::STATUS_OK) {
      throw std::runtime_error("cannot record to '" + a.out + "': " + Ext());
    }
    std::fprintf(stderr, "recording %s to %s (Ctrl-C stops)\n", device.getDeviceInfo().getUri(),
                 a.out.c_str());
    const auto start = std::chrono::steady_clock::now();
    openni::VideoStream* streams[] = {&depth, &color};
    openni::VideoFrameRef frame;
    int timeouts = 0;
    while (!g_stop.load()) {
      if (a.frames > 0 && frames >= a.frames) break;
      if (a.seconds > 0 &&
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >=
              a.seconds) {
        break;
      }
      int ready = -1;
      const openni::Status rc =
          openni::OpenNI::waitForAnyStream(streams, color_ok ? 2 : 1, &ready, 500);
      if (rc == openni::STATUS_TIME_OUT) {
        if (++timeouts >= 10) throw std::runtime_error("no frames for 5 s; device lost?");
        continue;
      }
      if (rc != openni::STATUS_OK) throw std::runtime_error("waiting for frames failed: " + Ext());
      timeouts = 0;
      if (streams[ready]->readFrame(&frame) != openni::STATUS_OK) {
        throw std::runtime_error("reading a frame failed: " + Ext());
      }
      if (ready == 0) ++frames;
    }
  } catch (...) {
    cleanup();
    throw;
  }
  cleanup();
  std::printf("recorded %d depth frames%s to %s\n", frames, color_ok ? " (+ colour)" : "",
              a.out.c_str());
  return 0;
}

int RecordRaw(const Args& a) {
  drivers::InitializeOpenNI2();
  drivers::OpenNI2SourceOptions o;
  o.uri = a.device;
  o.serial = a.serial;
  o.color = a.color;
  drivers::OpenNI2Source src(o);
  src.Open();
  std::fprintf(stderr, "recording %s to %s (Ctrl-C stops)\n", src.Describe().c_str(),
               a.out.c_str());
  drivers::OniWriter writer;
  core::RgbdFrame frame;
  int frames = 0;
  int64_t first_utime = 0;
  const auto start = std::chrono::steady_clock::now();
  while (!g_stop.load()) {
    if (a.frames > 0 && frames >= a.frames) break;
    if (a.seconds > 0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >=
            a.seconds) {
      break;
    }
    const core::ReadStatus st = src.Read(5000, &frame);
    if (st == core::ReadStatus::kTimeout) continue;
    if (st != core::ReadStatus::kOk)
      throw std::runtime_error("capture failed: " + src.last_error());
    const bool with_color = !frame.color.empty();
    if (!writer.is_open()) {
      writer.Open(a.out, frame.depth.width, frame.depth.height, 30, frame.intrinsics, with_color);
      first_utime = frame.utime;
    }
    writer.WriteFrame(frame.depth, with_color ? &frame.color : nullptr,
                      std::max<int64_t>(0, frame.utime - first_utime));
    ++frames;
  }
  writer.Close();
  src.Close();
  std::printf("recorded %d frames to %s\n", frames, a.out.c_str());
  return 0;
}

int FromPcd(const Args& a) {
  drivers::PcdDirectorySourceOptions o;
  o.path = a.from_pcd;
  o.frame_period_us = static_cast<int64_t>(1e6 / a.fps + 0.5);
  if (a.fx > 0.0) {
    o.estimate_intrinsics = false;
    o.intrinsics.fx = a.fx;
    o.intrinsics.fy = a.fy > 0.0 ? a.fy : a.fx;
  }
  drivers::PcdDirectorySource src(o);
  src.Open();
  std::fprintf(stderr, "%s\n", src.Describe().c_str());
  drivers::OniWriter writer;
  core::RgbdFrame frame;
  int frames = 0;
  bool with_color = false;
  while (!g_stop.load()) {
    const core::ReadStatus st = src.Read(1000, &frame);
    if (st == core::ReadStatus::kEndOfStream) break;
    if (st != core::ReadStatus::kOk) throw std::runtime_error(src.last_error());
    if (a.frames > 0 && frames >= a.frames) break;
    if (!writer.is_open()) {
      with_color = !frame.color.empty();
      writer.Open(a.out, frame.depth.width, frame.depth.height, a.fps, frame.intrinsics,
                  with_color);
    }
    writer.WriteFrame(frame.depth, with_color ? &frame.color : nullptr, frame.utime);
    ++frames;
  }
  writer.Close();
  std::printf("wrote %d frames (%s) to %s\n", frames, with_color ? "depth+color" : "depth",
              a.out.c_str());
  return 0;
}

}  // namespace
}  // namespace clutterseg::tools

int main(int argc, char** argv) {
  using clutterseg::tools::Args;
  Args a;
  CLI::App app{"Record an OpenNI2 camera to .oni, or build an .oni from PCD files."};
  app.add_option("OUT", a.out, "output .oni file")->required();
  auto* device = app.add_option("--device", a.device, "device URI (default: first device)");
  auto* serial = app.add_option("--serial", a.serial, "device serial number");
  device->excludes(serial);
  app.add_option("--frames", a.frames, "stop after N depth frames (0 = no limit)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--seconds", a.seconds, "stop after S seconds (0 = no limit)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--color", a.color, "also record colour (depth registered to colour)");
  auto* raw = app.add_flag("--raw", a.raw,
                           "record uncompressed through OniWriter instead of openni::Recorder");
  auto* pcd = app.add_option("--from-pcd", a.from_pcd,
                             "write the .oni from a directory of organized PCD files instead");
  pcd->excludes(device)->excludes(serial)->excludes(raw);
  app.add_option("--fps", a.fps, "frame rate written with --from-pcd")->check(CLI::Range(1, 1000));
  app.add_option("--fx", a.fx, "focal length for --from-pcd (default: fitted to the cloud)")
      ->check(CLI::PositiveNumber);
  app.add_option("--fy", a.fy, "vertical focal length for --from-pcd (default: fx)")
      ->check(CLI::PositiveNumber);
  app.set_version_flag("--version", std::string("clutterseg-record ") + clutterseg::kVersion);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  }

  std::signal(SIGINT, clutterseg::tools::OnSignal);
  std::signal(SIGTERM, clutterseg::tools::OnSignal);
  int rc = 1;
  try {
    if (!a.from_pcd.empty()) {
      rc = clutterseg::tools::FromPcd(a);
    } else if (a.raw) {
      rc = clutterseg::tools::RecordRaw(a);
    } else {
      rc = clutterseg::tools::RecordLive(a);
    }
  } catch (const clutterseg::tools::DeviceUnavailable& e) {
    std::fprintf(stderr, "clutterseg-record: error: %s\n", e.what());
    rc = clutterseg::kExitSourceUnavailable;  // as the daemon: the source cannot be opened
  } catch (const std::exception& e) {
    std::fprintf(stderr, "clutterseg-record: error: %s\n", e.what());
    rc = 1;
  }
  if (a.from_pcd.empty()) clutterseg::drivers::ShutdownOpenNI2();
  return rc;
}
