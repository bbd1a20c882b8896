// The daemon publishing in a robot's base frame: one recording replayed twice by the
// `clutterseg` executable into file:// logs, in the camera frame and with extrinsics, and the
// second run compared with the first transformed by those extrinsics.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/exit_codes.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "tests/daemon/daemon_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

// A pose no axis of which survives: 120 degrees about (1, 1, 1)/sqrt(3) is x -> y -> z -> x,
// then a further tilt, and a shift of a metre and a half.
struct Pose {
  double q[4];  // x, y, z, w
  double t[3];
  double r[3][3];
  Pose() : q{0.3535534, 0.6123724, 0.3535534, 0.6123724}, t{0.85, -0.4, 1.2} {
    const double x = q[0], y = q[1], z = q[2], w = q[3];
    const double m[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                            {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                            {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) r[i][j] = m[i][j];
    }
  }
  void Rotate(const float* v, double* out) const {
    for (int i = 0; i < 3; ++i) out[i] = r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2];
  }
  void Apply(const float* p, double* out) const {
    Rotate(p, out);
    for (int i = 0; i < 3; ++i) out[i] += t[i];
  }
  // Writes the pose as an extrinsics JSON file of parent frame base_link.
  void WriteJson(const std::string& path) const {
    std::ofstream f(path);
    f.precision(10);
    f << R"({"parent_frame": "base_link", "translation": [)" << t[0] << ", " << t[1] << ", " << t[2]
      << R"(], "rotation_xyzw": [)" << q[0] << ", " << q[1] << ", " << q[2] << ", " << q[3]
      << "]}\n";
  }
};

template <typename T>
std::vector<T> Messages(const std::string& log, const std::string& channel) {
  std::vector<T> out;
  for (const testutil::LogEvent& ev : testutil::ReadLcmLog(log)) {
    if (ev.channel != channel) continue;
    T m;
    EXPECT_EQ(m.decode(ev.data.data(), 0, static_cast<int>(ev.data.size())),
              static_cast<int>(ev.data.size()));
    out.push_back(m);
  }
  return out;
}

// Expects `got` (parent frame) == `pose` applied to `camera` (camera frame) within `tol` m.
void ExpectPoint(const Pose& pose, const float* camera, const float* got, double tol,
                 const std::string& what) {
  double want[3];
  pose.Apply(camera, want);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(got[i], want[i], tol) << what << " [" << i << "]";
}

void ExpectDirection(const Pose& pose, const float* camera, const float* got,
                     const std::string& what) {
  double want[3];
  pose.Rotate(camera, want);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(got[i], want[i], 1e-4) << what << " [" << i << "]";
}

double AngleDegrees(const float* a, const float* b) {
  double dot = 0.0, na = 0.0, nb = 0.0;
  for (int i = 0; i < 3; ++i) {
    dot += static_cast<double>(a[i]) * b[i];
    na += static_cast<double>(a[i]) * a[i];
    nb += static_cast<double>(b[i]) * b[i];
  }
  return std::acos(std::clamp(dot / std::sqrt(na * nb), -1.0, 1.0)) * 180.0 / 3.14159265358979;
}

class DaemonFrame : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = testing::ScratchDir("daemon_frame_" + std::to_string(getpid()));
    oni_ = (dir_ / "tabletop.oni").string();
    testutil::WriteTabletopOni(oni_, kFrames);
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  // Runs the daemon on the recording into `log`, with `extra` arguments; returns its exit code.
  static int RunDaemon(const std::string& log, const std::vector<std::string>& extra,
                       std::string* err) {
    std::vector<std::string> argv = {CLUTTERSEG_DAEMON_EXE,
                                     "--source",
                                     oni_,
                                     "--speed",
                                     "max",
                                     "--lcm-url",
                                     "file://" + log + "?mode=w",
                                     "--set",
                                     "lcm.object_points=40"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return testutil::Run(argv, std::chrono::minutes(5), err);
  }
  static constexpr int kFrames = 5;
  static inline std::filesystem::path dir_;
  static inline std::string oni_;
};

