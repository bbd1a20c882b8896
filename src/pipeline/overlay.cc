#include "clutterseg/pipeline/overlay.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>

#include "clutterseg/core/text_and_color.h"

namespace clutterseg::pipeline {
namespace {

constexpr int kGlyphWidth = 5;
constexpr int kGlyphHeight = 7;
constexpr int kGlyphAdvance = kGlyphWidth + 1;  // cells per character, one blank column
// Longest tag: 10 digits of a uint32_t id, '#', 19 digits of an int64_t track id.
constexpr int kMaxTagChars = 32;

constexpr core::Rgb8 kPatchColor{16, 16, 16};
constexpr core::Rgb8 kTextColor{255, 255, 255};

// 5x7 glyphs, one byte per row from the top, bit 4 = leftmost column: 0-9, '#', '-'.
constexpr std::array<std::array<uint8_t, kGlyphHeight>, 12> kFont{{
    {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E},  // 0
    {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E},  // 1
    {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F},  // 2
    {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E},  // 3
    {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02},  // 4
    {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E},  // 5
    {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E},  // 6
    {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08},  // 7
    {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E},  // 8
    {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C},  // 9
    {0x0A, 0x0A, 0x1F, 0x0A, 0x1F, 0x0A, 0x0A},  // #
    {0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00},  // -
}};

int GlyphIndex(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c == '#') return 10;
  if (c == '-') return 11;
  return -1;
}

// A pixel rectangle, half-open: columns [x0, x1), rows [y0, y1).
struct Rect {
  int x0{0}, y0{0}, x1{0}, y1{0};
};

Rect Clip(const Rect& r, int w, int h) {
  Rect c{std::max(r.x0, 0), std::max(r.y0, 0), std::min(r.x1, w), std::min(r.y1, h)};
  if (c.x1 < c.x0) c.x1 = c.x0;
  if (c.y1 < c.y0) c.y1 = c.y0;
  return c;
}

bool Inside(const Rect& r, int w, int h) {
  return r.x0 >= 0 && r.y0 >= 0 && r.x1 <= w && r.y1 <= h;
}

void FillRect(const Rect& r, core::Rgb8 colour, core::ColorImage* out) {
  const Rect c = Clip(r, out->width, out->height);
  for (int v = c.y0; v < c.y1; ++v) {
    core::Rgb8* row = out->data.data() + static_cast<size_t>(v) * out->width;
    std::fill(row + c.x0, row + c.x1, colour);
  }
}

// Decimal digits of `value` written at `buf`; returns their count (at most 20).
int WriteDecimal(uint64_t value, char* buf) {
  char rev[20];
  int n = 0;
  do {
    rev[n++] = static_cast<char>('0' + value % 10);
    value /= 10;
  } while (value != 0);
  for (int i = 0; i < n; ++i) buf[i] = rev[n - 1 - i];
  return n;
}

// "<id>" or "<id>#<track>" at `buf` (kMaxTagChars); returns the length.
int FormatTag(uint32_t id, int64_t track_id, char* buf) {
  int n = WriteDecimal(id, buf);
  if (track_id >= 0) {
    buf[n++] = '#';
    n += WriteDecimal(static_cast<uint64_t>(track_id), buf + n);
  }
  return n;
}

int TextWidth(int chars, int scale) { return chars == 0 ? 0 : (chars * kGlyphAdvance - 1) * scale; }

// Draws `chars` characters of `text` with their top-left corner at (x, y), each font cell
// `scale` px square, clipped to the image.
void DrawText(const char* text, int chars, int x, int y, int scale, core::Rgb8 colour,
              core::ColorImage* out) {
  for (int k = 0; k < chars; ++k) {
    const int g = GlyphIndex(text[k]);
    const int gx = x + k * kGlyphAdvance * scale;
    if (g < 0 || gx >= out->width) continue;
    for (int row = 0; row < kGlyphHeight; ++row) {
      const uint8_t bits = kFont[static_cast<size_t>(g)][static_cast<size_t>(row)];
      for (int col = 0; col < kGlyphWidth; ++col) {
        if ((bits & (0x10 >> col)) == 0) continue;
        const int px = gx + col * scale;
        const int py = y + row * scale;
        FillRect(Rect{px, py, px + scale, py + scale}, colour, out);
      }
    }
  }
}

// Which pixels the tags and the legend already cover, one byte per pixel.
class Occupancy {
 public:
  void Reset(int w, int h) {
    w_ = w;
    h_ = h;
    taken_.assign(static_cast<size_t>(w) * h, 0);
  }
  // True when `r` (inside the image) covers no taken pixel.
  bool Free(const Rect& r) const {
    for (int v = r.y0; v < r.y1; ++v) {
      const uint8_t* row = taken_.data() + static_cast<size_t>(v) * w_;
      if (std::find(row + r.x0, row + r.x1, uint8_t{1}) != row + r.x1) return false;
    }
    return true;
  }
  void Take(const Rect& r) {
    const Rect c = Clip(r, w_, h_);
    for (int v = c.y0; v < c.y1; ++v) {
      uint8_t* row = taken_.data() + static_cast<size_t>(v) * w_;
      std::fill(row + c.x0, row + c.x1, uint8_t{1});
    }
  }

