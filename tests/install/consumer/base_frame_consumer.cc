// A subscriber that reads objects in the robot's base frame, as docs/lcm.md shows it: only the
// installed LCM bindings and liblcm. Give it the daemon's URL (udpm://..., or a log as
// file:///abs/run.lcmlog?speed=0); it prints each frame's frame_id and, per object, the
// centroid and the gravity-aligned box, and ends at the end of a log or after N frames:
//   frame 3 in base_link: 4 objects
//     track 7: centroid (0.612 -0.118 0.054) m, upright box 0.081 x 0.062 x 0.104 m, yaw 31.2 deg
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <lcm/lcm-cpp.hpp>

#include "clutterseg/objects_t.hpp"
#include "clutterseg/wire_check.hpp"

namespace {

struct Printer {
  int frames = 0;
  void On(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    // Check the declared sizes before decoding a message from a shared bus.
    const auto* data = static_cast<const uint8_t*>(rbuf->data);
    if (rbuf->data_size < 8 ||
        !clutterseg::wire::CheckObjects(data + 8, rbuf->data_size - 8).empty()) {
      return;
    }
    clutterseg::objects_t m;
    if (m.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) < 0) return;
    std::printf("frame %lld in %s: %d objects\n", static_cast<long long>(m.frame_seq),
                m.frame_id.c_str(), m.num_objects);
    for (const clutterseg::object_t& o : m.objects) {
      std::printf("  track %lld: centroid (%.3f %.3f %.3f) m", static_cast<long long>(o.track_id),
                  o.centroid[0], o.centroid[1], o.centroid[2]);
      if (o.has_gravity_box) {
        // gbox_axes[2] is "up" (the support plane's normal); the yaw of the long side about
        // the frame's z axis, for a frame whose z points up (a robot's base).
        const float* a = o.gbox_axes[0];
        std::printf(", upright box %.3f x %.3f x %.3f m, yaw %.1f deg", o.gbox_extents[0],
                    o.gbox_extents[1], o.gbox_extents[2],
                    std::atan2(a[1], a[0]) * 180.0 / 3.14159265358979);
      }
      std::printf("\n");
    }
    ++frames;
  }
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: base_frame_consumer LCM_URL [FRAMES]\n");
    return 2;
  }
  const int max_frames = argc > 2 ? std::atoi(argv[2]) : 0;
  lcm::LCM lcm(argv[1]);
  if (!lcm.good()) return 4;
  Printer printer;
  lcm.subscribe("CLUTTERSEG_OBJECTS", &Printer::On, &printer);
  // handle() returns -1 at the end of a log.
  while ((max_frames == 0 || printer.frames < max_frames) && lcm.handle() == 0) {
  }
  return printer.frames > 0 ? 0 : 1;
}