TEST_F(DaemonFrame, ExtrinsicsPutEveryGeometricFieldInTheParentFrame) {
  const Pose pose;
  const std::string extrinsics = (dir_ / "hand_eye.json").string();
  pose.WriteJson(extrinsics);
  const std::string camera_log = (dir_ / "camera.lcmlog").string();
  const std::string base_log = (dir_ / "base.lcmlog").string();
  std::string err;
  // Every frame of the recording is another scene, so no track is confirmed: tentative tracks
  // are remembered, for lost tracks to turn too.
  const std::vector<std::string> remember = {"--set", "tracker.tentative_memory_frames=5"};
  std::vector<std::string> with_pose = remember;
  with_pose.insert(with_pose.end(), {"--set", "camera.extrinsics_file=" + extrinsics});
  ASSERT_EQ(RunDaemon(camera_log, remember, &err), kExitOk) << err;
  ASSERT_EQ(RunDaemon(base_log, with_pose, &err), kExitOk) << err;
  const auto cam = Messages<clutterseg::objects_t>(camera_log, "CLUTTERSEG_OBJECTS");
  const auto base = Messages<clutterseg::objects_t>(base_log, "CLUTTERSEG_OBJECTS");
  ASSERT_EQ(cam.size(), static_cast<size_t>(kFrames));
  ASSERT_EQ(base.size(), cam.size());
  const auto cam_labels = Messages<clutterseg::label_image_t>(camera_log, "CLUTTERSEG_LABELS");
  const auto base_labels = Messages<clutterseg::label_image_t>(base_log, "CLUTTERSEG_LABELS");
  ASSERT_EQ(base_labels.size(), cam_labels.size());

  int objects = 0, boxes = 0, lost = 0, samples = 0;
  for (size_t f = 0; f < cam.size(); ++f) {
    const clutterseg::objects_t& c = cam[f];
    const clutterseg::objects_t& b = base[f];
    const std::string at = "frame " + std::to_string(f);
    // Which frame: the camera's own name, or the file's parent frame with the camera's pose.
    EXPECT_EQ(c.frame_id, "camera");
    EXPECT_EQ(c.camera_translation[0], 0.0);
    EXPECT_EQ(c.camera_rotation_xyzw[3], 1.0);
    EXPECT_EQ(b.frame_id, "base_link");
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(b.camera_translation[i], pose.t[i], 1e-9);
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(b.camera_rotation_xyzw[i], pose.q[i], 1e-7);
    // Pixels and intrinsics stay the camera's.
    EXPECT_EQ(b.intrinsics.fx, c.intrinsics.fx);
    EXPECT_EQ(b.intrinsics.cx, c.intrinsics.cx);
    EXPECT_EQ(base_labels[f].data, cam_labels[f].data) << at;

    ASSERT_EQ(b.num_planes, c.num_planes) << at;
    for (size_t i = 0; i < c.planes.size(); ++i) {
      const auto& cp = c.planes[i];
      const auto& bp = b.planes[i];
      ExpectDirection(pose, cp.normal, bp.normal, at + " plane normal");
      // A point of the camera-frame plane lies on the published plane.
      float on[3];
      for (int k = 0; k < 3; ++k) on[k] = -cp.d * cp.normal[k];
      double p[3];
      pose.Apply(on, p);
      EXPECT_NEAR(bp.normal[0] * p[0] + bp.normal[1] * p[1] + bp.normal[2] * p[2] + bp.d, 0.0, 1e-3)
          << at << " plane " << cp.id;
    }
    ASSERT_EQ(b.num_objects, c.num_objects) << at;
    for (size_t i = 0; i < c.objects.size(); ++i) {
      const auto& co = c.objects[i];
      const auto& bo = b.objects[i];
      const std::string what = at + " object " + std::to_string(co.id);
      ++objects;
      ExpectPoint(pose, co.centroid, bo.centroid, 1e-3, what + " centroid");
      ExpectPoint(pose, co.obb_center, bo.obb_center, 1e-3, what + " obb centre");
      for (int a = 0; a < 3; ++a) {
        ExpectDirection(pose, co.obb_axes[a], bo.obb_axes[a], what + " obb axis");
        EXPECT_EQ(bo.obb_extents[a], co.obb_extents[a]);
      }
      // The axis-aligned box of the points in the parent frame: it holds the centroid and
      // the samples, and lies inside the box around the camera box's turned corners.
      for (int k = 0; k < 3; ++k) {
        EXPECT_LE(bo.aabb_min[k], bo.centroid[k]) << what;
        EXPECT_GE(bo.aabb_max[k], bo.centroid[k]) << what;
        double lo = 1e9, hi = -1e9;
        for (int corner = 0; corner < 8; ++corner) {
          const float v[3] = {(corner & 1) ? co.aabb_max[0] : co.aabb_min[0],
                              (corner & 2) ? co.aabb_max[1] : co.aabb_min[1],
                              (corner & 4) ? co.aabb_max[2] : co.aabb_min[2]};
          double p[3];
          pose.Apply(v, p);
          lo = std::min(lo, p[k]);
          hi = std::max(hi, p[k]);
        }
        EXPECT_GE(bo.aabb_min[k], lo - 1e-3) << what;
        EXPECT_LE(bo.aabb_max[k], hi + 1e-3) << what;
        EXPECT_LT(bo.aabb_max[k] - bo.aabb_min[k], hi - lo + 1e-3) << what;
      }
      ASSERT_EQ(bo.num_samples, co.num_samples) << what;
      for (size_t s = 0; s < co.samples.size(); ++s) {
        ExpectPoint(pose, co.samples[s].data(), bo.samples[s].data(), 1e-3, what + " sample");
        for (int k = 0; k < 3; ++k) {
          EXPECT_GE(bo.samples[s][k], bo.aabb_min[k] - 1e-6) << what;
          EXPECT_LE(bo.samples[s][k], bo.aabb_max[k] + 1e-6) << what;
        }
        ++samples;
      }
      // The gravity-aligned box turns with the rest, and stands upright on its plane.
      ASSERT_EQ(bo.has_gravity_box, co.has_gravity_box) << what;
      EXPECT_EQ(bo.support_plane_id, co.support_plane_id) << what;
      if (bo.has_gravity_box) {
        ++boxes;
        ExpectPoint(pose, co.gbox_center, bo.gbox_center, 1e-3, what + " gravity box centre");
        for (int a = 0; a < 3; ++a) {
          ExpectDirection(pose, co.gbox_axes[a], bo.gbox_axes[a], what + " gravity box axis");
          EXPECT_EQ(bo.gbox_extents[a], co.gbox_extents[a]);
        }
        EXPECT_EQ(bo.height_m, co.height_m);
        const auto plane = std::find_if(b.planes.begin(), b.planes.end(),
                                        [&](const auto& p) { return p.id == bo.support_plane_id; });
        ASSERT_NE(plane, b.planes.end()) << what;
        EXPECT_LT(AngleDegrees(bo.gbox_axes[2], plane->normal), 1.0) << what;
        EXPECT_GT(bo.height_m, 0.f) << what;
        EXPECT_NEAR(bo.gbox_extents[2], bo.height_m, 1e-6) << what;
      } else {
        EXPECT_EQ(bo.gbox_extents[0], 0.f) << what;
        EXPECT_EQ(bo.gbox_center[0], 0.f) << what;
      }
    }
    ASSERT_EQ(b.num_lost_tracks, c.num_lost_tracks) << at;
    for (size_t i = 0; i < c.lost_tracks.size(); ++i) {
      const auto& ct = c.lost_tracks[i];
      const auto& bt = b.lost_tracks[i];
      EXPECT_EQ(bt.track_id, ct.track_id);
      ExpectPoint(pose, ct.centroid, bt.centroid, 1e-3, at + " lost track centroid");
      // Each box holds the turned corners of the camera-frame box.
      for (int corner = 0; corner < 8; ++corner) {
        const float v[3] = {(corner & 1) ? ct.remembered_max[0] : ct.remembered_min[0],
                            (corner & 2) ? ct.remembered_max[1] : ct.remembered_min[1],
                            (corner & 4) ? ct.remembered_max[2] : ct.remembered_min[2]};
        const float w[3] = {(corner & 1) ? ct.aabb_max[0] : ct.aabb_min[0],
                            (corner & 2) ? ct.aabb_max[1] : ct.aabb_min[1],
                            (corner & 4) ? ct.aabb_max[2] : ct.aabb_min[2]};
        double p[3], q[3];
        pose.Apply(v, p);
        pose.Apply(w, q);
        for (int k = 0; k < 3; ++k) {
          EXPECT_LE(bt.remembered_min[k], p[k] + 1e-3) << at;
          EXPECT_GE(bt.remembered_max[k], p[k] - 1e-3) << at;
          EXPECT_LE(bt.aabb_min[k], q[k] + 1e-3) << at;
          EXPECT_GE(bt.aabb_max[k], q[k] - 1e-3) << at;
        }
      }
      ++lost;
    }
  }
  // The recording exercises every kind of field.
  EXPECT_GT(objects, 10);
  EXPECT_GT(boxes, 5);
  EXPECT_GT(samples, 100);
  EXPECT_GT(lost, 0);
}