 private:
  int w_{0}, h_{0};
  std::vector<uint8_t> taken_;
};

// Object pixels (label != 0) of `labels` inside `r`.
size_t ObjectPixels(const core::LabelImage& labels, const Rect& r) {
  const Rect c = Clip(r, labels.width, labels.height);
  size_t n = 0;
  for (int v = c.y0; v < c.y1; ++v) {
    const uint32_t* row = labels.data.data() + static_cast<size_t>(v) * labels.width;
    for (int u = c.x0; u < c.x1; ++u) n += row[u] != 0 ? 1 : 0;
  }
  return n;
}

// The legend's geometry: `rows` entries per column (column-major), in `box`.
struct LegendLayout {
  Rect box;
  int rows{0};
  int entry_width{0};  // swatch, gap, widest id
};

LegendLayout PlaceLegend(const core::LabelImage& labels, const std::vector<OverlayObject>& objects,
                         int scale) {
  LegendLayout layout;
  const int w = labels.width;
  const int h = labels.height;
  const int n = static_cast<int>(objects.size());
  char buf[kMaxTagChars];
  int widest = 1;
  for (const OverlayObject& o : objects) widest = std::max(widest, WriteDecimal(o.id, buf));
  layout.entry_width = (kGlyphHeight + 2) * scale + TextWidth(widest, scale);
  const int pitch_v = (kGlyphHeight + 2) * scale;  // rows: 7s entry, 2s gap (as padding)
  const int gap_u = 3 * scale;
  auto width_for = [&](int rows) {
    const int columns = (n + rows - 1) / rows;
    return columns * layout.entry_width + (columns - 1) * gap_u + 2 * scale;
  };
  // Columns at most half the image tall, the whole height when they would not fit across.
  int rows = std::clamp((h / 2) / pitch_v, 1, n);
  if (width_for(rows) + 2 * scale > w) rows = std::clamp(h / pitch_v, 1, n);
  layout.rows = rows;
  const int lw = width_for(rows);
  const int lh = rows * pitch_v;
  const int m = scale;
  const std::array<Rect, 4> corners{{
      {m, m, m + lw, m + lh},
      {w - m - lw, m, w - m, m + lh},
      {m, h - m - lh, m + lw, h - m},
      {w - m - lw, h - m - lh, w - m, h - m},
  }};
  size_t best = 0;
  size_t best_cost = ObjectPixels(labels, corners[0]);
  for (size_t k = 1; k < corners.size(); ++k) {
    const size_t cost = ObjectPixels(labels, corners[k]);
    if (cost < best_cost) {
      best = k;
      best_cost = cost;
    }
  }
  layout.box = corners[best];
  return layout;
}

void DrawLegend(const LegendLayout& layout, const std::vector<OverlayObject>& objects, int scale,
                core::ColorImage* out) {
  FillRect(layout.box, kPatchColor, out);
  const int pitch_v = (kGlyphHeight + 2) * scale;
  const int pitch_u = layout.entry_width + 3 * scale;
  const int swatch = kGlyphHeight * scale;
  char buf[kMaxTagChars];
  for (size_t k = 0; k < objects.size(); ++k) {
    const int column = static_cast<int>(k) / layout.rows;
    const int row = static_cast<int>(k) % layout.rows;
    const int x = layout.box.x0 + scale + column * pitch_u;
    const int y = layout.box.y0 + scale + row * pitch_v;
    if (x >= out->width || y >= out->height) continue;
    FillRect(Rect{x, y, x + swatch, y + swatch}, LabelColor(objects[k].id), out);
    const int chars = WriteDecimal(objects[k].id, buf);
    DrawText(buf, chars, x + swatch + 2 * scale, y, scale, kTextColor, out);
  }
}

// The part of the bounding box of `o` inside a w x h image, as columns [x0, x1) and rows
// [y0, y1); false when the box is empty or wholly outside.
bool VisibleBox(const OverlayObject& o, int w, int h, Rect* box) {
  if (o.min_u > o.max_u || o.min_v > o.max_v) return false;
  if (o.max_u < 0 || o.max_v < 0 || o.min_u >= w || o.min_v >= h) return false;
  *box = Rect{std::max(o.min_u, 0), std::max(o.min_v, 0), std::min(o.max_u, w - 1) + 1,
              std::min(o.max_v, h - 1) + 1};
  return true;
}

void DrawOutline(const Rect& b, core::Rgb8 colour, core::ColorImage* out) {
  FillRect(Rect{b.x0, b.y0, b.x1, b.y0 + 1}, colour, out);
  FillRect(Rect{b.x0, b.y1 - 1, b.x1, b.y1}, colour, out);
  FillRect(Rect{b.x0, b.y0, b.x0 + 1, b.y1}, colour, out);
  FillRect(Rect{b.x1 - 1, b.y0, b.x1, b.y1}, colour, out);
}

// Where a tw x th px tag of the visible box `b` goes: the first free candidate, else the
// first one pushed into the image.
Rect PlaceTag(const Rect& b, int tw, int th, int w, int h, const Occupancy& taken) {
  auto at = [&](int x, int y) {
    if (x + tw > w) x = w - tw;
    x = std::max(x, 0);
    return Rect{x, y, x + tw, y + th};
  };
  const std::array<Rect, 3> candidates{{
      at(b.x0, b.y0 - th),     // above the top-left corner
      at(b.x0 + 1, b.y0 + 1),  // inside it
      at(b.x0, b.y1),          // below the bottom-left corner
  }};
  for (const Rect& r : candidates) {
    if (Inside(r, w, h) && taken.Free(r)) return r;
  }
  Rect r = candidates[0];
  const int y = std::max(std::min(r.y0, h - th), 0);
  r.y1 += y - r.y0;
  r.y0 = y;
  return r;
}

}  // namespace

