// clutterseg-listen [--lcm-url URL] [--png DIR] [--count N]
// Prints every objects_t (and status_t) the daemon publishes; with --png, writes each
// label_image_t as a colour PNG (one colour per object id).
//
// Every message is checked against its own length before it is decoded (lcm-gen's decoders
// allocate each array at the size the message declares) and label images against the frame
// limits (core::FrameLimits): a malformed or hostile message is reported on stderr and
// skipped, never an allocation. Exit codes (core/exit_codes.h): 0, 5 when a message was
// rejected or a label PNG could not be written (each named on stderr), 1 an LCM error, 2 bad
// command line, 4 LCM unavailable.
#include <signal.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

#include <CLI/CLI.hpp>

#include "clutterseg/daemon/lcm_bus.h"
#include "clutterseg/daemon/messages.h"
#include "clutterseg/io/png_io.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/pipeline/overlay.h"
#include "clutterseg/status_t.hpp"
#include "clutterseg/version.h"
#include "clutterseg/wire_check.hpp"

namespace {

std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop.store(true); }

struct Listener {
  std::string png_dir;
  int64_t count{0};  // stop after this many objects_t (0 = never)
  int64_t seen{0};
  bool count_reached{false};
  int64_t last_seq{-1};
  bool quiet_status{false};
  uint64_t rejected{0};      // messages that failed the checks or the decode
  uint64_t png_failures{0};  // label PNGs that could not be written
  clutterseg::core::LabelImage labels;
  clutterseg::core::ColorImage image;
  clutterseg::io::PngWriter png_writer;  // buffers reused from frame to frame

  void OnObjects(std::string_view channel, const clutterseg::objects_t& msg) {
    const clutterseg::objects_t* m = &msg;
    std::printf(
        "%.*s frame %lld utime %lld camera %s: %d objects, %d planes, segment %.1f ms, "
        "capture->publish %.1f ms\n",
        static_cast<int>(channel.size()), channel.data(), static_cast<long long>(m->frame_seq),
        static_cast<long long>(m->utime), m->camera_name.c_str(), m->num_objects, m->num_planes,
        m->times.total_ms, m->capture_to_publish_ms);
    const double* t = m->camera_translation;
    const double* q = m->camera_rotation_xyzw;
    std::printf("  frame %s, camera at (%.3f %.3f %.3f) m, rotation xyzw (%.4f %.4f %.4f %.4f)\n",
                m->frame_id.c_str(), t[0], t[1], t[2], q[0], q[1], q[2], q[3]);
    for (const auto& p : m->planes) {
      std::printf("  plane %d%s n (%.3f %.3f %.3f) d %.3f m, %d points\n", p.id,
                  p.is_support ? " [support]" : "", p.normal[0], p.normal[1], p.normal[2], p.d,
                  p.num_points);
    }
    for (const auto& o : m->objects) {
      std::printf(
          "  object %d: %d points, centroid (%.3f %.3f %.3f) m, size %.3f x %.3f x "
          "%.3f m, on plane %d, rgb %d %d %d, confidence %.2f\n",
          o.id, o.num_points, o.centroid[0], o.centroid[1], o.centroid[2], o.obb_extents[0],
          o.obb_extents[1], o.obb_extents[2], o.support_plane_id, o.mean_color[0], o.mean_color[1],
          o.mean_color[2], o.confidence);
      if (o.track_id >= 0) {
        std::printf("    track %lld (%s, age %d frames)\n", static_cast<long long>(o.track_id),
                    o.track_state == clutterseg::object_t::TRACK_CONFIRMED ? "confirmed" : "new",
                    o.track_age_frames);
      }
      if (o.has_gravity_box) {
        std::printf(
            "    upright box: centre (%.3f %.3f %.3f) m, %.3f x %.3f x %.3f m, long side (%.3f "
            "%.3f %.3f), up (%.3f %.3f %.3f), height %.3f m above plane %d\n",
            o.gbox_center[0], o.gbox_center[1], o.gbox_center[2], o.gbox_extents[0],
            o.gbox_extents[1], o.gbox_extents[2], o.gbox_axes[0][0], o.gbox_axes[0][1],
            o.gbox_axes[0][2], o.gbox_axes[2][0], o.gbox_axes[2][1], o.gbox_axes[2][2], o.height_m,
            o.support_plane_id);
      } else {
        std::printf("    upright box: none (no support plane)\n");
      }
    }
    std::fflush(stdout);
    ++seen;
    // Stop once this frame's label image (published right after) was handled too.
    if (count > 0 && seen >= count) {
      count_reached = true;
      last_seq = m->frame_seq;
    }
  }