TEST_F(DaemonFrame, ABadExtrinsicsFileExitsTwoNamingTheFileAndField) {
  const std::string path = (dir_ / "hand_eye_bad.yaml").string();
  {
    std::ofstream f(path);
    f << "header: {frame_id: base_link}\ntransform:\n  translation: {x: 0.1, y: 0, z: 0.5}\n"
         "  rotation: {x: 0, y: 0, z: 0.2, w: 1}\n";
  }
  std::string err;
  EXPECT_EQ(
      RunDaemon((dir_ / "bad.lcmlog").string(), {"--set", "camera.extrinsics_file=" + path}, &err),
      kExitUsage);
  EXPECT_NE(err.find("camera.extrinsics_file = '" + path + "'"), std::string::npos) << err;
  EXPECT_NE(err.find("'transform.rotation' has norm"), std::string::npos) << err;
}

// camera.decimation = 2 on the real OniFile replay: everything is published at 320x240 with the
// intrinsics of that image, and the same objects come out where they were at full resolution,
// each with about a quarter of its points (a few small pieces more); a bad factor exits 2
// naming the key. The bridge cut (segmenter.linkage.bridge_max_edges) and the flush-stack cut
// (segmenter.objects.stack_cut_min_step_m) are off in both runs: they decide on the supervoxel
// graph and on counts of points, a quarter of them at half resolution, and one of these
// tabletops has a bridge and a stack they cut at one resolution only (the bridge cut's effect
// on decimated streams is measured in docs/results.md, "Bridge cut").
TEST_F(DaemonFrame, DecimationPublishesTheSameObjectsAtAQuarterOfThePixels) {
  const std::string full_log = (dir_ / "full.lcmlog").string();
  const std::string half_log = (dir_ / "half.lcmlog").string();
  const std::vector<std::string> no_bridge = {"--set", "segmenter.linkage.bridge_max_edges=0",
                                              "--set", "segmenter.objects.stack_cut_min_step_m=0"};
  std::vector<std::string> half_args = no_bridge;
  half_args.insert(half_args.end(), {"--set", "camera.decimation=2"});
  std::string err;
  ASSERT_EQ(RunDaemon(full_log, no_bridge, &err), kExitOk) << err;
  ASSERT_EQ(RunDaemon(half_log, half_args, &err), kExitOk) << err;
  const auto full = Messages<clutterseg::objects_t>(full_log, "CLUTTERSEG_OBJECTS");
  const auto half = Messages<clutterseg::objects_t>(half_log, "CLUTTERSEG_OBJECTS");
  const auto half_labels = Messages<clutterseg::label_image_t>(half_log, "CLUTTERSEG_LABELS");
  ASSERT_EQ(full.size(), static_cast<size_t>(kFrames));
  ASSERT_EQ(half.size(), full.size());
  ASSERT_EQ(half_labels.size(), full.size());
  int big = 0, matched = 0;
  for (size_t f = 0; f < full.size(); ++f) {
    const clutterseg::objects_t& a = full[f];
    const clutterseg::objects_t& b = half[f];
    const std::string at = "frame " + std::to_string(f);
    ASSERT_EQ(a.intrinsics.width, 640) << at;
    EXPECT_EQ(b.intrinsics.width, 320) << at;
    EXPECT_EQ(b.intrinsics.height, 240) << at;
    EXPECT_DOUBLE_EQ(b.intrinsics.fx, a.intrinsics.fx / 2) << at;
    EXPECT_DOUBLE_EQ(b.intrinsics.fy, a.intrinsics.fy / 2) << at;
    EXPECT_DOUBLE_EQ(b.intrinsics.cx, (a.intrinsics.cx + 0.5) / 2 - 0.5) << at;
    EXPECT_EQ(half_labels[f].width, 320) << at;
    EXPECT_EQ(half_labels[f].height, 240) << at;
    // Coarser points leave a few more small pieces (1-2 per frame here), never fewer objects.
    EXPECT_GE(b.num_objects, a.num_objects) << at;
    EXPECT_LE(b.num_objects, a.num_objects + 2) << at;
    for (const auto& o : a.objects) {
      if (o.num_points < 2000) continue;
      ++big;
      for (const auto& q : b.objects) {
        const double d = std::hypot(o.centroid[0] - q.centroid[0], o.centroid[1] - q.centroid[1],
                                    o.centroid[2] - q.centroid[2]);
        const double share = static_cast<double>(q.num_points) / o.num_points;
        if (d < 0.01 && share > 0.2 && share < 0.3) {
          ++matched;
          // Its pixels are in the 320x240 image.
          EXPECT_LE(q.bbox_max_u, 319) << at;
          EXPECT_LE(q.bbox_max_v, 239) << at;
          break;
        }
      }
    }
  }
  ASSERT_GE(big, kFrames);
  EXPECT_GE(matched, big * 9 / 10) << matched << " of " << big;

  EXPECT_EQ(
      RunDaemon((dir_ / "bad_decimation.lcmlog").string(), {"--set", "camera.decimation=5"}, &err),
      kExitUsage);
  EXPECT_NE(err.find("camera.decimation"), std::string::npos) << err;
}