core::Rgb8 LabelColor(uint32_t id) {
  if (id == 0) return core::Rgb8{0, 0, 0};
  // Golden-ratio hue steps give well separated colours for consecutive ids.
  return core::HsvToRgb(0.13 + 0.618033988749895 * id, (id % 3 == 0) ? 0.65 : 0.85,
                        (id % 2 == 0) ? 0.95 : 0.8);
}

void CloudToImage(const core::PointCloud& cloud, core::ColorImage* out) {
  const int w = cloud.width;
  const int h = std::max(cloud.height, 1);
  out->Reset(w, h);
  if (cloud.has_color()) {
    for (size_t i = 0; i < cloud.size(); ++i) {
      out->data[i] = core::IsValid(cloud.xyz[i]) ? core::UnpackRgba(cloud.rgba[i]) : core::Rgb8{};
    }
    return;
  }
  float zmin = 1e9f, zmax = 0.f;
  for (const core::Vec3f& p : cloud.xyz) {
    if (!core::IsValid(p)) continue;
    zmin = std::min(zmin, p.z);
    zmax = std::max(zmax, p.z);
  }
  const float range = std::max(zmax - zmin, 1e-3f);
  for (size_t i = 0; i < cloud.size(); ++i) {
    const core::Vec3f& p = cloud.xyz[i];
    if (!core::IsValid(p)) continue;
    const auto g = static_cast<uint8_t>(230.f - 180.f * (p.z - zmin) / range);
    out->data[i] = core::Rgb8{g, g, g};
  }
}

void ProjectForDisplay(const core::PointCloud& cloud, const core::LabelImage& labels,
                       const core::CameraIntrinsics& intrinsics, core::PointCloud* view,
                       core::LabelImage* view_labels) {
  const int w = intrinsics.width, h = intrinsics.height;
  const size_t pixels = static_cast<size_t>(w) * static_cast<size_t>(h);
  const core::Vec3f invalid{core::kInvalidDepth, core::kInvalidDepth, core::kInvalidDepth};
  view->width = w;
  view->height = h;
  view->xyz.assign(pixels, invalid);
  view->label.clear();
  const bool color = cloud.has_color();
  view->rgba.assign(color ? pixels : 0, 0u);
  view_labels->Reset(w, h, 0u);
  for (size_t i = 0; i < cloud.size(); ++i) {
    const core::Vec3f& p = cloud.xyz[i];
    if (!core::IsValid(p) || !(p.z > 0.f)) continue;
    const double u = std::round(intrinsics.fx * p.x / p.z + intrinsics.cx);
    const double v = std::round(intrinsics.fy * p.y / p.z + intrinsics.cy);
    if (!(u >= 0.0 && u < w && v >= 0.0 && v < h)) continue;
    const size_t px = static_cast<size_t>(v) * static_cast<size_t>(w) + static_cast<size_t>(u);
    if (core::IsValid(view->xyz[px]) && view->xyz[px].z <= p.z) continue;
    view->xyz[px] = p;
    if (color) view->rgba[px] = cloud.rgba[i];
    view_labels->data[px] = i < labels.data.size() ? labels.data[i] : 0u;
  }
}

