// Cameras on several machines of one LAN, as real network namespaces: two hosts each run a
// daemon of their own camera that publishes over udpm with ttl=1 through a bridge (an
// unmanaged switch), each in the robot's base frame through its own extrinsics, and a
// subscriber on a third host must receive every message of both, none twice. The deployment
// docs/daemon.md describes ("Cameras on several machines of one LAN").
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "clutterseg/core/exit_codes.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/status_t.hpp"
#include "tests/daemon/daemon_cli.h"
#include "tests/daemon/daemon_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

using std::chrono::seconds;

constexpr char kGroup[] = "239.255.76.67";
constexpr char kLanUrl[] = "udpm://239.255.76.67:7667?ttl=1";

// A camera's pose in base_link: a turn of `degrees` about `axis`, then a shift `t` (m).
struct CameraPose {
  Eigen::Quaterniond q;
  Eigen::Vector3d t;
};

// What one camera's daemon delivered to the subscriber.
struct Received {
  std::set<int64_t> object_seqs;
  std::map<int64_t, clutterseg::objects_t> by_seq;
  int objects{0};
  int labels{0};
  int statuses{0};
};

TEST(DaemonLan, TwoHostsPublishAndASubscriberOnAThirdReceivesEverything) {
  testutil::LanSegment lan(3);
  if (!lan.ok()) GTEST_SKIP() << "skipped: " << lan.why();
  const std::filesystem::path dir = testing::ScratchDir("daemon_lan");
  const std::string oni = (dir / "tabletop.oni").string();
  testutil::WriteTabletopOni(oni, 45);
  const std::string log = (dir / "subscriber.lcmlog").string();

  // The subscriber (host 2) first, certain to hear the group before anything is sent.
  testutil::Child logger = testutil::Spawn(
      lan.host(2).Exec({"lcm-logger", std::string("--lcm-url=") + kLanUrl, "-f", log}));
  ASSERT_GT(logger.pid, 0);
  ASSERT_TRUE(testutil::WaitForMulticastMember(lan.host(2), kGroup, seconds(20)))
      << "the subscriber never joined " << kGroup;

  // Both replay one recording, as two cameras at different places of the cell would see one
  // scene if they were at the same place: the same camera-frame objects, in base_link through
  // different extrinsics.
  const std::vector<std::string> cameras = {"left", "right"};
  const std::vector<CameraPose> poses = {
      {Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 0.2, -0.3).normalized())),
       Eigen::Vector3d(0.4, -0.6, 1.1)},
      {Eigen::Quaterniond(Eigen::AngleAxisd(-2.1, Eigen::Vector3d(0.1, 1, 0.4).normalized())),
       Eigen::Vector3d(-0.5, 0.3, 0.9)}};
  std::vector<testutil::Child> daemons;
  for (size_t i = 0; i < cameras.size(); ++i) {
    const std::string extrinsics = (dir / (cameras[i] + "_extrinsics.json")).string();
    {
      const CameraPose& p = poses[i];
      std::ofstream f(extrinsics);
      f.precision(12);
      f << R"({"parent_frame": "base_link", "translation": [)" << p.t.x() << ", " << p.t.y() << ", "
        << p.t.z() << R"(], "rotation_xyzw": [)" << p.q.x() << ", " << p.q.y() << ", " << p.q.z()
        << ", " << p.q.w() << "]}\n";
    }
    daemons.push_back(
        testutil::Spawn(lan.host(static_cast<int>(i))
                            .Exec({CLUTTERSEG_DAEMON_EXE, "--source", oni, "--speed", "realtime",
                                   "--lcm-url", kLanUrl, "--set", "camera_name=" + cameras[i],
                                   "--set", "camera.extrinsics_file=" + extrinsics, "--set",
                                   "lcm.lock_dir=" + (dir / ("locks_" + cameras[i])).string()})));
    ASSERT_GT(daemons.back().pid, 0);
  }
  std::map<std::string, int64_t> published;
  for (size_t i = 0; i < cameras.size(); ++i) {
    std::string err;
    ASSERT_EQ(testutil::Wait(&daemons[i], seconds(120), &err), kExitOk) << cameras[i] << ":\n"
                                                                        << err;
    published[cameras[i]] = testutil::DoneCount(err, "published");
    ASSERT_GT(published[cameras[i]], 0) << err;
  }
  ASSERT_EQ(kill(logger.pid, SIGINT), 0);
  std::string logger_err;
  EXPECT_EQ(testutil::Wait(&logger, seconds(20), &logger_err), 0) << logger_err;

  std::map<std::string, Received> got;
  for (const testutil::LogEvent& ev : testutil::ReadLcmLog(log)) {
    const int n = static_cast<int>(ev.data.size());
    if (ev.channel == "CLUTTERSEG_OBJECTS") {
      clutterseg::objects_t o;
      ASSERT_GE(o.decode(ev.data.data(), 0, n), 0);
      Received& r = got[o.camera_name];
      ++r.objects;
      r.object_seqs.insert(o.frame_seq);
      r.by_seq[o.frame_seq] = o;
    } else if (ev.channel == "CLUTTERSEG_LABELS") {
      clutterseg::label_image_t l;
      ASSERT_GE(l.decode(ev.data.data(), 0, n), 0);
      ++got[l.camera_name].labels;
    } else if (ev.channel == "CLUTTERSEG_STATUS") {
      clutterseg::status_t s;
      ASSERT_GE(s.decode(ev.data.data(), 0, n), 0);
      ++got[s.camera_name].statuses;
    }
  }
  ASSERT_EQ(got.size(), cameras.size()) << "cameras heard: " << got.size();
  for (const std::string& camera : cameras) {
    SCOPED_TRACE(camera);
    const Received& r = got[camera];
    // Every frame the daemon says it published arrived, once, with its label image.
    EXPECT_EQ(r.objects, published[camera]);
    EXPECT_EQ(static_cast<int64_t>(r.object_seqs.size()), published[camera]);
    EXPECT_EQ(r.labels, published[camera]);
    EXPECT_GE(r.statuses, 1);
  }

  // Both cameras' objects in base_link: taken back into each camera's frame by its own pose,
  // they are the same objects. Compared over the frames both published from the first on, in
  // a row (a frame dropped in real time would change what a later frame's depth filter saw).
  int frames_compared = 0, objects_compared = 0;
  const Received& left = got["left"];
  const Received& right = got["right"];
  for (int64_t seq = 0; left.by_seq.count(seq) > 0 && right.by_seq.count(seq) > 0; ++seq) {
    const clutterseg::objects_t* msg[2] = {&left.by_seq.at(seq), &right.by_seq.at(seq)};
    for (int c = 0; c < 2; ++c) {
      EXPECT_EQ(msg[c]->frame_id, "base_link");
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(msg[c]->camera_translation[k], poses[c].t[k], 1e-9);
    }
    ASSERT_EQ(msg[0]->num_objects, msg[1]->num_objects) << "frame " << seq;
    for (int i = 0; i < msg[0]->num_objects; ++i) {
      Eigen::Vector3d in_camera[2];
      for (int c = 0; c < 2; ++c) {
        const float* p = msg[c]->objects[static_cast<size_t>(i)].centroid;
        in_camera[c] = poses[c].q.conjugate() * (Eigen::Vector3d(p[0], p[1], p[2]) - poses[c].t);
      }
      EXPECT_LT((in_camera[0] - in_camera[1]).norm(), 1e-3) << "frame " << seq << " object " << i;
      // ... and not the same numbers: the two base-frame centroids differ.
      const float* a = msg[0]->objects[static_cast<size_t>(i)].centroid;
      const float* b = msg[1]->objects[static_cast<size_t>(i)].centroid;
      EXPECT_GT(Eigen::Vector3d(a[0] - b[0], a[1] - b[1], a[2] - b[2]).norm(), 0.1);
      ++objects_compared;
    }
    ++frames_compared;
  }
  EXPECT_GE(frames_compared, 1);
  EXPECT_GE(objects_compared, 1);
}

}  // namespace
}  // namespace clutterseg::daemon