  void OnLabels(const clutterseg::label_image_t& msg) {
    const clutterseg::label_image_t* m = &msg;
    if (count_reached && m->frame_seq >= last_seq) g_stop.store(true);
    if (png_dir.empty()) return;
    try {
      clutterseg::daemon::DecodeLabelImage(*m, &labels);
    } catch (const std::exception& e) {
      ++rejected;
      std::fprintf(stderr, "clutterseg-listen: frame %lld: rejected its label image: %s\n",
                   static_cast<long long>(m->frame_seq), e.what());
      return;
    }
    try {
      clutterseg::pipeline::RenderOverlay(labels, nullptr, &image);
      char name[64];
      std::snprintf(name, sizeof(name), "/labels_%06lld.png", static_cast<long long>(m->frame_seq));
      png_writer.WriteColor(png_dir + name, image);
    } catch (const std::exception& e) {
      ++png_failures;
      std::fprintf(stderr, "clutterseg-listen: frame %lld: %s\n",
                   static_cast<long long>(m->frame_seq), e.what());
    }
  }

  // Checks, decodes and dispatches one message of type `Message`; rejected messages are
  // reported and counted.
  template <typename Message, typename Check, typename Handle>
  void Receive(std::string_view channel, const uint8_t* data, size_t size, Check check,
               Handle handle, Message* message) {
    std::string problem;
    if (size < 8 || size > static_cast<size_t>(INT32_MAX)) {
      problem = "message of " + std::to_string(size) + " bytes";
    } else {
      problem = check(data + 8, size - 8);  // after the type hash
    }
    if (problem.empty()) {
      try {
        if (message->decode(data, 0, static_cast<int>(size)) < 0) {
          problem = "does not decode as " + std::string(Message::getTypeName());
        }
      } catch (const std::exception& e) {  // lcm-gen's decoders throw on some malformed input
        problem = std::string("does not decode as ") + Message::getTypeName() + ": " + e.what();
      }
    }
    if (!problem.empty()) {
      ++rejected;
      std::fprintf(stderr, "clutterseg-listen: %.*s: rejected a message of %zu bytes: %s\n",
                   static_cast<int>(channel.size()), channel.data(), size, problem.c_str());
      return;
    }
    handle(*message);
  }

  void OnStatus(std::string_view channel, const clutterseg::status_t& msg) {
    const clutterseg::status_t* s = &msg;
    if (quiet_status) return;
    char extra[160] = "";
    if (s->overlays_written + s->overlays_dropped + s->overlay_failures > 0) {
      std::snprintf(extra, sizeof(extra), ", overlays %lld written / %lld dropped / %lld failed",
                    static_cast<long long>(s->overlays_written),
                    static_cast<long long>(s->overlays_dropped),
                    static_cast<long long>(s->overlay_failures));
    }
    std::printf(
        "%.*s %s: %.1f fps, segment p50 %.1f p99 %.1f ms, capture->publish p50 %.1f p99 "
        "%.1f ms, queue %d/%d, captured %lld processed %lld dropped %lld%s, %s%s%s\n",
        static_cast<int>(channel.size()), channel.data(), s->camera_name.c_str(), s->fps,
        s->segment_p50_ms, s->segment_p99_ms, s->capture_to_publish_p50_ms,
        s->capture_to_publish_p99_ms, s->queue_depth, s->queue_capacity,
        static_cast<long long>(s->frames_captured), static_cast<long long>(s->frames_processed),
        static_cast<long long>(s->frames_dropped), extra, s->device_state_name.c_str(),
        s->last_error.empty() ? "" : ", last error: ", s->last_error.c_str());
    std::fflush(stdout);
  }
};

}  // namespace