void DepthToImage(const core::DepthImage& depth, core::ColorImage* out) {
  out->Reset(depth.width, depth.height);
  uint16_t dmin = UINT16_MAX, dmax = 0;
  for (const uint16_t d : depth.data) {
    if (d == 0) continue;
    dmin = std::min(dmin, d);
    dmax = std::max(dmax, d);
  }
  const float range = std::max(static_cast<float>(dmax) - static_cast<float>(dmin), 1.f);
  for (size_t i = 0; i < depth.data.size(); ++i) {
    const uint16_t d = depth.data[i];
    if (d == 0) continue;
    const auto g = static_cast<uint8_t>(230.f - 180.f * (static_cast<float>(d - dmin)) / range);
    out->data[i] = core::Rgb8{g, g, g};
  }
}

void RenderOverlay(const core::LabelImage& labels, const core::ColorImage* base,
                   core::ColorImage* out) {
  const int w = labels.width;
  const int h = labels.height;
  out->Reset(w, h);
  const bool have_base = base != nullptr && base->width == w && base->height == h;
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      const core::Rgb8 b = have_base ? base->data[i] : core::Rgb8{};
      const uint32_t l = labels.data[i];
      if (l == 0) {
        out->data[i] = core::Rgb8{static_cast<uint8_t>(b.r / 2), static_cast<uint8_t>(b.g / 2),
                                  static_cast<uint8_t>(b.b / 2)};
        continue;
      }
      const core::Rgb8 c = LabelColor(l);
      const bool border =
          (u > 0 && labels.data[i - 1] != l) || (u + 1 < w && labels.data[i + 1] != l) ||
          (v > 0 && labels.data[i - w] != l) || (v + 1 < h && labels.data[i + w] != l);
      if (border) {
        out->data[i] = c;
      } else {
        out->data[i] = core::Rgb8{static_cast<uint8_t>((c.r * 3 + b.r * 2) / 5),
                                  static_cast<uint8_t>((c.g * 3 + b.g * 2) / 5),
                                  static_cast<uint8_t>((c.b * 3 + b.b * 2) / 5)};
      }
    }
  }
}

void OverlayObjectsFrom(const std::vector<Object>& objects, std::vector<OverlayObject>* out) {
  out->clear();
  for (const Object& o : objects) {
    if (o.num_points == 0) continue;
    out->push_back(
        OverlayObject{o.id, -1, o.pixel_min_u, o.pixel_min_v, o.pixel_max_u, o.pixel_max_v});
  }
}

int OverlayTextScale(int width, int height) {
  return std::clamp(std::min(width, height) / 240, 1, 4);
}

void RenderOverlay(const core::LabelImage& labels, const core::ColorImage* base,
                   const std::vector<OverlayObject>& objects, core::ColorImage* out) {
  RenderOverlay(labels, base, out);
  const int w = out->width;
  const int h = out->height;
  if (w <= 0 || h <= 0 || objects.empty()) return;
  const int scale = OverlayTextScale(w, h);

  thread_local Occupancy taken;
  taken.Reset(w, h);
  const LegendLayout legend = PlaceLegend(labels, objects, scale);
  taken.Take(legend.box);

  // Outlines first, so that tags and the legend lie over them.
  Rect box;
  for (const OverlayObject& o : objects) {
    if (VisibleBox(o, w, h, &box)) DrawOutline(box, LabelColor(o.id), out);
  }

  char buf[kMaxTagChars];
  const int th = (kGlyphHeight + 2) * scale;
  for (const OverlayObject& o : objects) {
    if (!VisibleBox(o, w, h, &box)) continue;
    const int chars = FormatTag(o.id, o.track_id, buf);
    const int tw = TextWidth(chars, scale) + 2 * scale;
    const Rect r = PlaceTag(box, tw, th, w, h, taken);
    taken.Take(r);
    FillRect(r, kPatchColor, out);
    DrawText(buf, chars, r.x0 + scale, r.y0 + scale, scale, kTextColor, out);
  }

  DrawLegend(legend, objects, scale, out);
}

}  // namespace clutterseg::pipeline
