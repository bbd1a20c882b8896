#include "clutterseg/pipeline/overlay.h"

#include <algorithm>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace clutterseg::pipeline {
namespace {

// The 5x7 shapes the overlay documents, typed here independently of overlay.cc: one byte per
// row from the top, bit 4 = leftmost column.
const std::map<char, std::vector<uint8_t>>& Glyphs() {
  static const std::map<char, std::vector<uint8_t>> glyphs{
      {'0', {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}},
      {'1', {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E}},
      {'2', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}},
      {'3', {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E}},
      {'4', {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}},
      {'5', {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E}},
      {'6', {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}},
      {'7', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
      {'8', {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}},
      {'9', {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}},
      {'#', {0x0A, 0x0A, 0x1F, 0x0A, 0x1F, 0x0A, 0x0A}},
  };
  return glyphs;
}

bool Same(core::Rgb8 a, core::Rgb8 b) { return a.r == b.r && a.g == b.g && a.b == b.b; }
bool White(core::Rgb8 c) { return c.r == 255 && c.g == 255 && c.b == 255; }
bool Dark(core::Rgb8 c) { return c.r < 40 && c.g < 40 && c.b < 40; }

// Checks that `text` is drawn at (x, y) with font cells `s` px square: every cell of a set
// glyph bit white, every other cell of the 6 x 7 character box dark (the patch).
void ExpectText(const core::ColorImage& img, int x, int y, int s, const std::string& text) {
  for (size_t k = 0; k < text.size(); ++k) {
    const std::vector<uint8_t>& rows = Glyphs().at(text[k]);
    for (int row = 0; row < 7; ++row) {
      for (int col = 0; col < 6; ++col) {
        const bool on = col < 5 && (rows[static_cast<size_t>(row)] & (0x10 >> col)) != 0;
        for (int dy = 0; dy < s; ++dy) {
          for (int dx = 0; dx < s; ++dx) {
            const int u = x + (static_cast<int>(k) * 6 + col) * s + dx;
            const int v = y + row * s + dy;
            if (col == 5 && k + 1 == text.size()) continue;  // no gap after the last one
            const core::Rgb8 c = img.at(u, v);
            if (on) {
              ASSERT_TRUE(White(c)) << "'" << text[k] << "' of " << text << " cell (" << col << ", "
                                    << row << ") at (" << u << ", " << v << ")";
            } else {
              ASSERT_TRUE(Dark(c)) << "'" << text[k] << "' of " << text << " gap (" << col << ", "
                                   << row << ") at (" << u << ", " << v << ")";
            }
          }
        }
      }
    }
  }
}

// Labels `id` on the disc of radius r around (cu, cv), clipped to the image.
void Disc(int cu, int cv, int r, uint32_t id, core::LabelImage* labels) {
  for (int v = std::max(cv - r, 0); v <= std::min(cv + r, labels->height - 1); ++v) {
    for (int u = std::max(cu - r, 0); u <= std::min(cu + r, labels->width - 1); ++u) {
      if ((u - cu) * (u - cu) + (v - cv) * (v - cv) <= r * r) labels->at(u, v) = id;
    }
  }
}

// The inclusive image box of the pixels labelled `id`.
OverlayObject BoxOf(const core::LabelImage& labels, uint32_t id, int64_t track_id = -1) {
  OverlayObject o{id, track_id, labels.width, labels.height, -1, -1};
  for (int v = 0; v < labels.height; ++v) {
    for (int u = 0; u < labels.width; ++u) {
      if (labels.at(u, v) != id) continue;
      o.min_u = std::min(o.min_u, u);
      o.min_v = std::min(o.min_v, v);
      o.max_u = std::max(o.max_u, u);
      o.max_v = std::max(o.max_v, v);
    }
  }
  return o;
}

constexpr core::Rgb8 kGrey{120, 120, 120};

TEST(OverlayText, ScaleGrowsWithTheImage) {
  EXPECT_EQ(OverlayTextScale(1, 1), 1);
  EXPECT_EQ(OverlayTextScale(320, 240), 1);
  EXPECT_EQ(OverlayTextScale(640, 480), 2);
  EXPECT_EQ(OverlayTextScale(1280, 960), 4);
  EXPECT_EQ(OverlayTextScale(4000, 3000), 4);
}

TEST(AnnotatedOverlay, OutlinesTheBoxInTheObjectColour) {
  core::LabelImage labels(640, 480, 0u);
  Disc(250, 200, 50, 3, &labels);
  const core::ColorImage base(640, 480, kGrey);
  const OverlayObject o = BoxOf(labels, 3);
  ASSERT_EQ(o.min_u, 200);
  ASSERT_EQ(o.max_v, 250);
  core::ColorImage out;
  RenderOverlay(labels, &base, {o}, &out);
  ASSERT_EQ(out.width, 640);
  ASSERT_EQ(out.height, 480);
  const core::Rgb8 c = LabelColor(3);
  // The box corners are background pixels (outside the disc), dimmed without the outline;
  // the edge midpoints are the disc's own border.
  for (const auto& [u, v] : std::vector<std::pair<int, int>>{
           {200, 150}, {300, 150}, {200, 250}, {300, 250}, {250, 150}, {200, 200}, {300, 220}}) {
    EXPECT_TRUE(Same(out.at(u, v), c)) << u << ", " << v;
  }
  // Just outside and inside the outline the overlay is the plain one (dimmed background).
  EXPECT_EQ(out.at(301, 250).r, 60);
  EXPECT_EQ(out.at(299, 249).r, 60);
  EXPECT_EQ(out.at(200, 251).r, 60);
}

TEST(AnnotatedOverlay, TagsTheBoxWithIdAndTrackAboveItsCorner) {
  core::LabelImage labels(640, 480, 0u);
  Disc(250, 200, 50, 47, &labels);
  const core::ColorImage base(640, 480, kGrey);
  core::ColorImage out;
  RenderOverlay(labels, &base, {BoxOf(labels, 47, 1234)}, &out);
  // Scale 2: the tag is 18 px tall with 2 px of padding, its bottom row right above the box.
  const int s = 2;
  ExpectText(out, 200 + s, 150 - 18 + s, s, "47#1234");
  // The patch around the text is dark, and the row under it is the box outline.
  EXPECT_TRUE(Dark(out.at(200, 132)));
  EXPECT_TRUE(Dark(out.at(200 + 2 * s + (7 * 6 - 1) * s - 1, 149)));
  EXPECT_TRUE(Same(out.at(201, 150), LabelColor(47)));
  // Without a track id the tag is the id alone: no '#' after it.
  RenderOverlay(labels, &base, {BoxOf(labels, 47)}, &out);
  ExpectText(out, 200 + s, 150 - 18 + s, s, "47");
  EXPECT_TRUE(Same(out.at(200 + 2 * s + 11 * s + 2, 140), core::Rgb8{60, 60, 60}));
}

TEST(AnnotatedOverlay, WritesTheLargestIdsAndTrackIdsInFull) {
  core::LabelImage labels(640, 480, 0u);
  Disc(150, 300, 40, 65535, &labels);
  core::ColorImage out;
  RenderOverlay(labels, nullptr, {BoxOf(labels, 65535, int64_t{1} << 40)}, &out);
  ExpectText(out, 110 + 2, 260 - 18 + 2, 2, "65535#1099511627776");
  // An id beyond 65535 and the largest track id still fit in the tag's buffer.
  const OverlayObject big{4294967295u, INT64_MAX, 10, 300, 20, 310};
  core::ColorImage wide;
  core::LabelImage wide_labels(2000, 480, 0u);
  RenderOverlay(wide_labels, nullptr, {big}, &wide);
  ExpectText(wide, 10 + 2, 300 - 18 + 2, 2, "4294967295#9223372036854775807");
}

TEST(AnnotatedOverlay, TagMovesInsideTheBoxWhenThereIsNoRoomAbove) {
  core::LabelImage labels(640, 480, 0u);
  Disc(10, 12, 30, 5, &labels);  // touches the top and left borders
  Disc(400, 300, 20, 6, &labels);
  const OverlayObject o = BoxOf(labels, 5);
  ASSERT_EQ(o.min_u, 0);
  ASSERT_EQ(o.min_v, 0);
  core::ColorImage out;
  RenderOverlay(labels, nullptr, {o, BoxOf(labels, 6)}, &out);
  const core::Rgb8 c = LabelColor(5);
  EXPECT_TRUE(Same(out.at(0, 0), c));
  EXPECT_TRUE(Same(out.at(o.max_u, 0), c));
  EXPECT_TRUE(Same(out.at(0, o.max_v), c));
  EXPECT_TRUE(Same(out.at(o.max_u, o.max_v), c));
  ExpectText(out, 1 + 2, 1 + 2, 2, "5");
  // The legend avoided the top-left corner the object fills: it is in the top-right one.
  EXPECT_TRUE(Dark(out.at(639 - 2, 2)));
  EXPECT_TRUE(Same(out.at(639, 0), core::Rgb8{}));  // the margin, black background
}

TEST(AnnotatedOverlay, TagsOfNeighboursDoNotOverlap) {
  core::LabelImage labels(640, 480, 0u);
  // Two boxes whose top-left corners are 6 px apart: the second tag cannot go above.
  Disc(300, 300, 30, 1, &labels);
  Disc(306, 330, 30, 2, &labels);
  const OverlayObject a = BoxOf(labels, 1);
  OverlayObject b = BoxOf(labels, 2);
  b.min_u = a.min_u + 6;
  b.min_v = a.min_v + 6;
  core::ColorImage out;
  RenderOverlay(labels, nullptr, {a, b}, &out);
  ExpectText(out, a.min_u + 2, a.min_v - 18 + 2, 2, "1");
  ExpectText(out, b.min_u + 1 + 2, b.min_v + 1 + 2, 2, "2");
}

// Where the swatch of colour `c` starts in `out` within the rectangle, and how many pixels
// of that colour it holds.
struct Found {
  int u{-1}, v{-1};
  int pixels{0};
};
Found FindColour(const core::ColorImage& out, core::Rgb8 c, int u1, int v1) {
  Found f;
  for (int v = 0; v < v1; ++v) {
    for (int u = 0; u < u1; ++u) {
      if (!Same(out.at(u, v), c)) continue;
      if (f.pixels++ == 0) {
        f.u = u;
        f.v = v;
      }
    }
  }
  return f;
}

TEST(AnnotatedOverlay, LegendHoldsOneSwatchPerObjectInColumns) {
  core::LabelImage labels(640, 480, 0u);
  std::vector<OverlayObject> objects;
  // 30 objects in the bottom half, so the legend goes to the top-left corner.
  for (uint32_t k = 0; k < 30; ++k) {
    const uint32_t id = k + 1;
    Disc(30 + static_cast<int>(k % 10) * 60, 320 + static_cast<int>(k / 10) * 55, 20, id, &labels);
    objects.push_back(BoxOf(labels, id));
  }
  core::ColorImage out;
  RenderOverlay(labels, nullptr, objects, &out);
  // Scale 2: 14 px swatches, 18 px rows, columns at most 240 px tall.
  std::vector<Found> swatches;
  for (const OverlayObject& o : objects) {
    const Found f = FindColour(out, LabelColor(o.id), 320, 240);
    EXPECT_EQ(f.pixels, 14 * 14) << "id " << o.id;
    swatches.push_back(f);
  }
  EXPECT_EQ(swatches[0].u, 4);
  EXPECT_EQ(swatches[0].v, 4);
  int columns = 1;
  for (size_t k = 1; k < swatches.size(); ++k) {
    if (swatches[k].u == swatches[k - 1].u) {
      EXPECT_EQ(swatches[k].v, swatches[k - 1].v + 18) << k;
    } else {
      EXPECT_GT(swatches[k].u, swatches[k - 1].u + 14) << k;
      EXPECT_EQ(swatches[k].v, 4) << k;
      ++columns;
    }
    EXPECT_LT(swatches[k].v + 14, 240) << k;
  }
  EXPECT_EQ(columns, 3);  // 13 rows fit in half of 480 px
  // Each swatch is followed by its id.
  ExpectText(out, swatches[0].u + 14 + 4, swatches[0].v, 2, "1");
  ExpectText(out, swatches[29].u + 14 + 4, swatches[29].v, 2, "30");
}

TEST(AnnotatedOverlay, KeepsThePlainOverlayAwayFromTheAnnotations) {
  core::LabelImage labels(640, 480, 0u);
  Disc(400, 300, 60, 1, &labels);
  Disc(480, 300, 30, 2, &labels);  // touches object 1: a shared border
  core::ColorImage base(640, 480);
  for (int v = 0; v < 480; ++v) {
    for (int u = 0; u < 640; ++u) {
      base.at(u, v) = core::Rgb8{static_cast<uint8_t>(u % 256), static_cast<uint8_t>(v % 256),
                                 static_cast<uint8_t>((u + v) % 256)};
    }
  }
  const std::vector<OverlayObject> objects{BoxOf(labels, 1), BoxOf(labels, 2)};
  core::ColorImage plain, annotated;
  RenderOverlay(labels, &base, &plain);
  RenderOverlay(labels, &base, objects, &annotated);
  // The plain overlay: blended interior, solid borders, halved background.
  const core::Rgb8 c = LabelColor(1);
  const core::Rgb8 b = base.at(400, 300);
  EXPECT_EQ(plain.at(400, 300).r, (c.r * 3 + b.r * 2) / 5);
  EXPECT_EQ(plain.at(400, 300).g, (c.g * 3 + b.g * 2) / 5);
  EXPECT_TRUE(Same(plain.at(400, 240), c));  // top of the disc
  EXPECT_EQ(plain.at(100, 400).r, base.at(100, 400).r / 2);
  // The annotated one differs only on the outlines, the tags above the boxes and the
  // legend in the top-left corner.
  auto annotation = [&](int u, int v) {
    if (u < 100 && v < 60) return true;  // legend: two entries
    for (const OverlayObject& o : objects) {
      const bool on_outline = u >= o.min_u && u <= o.max_u && v >= o.min_v && v <= o.max_v &&
                              (u == o.min_u || u == o.max_u || v == o.min_v || v == o.max_v);
      const bool in_tag = u >= o.min_u && u < o.min_u + 14 && v >= o.min_v - 18 && v < o.min_v;
      if (on_outline || in_tag) return true;
    }
    return false;
  };
  int differing = 0;
  for (int v = 0; v < 480; ++v) {
    for (int u = 0; u < 640; ++u) {
      if (Same(plain.at(u, v), annotated.at(u, v))) continue;
      ++differing;
      ASSERT_TRUE(annotation(u, v)) << u << ", " << v;
    }
  }
  EXPECT_GT(differing, 0);
}

TEST(AnnotatedOverlay, ClipsEverythingOnAnyImageSize) {
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{
           {1, 1}, {7, 5}, {5, 7}, {2, 40}, {40, 2}, {33, 17}, {640, 480}}) {
    core::LabelImage labels(w, h, 0u);
    Disc(w - 1, h - 1, std::max(w, h) / 3, 7, &labels);  // in the bottom-right corner
    Disc(0, 0, 1, 65535, &labels);
    std::vector<OverlayObject> objects{BoxOf(labels, 7, int64_t{1} << 40), BoxOf(labels, 65535, 0)};
    // Boxes partly and wholly outside the image, an empty one, extreme coordinates.
    objects.push_back(OverlayObject{9, 12, -5, -5, w + 5, h + 5});
    objects.push_back(OverlayObject{10, -1, w, h, w + 3, h + 3});
    objects.push_back(OverlayObject{11, -1, 5, 5, 4, 4});
    objects.push_back(OverlayObject{12, 99, INT32_MIN, INT32_MIN, INT32_MAX, INT32_MAX});
    for (uint32_t id = 100; id < 160; ++id) objects.push_back(OverlayObject{id, -1, 0, 0, 0, 0});
    const core::ColorImage base(w, h, kGrey);
    core::ColorImage out;
    RenderOverlay(labels, &base, objects, &out);
    ASSERT_EQ(out.width, w);
    ASSERT_EQ(out.height, h);
    ASSERT_EQ(out.data.size(), static_cast<size_t>(w) * h);
    // Steady state: a second frame of the same size reuses the storage.
    const core::Rgb8* storage = out.data.data();
    RenderOverlay(labels, &base, objects, &out);
    EXPECT_EQ(out.data.data(), storage) << w << "x" << h;
    // The boxes of objects 9 and 12 cover the whole image: the outline drawn last (12's)
    // runs along the border wherever no tag or legend covers it.
    if (w >= 100) {
      for (int u = 0; u < w; ++u) EXPECT_TRUE(Same(out.at(u, h - 1), LabelColor(12))) << u;
      for (int v = 240; v < h; ++v) EXPECT_TRUE(Same(out.at(w - 1, v), LabelColor(12))) << v;
    }
  }
  // No objects: exactly the plain overlay.
  core::LabelImage labels(7, 5, 0u);
  labels.at(3, 2) = 1;
  core::ColorImage plain, annotated;
  RenderOverlay(labels, nullptr, &plain);
  RenderOverlay(labels, nullptr, {}, &annotated);
  ASSERT_EQ(annotated.data.size(), plain.data.size());
  for (size_t i = 0; i < plain.data.size(); ++i)
    EXPECT_TRUE(Same(plain.data[i], annotated.data[i]));
  // An empty image.
  core::LabelImage empty;
  RenderOverlay(empty, nullptr, {OverlayObject{1, 1, 0, 0, 3, 3}}, &annotated);
  EXPECT_TRUE(annotated.data.empty());
}

TEST(AnnotatedOverlay, ObjectsFromTheSegmenterKeepIdAndImageBox) {
  std::vector<Object> objects(3);
  objects[0].id = 1;
  objects[0].num_points = 10;
  objects[0].pixel_min_u = 3;
  objects[0].pixel_min_v = 4;
  objects[0].pixel_max_u = 30;
  objects[0].pixel_max_v = 40;
  objects[1].id = 2;  // no points: nothing to draw
  objects[2].id = 3;
  objects[2].num_points = 1;
  objects[2].pixel_min_u = objects[2].pixel_max_u = 7;
  objects[2].pixel_min_v = objects[2].pixel_max_v = 8;
  std::vector<OverlayObject> out{OverlayObject{99}};
  OverlayObjectsFrom(objects, &out);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].id, 1u);
  EXPECT_EQ(out[0].track_id, -1);
  EXPECT_EQ(out[0].min_u, 3);
  EXPECT_EQ(out[0].min_v, 4);
  EXPECT_EQ(out[0].max_u, 30);
  EXPECT_EQ(out[0].max_v, 40);
  EXPECT_EQ(out[1].id, 3u);
  EXPECT_EQ(out[1].max_v, 8);
}

}  // namespace
}  // namespace clutterseg::pipeline
