// End-to-end tests of the `clutterseg` executable on synthetic recordings with ground truth:
// clutterseg-synth writes an .oni recording plus per-frame labelled PCDs, the daemon replays it
// into an LCM log file, and the test scores every published frame against the ground truth.
// A second test compares a fresh run against the committed golden log (golden/README.md).
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/types.h"
#include "clutterseg/daemon/messages.h"
#include "clutterseg/daemon/regress.h"
#include "clutterseg/eval/metrics.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "tests/daemon/daemon_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

namespace fs = std::filesystem;

// The ground-truth recording: one incremental sequence, frame k holds k objects.
constexpr int kE2eFrames = 6;
constexpr int kE2eSeed = 3;

// Every scored frame must reach this weighted overlap (WOv). Measured on this recording
// (Release, GCC 12), frames 1-5: 0.805 0.934 0.900 0.960 0.815. The lowest frames lose to two
// known weaknesses, a bowl whose inside is split off as a small fragment (frame 1) and two
// touching objects merged into one (frame 5). The threshold is the minimum minus 0.1.
constexpr double kMinFrameWov = 0.7;
// The mean WOv over the scored frames must reach this: measured 0.883, minus 0.1.
constexpr double kMinMeanWov = 0.78;
// Objects (ground truth and published) count when they have at least this many valid pixels;
// smaller published fragments are tolerated. Measured: the smallest ground-truth object has
// 1350 pixels; the only fragments (of the bowl) have 151-175.
constexpr size_t kMinVisiblePixels = 300;
// |published objects - ground-truth objects|, both of >= kMinVisiblePixels, must not exceed
// this. Measured: 0 on frames 0-4, 1 on frame 5 (the merged pair).
constexpr int kObjectCountTolerance = 1;
// Every published object has at least this fraction of its pixels on ground-truth objects
// (little leakage onto the table). Measured minimum: 0.980.
constexpr double kMinObjectPixelsOnObjects = 0.9;

// The golden recording; must match tools/update_golden.sh.
constexpr int kGoldenFrames = 8;
constexpr int kGoldenSeed = 11;

template <typename T>
void DecodeOrFail(const testutil::LogEvent& ev, T* msg) {
  ASSERT_EQ(msg->decode(ev.data.data(), 0, static_cast<int>(ev.data.size())),
            static_cast<int>(ev.data.size()))
      << "cannot decode a message on " << ev.channel;
}

// A per-run scratch directory (unique per process so parallel ctest runs do not collide).
fs::path Scratch(const std::string& name) {
  return testing::ScratchDir(name + "_" + std::to_string(getpid()));
}

// Runs clutterseg-synth for one incremental sequence into `oni` (and `gt_dir` when non-empty).
void Synthesize(int frames, int seed, const fs::path& oni, const fs::path& gt_dir) {
  std::vector<std::string> argv{CLUTTERSEG_SYNTH_EXE,
                                "--sequence",
                                "--count",
                                "1",
                                "--frames",
                                std::to_string(frames),
                                "--seed",
                                std::to_string(seed),
                                "--oni",
                                oni.string()};
  if (!gt_dir.empty()) {
    argv.push_back("--out");
    argv.push_back(gt_dir.string());
  }
  std::string err;
  ASSERT_EQ(testutil::Run(argv, std::chrono::minutes(2), &err), 0) << err;
}

// Replays `oni` through the daemon at full speed into the LCM log `log`, with extra
// `--set KEY=VALUE` overrides.
void RunDaemon(const fs::path& oni, const fs::path& log, const std::vector<std::string>& sets) {
  std::vector<std::string> argv{CLUTTERSEG_DAEMON_EXE,
                                "--source",
                                oni.string(),
                                "--speed",
                                "max",
                                "--lcm-url",
                                "file://" + log.string() + "?mode=w"};
  for (const std::string& s : sets) {
    argv.push_back("--set");
    argv.push_back(s);
  }
  std::string err;
  ASSERT_EQ(testutil::Run(argv, std::chrono::minutes(2), &err), 0) << err;
}

// Exit code of `clutterseg-regress golden candidate`.
int Regress(const fs::path& golden, const fs::path& candidate) {
  std::string err;
  return testutil::Run({CLUTTERSEG_REGRESS_EXE, golden.string(), candidate.string()},
                       std::chrono::minutes(1), &err);
}

// The comparison report of two logs, for failure messages.
std::string RegressReportText(const fs::path& a, const fs::path& b) {
  const RegressOptions options;
  try {
    return CompareLogs(a.string(), b.string(), options).ToString(options);
  } catch (const std::exception& e) {
    return e.what();
  }
}