int main(int argc, char** argv) {
  std::string url = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304";
  std::string objects_channel = "CLUTTERSEG_OBJECTS";
  std::string labels_channel = "CLUTTERSEG_LABELS";
  std::string status_channel = "CLUTTERSEG_STATUS";
  Listener listener;
  CLI::App app{"clutterseg-listen: print the segmentation published by clutterseg"};
  app.add_option("--lcm-url", url,
                 "LCM URL (default udpm with a 4 MB receive buffer for label images; "
                 "file:///abs/run.lcmlog?speed=0 replays a log)");
  app.add_option("--png", listener.png_dir, "write each label image as DIR/labels_NNNNNN.png");
  app.add_option("--count", listener.count, "exit after N objects messages (0 = run until ^C)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--objects-channel", objects_channel, "objects_t channel");
  app.add_option("--labels-channel", labels_channel, "label_image_t channel");
  app.add_option("--status-channel", status_channel, "status_t channel");
  app.add_flag("--no-status", listener.quiet_status, "do not print status_t messages");
  app.set_version_flag("--version", std::string("clutterseg-listen ") + clutterseg::kVersion);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (!listener.png_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(listener.png_dir, ec);
    if (!std::filesystem::is_directory(listener.png_dir)) {
      std::fprintf(stderr, "clutterseg-listen: cannot create --png directory '%s': %s\n",
                   listener.png_dir.c_str(), ec ? ec.message().c_str() : "not a directory");
      return 1;
    }
  }
  std::unique_ptr<clutterseg::daemon::LcmBus> bus;
  try {
    bus = std::make_unique<clutterseg::daemon::LcmBus>(url);
  } catch (const clutterseg::daemon::LcmUnavailableError& e) {
    std::fprintf(stderr, "clutterseg-listen: %s\n", e.what());
    return 4;
  }
  clutterseg::objects_t objects;
  clutterseg::label_image_t labels;
  clutterseg::status_t status;
  try {
    bus->SubscribeRaw(
        objects_channel, [&](std::string_view channel, const uint8_t* data, size_t size) {
          listener.Receive(
              channel, data, size, clutterseg::wire::CheckObjects,
              [&](const clutterseg::objects_t& m) { listener.OnObjects(channel, m); }, &objects);
        });
    bus->SubscribeRaw(
        labels_channel, [&](std::string_view channel, const uint8_t* data, size_t size) {
          listener.Receive(
              channel, data, size, clutterseg::wire::CheckLabels,
              [&](const clutterseg::label_image_t& m) { listener.OnLabels(m); }, &labels);
        });
    bus->SubscribeRaw(
        status_channel, [&](std::string_view channel, const uint8_t* data, size_t size) {
          listener.Receive(
              channel, data, size, clutterseg::wire::CheckStatus,
              [&](const clutterseg::status_t& m) { listener.OnStatus(channel, m); }, &status);
        });
    signal(SIGINT, OnSignal);
    signal(SIGTERM, OnSignal);
    while (!g_stop.load()) {
      const int n = bus->Handle(200);
      if (n < 0) break;                             // end of a file:// log, or an error
      if (n == 0 && listener.count_reached) break;  // no label image follows
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "clutterseg-listen: error: %s\n", e.what());
    return 1;
  }
  if (listener.rejected > 0) {
    std::fprintf(stderr, "clutterseg-listen: %llu message(s) rejected\n",
                 static_cast<unsigned long long>(listener.rejected));
  }
  if (listener.png_failures > 0) {
    std::fprintf(stderr, "clutterseg-listen: %llu label PNG(s) could not be written\n",
                 static_cast<unsigned long long>(listener.png_failures));
  }
  return listener.rejected > 0 || listener.png_failures > 0 ? 5 : 0;  // kExitIncomplete
}
