#include "clutterseg/pipeline/tracker.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <set>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"
#include "tests/pipeline/alloc_count.h"
#include "tests/pipeline/tracking_sequences.h"

namespace clutterseg::pipeline {
namespace {

// A hand-made frame: objects are pixel rectangles of a W x H label image; pixel (u, v) lies
// at (5 mm * u, 5 mm * v, 1 m) and every object is 5 cm deep.
struct Rect {
  int u0, v0, u1, v1;  // [u0, u1) x [v0, v1)
};

constexpr float kPixelM = 0.005f;

SegmentationResult MakeFrame(const std::vector<Rect>& rects, int width = 120, int height = 80) {
  SegmentationResult r;
  r.width = width;
  r.height = height;
  r.labels.Reset(width, height, 0);
  for (size_t k = 0; k < rects.size(); ++k) {
    const Rect& q = rects[k];
    Object o;
    o.id = static_cast<uint32_t>(k) + 1;
    double su = 0.0, sv = 0.0;
    for (int v = q.v0; v < q.v1; ++v) {
      for (int u = q.u0; u < q.u1; ++u) {
        r.labels.at(u, v) = o.id;
        su += u;
        sv += v;
        ++o.num_points;
      }
    }
    o.centroid = core::Vec3f{static_cast<float>(kPixelM * su / o.num_points),
                             static_cast<float>(kPixelM * sv / o.num_points), 1.025f};
    o.aabb_min = core::Vec3f{kPixelM * q.u0, kPixelM * q.v0, 1.f};
    o.aabb_max = core::Vec3f{kPixelM * (q.u1 - 1), kPixelM * (q.v1 - 1), 1.05f};
    r.objects.push_back(o);
  }
  return r;
}

// The same frame as an unorganized 1 x N cloud (same point order).
SegmentationResult Flattened(SegmentationResult r) {
  r.labels.width = static_cast<int>(r.labels.data.size());
  r.labels.height = 1;
  r.width = r.labels.width;
  r.height = 1;
  return r;
}

std::vector<int64_t> Ids(const TrackingResult& t) {
  std::vector<int64_t> ids;
  for (const ObjectTrack& o : t.objects) ids.push_back(o.track_id);
  return ids;
}

bool IsLost(const TrackingResult& t, int64_t id) {
  return std::any_of(t.lost.begin(), t.lost.end(),
                     [&](const LostTrack& l) { return l.track_id == id; });
}

bool Ended(const TrackingResult& t, int64_t id) {
  return std::count(t.ended_track_ids.begin(), t.ended_track_ids.end(), id) == 1;
}

class TrackerTest : public ::testing::Test {
 protected:
  const TrackingResult& Step(const std::vector<Rect>& rects) {
    dut_.Update(MakeFrame(rects), seq_++, &out_);
    return out_;
  }
  TrackerParams params_;
  Tracker dut_{params_};
  int64_t seq_{0};
  TrackingResult out_;
};

const Rect kA{10, 10, 30, 30};
const Rect kB{50, 10, 70, 30};
const Rect kC{31, 10, 45, 30};  // touching kA (one pixel gap)

TEST_F(TrackerTest, KeepsIdsConfirmsAfterConfirmFramesAndCountsAge) {
  for (int f = 0; f < 5; ++f) {
    const TrackingResult& t = Step({kA, kB});
    ASSERT_EQ(t.objects.size(), 2u);
    EXPECT_EQ(Ids(t), (std::vector<int64_t>{1, 2})) << "frame " << f;
    for (const ObjectTrack& o : t.objects) {
      EXPECT_EQ(o.age_frames, f);
      EXPECT_EQ(o.seen_frames, f + 1);
      EXPECT_EQ(o.state,
                f + 1 >= params_.confirm_frames ? TrackState::kConfirmed : TrackState::kNew);
    }
    EXPECT_TRUE(t.lost.empty());
    EXPECT_TRUE(t.ended_track_ids.empty());
    EXPECT_GE(t.time_ms, 0.0);
  }
  EXPECT_EQ(dut_.next_track_id(), 3);
}

TEST_F(TrackerTest, FollowsMasksWhenTheSegmenterRenumbers) {
  Step({kA, kB});
  const TrackingResult& t = Step({kB, kA});  // label 1 is now kB
  EXPECT_EQ(Ids(t), (std::vector<int64_t>{2, 1}));
  EXPECT_EQ(t.counts.continued, 2);
}

TEST_F(TrackerTest, AddedAndRemovedNeighboursDoNotDisturbATrack) {
  for (int f = 0; f < 3; ++f) Step({kA, kB});
  // A new object touching kA gets a new id; kA and kB keep theirs.
  const TrackingResult& added = Step({kA, kC, kB});
  EXPECT_EQ(Ids(added), (std::vector<int64_t>{1, 3, 2}));
  EXPECT_EQ(added.objects[1].state, TrackState::kNew);
  EXPECT_EQ(added.counts.created, 1);
  for (int f = 0; f < 3; ++f) Step({kA, kC, kB});
  // kB removed: it is remembered, the others are untouched.
  const TrackingResult& removed = Step({kA, kC});
  EXPECT_EQ(Ids(removed), (std::vector<int64_t>{1, 3}));
  ASSERT_EQ(removed.lost.size(), 1u);
  EXPECT_EQ(removed.lost[0].track_id, 2);
  EXPECT_EQ(removed.lost[0].frames_since_seen, 1);
  EXPECT_TRUE(removed.lost[0].was_confirmed);
  EXPECT_EQ(removed.lost[0].state, TrackState::kLost);
  EXPECT_NEAR(removed.lost[0].centroid.x, kPixelM * 59.5f, 1e-5f);
}

TEST_F(TrackerTest, ForgottenTracksEndOnceAndTheirIdsAreNeverReused) {
  params_.memory_frames = 4;
  Tracker dut(params_);
  TrackingResult t;
  int64_t seq = 0;
  for (int f = 0; f < 3; ++f) dut.Update(MakeFrame({kA, kB}), seq++, &t);
  int ended_at = -1;
  std::set<int64_t> ended;
  for (int f = 0; f < 8; ++f) {
    dut.Update(MakeFrame({kA}), seq++, &t);
    EXPECT_EQ(Ids(t), (std::vector<int64_t>{1}));
    if (Ended(t, 2)) {
      EXPECT_EQ(ended_at, -1) << "ended twice";
      ended_at = f;
    }
    EXPECT_EQ(IsLost(t, 2), f < params_.memory_frames);
    ended.insert(t.ended_track_ids.begin(), t.ended_track_ids.end());
  }
  EXPECT_EQ(ended_at, params_.memory_frames);  // lost for memory_frames frames, then ended
  // kB back at its place after its track ended: a new id.
  dut.Update(MakeFrame({kA, kB}), seq++, &t);
  EXPECT_EQ(Ids(t), (std::vector<int64_t>{1, 3}));
  EXPECT_EQ(ended, (std::set<int64_t>{2}));
}

TEST_F(TrackerTest, ShortLivedSpuriousObjectIsNeverConfirmedAndLeavesNoMemory) {
  for (int f = 0; f < 3; ++f) Step({kA});
  const TrackingResult& blip = Step({kA, kB});
  EXPECT_EQ(blip.objects[1].state, TrackState::kNew);
  const TrackingResult& after = Step({kA});
  EXPECT_TRUE(after.lost.empty());
  EXPECT_TRUE(Ended(after, 2));
}

TEST_F(TrackerTest, HiddenObjectGetsItsIdBackEvenWhenItReappearsPartly) {
  for (int f = 0; f < 4; ++f) Step({kA, kB});
  // kB hidden progressively from its left (an arm sweeping left to right), then gone.
  Step({kA, Rect{58, 10, 70, 30}});
  Step({kA, Rect{66, 10, 70, 30}});
  for (int f = 0; f < 5; ++f) {
    const TrackingResult& t = Step({kA});
    ASSERT_TRUE(IsLost(t, 2));
  }
  // It reappears from the left edge: the sliver lies in the remembered (whole) box.
  const TrackingResult& back = Step({kA, Rect{50, 10, 54, 30}});
  EXPECT_EQ(Ids(back), (std::vector<int64_t>{1, 2}));
  EXPECT_TRUE(back.objects[1].reacquired);
  EXPECT_EQ(back.objects[1].state, TrackState::kConfirmed);
  EXPECT_EQ(back.counts.reacquired, 1);
  EXPECT_TRUE(back.lost.empty());
  EXPECT_EQ(Ids(Step({kA, kB})), (std::vector<int64_t>{1, 2}));
}

TEST_F(TrackerTest, ANewObjectBesideARememberedOneDoesNotTakeItsId) {
  for (int f = 0; f < 4; ++f) Step({kA, kB});
  Step({kA});
  // Something else appears right beside where kB was (overlapping its box by a third).
  const TrackingResult& t = Step({kA, Rect{63, 10, 83, 30}});
  EXPECT_EQ(Ids(t), (std::vector<int64_t>{1, 3}));
  EXPECT_TRUE(IsLost(t, 2));
}

TEST_F(TrackerTest, SplitKeepsTheIdOnTheLargerPart) {
  const Rect whole{10, 10, 50, 30};
  for (int f = 0; f < 4; ++f) Step({whole, kB});
  // The object falls apart into a small left part and a large right part (label order puts
  // the small one first).
  const TrackingResult& t =
      Step({Rect{10, 10, 22, 30}, Rect{24, 10, 50, 30}, Rect{55, 10, 75, 30}});
  EXPECT_EQ(Ids(t), (std::vector<int64_t>{3, 1, 2}));
  EXPECT_EQ(t.counts.splits, 1);
  EXPECT_EQ(t.objects[0].state, TrackState::kNew);
}

TEST_F(TrackerTest, MergeKeepsTheLargerTrackAndTheOtherComesBackOnSeparation) {
  const Rect small{10, 10, 20, 30}, large{21, 10, 50, 30};
  for (int f = 0; f < 4; ++f) Step({small, large});
  EXPECT_EQ(Ids(out_), (std::vector<int64_t>{1, 2}));
  const TrackingResult& merged = Step({Rect{10, 10, 50, 30}});
  EXPECT_EQ(Ids(merged), (std::vector<int64_t>{2}));
  EXPECT_EQ(merged.counts.merges, 1);
  ASSERT_EQ(merged.lost.size(), 1u);
  EXPECT_EQ(merged.lost[0].track_id, 1);
  Step({Rect{10, 10, 50, 30}});
  const TrackingResult& apart = Step({small, large});
  EXPECT_EQ(Ids(apart), (std::vector<int64_t>{1, 2}));
  EXPECT_TRUE(apart.objects[0].reacquired);
  EXPECT_EQ(apart.counts.splits, 1);
}

// Two objects of about one size merge (the larger track keeps the merged object) and come
// apart with the other one now the larger part. By default the merged track may only go to the
// larger part, the other object's, and one of them loses its id; with split_own_margin_m each
// object gets its own id back.
TEST(TrackerSplitOwnPart, AMergeThatComesApartGivesEachObjectItsOwnId) {
  const Rect a{10, 10, 30, 30}, b{30, 10, 51, 30}, merged{10, 10, 51, 30};
  const Rect a_after{10, 10, 32, 30}, b_after{32, 10, 51, 30};  // a now the larger part
  for (const float margin : {0.f, 0.01f}) {
    TrackerParams p;
    p.split_own_margin_m = margin;
    Tracker dut(p);
    TrackingResult out;
    int64_t seq = 0;
    for (int f = 0; f < 4; ++f) dut.Update(MakeFrame({a, b}), seq++, &out);
    ASSERT_EQ(Ids(out), (std::vector<int64_t>{1, 2}));
    for (int f = 0; f < 2; ++f) dut.Update(MakeFrame({merged}), seq++, &out);
    ASSERT_EQ(Ids(out), (std::vector<int64_t>{2})) << "b is the larger track";
    dut.Update(MakeFrame({a_after, b_after}), seq++, &out);
    if (margin > 0.f) {
      EXPECT_EQ(Ids(out), (std::vector<int64_t>{1, 2}));
      EXPECT_TRUE(out.objects[0].reacquired);
    } else {
      // The merged track may go to the larger part only, which reacquires its own remembered
      // id instead: the smaller part, b, starts a new track.
      EXPECT_EQ(Ids(out), (std::vector<int64_t>{1, 3}));
    }
  }
}

// One segment covering two objects splits; the larger part keeps its track (1) and the other
// starts its own (2). The larger part then leaves, so track 1 is remembered with the box of the
// whole. When noise moves the remaining object's boundary (a third of it missing), its
// continuation scores lower than track 1's remembered box, which encloses it: with
// continuation_before_reacquire it keeps its own id; without, it takes the id of the object
// that left.
TEST(TrackerContinuation, AnObjectWhoseBoundaryMovesKeepsItsIdBesideAnEnclosingRememberedBox) {
  const Rect whole{10, 10, 40, 30}, part{10, 10, 22, 30}, other{23, 10, 40, 30};
  const Rect shrunk{10, 10, 17, 30};
  for (const bool rule : {true, false}) {
    TrackerParams p;
    p.continuation_before_reacquire = rule;
    Tracker dut(p);
    TrackingResult out;
    int64_t seq = 0;
    for (int f = 0; f < 4; ++f) dut.Update(MakeFrame({whole}), seq++, &out);
    for (int f = 0; f < 4; ++f) dut.Update(MakeFrame({part, other}), seq++, &out);
    ASSERT_EQ(Ids(out), (std::vector<int64_t>{2, 1}));
    ASSERT_EQ(out.objects[0].state, TrackState::kConfirmed);
    dut.Update(MakeFrame({part}), seq++, &out);
    ASSERT_EQ(Ids(out), (std::vector<int64_t>{2}));
    ASSERT_TRUE(IsLost(out, 1));
    dut.Update(MakeFrame({shrunk}), seq++, &out);
    if (rule) {
      EXPECT_EQ(Ids(out), (std::vector<int64_t>{2}));
      EXPECT_TRUE(IsLost(out, 1));
      EXPECT_EQ(out.counts.continued, 1);
    } else {
      EXPECT_EQ(Ids(out), (std::vector<int64_t>{1})) << "the failure the rule prevents";
      EXPECT_TRUE(IsLost(out, 2));
    }
    // Back at its full extent, the object keeps its id (without the rule the ids would
    // swap again: the remembered box of track 2 encloses it).
    dut.Update(MakeFrame({part}), seq++, &out);
    if (rule) {
      EXPECT_EQ(Ids(out), (std::vector<int64_t>{2}));
    }
  }
}

// Frames with depth: each surface is a rectangle at one depth, drawn in order (a later one in
// front); surfaces that share a label are one segment (a merge). Pixel (u, v) of a surface at
// depth z lies at (5 mm * u, 5 mm * v, z) and every object's box is 5 cm deep.
struct Surface {
  Rect rect;
  float z;
  uint32_t label;
};

SegmentationResult MakeDepthFrame(const std::vector<Surface>& surfaces, core::PointCloud* cloud,
                                  int width = 120, int height = 80) {
  SegmentationResult r;
  r.width = width;
  r.height = height;
  r.labels.Reset(width, height, 0);
  cloud->width = width;
  cloud->height = height;
  cloud->xyz.assign(static_cast<size_t>(width) * height, core::Vec3f{NAN, NAN, NAN});
  uint32_t max_label = 0;
  for (const Surface& f : surfaces) {
    max_label = std::max(max_label, f.label);
    for (int v = f.rect.v0; v < f.rect.v1; ++v) {
      for (int u = f.rect.u0; u < f.rect.u1; ++u) {
        r.labels.at(u, v) = f.label;
        cloud->xyz[static_cast<size_t>(v) * width + u] = core::Vec3f{kPixelM * u, kPixelM * v, f.z};
      }
    }
  }
  for (uint32_t id = 1; id <= max_label; ++id) {
    Object o;
    o.id = id;
    core::Vec3f lo{1e9f, 1e9f, 1e9f}, hi{-1e9f, -1e9f, -1e9f};
    double sx = 0.0, sy = 0.0, sz = 0.0;
    for (size_t i = 0; i < r.labels.data.size(); ++i) {
      if (r.labels.data[i] != id) continue;
      const core::Vec3f& p = cloud->xyz[i];
      sx += p.x;
      sy += p.y;
      sz += p.z;
      lo = core::Vec3f{std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
      hi = core::Vec3f{std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
      ++o.num_points;
    }
    EXPECT_GT(o.num_points, 0u) << "labels are 1..n, as the Segmenter numbers them";
    const float n = static_cast<float>(o.num_points);
    o.centroid = core::Vec3f{static_cast<float>(sx / n), static_cast<float>(sy / n),
                             static_cast<float>(sz / n) + 0.025f};
    o.aabb_min = lo;
    o.aabb_max = core::Vec3f{hi.x, hi.y, hi.z + 0.05f};
    r.objects.push_back(o);
  }
  return r;
}

class TrackerDepthTest : public ::testing::Test {
 protected:
  // One frame, to the tracker with its depth (and to a second tracker without it).
  const TrackingResult& Step(const std::vector<Surface>& surfaces) {
    const SegmentationResult frame = MakeDepthFrame(surfaces, &cloud_);
    no_depth_.Update(frame, seq_, &no_depth_out_);
    dut_.Update(frame, seq_++, &out_, cloud_);
    return out_;
  }
  Tracker dut_{TrackerParams{}};
  Tracker no_depth_{TrackerParams{}};
  int64_t seq_{0};
  core::PointCloud cloud_;
  TrackingResult out_, no_depth_out_;
};

TEST_F(TrackerDepthTest, AnObjectPutDownOnATrackDoesNotTakeItsId) {
  const Surface a{kA, 1.0f, 1}, b{kB, 1.0f, 2};
  for (int f = 0; f < 4; ++f) EXPECT_EQ(Ids(Step({a, b})), (std::vector<int64_t>{1, 2}));
  // An object put down on kA hides most of it; the segmentation joins it to kA's rim.
  const Surface on_a{Rect{12, 12, 28, 28}, 0.9f, 1};
  for (int f = 0; f < 3; ++f) {
    const TrackingResult& t = Step({a, on_a, b});
    EXPECT_EQ(Ids(t), (std::vector<int64_t>{3, 2})) << "frame " << f;
    EXPECT_TRUE(IsLost(t, 1));
  }
  // Without the depth the surface in front continues kA's track.
  EXPECT_EQ(Ids(no_depth_out_), (std::vector<int64_t>{1, 2}));
  // Taken away again: kA gets its id back from its remembered surface.
  const TrackingResult& back = Step({a, b});
  EXPECT_EQ(Ids(back), (std::vector<int64_t>{1, 2}));
  EXPECT_TRUE(back.objects[0].reacquired);
  EXPECT_TRUE(IsLost(back, 3));
}

TEST_F(TrackerDepthTest, WhatIsLeftInViewOfAHiddenTrackKeepsItsId) {
  const Surface a{kA, 1.0f, 1}, b{kB, 1.0f, 2};
  for (int f = 0; f < 4; ++f) Step({a, b});
  // Two thirds of kA hidden by an object in front, segmented apart from kA's visible rest.
  for (int f = 0; f < 3; ++f) {
    const TrackingResult& t = Step({a, Surface{Rect{8, 8, 32, 24}, 0.9f, 3}, b});
    EXPECT_EQ(Ids(t), (std::vector<int64_t>{1, 2, 3})) << "frame " << f;
  }
}

TEST_F(TrackerDepthTest, APieceLeftInViewByACrossingOccluderKeepsItsId) {
  // A long object, 25 cm wide.
  const Surface whole{Rect{10, 10, 60, 30}, 1.0f, 1};
  for (int f = 0; f < 4; ++f) EXPECT_EQ(Ids(Step({whole})), (std::vector<int64_t>{1}));
  // An occluder in front hides its left part, then, moving right, all but its left end: the
  // piece in view then lies off the previous mask and 17 cm from the previous centroid, but
  // on the surface the track remembers.
  const TrackingResult& right =
      Step({Surface{Rect{45, 10, 60, 30}, 1.0f, 1}, Surface{Rect{10, 10, 45, 30}, 0.6f, 2}});
  EXPECT_EQ(Ids(right), (std::vector<int64_t>{1, 2}));
  const TrackingResult& left =
      Step({Surface{Rect{10, 10, 25, 30}, 1.0f, 1}, Surface{Rect{25, 10, 60, 30}, 0.6f, 2}});
  EXPECT_EQ(Ids(left), (std::vector<int64_t>{1, 2}));
  EXPECT_FALSE(left.objects[0].reacquired);
  // Without the depth the piece is a new object.
  EXPECT_EQ(no_depth_out_.objects[0].track_id, 3);
}

TEST_F(TrackerDepthTest, ANewObjectWhereARememberedOneWasDoesNotTakeItsId) {
  const Surface a{kA, 1.0f, 1}, b{kB, 1.0f, 2}, b_alone{kB, 1.0f, 1};
  for (int f = 0; f < 4; ++f) Step({a, b});
  for (int f = 0; f < 2; ++f) EXPECT_TRUE(IsLost(Step({b_alone}), 1));  // kA taken away
  // Another object put where kA stood, 2 cm nearer: within kA's remembered box, but its
  // surface is not kA's.
  const Surface other{Rect{12, 12, 28, 28}, 0.98f, 1};
  const TrackingResult& t = Step({other, b});
  EXPECT_EQ(Ids(t), (std::vector<int64_t>{3, 2}));
  EXPECT_EQ(Ids(no_depth_out_), (std::vector<int64_t>{1, 2}));  // by the box alone it would
  // kA put back where it stood (and the other object gone) is kA again.
  for (int f = 0; f < 2; ++f) Step({b_alone});
  EXPECT_EQ(Ids(Step({a, b})), (std::vector<int64_t>{1, 2}));
}

// An occluder sweeps across a long object on a table. Its left end shows again while the
// track still continues on its right end (so the left end starts a new track); then the right
// end is hidden too. The left end shows the track's remembered surface: the track that began in
// the frame the object was last seen in does not keep it, the object gets its id back.
TEST_F(TrackerDepthTest, AnEndShowingAgainBesideAnOccluderGetsTheObjectsIdBack) {
  const Surface table{Rect{0, 0, 120, 80}, 1.2f, 0};
  for (int f = 0; f < 4; ++f) {
    EXPECT_EQ(Ids(Step({table, Surface{Rect{10, 10, 60, 30}, 1.0f, 1}})),
              (std::vector<int64_t>{1}));
  }
  // The occluder (a segment of its own) hides the left half, then the middle.
  EXPECT_EQ(Ids(Step({table, Surface{Rect{35, 10, 60, 30}, 1.0f, 1},
                      Surface{Rect{5, 5, 35, 35}, 0.6f, 2}})),
            (std::vector<int64_t>{1, 2}));
  const TrackingResult& both =
      Step({table, Surface{Rect{10, 10, 18, 30}, 1.0f, 1}, Surface{Rect{45, 10, 60, 30}, 1.0f, 2},
            Surface{Rect{18, 5, 45, 35}, 0.6f, 3}});
  EXPECT_EQ(Ids(both), (std::vector<int64_t>{3, 1, 2}));
  // The right end hidden: the left end shows the object's remembered surface, and the new track
  // of its last frame does not keep it: the object's id in that frame, and after.
  for (int f = 0; f < 3; ++f) {
    const TrackingResult& back = Step(
        {table, Surface{Rect{10, 10, 25, 30}, 1.0f, 1}, Surface{Rect{25, 5, 65, 35}, 0.6f, 2}});
    EXPECT_EQ(back.objects[0].track_id, 1) << f;
    EXPECT_FALSE(back.objects[0].reacquired) << f;
  }
}

// The same with an occluder that is not segmented (too near, or without depth): the object's
// right end leaves no changed surface behind, only pixels on no object.
TEST_F(TrackerDepthTest, AnEndShowingAgainBesideAnOccluderWithoutDepthGetsTheObjectsIdBack) {
  for (int f = 0; f < 4; ++f) Step({Surface{Rect{10, 10, 60, 30}, 1.0f, 1}});
  EXPECT_EQ(Ids(Step({Surface{Rect{35, 10, 60, 30}, 1.0f, 1}})), (std::vector<int64_t>{1}));
  // The left end shows again while the right one is in view: a new track (the object's holds the
  // right end).
  EXPECT_EQ(
      Ids(Step({Surface{Rect{10, 10, 18, 30}, 1.0f, 1}, Surface{Rect{45, 10, 60, 30}, 1.0f, 2}})),
      (std::vector<int64_t>{2, 1}));
  // The right end gone: the left end is the object again, at once.
  for (int f = 0; f < 3; ++f) {
    const TrackingResult& t = Step({Surface{Rect{10, 10, 30, 30}, 1.0f, 1}});
    EXPECT_EQ(Ids(t), (std::vector<int64_t>{1})) << f;
    EXPECT_FALSE(t.objects[0].reacquired) << f;
  }
}

// A tracker with `params` fed frames with their depth, one per call; returns the frame's ids.
class DepthSequence {
 public:
  explicit DepthSequence(const TrackerParams& params) : dut_(params) {}
  std::vector<int64_t> operator()(const std::vector<Surface>& surfaces) {
    dut_.Update(MakeDepthFrame(surfaces, &cloud_), seq_++, &out_, cloud_);
    return Ids(out_);
  }
  const TrackingResult& out() const { return out_; }

 private:
  Tracker dut_;
  core::PointCloud cloud_;
  TrackingResult out_;
  int64_t seq_{0};
};

// An occluder (a segment of its own) sweeps right across a long object with nothing behind it:
// first the object's left part is hidden, then its middle, while its left end shows again and
// most of what the track held in the previous frame falls into holes (no depth). The occluder
// reaches the track's previous mask only where it came in front: with
// occluder_is_not_continuation it does not continue the track, and the left end takes the
// object's id by its remembered surface, in its first frame; without, it gets a new id.
std::vector<int64_t> SweptEndIds(bool occluder_is_not_continuation) {
  TrackerParams params;
  params.occluder_is_not_continuation = occluder_is_not_continuation;
  DepthSequence step(params);
  for (int f = 0; f < 4; ++f) {
    EXPECT_EQ(step({Surface{Rect{10, 10, 60, 30}, 1.0f, 1}}), (std::vector<int64_t>{1}));
  }
  EXPECT_EQ(step({Surface{Rect{35, 10, 60, 30}, 1.0f, 1}, Surface{Rect{10, 10, 35, 30}, 0.6f, 2}}),
            (std::vector<int64_t>{1, 2}));
  // The occluder over columns 22-40: 100 of the 500 pixels the track held, the other 400 holes.
  const std::vector<int64_t> ids =
      step({Surface{Rect{10, 10, 22, 30}, 1.0f, 1}, Surface{Rect{22, 10, 40, 30}, 0.6f, 2}});
  EXPECT_FALSE(step.out().objects[0].reacquired);
  return ids;
}

// Two touching objects, apart for `apart_frames`, then segmented as one for longer than
// memory_frames (both still there), then apart again: with merged_memory an absorbed track that
// was seen for memory_frames is remembered while its surface stays in view and takes its id
// back; without, or when it was seen for fewer frames (a piece split off for a few frames while
// an object was put down), it has ended and the object gets a new id.
std::vector<int64_t> LongMergeIds(bool merged_memory, int apart_frames) {
  TrackerParams params;
  params.merged_memory = merged_memory;
  DepthSequence step(params);
  const Surface a{Rect{10, 10, 30, 30}, 1.0f, 1}, b{Rect{30, 10, 55, 30}, 1.0f, 2};
  for (int f = 0; f < apart_frames; ++f) EXPECT_EQ(step({a, b}), (std::vector<int64_t>{1, 2}));
  for (int f = 0; f < params.memory_frames + 20; ++f) {
    EXPECT_EQ(step({Surface{Rect{10, 10, 55, 30}, 1.0f, 1}}), (std::vector<int64_t>{2})) << f;
  }
  return step({a, b});
}

TEST(TrackerMergedMemory, AnObjectMergedLongerThanTheMemoryGetsItsIdBackWhenApart) {
  const int seen = TrackerParams{}.memory_frames;
  EXPECT_EQ(LongMergeIds(true, seen), (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(LongMergeIds(false, seen), (std::vector<int64_t>{3, 2}));
}

TEST(TrackerMergedMemory, APieceSeenApartForAFewFramesIsNotRememberedThroughALongMerge) {
  EXPECT_EQ(LongMergeIds(true, 7), (std::vector<int64_t>{3, 2}));
}

// An object mostly hidden behind another, with a piece of it showing beside the occluder under
// a track of its own. The occluder is taken away and the surface it hid is segmented with the
// piece; then the whole object is one segment. With uncovered_view_not_reference the merge goes to
// the track of the object's larger part, whose view was its own; without, to the piece's track,
// whose view the uncovered surface had made the larger.
std::vector<int64_t> UncoveredMergeIds(bool uncovered_view_not_reference) {
  TrackerParams params;
  params.uncovered_view_not_reference = uncovered_view_not_reference;
  DepthSequence step(params);
  const Surface part{Rect{10, 10, 30, 30}, 1.0f, 1}, occluder{Rect{30, 10, 55, 30}, 0.9f, 2},
      piece{Rect{55, 10, 60, 30}, 1.0f, 3};
  for (int f = 0; f < 5; ++f) {
    EXPECT_EQ(step({part, occluder, piece}), (std::vector<int64_t>{1, 2, 3})) << f;
  }
  EXPECT_EQ(step({part, Surface{Rect{30, 10, 60, 30}, 1.0f, 2}}), (std::vector<int64_t>{1, 3}));
  return step({Surface{Rect{10, 10, 60, 30}, 1.0f, 1}});
}

TEST(TrackerUncovered, AMergeAfterAnUncoveringGoesToTheObjectsLargerPart) {
  EXPECT_EQ(UncoveredMergeIds(true), (std::vector<int64_t>{1}));
  EXPECT_EQ(UncoveredMergeIds(false), (std::vector<int64_t>{3}));
}

TEST(TrackerOccluder, AnEndShowingAgainBesideAnOccluderOverHolesKeepsTheObjectsId) {
  EXPECT_EQ(SweptEndIds(true), (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(SweptEndIds(false), (std::vector<int64_t>{3, 2}));  // the occluder continued it
}

// A track whose merge with a newcomer comes apart, the newcomer's pixels now on no object,
// continues on its own object; a piece of its remembered surface beside it that was not in the
// merge does not take the track by that surface.
TEST_F(TrackerDepthTest, AVanishedTrackThatContinuesDoesNotJumpToAPieceOfItsSurface) {
  for (int f = 0; f < 4; ++f) {
    EXPECT_EQ(Ids(Step({Surface{Rect{10, 10, 40, 30}, 1.0f, 1}})), (std::vector<int64_t>{1}));
  }
  // A newcomer against it, segmented with it; a strip of it unlabelled in this frame.
  EXPECT_EQ(
      Ids(Step({Surface{Rect{10, 10, 36, 30}, 1.0f, 1}, Surface{Rect{40, 10, 75, 30}, 1.0f, 1}})),
      (std::vector<int64_t>{1}));
  // The newcomer gone from the segmentation; the strip a segment of its own.
  const TrackingResult& t =
      Step({Surface{Rect{10, 10, 36, 30}, 1.0f, 1}, Surface{Rect{36, 10, 40, 30}, 1.0f, 2}});
  ASSERT_EQ(t.objects.size(), 2u);
  EXPECT_EQ(t.objects[0].track_id, 1);
  EXPECT_NE(t.objects[1].track_id, 1);
}

// A large object mostly hidden (by something the segmentation leaves out) merges with a
// smaller neighbour: the segment is mostly the neighbour in view, and the neighbour's track
// keeps it, not the track of the largest remembered view.
TEST_F(TrackerDepthTest, AMergeGoesToTheTrackClearlyMostInView) {
  const Surface small{Rect{45, 10, 55, 40}, 1.0f, 2};
  for (int f = 0; f < 4; ++f) {
    EXPECT_EQ(Ids(Step({Surface{Rect{10, 10, 40, 40}, 1.0f, 1}, small})),
              (std::vector<int64_t>{1, 2}));
  }
  const Surface rest{Rect{36, 10, 40, 35}, 1.0f, 1};  // 100 of its 900 pixels
  EXPECT_EQ(Ids(Step({rest, small})), (std::vector<int64_t>{1, 2}));
  for (int f = 0; f < 2; ++f) {
    const TrackingResult& t = Step({rest, Surface{small.rect, 1.0f, 1}});
    EXPECT_EQ(Ids(t), (std::vector<int64_t>{2})) << f;
    EXPECT_TRUE(IsLost(t, 1)) << f;
  }
}

// An object put down across a long object on a table cuts it into two halves and a sliver
// below the newcomer, nearer the object's centroid than either half: a half keeps the id.
TEST_F(TrackerDepthTest, ASliverOfAnObjectCutInTwoDoesNotKeepItsId) {
  const Surface table{Rect{0, 0, 120, 80}, 1.2f, 0};
  for (int f = 0; f < 4; ++f) Step({table, Surface{Rect{10, 10, 60, 30}, 1.0f, 1}});
  const TrackingResult& t =
      Step({table, Surface{Rect{10, 10, 30, 30}, 1.0f, 1}, Surface{Rect{40, 10, 60, 30}, 1.0f, 2},
            Surface{Rect{30, 28, 40, 30}, 1.0f, 3}, Surface{Rect{30, 5, 40, 28}, 0.9f, 4}});
  ASSERT_EQ(t.objects.size(), 4u);
  EXPECT_EQ(t.objects[0].track_id, 1);  // the halves tie; the first keeps it
  EXPECT_NE(t.objects[2].track_id, 1);  // not the sliver
  EXPECT_EQ(t.counts.splits, 1);
}

TEST_F(TrackerDepthTest, ANewBandDecidesWhichDepthsAreTheRememberedSurface) {
  const Surface a{kA, 1.0f, 1}, b{kB, 1.0f, 2}, b_alone{kB, 1.0f, 1};
  for (int f = 0; f < 4; ++f) Step({a, b});
  TemporalFilterParams bad;
  bad.min_band_m = -1.f;
  EXPECT_THROW(dut_.SetBand(bad), std::invalid_argument);
  // A band of 3 cm (a reload of segmenter.temporal): a surface 2 cm nearer where kA stood is
  // kA's remembered surface; within the default band it was not
  // (ANewObjectWhereARememberedOneWasDoesNotTakeItsId).
  TemporalFilterParams wide;
  wide.min_band_m = 0.03f;
  dut_.SetBand(wide);
  for (int f = 0; f < 2; ++f) EXPECT_TRUE(IsLost(Step({b_alone}), 1));
  EXPECT_EQ(Ids(Step({Surface{Rect{12, 12, 28, 28}, 0.98f, 1}, b})), (std::vector<int64_t>{1, 2}));
}

TEST_F(TrackerDepthTest, AnObjectShowingAgainGetsItsIdBackFromTheNewTrackOfItsFirstFrames) {
  // On a table (background), kA is seen with its left half only (its right half behind
  // something not segmented).
  const Surface table{Rect{0, 0, 120, 80}, 1.2f, 0};
  const Surface left{Rect{10, 10, 20, 30}, 1.0f, 1}, b{kB, 1.0f, 2};
  for (int f = 0; f < 4; ++f) Step({table, left, b});
  // An arm in front hides it wholly; it is remembered (its surface: the left half).
  for (int f = 0; f < 2; ++f) {
    EXPECT_TRUE(IsLost(Step({table, Surface{Rect{5, 5, 35, 35}, 0.6f, 1}, b}), 1));
  }
  // The arm leaves the other way: the right half shows first, which is no remembered surface,
  // so it starts a new track, and that track follows the object as more of it shows...
  const TrackingResult& sliver = Step({table, Surface{Rect{20, 10, 30, 30}, 1.0f, 1}, b});
  EXPECT_EQ(Ids(sliver), (std::vector<int64_t>{4, 2}));
  EXPECT_EQ(Ids(Step({table, Surface{Rect{16, 10, 30, 30}, 1.0f, 1}, b})),
            (std::vector<int64_t>{4, 2}));
  // ...until the object shows its remembered surface with half its pixels: it is kA again (by
  // the scores alone the new track would keep it: mask IoU 0.7 against a surface half shown).
  const TrackingResult& whole = Step({table, Surface{kA, 1.0f, 1}, b});
  EXPECT_EQ(Ids(whole), (std::vector<int64_t>{1, 2}));
  EXPECT_TRUE(whole.objects[0].reacquired);
  EXPECT_TRUE(Ended(whole, 4));
}

// An object put down against kA is joined to it by the segmentation in the frame it arrives
// (kA's track continues on the joined segment, most of it pixels that were background), then
// segmented apart: kA keeps its id, although the newcomer is the larger part and lies nearer the
// joined segment's centroid. The joined view is neither kA's own view nor its reference. Joined
// and apart again, each gets its id back.
TEST_F(TrackerDepthTest, AnObjectPutDownAgainstATrackAndJoinedToItLeavesItItsId) {
  const Surface a{kA, 1.0f, 1}, b{kB, 1.0f, 2};
  // 750 pixels against kA's 400, along its lower edge.
  const Surface joined{Rect{10, 30, 40, 55}, 1.0f, 1}, apart{Rect{10, 30, 40, 55}, 1.0f, 3};
  for (int f = 0; f < 4; ++f) Step({a, b});
  ASSERT_EQ(Ids(out_), (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(Ids(Step({a, b, joined})), (std::vector<int64_t>{1, 2}));
  for (int k = 0; k < 3; ++k) {
    const TrackingResult& t = Step({a, b, apart});
    EXPECT_EQ(Ids(t), (std::vector<int64_t>{1, 2, 3})) << k;
    EXPECT_EQ(t.counts.splits, 1) << k;
    // Joined again, a merge of two tracks: the larger keeps the segment, kA is remembered.
    const TrackingResult& m = Step({a, b, joined});
    EXPECT_EQ(Ids(m), (std::vector<int64_t>{3, 2})) << k;
    EXPECT_TRUE(IsLost(m, 1)) << k;
  }
}

// The depth of the whole scene for MakeDepthFrame's `surfaces`: a table at `table_z` where
// no surface is (the support plane, which the working cloud leaves out).
std::vector<float> SceneDepth(const std::vector<Surface>& surfaces, float table_z, int width = 120,
                              int height = 80) {
  std::vector<float> z(static_cast<size_t>(width) * height, table_z);
  for (const Surface& f : surfaces) {
    for (int v = f.rect.v0; v < f.rect.v1; ++v) {
      for (int u = f.rect.u0; u < f.rect.u1; ++u) z[static_cast<size_t>(v) * width + u] = f.z;
    }
  }
  return z;
}

// An object lying on a small one, segmented with it; then taken away, down to the table, and
// the small one merged with its neighbour. With the scene's depth, the track of the two
// continues on what is left (the pixels taken away went back to the table, they were not
// hidden) and restarts its reference view from it: the merge keeps the neighbour's id, the
// larger object. On the cloud's depth alone (the table has none) nothing changed there, and
// the track keeps the merge by the size of what was taken away.
TEST(TrackerSceneDepth, WhatIsLeftOfATrackAfterAnObjectWasTakenAwayIsItsViewNow) {
  const Surface on_top{Rect{10, 10, 40, 40}, 0.9f, 1}, small{Rect{40, 10, 50, 40}, 1.0f, 1};
  const Surface neighbour{Rect{50, 10, 70, 40}, 1.0f, 2};
  const Surface small_alone{small.rect, 1.0f, 1}, neighbour_alone{neighbour.rect, 1.0f, 2};
  const Surface merged{Rect{40, 10, 70, 40}, 1.0f, 1};
  const std::vector<std::vector<Surface>> frames = {
      {on_top, small, neighbour}, {on_top, small, neighbour},     {on_top, small, neighbour},
      {on_top, small, neighbour}, {small_alone, neighbour_alone}, {merged}};
  for (const bool scene : {true, false}) {
    Tracker dut{TrackerParams{}};
    TrackingResult out;
    core::PointCloud cloud;
    for (size_t f = 0; f < frames.size(); ++f) {
      const SegmentationResult frame = MakeDepthFrame(frames[f], &cloud);
      const std::vector<float> scene_z = SceneDepth(frames[f], 1.1f);
      dut.Update(frame, static_cast<int64_t>(f), &out, cloud,
                 scene ? std::span<const float>(scene_z) : std::span<const float>());
      if (f <= 4) {
        ASSERT_EQ(Ids(out), (std::vector<int64_t>{1, 2})) << f << " (4: what is left continues)";
      }
    }
    if (scene) {
      EXPECT_EQ(Ids(out), (std::vector<int64_t>{2})) << "the larger object keeps the merge";
      EXPECT_TRUE(IsLost(out, 1));
    } else {
      EXPECT_EQ(Ids(out), (std::vector<int64_t>{1}));
      EXPECT_TRUE(IsLost(out, 2));
    }
  }
}

// An object hidden behind one put down in front of it is not taken away: its track keeps its
// whole reference view (and gets its id back when the object in front leaves).
TEST(TrackerSceneDepth, AHiddenObjectKeepsItsWholeView) {
  const Surface a{Rect{10, 10, 40, 40}, 1.0f, 1}, b{Rect{50, 10, 60, 40}, 1.0f, 2};
  const Surface front{Rect{10, 10, 35, 40}, 0.8f, 3}, a_rest{Rect{35, 10, 40, 40}, 1.0f, 1};
  const Surface a_rest_merged{Rect{35, 10, 60, 40}, 1.0f, 1};
  Tracker dut{TrackerParams{}};
  TrackingResult out;
  core::PointCloud cloud;
  int64_t seq = 0;
  auto step = [&](const std::vector<Surface>& surfaces) {
    const SegmentationResult frame = MakeDepthFrame(surfaces, &cloud);
    const std::vector<float> scene_z = SceneDepth(surfaces, 1.1f);
    dut.Update(frame, seq++, &out, cloud, scene_z);
    return Ids(out);
  };
  for (int f = 0; f < 4; ++f) ASSERT_EQ(step({a, b}), (std::vector<int64_t>{1, 2}));
  // Most of kA hidden: what is left of it keeps its id, the object in front is new.
  EXPECT_EQ(step({a_rest, b, Surface{front.rect, 0.8f, 3}}), (std::vector<int64_t>{1, 2, 3}));
  // What is left of kA merged with b (the larger now in view): kA's remembered whole view keeps
  // the merge, as before.
  const std::vector<int64_t> ids = step({a_rest_merged, Surface{front.rect, 0.8f, 2}});
  EXPECT_EQ(ids, (std::vector<int64_t>{1, 3}));
  EXPECT_TRUE(IsLost(out, 2));
}

// A tracker with the scene's depth, memory_frames 5 and the given hidden_memory_frames: kA
// and kB for four frames, then `middle` for twenty frames, then kA and kB again. Returns the
// ids of the last frame; `ended_at` is the frame kA's track ended in (-1: never).
std::vector<int64_t> HiddenMemoryRun(int hidden_memory_frames, const std::vector<Surface>& middle,
                                     int64_t* ended_at) {
  TrackerParams params;
  params.memory_frames = 5;
  params.hidden_memory_frames = hidden_memory_frames;
  Tracker dut{params};
  TrackingResult out;
  core::PointCloud cloud;
  const Surface a{kA, 1.0f, 1}, b{kB, 1.0f, 2};
  *ended_at = -1;
  for (int64_t f = 0; f < 25; ++f) {
    const std::vector<Surface> surfaces = f < 4 || f == 24 ? std::vector<Surface>{a, b} : middle;
    const SegmentationResult frame = MakeDepthFrame(surfaces, &cloud);
    dut.Update(frame, f, &out, cloud, SceneDepth(surfaces, 1.1f));
    if (Ended(out, 1)) *ended_at = f;
  }
  return Ids(out);
}

// A box put down over kA hides it for twenty frames, longer than memory_frames: with
// hidden_memory_frames kA's track stays remembered while its surface is hidden and kA gets its
// id back when the box is taken away; without, it ends and kA comes back under a new id.
TEST(TrackerHiddenMemory, AnObjectHiddenLongerThanTheMemoryGetsItsIdBack) {
  const std::vector<Surface> box_on_a = {Surface{Rect{8, 8, 32, 32}, 0.9f, 1},
                                         Surface{kB, 1.0f, 2}};
  int64_t ended_at = 0;
  EXPECT_EQ(HiddenMemoryRun(100, box_on_a, &ended_at), (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(ended_at, -1);
  EXPECT_EQ(HiddenMemoryRun(0, box_on_a, &ended_at), (std::vector<int64_t>{4, 2}));
  EXPECT_EQ(ended_at, 9) << "last seen in frame 3, remembered for 5 frames";
  // ... but not past hidden_memory_frames after it was last seen.
  EXPECT_EQ(HiddenMemoryRun(15, box_on_a, &ended_at), (std::vector<int64_t>{4, 2}));
  EXPECT_EQ(ended_at, 19);
}

// kA taken away (the table shows where it lay): its surface is not hidden, so its track ends
// after memory_frames whatever hidden_memory_frames.
TEST(TrackerHiddenMemory, AnObjectTakenAwayEndsAfterTheMemory) {
  int64_t ended_at = 0;
  EXPECT_EQ(HiddenMemoryRun(100, {Surface{kB, 1.0f, 1}}, &ended_at), (std::vector<int64_t>{3, 2}));
  EXPECT_EQ(ended_at, 9);
}

// kA and kB on a table for twelve frames (older than joined_view_frames), then a newcomer of
// `newcomer_rect` at 0.95 m put down against kA and segmented with it for four frames, then cut
// off. Returns the ids of every frame from the newcomer's first (kA or the merge, kB, and the
// newcomer once cut off).
std::vector<std::vector<int64_t>> NewcomerRun(const Rect& newcomer_rect) {
  Tracker dut{TrackerParams{}};
  TrackingResult out;
  core::PointCloud cloud;
  const Surface a{kA, 1.0f, 1}, b{kB, 1.0f, 2};
  std::vector<std::vector<int64_t>> ids;
  for (int64_t f = 0; f < 18; ++f) {
    std::vector<Surface> surfaces = {a, b};
    if (f >= 12) surfaces.push_back(Surface{newcomer_rect, 0.95f, f < 16 ? 1u : 3u});
    const SegmentationResult frame = MakeDepthFrame(surfaces, &cloud);
    dut.Update(frame, f, &out, cloud, SceneDepth(surfaces, 1.1f));
    if (f >= 12) ids.push_back(Ids(out));
  }
  return ids;
}

// A newcomer more than twice kA's size, segmented with it: the segment is mostly the newcomer
// and gets a new id, which the newcomer keeps once cut off; kA, remembered, gets its id back.
TEST(TrackerNewcomer, ASegmentMostlyOfANewcomerIsTheNewcomers) {
  const std::vector<std::vector<int64_t>> ids = NewcomerRun(Rect{30, 10, 60, 40});  // 900 px
  for (size_t f = 0; f < 4; ++f) EXPECT_EQ(ids[f], (std::vector<int64_t>{3, 2})) << f;
  EXPECT_EQ(ids[4], (std::vector<int64_t>{1, 2, 3}));
  EXPECT_EQ(ids[5], (std::vector<int64_t>{1, 2, 3}));
}

// A newcomer under twice kA's size: kA's track keeps the segment, as before.
TEST(TrackerNewcomer, ASegmentNotMostlyOfANewcomerKeepsTheTracksId) {
  const std::vector<std::vector<int64_t>> ids = NewcomerRun(Rect{30, 10, 50, 40});  // 600 px
  for (size_t f = 0; f < 4; ++f) EXPECT_EQ(ids[f], (std::vector<int64_t>{1, 2})) << f;
  EXPECT_EQ(ids[5], (std::vector<int64_t>{1, 2, 3}));
}

// kA and kB for twelve frames; a newcomer of 300 pixels put down against kA (400) is an object
// of its own for one frame, then one segment with kA for four frames (kA's track keeps the merge,
// the newcomer's, not yet confirmed, is absorbed), then apart again. Returns the newcomer's id
// in its first frame and once apart.
std::pair<int64_t, int64_t> TentativeMergeRun(bool tentative_merge_memory) {
  TrackerParams params;
  params.tentative_merge_memory = tentative_merge_memory;
  Tracker dut{params};
  TrackingResult out;
  core::PointCloud cloud;
  const Surface a{kA, 1.0f, 1}, b{kB, 1.0f, 2};
  const Rect newcomer{30, 10, 45, 30};
  std::pair<int64_t, int64_t> ids{0, 0};
  for (int64_t f = 0; f < 19; ++f) {
    std::vector<Surface> surfaces = {a, b};
    if (f >= 12) surfaces.push_back(Surface{newcomer, 1.0f, f >= 13 && f < 17 ? 1u : 3u});
    const SegmentationResult frame = MakeDepthFrame(surfaces, &cloud);
    dut.Update(frame, f, &out, cloud, SceneDepth(surfaces, 1.1f));
    if (f == 12) ids.first = out.objects.at(2).track_id;
    if (f == 18) ids.second = out.objects.at(2).track_id;
    if (f >= 13 && f < 17) {
      EXPECT_EQ(Ids(out), (std::vector<int64_t>{1, 2})) << f;
    }
  }
  return ids;
}

// With tentative_merge_memory the newcomer's track is remembered through the merge and the
// newcomer gets its first id back; without, a new one.
TEST(TrackerTentativeMerge, ANewcomerAbsorbedBeforeItWasConfirmedGetsItsIdBack) {
  EXPECT_EQ(TentativeMergeRun(true), (std::pair<int64_t, int64_t>{3, 3}));
  EXPECT_EQ(TentativeMergeRun(false), (std::pair<int64_t, int64_t>{3, 4}));
}

// A tracker with the frame's depth and the given joined_view_frames, one frame per Step.
class JoinedViewRun {
 public:
  explicit JoinedViewRun(int joined_view_frames) : dut_(Params(joined_view_frames)) {}
  std::vector<int64_t> Step(const std::vector<Surface>& surfaces) {
    dut_.Update(MakeDepthFrame(surfaces, &cloud_), seq_++, &out_, cloud_);
    return Ids(out_);
  }
  const TrackingResult& out() const { return out_; }

 private:
  static TrackerParams Params(int joined_view_frames) {
    TrackerParams p;
    p.joined_view_frames = joined_view_frames;
    return p;
  }
  Tracker dut_;
  TrackingResult out_;
  core::PointCloud cloud_;
  int64_t seq_{0};
};

// kA and kB seen for four frames (`still`), then a newcomer segmented with kA for seven frames
// (`joined`: labels 1 and 2), then cut off (`apart`: labels 1, 2, 3), as before the objects by
// arrival cut it off (their confirmation and the partition hysteresis). With
// joined_view_frames 10, kA keeps its id; with 0 the merged view became kA's own from its
// second frame and the split handed kA's id to the newcomer.
void ExpectTheIdStaysWithTheJoinedTrackWhenCutOff(const std::vector<Surface>& still,
                                                  const std::vector<Surface>& joined,
                                                  const std::vector<Surface>& apart) {
  for (const int frames : {10, 0}) {
    JoinedViewRun run(frames);
    for (int f = 0; f < 4; ++f) run.Step(still);
    for (int f = 0; f < 7; ++f) {
      EXPECT_EQ(run.Step(joined), (std::vector<int64_t>{1, 2})) << frames << " " << f;
    }
    const std::vector<int64_t> ids = run.Step(apart);
    ASSERT_EQ(ids.size(), 3u);
    if (frames > 0) {
      EXPECT_EQ(ids, (std::vector<int64_t>{1, 2, 3}));
    } else {
      EXPECT_NE(ids[0], 1) << "without it the newcomer takes kA's id";
      EXPECT_EQ(ids[2], 1);
    }
  }
}

// The same, with the object put down against kA.
TEST(TrackerJoinedView, AnObjectJoinedToATrackForSeveralFramesLeavesItItsIdWhenCutOff) {
  const Surface a{kA, 1.0f, 1}, b{kB, 1.0f, 2};
  const Surface joined{Rect{10, 30, 40, 55}, 1.0f, 1}, apart{Rect{10, 30, 40, 55}, 1.0f, 3};
  ExpectTheIdStaysWithTheJoinedTrackWhenCutOff({a, b}, {a, b, joined}, {a, b, apart});
}

// An object put down on kA, on a table, covering a quarter of it and reaching out over the
// table. The newcomer's pixels were kA's or the table's and came nearer (fewer than half of them
// were background before, and a quarter of kA's surface changed, so neither the join against
// kA nor the surface change rule sees it).
TEST(TrackerJoinedView, AnObjectPutDownOnATrackAndJoinedToItLeavesItItsIdWhenCutOff) {
  const Surface table{Rect{0, 0, 120, 80}, 1.2f, 0};
  const Surface a{kA, 1.0f, 1}, b{kB, 1.0f, 2};
  const Rect on_a{20, 20, 45, 36};  // 400 pixels, 100 of them over kA's 400
  ExpectTheIdStaysWithTheJoinedTrackWhenCutOff({table, a, b}, {table, a, b, Surface{on_a, 0.9f, 1}},
                                               {table, a, b, Surface{on_a, 0.9f, 3}});
}

// An object put down across the middle of a long one on a table, hiding a third of it (too
// little for the join by what came nearer) and segmented with both ends for seven frames, then
// cut off: the merged view had become the track's own and the newcomer lay nearest its
// centroid, but the newcomer came in front of what was there and does not keep the id; an end
// that stayed does. With joined_view_frames 0 only what came in front in the frame of the split
// counts, and the newcomer took the id.
TEST(TrackerCameInFront, AnObjectPutDownAcrossATrackDoesNotTakeItsIdWhenCutOff) {
  const Surface table{Rect{0, 0, 120, 80}, 1.2f, 0};
  const Rect left{10, 10, 30, 30}, right{50, 10, 75, 30};  // 400 and 500 pixels
  const Rect across{30, 8, 50, 32};  // 480 pixels, 400 of them over the object's 1300
  for (const int frames : {10, 0}) {
    JoinedViewRun run(frames);
    for (int f = 0; f < 4; ++f) {
      EXPECT_EQ(run.Step({table, Surface{Rect{10, 10, 75, 30}, 1.0f, 1}}),
                (std::vector<int64_t>{1}));
    }
    for (int f = 0; f < 7; ++f) {
      const std::vector<Surface> joined{table, Surface{left, 1.0f, 1}, Surface{right, 1.0f, 1},
                                        Surface{across, 0.9f, 1}};
      EXPECT_EQ(run.Step(joined), (std::vector<int64_t>{1})) << frames << " " << f;
    }
    const std::vector<int64_t> ids = run.Step(
        {table, Surface{left, 1.0f, 1}, Surface{right, 1.0f, 2}, Surface{across, 0.9f, 3}});
    ASSERT_EQ(ids.size(), 3u);
    EXPECT_EQ(run.out().counts.splits, 1);
    if (frames > 0) {
      EXPECT_EQ(ids[1], 1) << "the larger end, nearer the track's centroid, keeps the id";
      EXPECT_NE(ids[2], 1);
    } else {
      EXPECT_EQ(ids[2], 1) << "without it the newcomer, nearest the centroid, takes the id";
    }
  }
}

TEST_F(TrackerTest, UnorganizedCloudsGiveTheSameIds) {
  Tracker flat(params_);
  TrackingResult t;
  const std::vector<std::vector<Rect>> frames = {
      {kA, kB}, {kB, kA}, {kA}, {kA, kC, kB}, {Rect{10, 10, 45, 30}, kB}, {kA, kC, kB}};
  for (size_t f = 0; f < frames.size(); ++f) {
    Step(frames[f]);
    flat.Update(Flattened(MakeFrame(frames[f])), static_cast<int64_t>(f), &t);
    EXPECT_EQ(Ids(t), Ids(out_)) << "frame " << f;
  }
}

TEST_F(TrackerTest, WithoutComparableMasksGeometryKeepsTheIds) {
  Step({kA, kB});
  // A frame of another size (masks not comparable), objects moved by 1 cm.
  dut_.Update(MakeFrame({Rect{kB.u0 + 2, 10, kB.u1 + 2, 30}, Rect{12, 10, 32, 30}}, 140, 90),
              seq_++, &out_);
  EXPECT_EQ(Ids(out_), (std::vector<int64_t>{2, 1}));
}

TEST_F(TrackerTest, DroppedFramesCountAsElapsed) {
  params_.memory_frames = 10;
  Tracker dut(params_);
  TrackingResult t;
  for (int64_t s = 0; s < 3; ++s) dut.Update(MakeFrame({kA, kB}), s, &t);
  dut.Update(MakeFrame({kA}), 8, &t);
  ASSERT_EQ(t.lost.size(), 1u);
  EXPECT_EQ(t.lost[0].frames_since_seen, 6);
  EXPECT_EQ(t.objects[0].age_frames, 8);
  EXPECT_EQ(t.objects[0].seen_frames, 4);
  dut.Update(MakeFrame({kA}), 13, &t);
  EXPECT_TRUE(Ended(t, 2));
}

TEST_F(TrackerTest, ResetAndRestartedSequencesEndEveryTrack) {
  for (int f = 0; f < 3; ++f) Step({kA, kB});
  dut_.Update(MakeFrame({kA, kB}), 0, &out_);  // the source restarted
  EXPECT_TRUE(out_.reset);
  EXPECT_EQ(out_.ended_track_ids, (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(Ids(out_), (std::vector<int64_t>{3, 4}));
  dut_.Update(MakeFrame({kA, kB}), 1, &out_);
  EXPECT_FALSE(out_.reset);
  EXPECT_EQ(Ids(out_), (std::vector<int64_t>{3, 4}));
  dut_.Reset();
  dut_.Update(MakeFrame({kA}), 2, &out_);
  EXPECT_TRUE(out_.reset);
  EXPECT_EQ(out_.ended_track_ids, (std::vector<int64_t>{3, 4}));
  EXPECT_EQ(Ids(out_), (std::vector<int64_t>{5}));
}

TEST_F(TrackerTest, NewParamsKeepTheTracks) {
  for (int f = 0; f < 2; ++f) Step({kA, kB});
  TrackerParams p = params_;
  p.confirm_frames = 1;
  dut_.SetParams(p);
  const TrackingResult& t = Step({kA, kB, kC});
  EXPECT_EQ(Ids(t), (std::vector<int64_t>{1, 2, 3}));
  EXPECT_EQ(t.objects[2].state, TrackState::kConfirmed);
  p.memory_frames = -1;
  EXPECT_THROW(dut_.SetParams(p), std::invalid_argument);
  EXPECT_EQ(dut_.params().confirm_frames, 1);
}

TEST_F(TrackerTest, EmptyFramesAndLabelsWithoutObjectsAreHandled) {
  SegmentationResult empty;
  dut_.Update(empty, 0, &out_);
  EXPECT_TRUE(out_.objects.empty());
  SegmentationResult odd = MakeFrame({kA});
  odd.labels.at(100, 70) = 9;  // a label without an object is background
  dut_.Update(odd, 1, &out_);
  EXPECT_EQ(Ids(out_), (std::vector<int64_t>{1}));
  dut_.Update(MakeFrame({kA}), 2, &out_);
  EXPECT_EQ(Ids(out_), (std::vector<int64_t>{1}));
}

TEST(TrackerParams, ValidationNamesTheKey) {
  auto expect_key = [](TrackerParams p, const std::string& key) {
    try {
      p.ValidateOrThrow();
      ADD_FAILURE() << key << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("tracker." + key + " = "), std::string::npos)
          << e.what();
    }
  };
  EXPECT_NO_THROW(TrackerParams{}.ValidateOrThrow());
  TrackerParams p;
  p.confirm_frames = 0;
  expect_key(p, "confirm_frames");
  p = {};
  p.memory_frames = -1;
  expect_key(p, "memory_frames");
  p = {};
  p.tentative_memory_frames = p.memory_frames + 1;
  expect_key(p, "tentative_memory_frames");
  p = {};
  p.hidden_memory_frames = -1;
  expect_key(p, "hidden_memory_frames");
  p = {};
  p.min_mask_overlap = 0.f;
  expect_key(p, "min_mask_overlap");
  p = {};
  p.max_centroid_step_m = -1.f;
  expect_key(p, "max_centroid_step_m");
  p = {};
  p.max_size_ratio = 0.5f;
  expect_key(p, "max_size_ratio");
  p = {};
  p.reacquire_distance_m = 0.f;
  expect_key(p, "reacquire_distance_m");
  p = {};
  p.reacquire_min_box_inside = 2.f;
  expect_key(p, "reacquire_min_box_inside");
  p = {};
  p.reference_decay = -0.1f;
  expect_key(p, "reference_decay");
  p = {};
  p.split_own_margin_m = -0.01f;
  expect_key(p, "split_own_margin_m");
  p = {};
  p.joined_view_frames = -1;
  expect_key(p, "joined_view_frames");
  p = {};
  p.part_min_fraction = 0.4f;
  expect_key(p, "part_min_fraction");
  p = {};
  p.mask_weight = 1.5f;
  expect_key(p, "mask_weight");
  p = {};
  p.lost_score_factor = 0.f;
  expect_key(p, "lost_score_factor");
  p = {};
  p.surface_change_min_step_m = 0.f;
  expect_key(p, "surface_change_min_step_m");
  p = {};
  p.surface_change_min_share = 0.f;
  expect_key(p, "surface_change_min_share");
  TemporalFilterParams band;
  band.min_band_m = -1.f;
  EXPECT_THROW((Tracker{TrackerParams{}, band}), std::invalid_argument);
  p = {};
  p.confirm_frames = 0;
  EXPECT_THROW(Tracker{p}, std::invalid_argument);
}

TEST(TrackerSteadyState, UpdateDoesNotAllocate) {
  Tracker dut{TrackerParams{}};
  TrackingResult out;
  const std::vector<SegmentationResult> frames = {
      MakeFrame({kA, kB}), MakeFrame({kA, kC, kB}), MakeFrame({Rect{10, 10, 45, 30}, kB}),
      MakeFrame({kA, kB}), MakeFrame({kA}),         MakeFrame({kA, kC, kB})};
  int64_t seq = 0;
  for (int round = 0; round < 3; ++round) {
    for (const SegmentationResult& f : frames) dut.Update(f, seq++, &out);
  }
  tracking_test::CountAllocations(true);
  for (int round = 0; round < 5; ++round) {
    for (const SegmentationResult& f : frames) dut.Update(f, seq++, &out);
  }
  tracking_test::CountAllocations(false);
  EXPECT_EQ(tracking_test::CountedAllocations(), 0);
  // The counter counts: a fresh output struct allocates.
  tracking_test::CountAllocations(true);
  TrackingResult fresh;
  dut.Update(frames[0], seq++, &fresh);
  tracking_test::CountAllocations(false);
  EXPECT_GT(tracking_test::CountedAllocations(), 0);
}

// Synthetic sequences rendered by the generator and segmented by the real Segmenter.

using tracking_test::RunScenario;
using tracking_test::ScenarioRun;
using tracking_test::TrackingSceneParams;

synth::SequenceParams Scenario(synth::Scenario s, int frames = 30) {
  synth::SequenceParams p;
  p.scenario = s;
  p.num_frames = frames;
  p.num_objects = 6;
  p.step_frames = 4;
  return p;
}

void ExpectSteadyIdentities(const ScenarioRun& run, const char* what, bool scene_changes = true) {
  for (const eval::TrackingMetrics* m : {&run.track_all, &run.track_confirmed}) {
    EXPECT_GE(m->identity_consistency, 0.97) << what;
    EXPECT_EQ(m->id_reuse, 0) << what;
    EXPECT_GT(m->matched_object_frames, 0) << what;
  }
  // Raw label values as ids, for contrast: objects change number as others come and go.
  if (scene_changes) {
    EXPECT_GT(run.track_all.identity_consistency, run.label_value.identity_consistency) << what;
  }
  // Ids are unique, increasing for new tracks, and never come back once ended.
  std::set<int64_t> ended;
  int64_t max_id = 0;
  for (const TrackingResult& t : run.tracking) {
    std::set<int64_t> seen;
    for (const ObjectTrack& o : t.objects) {
      EXPECT_TRUE(seen.insert(o.track_id).second) << what << ": id twice in a frame";
      EXPECT_EQ(ended.count(o.track_id), 0u) << what << ": ended id " << o.track_id << " back";
      if (o.age_frames == 0) {
        EXPECT_GT(o.track_id, max_id) << what;
      }
      max_id = std::max(max_id, o.track_id);
    }
    for (const LostTrack& l : t.lost) EXPECT_EQ(seen.count(l.track_id), 0u) << what;
    ended.insert(t.ended_track_ids.begin(), t.ended_track_ids.end());
  }
}

TEST(TrackerSequences, ObjectsAddedOneByOne) {
  for (uint64_t seed : {1u, 2u}) {
    ExpectSteadyIdentities(
        RunScenario(TrackingSceneParams(), Scenario(synth::Scenario::kAdd), seed), "add");
  }
}

TEST(TrackerSequences, ObjectsRemovedAreLostThenEnded) {
  TrackerParams params;
  params.memory_frames = 6;
  const ScenarioRun run =
      RunScenario(TrackingSceneParams(), Scenario(synth::Scenario::kRemove), 2, params);
  ExpectSteadyIdentities(run, "remove");
  // Every removed object's track is remembered in the frame it vanished and ended
  // memory_frames later (unless the sequence ended first).
  int checked = 0;
  for (const eval::ObjectTrackingScore& o : run.track_all.objects) {
    int last = -1;
    for (int k = 0; k < run.frames; ++k) {
      const auto& gt = run.gt_ids[static_cast<size_t>(k)];
      if (std::count(gt.begin(), gt.end(), o.gt_id)) last = k;
    }
    if (last < 0 || last + 1 >= run.frames || o.matched_frames == 0) continue;
    EXPECT_TRUE(IsLost(run.tracking[static_cast<size_t>(last) + 1], o.main_id))
        << "object " << o.gt_id;
    const int end_frame = last + 1 + params.memory_frames;
    if (end_frame < run.frames) {
      EXPECT_TRUE(Ended(run.tracking[static_cast<size_t>(end_frame)], o.main_id))
          << "object " << o.gt_id;
    }
    ++checked;
  }
  EXPECT_GE(checked, 4);
}

TEST(TrackerSequences, ObjectsAddedAndRemoved) {
  for (uint64_t seed : {1u, 2u}) {
    ExpectSteadyIdentities(
        RunScenario(TrackingSceneParams(), Scenario(synth::Scenario::kAddRemove, 40), seed),
        "add-remove");
  }
}

TEST(TrackerSequences, OccludedObjectsRecoverTheirIds) {
  int recovered = 0;
  for (uint64_t seed : {1u, 2u}) {
    const ScenarioRun run =
        RunScenario(TrackingSceneParams(), Scenario(synth::Scenario::kOccluder), seed);
    ExpectSteadyIdentities(run, "occluder");
    // An object hidden for at least one frame and seen again under the same id.
    for (const eval::ObjectTrackingScore& o : run.track_all.objects) {
      if (o.distinct_ids != 1) continue;
      bool hidden = false, back = false;
      for (int k = 0; k < run.frames; ++k) {
        const auto& gt = run.gt_ids[static_cast<size_t>(k)];
        const bool listed = std::count(gt.begin(), gt.end(), o.gt_id) > 0;
        if (!listed && k > 0) hidden = true;
        if (listed && hidden) {
          for (const ObjectTrack& t : run.tracking[static_cast<size_t>(k)].objects) {
            back = back || (t.track_id == o.main_id && t.reacquired);
          }
        }
      }
      recovered += back ? 1 : 0;
    }
  }
  EXPECT_GE(recovered, 2);
}

TEST(TrackerSequences, StaticSceneIsSteady) {
  for (uint64_t seed : {1u, 2u}) {
    const ScenarioRun run =
        RunScenario(TrackingSceneParams(), Scenario(synth::Scenario::kStatic), seed);
    ExpectSteadyIdentities(run, "static", /*scene_changes=*/false);
    // Confirmation and memory keep the reported set steady.
    EXPECT_LE(run.track_confirmed.flicker, 0.1) << "seed " << seed;
    EXPECT_LE(run.track_confirmed.flicker, run.track_all.flicker) << "seed " << seed;
  }
}

// The ids, states and lost tracks of two trackings of frame `k` are the same.
void ExpectSameTracking(const TrackingResult& x, const TrackingResult& y, size_t k) {
  ASSERT_EQ(x.objects.size(), y.objects.size()) << "frame " << k;
  for (size_t i = 0; i < x.objects.size(); ++i) {
    EXPECT_EQ(x.objects[i].track_id, y.objects[i].track_id) << "frame " << k;
    EXPECT_EQ(x.objects[i].age_frames, y.objects[i].age_frames);
    EXPECT_EQ(x.objects[i].seen_frames, y.objects[i].seen_frames);
    EXPECT_EQ(x.objects[i].state, y.objects[i].state);
    EXPECT_EQ(x.objects[i].reacquired, y.objects[i].reacquired);
  }
  ASSERT_EQ(x.lost.size(), y.lost.size()) << "frame " << k;
  for (size_t i = 0; i < x.lost.size(); ++i) {
    EXPECT_EQ(x.lost[i].track_id, y.lost[i].track_id);
    EXPECT_EQ(x.lost[i].frames_since_seen, y.lost[i].frames_since_seen);
    EXPECT_EQ(x.lost[i].centroid.x, y.lost[i].centroid.x);
    EXPECT_EQ(x.lost[i].remembered_max.z, y.lost[i].remembered_max.z);
  }
  EXPECT_EQ(x.ended_track_ids, y.ended_track_ids) << "frame " << k;
}

TEST(TrackerSequences, DeterministicForTheSameInput) {
  core::ThreadPool pool(2);
  const synth::SequenceParams seq = Scenario(synth::Scenario::kOccluder, 16);
  const ScenarioRun a = RunScenario(TrackingSceneParams(), seq, 3);
  const ScenarioRun b = RunScenario(TrackingSceneParams(), seq, 3, TrackerParams{}, &pool);
  ASSERT_EQ(a.tracking.size(), b.tracking.size());
  for (size_t k = 0; k < a.tracking.size(); ++k)
    ExpectSameTracking(a.tracking[k], b.tracking[k], k);
}

// The daemon's two halves (Associate, publish, RememberSurfaces) track as Update does: objects
// added one by one into touching piles (merges, splits, newcomers against remembered tracks)
// and an arm passing in front (remembered surfaces reacquired), with the frame's depth.
TEST(TrackerSequences, AssociateThenRememberSurfacesIsUpdate) {
  const synth::SceneParams scene = TrackingSceneParams();
  for (const synth::Scenario kind : {synth::Scenario::kAdd, synth::Scenario::kOccluder}) {
    const std::vector<synth::Scene> frames =
        synth::GenerateScenarioSequence(scene, Scenario(kind, 40), 5);
    Segmenter segmenter(SegmenterParams{});
    Tracker whole(TrackerParams{}), halves(TrackerParams{});
    synth::RenderedFrame rendered;
    core::PointCloud cloud;
    SegmentationResult result;
    TrackingResult x, y;
    int remembered = 0;
    for (size_t k = 0; k < frames.size(); ++k) {
      synth::RenderScene(frames[k], scene.intrinsics, synth::SensorParams{},
                         synth::HashCounter(5, 0x7a11, k + 1), &rendered);
      synth::ToPointCloud(rendered, &cloud);
      segmenter.Process(cloud, scene.intrinsics, &result);
      whole.Update(result, static_cast<int64_t>(k), &x, segmenter.working_cloud());
      halves.Associate(result, static_cast<int64_t>(k), &y, segmenter.working_cloud());
      halves.RememberSurfaces();
      halves.RememberSurfaces();  // nothing pending: does nothing
      ExpectSameTracking(x, y, k);
      remembered += static_cast<int>(y.lost.size());
    }
    if (kind == synth::Scenario::kOccluder) {
      EXPECT_GT(remembered, 0);  // tracks were remembered
    }
  }
}

TEST(TrackerSequencesDeathTest, AssociateWithoutRememberSurfacesIsAProgrammingError) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  SegmentationResult frame;
  frame.labels.Reset(4, 4, 0u);
  Tracker tracker(TrackerParams{});
  TrackingResult out;
  tracker.Associate(frame, 0, &out);
  EXPECT_DEATH(tracker.Associate(frame, 1, &out), "RememberSurfaces|remember_frame");
}

}  // namespace
}  // namespace clutterseg::pipeline