TEST(DaemonEndToEnd, EveryFrameMatchesSyntheticGroundTruth) {
  const fs::path dir = Scratch("daemon_e2e_gt");
  const fs::path oni = dir / "synth.oni";
  const fs::path gt_dir = dir / "gt";
  const fs::path log = dir / "out.lcmlog";
  ASSERT_NO_FATAL_FAILURE(Synthesize(kE2eFrames, kE2eSeed, oni, gt_dir));
  ASSERT_NO_FATAL_FAILURE(RunDaemon(oni, log, {}));

  std::vector<clutterseg::objects_t> objects;
  std::map<int64_t, std::vector<clutterseg::label_image_t>> labels;
  for (const testutil::LogEvent& ev : testutil::ReadLcmLog(log.string())) {
    if (ev.channel == "CLUTTERSEG_OBJECTS") {
      clutterseg::objects_t m;
      ASSERT_NO_FATAL_FAILURE(DecodeOrFail(ev, &m));
      objects.push_back(std::move(m));
    } else if (ev.channel == "CLUTTERSEG_LABELS") {
      clutterseg::label_image_t m;
      ASSERT_NO_FATAL_FAILURE(DecodeOrFail(ev, &m));
      labels[m.frame_seq].push_back(std::move(m));
    }
  }
  // Exactly one objects_t per frame, in frame order, and one label image for each.
  ASSERT_EQ(objects.size(), static_cast<size_t>(kE2eFrames));
  ASSERT_EQ(labels.size(), static_cast<size_t>(kE2eFrames));

  eval::FrameEvaluator evaluator(eval::EvalParams{});  // plain convention
  eval::FrameMetrics metrics;
  core::PointCloud gt;
  core::LabelImage label_image;
  std::vector<uint32_t> pred;
  int scored_frames = 0;
  double wov_sum = 0.0;
  for (int k = 0; k < kE2eFrames; ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    const clutterseg::objects_t& msg = objects[static_cast<size_t>(k)];
    ASSERT_EQ(msg.frame_seq, k);
    ASSERT_EQ(labels[k].size(), 1u);
    const clutterseg::label_image_t& label_msg = labels[k].front();
    EXPECT_EQ(label_msg.utime, msg.utime);
    ASSERT_NO_THROW(DecodeLabelImage(label_msg, &label_image));

    char name[32];
    std::snprintf(name, sizeof(name), "frame_%06d.pcd", k);
    io::ReadPcd((gt_dir / name).string(), io::ReadLimits{}, &gt);
    ASSERT_TRUE(gt.has_label());
    ASSERT_EQ(label_image.width, static_cast<int>(gt.width));
    ASSERT_EQ(label_image.height, static_cast<int>(gt.height));
    ASSERT_EQ(msg.intrinsics.width, label_image.width);
    ASSERT_EQ(msg.intrinsics.height, label_image.height);

    // Label ids in the image are exactly the published object ids.
    std::set<int32_t> ids;
    for (const clutterseg::object_t& o : msg.objects) ids.insert(o.id);
    EXPECT_EQ(ids.size(), msg.objects.size()) << "object ids are not unique";
    std::map<uint32_t, size_t> pixels_per_id;
    for (uint32_t l : label_image.data) {
      if (l != 0) ++pixels_per_id[l];
    }
    for (const auto& [id, count] : pixels_per_id) {
      EXPECT_TRUE(ids.count(static_cast<int32_t>(id))) << "label " << id << " has no object";
    }

    pred.assign(label_image.data.begin(), label_image.data.end());
    evaluator.Evaluate(gt.xyz, gt.label, pred, &metrics);
    int gt_objects = 0;
    for (const eval::ObjectScore& s : metrics.objects) {
      if (s.size >= kMinVisiblePixels) ++gt_objects;
    }
    int published_objects = 0;
    for (const clutterseg::object_t& o : msg.objects) {
      if (pixels_per_id[static_cast<uint32_t>(o.id)] >= kMinVisiblePixels) ++published_objects;
    }
    std::printf(
        "frame %d: ground truth %d objects (%d of >= %zu px), published %d (%d of >= %zu "
        "px), WOv %.3f\n",
        k, metrics.num_gt_objects, gt_objects, kMinVisiblePixels, msg.num_objects,
        published_objects, kMinVisiblePixels, metrics.wov);
    EXPECT_EQ(metrics.num_gt_objects, k) << "frame k of the sequence holds k objects";
    EXPECT_LE(std::abs(published_objects - gt_objects), kObjectCountTolerance)
        << "published " << published_objects << " objects of >= " << kMinVisiblePixels
        << " px, ground truth " << gt_objects;
    if (metrics.scored) {
      ++scored_frames;
      wov_sum += metrics.wov;
      EXPECT_GE(metrics.wov, kMinFrameWov);
    }

    // Each object's pixels in the label image: as many as its points, mostly on objects.
    std::map<uint32_t, size_t> on_objects;
    for (size_t i = 0; i < label_image.data.size(); ++i) {
      if (label_image.data[i] != 0 && gt.label[i] != 0) ++on_objects[label_image.data[i]];
    }
    for (const clutterseg::object_t& o : msg.objects) {
      const size_t pixels = pixels_per_id[static_cast<uint32_t>(o.id)];
      EXPECT_EQ(static_cast<size_t>(o.num_points), pixels) << "object " << o.id;
      EXPECT_GE(static_cast<double>(on_objects[static_cast<uint32_t>(o.id)]),
                kMinObjectPixelsOnObjects * static_cast<double>(pixels))
          << "object " << o.id << " leaks onto the background";
    }

    // Every centroid is finite, inside the frame's valid range (the bounding box of the
    // frame's measured points) and inside its own object's boxes.
    std::array<float, 3> lo;
    std::array<float, 3> hi;
    lo.fill(std::numeric_limits<float>::max());
    hi.fill(std::numeric_limits<float>::lowest());
    for (const core::Vec3f& p : gt.xyz) {
      if (!core::IsValid(p)) continue;
      const std::array<float, 3> c{p.x, p.y, p.z};
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], c[a]);
        hi[a] = std::max(hi[a], c[a]);
      }
    }
    constexpr float kFrameEpsM = 5e-3f;  // depth quantisation of the recording
    constexpr float kEpsM = 1e-3f;
    for (const clutterseg::object_t& o : msg.objects) {
      SCOPED_TRACE("object " + std::to_string(o.id));
      EXPECT_GT(o.num_points, 0);
      for (int a = 0; a < 3; ++a) {
        ASSERT_TRUE(std::isfinite(o.centroid[a]));
        EXPECT_GE(o.centroid[a], lo[a] - kFrameEpsM);
        EXPECT_LE(o.centroid[a], hi[a] + kFrameEpsM);
        EXPECT_GE(o.centroid[a], o.aabb_min[a] - kEpsM);
        EXPECT_LE(o.centroid[a], o.aabb_max[a] + kEpsM);
      }
      ASSERT_GT(o.centroid[2], 0.0f);
      // The centroid lies in the convex hull of the object's points, so its projection lies
      // inside the object's pixel box (one pixel of rounding slack).
      const double u = msg.intrinsics.fx * o.centroid[0] / o.centroid[2] + msg.intrinsics.cx;
      const double v = msg.intrinsics.fy * o.centroid[1] / o.centroid[2] + msg.intrinsics.cy;
      EXPECT_GE(u, o.bbox_min_u - 1.0);
      EXPECT_LE(u, o.bbox_max_u + 1.0);
      EXPECT_GE(v, o.bbox_min_v - 1.0);
      EXPECT_LE(v, o.bbox_max_v + 1.0);
    }
  }
  ASSERT_EQ(scored_frames, kE2eFrames - 1);  // frame 0 is the empty table
  std::printf("mean WOv over %d frames: %.3f\n", scored_frames, wov_sum / scored_frames);
  EXPECT_GE(wov_sum / scored_frames, kMinMeanWov);
  std::error_code ec;
  fs::remove_all(dir, ec);
}