// Waits up to 10 s until the child's stderr holds `text`.
bool WaitForText(testutil::Child* child, const std::string& text, std::string* err) {
  for (int i = 0; i < 1000; ++i) {
    testutil::Drain(child, err);
    if (err->find(text) != std::string::npos) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

TEST_F(DaemonFrame, AReloadMovesTheObjectsToTheNewPoseAndABadFileKeepsTheOld) {
  const Pose pose;
  const std::string good = (dir_ / "reload_hand_eye.json").string();
  pose.WriteJson(good);
  const std::string bad = (dir_ / "reload_bad.json").string();
  std::ofstream(bad) << R"({"parent_frame": "base_link", "translation": [0, 0, 0]})"
                     << "\n";
  const std::string config = (dir_ / "reload.yaml").string();
  const auto write_config = [&](const std::string& extrinsics) {
    std::ofstream(config) << "camera:\n  extrinsics_file: \"" << extrinsics << "\"\n";
  };
  write_config("");
  const std::string log = (dir_ / "reload.lcmlog").string();
  // Each pass of the loop is compared with an earlier one. The objects by arrival keep a
  // per-pixel history across the passes, and at the realtime pace a loaded machine drops
  // frames, so their splits need not repeat from pass to pass; nor need the flush-stack cut's,
  // whose steps are measured on the depths the temporal filter has averaged, which differ from
  // pass to pass (one loaded run found the objects of one frame 1-10 cm from the earlier
  // pass's with it on). This test is about the pose, so both are off.
  testutil::Child child = testutil::Spawn(
      {CLUTTERSEG_DAEMON_EXE, "--config", config, "--source", oni_, "--speed", "realtime", "--loop",
       "--set", "segmenter.partition.arrival_gap_frames=0", "--set",
       "segmenter.objects.stack_cut_min_step_m=0", "--lcm-url", "file://" + log + "?mode=w"});
  ASSERT_GT(child.pid, 0);
  std::string err;
  for (int i = 0; i < 1000; ++i) {
    std::error_code ec;
    if (std::filesystem::file_size(log, ec) > 200000 && !ec) break;
    testutil::Drain(&child, &err);
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  // A file without a rotation: the reload fails as a whole and the camera frame stays.
  write_config(bad);
  ASSERT_EQ(kill(child.pid, SIGHUP), 0);
  ASSERT_TRUE(WaitForText(&child, "SIGHUP: reload failed, keeping the current parameters", &err))
      << err;
  EXPECT_NE(err.find(bad), std::string::npos) << err;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  write_config(good);
  ASSERT_EQ(kill(child.pid, SIGHUP), 0);
  ASSERT_TRUE(WaitForText(&child, "SIGHUP: objects from the next frame in frame 'base_link'", &err))
      << err;
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ASSERT_EQ(kill(child.pid, SIGTERM), 0);
  ASSERT_EQ(testutil::Wait(&child, std::chrono::seconds(30), &err), kExitOk) << err;

  // The camera frame up to one frame, the base frame from the next one on, never back.
  const auto msgs = Messages<clutterseg::objects_t>(log, "CLUTTERSEG_OBJECTS");
  size_t first_base = msgs.size();
  for (size_t i = 0; i < msgs.size(); ++i) {
    if (msgs[i].frame_id == "base_link") {
      first_base = i;
      break;
    }
    EXPECT_EQ(msgs[i].frame_id, "camera") << "frame " << msgs[i].frame_seq;
  }
  ASSERT_GE(first_base, static_cast<size_t>(2 * kFrames)) << "the bad file changed nothing";
  ASSERT_LT(first_base + kFrames, msgs.size()) << err;
  int matched = 0;
  for (size_t i = first_base; i < msgs.size(); ++i) {
    EXPECT_EQ(msgs[i].frame_id, "base_link") << "frame " << msgs[i].frame_seq;
    // The same input frame one or more passes earlier (the recording loops every kFrames), in
    // the camera frame, moved by the pose: every object within 1 cm of one of them.
    const clutterseg::objects_t* cam = nullptr;
    for (size_t j = first_base; j-- > 0;) {
      if ((msgs[i].frame_seq - msgs[j].frame_seq) % kFrames == 0) {
        cam = &msgs[j];
        break;
      }
    }
    ASSERT_NE(cam, nullptr);
    for (const auto& o : msgs[i].objects) {
      double best = 1e9;
      for (const auto& c : cam->objects) {
        double want[3];
        pose.Apply(c.centroid, want);
        best = std::min(best, std::hypot(o.centroid[0] - want[0], o.centroid[1] - want[1],
                                         o.centroid[2] - want[2]));
      }
      EXPECT_LT(best, 0.01) << "frame " << msgs[i].frame_seq;
      ++matched;
    }
  }
  EXPECT_GT(matched, 0);
}

}  // namespace
}  // namespace clutterseg::daemon