TEST(DaemonGolden, FreshRunMatchesGoldenLogAndAPerturbedRunDoesNot) {
  const fs::path golden = CLUTTERSEG_GOLDEN_LOG;
  ASSERT_TRUE(fs::exists(golden)) << golden << " is missing: run tools/update_golden.sh";
  const fs::path dir = Scratch("daemon_golden");
  const fs::path oni = dir / "synth_seed11.oni";
  const fs::path fresh = dir / "fresh.lcmlog";
  const fs::path perturbed = dir / "perturbed.lcmlog";
  ASSERT_NO_FATAL_FAILURE(Synthesize(kGoldenFrames, kGoldenSeed, oni, {}));
  ASSERT_NO_FATAL_FAILURE(RunDaemon(oni, fresh, {}));
  EXPECT_EQ(Regress(golden, fresh), 0)
      << RegressReportText(golden, fresh)
      << "\nIf the algorithm changed on purpose, run tools/update_golden.sh (see "
         "tests/daemon/golden/README.md).";

  // The comparison must be able to fail: doubling the supervoxel seed spacing changes the
  // segmentation well beyond the tolerances.
  ASSERT_NO_FATAL_FAILURE(
      RunDaemon(oni, perturbed, {"segmenter.supervoxel.seed_resolution_m=0.06"}));
  EXPECT_EQ(Regress(golden, perturbed), 1) << RegressReportText(golden, perturbed);
  std::error_code ec;
  fs::remove_all(dir, ec);
}

}  // namespace
}  // namespace clutterseg::daemon
