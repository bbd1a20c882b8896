#include "clutterseg/io/png_io.h"

#include <png.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <sys/stat.h>

#include "clutterseg/io/pcd.h"
#include "tests/testing/test_data.h"

namespace clutterseg::io {
namespace {

void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// Expects `fn` to throw std::runtime_error whose message starts with `path` and contains `what`.
template <typename Fn>
void ExpectFailure(Fn fn, const std::string& path, const std::string& what) {
  try {
    fn();
    ADD_FAILURE() << "no error; expected '" << what << "' for " << path;
  } catch (const std::runtime_error& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << msg;
    EXPECT_NE(msg.find(what), std::string::npos) << "expected '" << what << "' in: " << msg;
  }
}

// Writes a PNG in one of libpng's simplified formats (grey, RGBA, palette...).
void WriteSimplePng(const std::string& path, int width, int height, png_uint_32 format,
                    const std::vector<uint8_t>& pixels, const std::vector<uint8_t>* colormap,
                    int colormap_entries) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width);
  image.height = static_cast<png_uint_32>(height);
  image.format = format;
  image.colormap_entries = static_cast<png_uint_32>(colormap_entries);
  ASSERT_NE(png_image_write_to_file(&image, path.c_str(), 0, pixels.data(), 0,
                                    colormap != nullptr ? colormap->data() : nullptr),
            0)
      << image.message;
}

TEST(PngTest, DepthRoundTripIsExact) {
  core::DepthImage depth(37, 21);
  std::mt19937 rng(3);
  for (uint16_t& d : depth.data) d = static_cast<uint16_t>(rng());
  depth.data[0] = 0;
  depth.data[1] = 65535;
  depth.data[2] = 0x0102;  // catches a byte-order mistake
  const std::string path = (testing::ScratchDir("png_depth") / "d.png").string();
  WriteDepthPng(path, depth);
  const core::DepthImage back = ReadDepthPng(path);
  EXPECT_EQ(back.width, 37);
  EXPECT_EQ(back.height, 21);
  EXPECT_EQ(back.data, depth.data);

  // TUM-style scaling: value / 5000 m = value * 0.2 mm, rounded.
  const core::DepthImage scaled = ReadDepthPng(path, 0.2);
  EXPECT_EQ(scaled.data[2], 52);  // 258 * 0.2 = 51.6
  EXPECT_EQ(scaled.data[1], 13107);
  EXPECT_THROW(ReadDepthPng(path, 0.0), std::invalid_argument);
}

TEST(PngTest, ColourRoundTripIsExact) {
  core::ColorImage image(19, 11);
  std::mt19937 rng(4);
  for (core::Rgb8& c : image.data) {
    c = core::Rgb8{static_cast<uint8_t>(rng()), static_cast<uint8_t>(rng()),
                   static_cast<uint8_t>(rng())};
  }
  const std::string path = (testing::ScratchDir("png_colour") / "c.png").string();
  WriteColorPng(path, image);
  const core::ColorImage back = ReadColorPng(path);
  ASSERT_EQ(back.width, 19);
  ASSERT_EQ(back.height, 11);
  for (size_t i = 0; i < image.size(); ++i) {
    ASSERT_EQ(back.data[i].r, image.data[i].r);
    ASSERT_EQ(back.data[i].g, image.data[i].g);
    ASSERT_EQ(back.data[i].b, image.data[i].b);
  }
}

// One writer, reused: a large frame, then smaller and one-pixel-wide images, colour and depth
// interleaved; libpng (which checks every chunk's CRC and the zlib stream's Adler-32) reads
// each back exactly. A full disk is an error naming the file.
TEST(PngTest, OneWriterWritesFramesOfEverySizeExactly) {
  PngWriter writer;
  std::mt19937 rng(5);
  const std::filesystem::path dir = testing::ScratchDir("png_writer");
  const int sizes[][2] = {{640, 480}, {19, 11}, {1, 7}, {2, 1}, {640, 480}};
  int k = 0;
  for (const auto& wh : sizes) {
    core::ColorImage image(wh[0], wh[1]);
    // Smooth gradients with noise, as overlays are, and one random row: both filter paths.
    for (int v = 0; v < wh[1]; ++v) {
      for (int u = 0; u < wh[0]; ++u) {
        const auto noise = static_cast<uint8_t>(v == 3 ? rng() : rng() % 4);
        image.at(u, v) = core::Rgb8{static_cast<uint8_t>(u + noise), static_cast<uint8_t>(v),
                                    static_cast<uint8_t>(u ^ v)};
      }
    }
    const std::string colour_path = (dir / ("c" + std::to_string(k) + ".png")).string();
    writer.WriteColor(colour_path, image);
    const core::ColorImage back = ReadColorPng(colour_path);
    ASSERT_EQ(back.width, wh[0]);
    ASSERT_EQ(back.height, wh[1]);
    for (size_t i = 0; i < image.size(); ++i) {
      ASSERT_EQ(back.data[i].r, image.data[i].r) << colour_path << " pixel " << i;
      ASSERT_EQ(back.data[i].g, image.data[i].g) << colour_path << " pixel " << i;
      ASSERT_EQ(back.data[i].b, image.data[i].b) << colour_path << " pixel " << i;
    }
    core::DepthImage depth(wh[0], wh[1]);
    for (uint16_t& d : depth.data) d = static_cast<uint16_t>(rng());
    const std::string depth_path = (dir / ("d" + std::to_string(k) + ".png")).string();
    writer.WriteDepth(depth_path, depth);
    EXPECT_EQ(ReadDepthPng(depth_path).data, depth.data) << depth_path;
    ++k;
  }
  ExpectFailure([&] { writer.WriteColor("/dev/full", core::ColorImage(64, 64)); }, "/dev/full",
                "write failed");
  // The writer still works after a failure.
  const std::string after = (dir / "after.png").string();
  writer.WriteColor(after, core::ColorImage(3, 2));
  EXPECT_EQ(ReadColorPng(after).width, 3);
}

TEST(PngTest, ColourReadExpandsGreyRgbaAndPalette) {
  const auto dir = testing::ScratchDir("png_formats");
  const std::string grey = (dir / "grey.png").string();
  WriteSimplePng(grey, 2, 1, PNG_FORMAT_GRAY, {10, 200}, nullptr, 0);
  core::ColorImage img = ReadColorPng(grey);
  ASSERT_EQ(img.size(), 2u);
  EXPECT_EQ(img.data[1].r, 200);
  EXPECT_EQ(img.data[1].g, 200);
  EXPECT_EQ(img.data[1].b, 200);

  const std::string rgba = (dir / "rgba.png").string();
  WriteSimplePng(rgba, 2, 1, PNG_FORMAT_RGBA, {1, 2, 3, 255, 4, 5, 6, 255}, nullptr, 0);
  img = ReadColorPng(rgba);
  ASSERT_EQ(img.size(), 2u);
  EXPECT_EQ(img.data[1].r, 4);
  EXPECT_EQ(img.data[1].g, 5);
  EXPECT_EQ(img.data[1].b, 6);

  const std::string palette = (dir / "palette.png").string();
  const std::vector<uint8_t> colormap = {255, 0, 0, 0, 128, 255};
  WriteSimplePng(palette, 3, 1, PNG_FORMAT_RGB_COLORMAP, {1, 0, 1}, &colormap, 2);
  img = ReadColorPng(palette);
  ASSERT_EQ(img.size(), 3u);
  EXPECT_EQ(img.data[0].r, 0);
  EXPECT_EQ(img.data[0].g, 128);
  EXPECT_EQ(img.data[0].b, 255);
  EXPECT_EQ(img.data[1].r, 255);
  EXPECT_EQ(img.data[1].g, 0);
}

TEST(PngTest, DepthReadRefusesEightBitAndColour) {
  const auto dir = testing::ScratchDir("png_refuse");
  const std::string grey8 = (dir / "grey8.png").string();
  WriteSimplePng(grey8, 2, 1, PNG_FORMAT_GRAY, {10, 200}, nullptr, 0);
  ExpectFailure([&] { ReadDepthPng(grey8); }, grey8, "expected a 16-bit single-channel grey");
  ExpectFailure([&] { ReadDepthPng(grey8); }, grey8, "got 8-bit grey");
  const std::string rgb = (dir / "rgb.png").string();
  WriteColorPng(rgb, core::ColorImage(4, 4));
  ExpectFailure([&] { ReadDepthPng(rgb); }, rgb, "got 8-bit RGB");
}

TEST(PngTest, CorruptFilesNameThePath) {
  const auto dir = testing::ScratchDir("png_corrupt");
  const std::string empty = (dir / "empty.png").string();
  WriteText(empty, "");
  ExpectFailure([&] { ReadDepthPng(empty); }, empty, "empty file");
  const std::string garbage = (dir / "garbage.png").string();
  WriteText(garbage, "this is not a PNG file at all, just some text\n");
  ExpectFailure([&] { ReadColorPng(garbage); }, garbage, "");
  ExpectFailure([&] { ReadDepthPng(garbage); }, garbage, "");

  core::DepthImage depth(64, 64);
  for (size_t i = 0; i < depth.size(); ++i) depth.data[i] = static_cast<uint16_t>(i * 2654435761u);
  const std::string good = (dir / "good.png").string();
  WriteDepthPng(good, depth);
  std::ifstream in(good, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  const std::string truncated = (dir / "truncated.png").string();
  WriteText(truncated, bytes.substr(0, bytes.size() / 2));
  ExpectFailure([&] { ReadDepthPng(truncated); }, truncated, "");
  const std::string missing = (dir / "missing.png").string();
  ExpectFailure([&] { ReadColorPng(missing); }, missing, "cannot open");
  ExpectFailure([&] { WriteColorPng((dir / "no/such/dir.png").string(), core::ColorImage(2, 2)); },
                (dir / "no/such/dir.png").string(), "cannot open for writing");
}

TEST(IntrinsicsJsonTest, FlatNestedAndMatrixForms) {
  const auto dir = testing::ScratchDir("json_forms");
  WriteText(dir / "flat.json",
            R"({"fx": 500.5, "fy": 501, "cx": 320.25, "cy": 240.75, "width": 640, "height": 480})");
  core::CameraIntrinsics k = ReadIntrinsicsJson((dir / "flat.json").string());
  EXPECT_EQ(k.fx, 500.5);
  EXPECT_EQ(k.fy, 501.0);
  EXPECT_EQ(k.cx, 320.25);
  EXPECT_EQ(k.cy, 240.75);
  EXPECT_EQ(k.width, 640);
  EXPECT_EQ(k.height, 480);

  WriteText(dir / "nested.json",
            "{\"name\": \"cam\\u00e9\", \"camera\": {\"fx\": 610, \"fy\": 611, \"cx\": 1e2,"
            " \"cy\": 2E2, \"width\": 320, \"height\": 240}, \"extra\": [true, false, null]}");
  k = ReadIntrinsicsJson((dir / "nested.json").string());
  EXPECT_EQ(k.fx, 610.0);
  EXPECT_EQ(k.cx, 100.0);
  EXPECT_EQ(k.cy, 200.0);
  EXPECT_EQ(k.width, 320);

  WriteText(dir / "rows.json", R"({"K": [[600, 0, 300], [0, 601, 200], [0, 0, 1]]})");
  k = ReadIntrinsicsJson((dir / "rows.json").string());
  EXPECT_EQ(k.fx, 600.0);
  EXPECT_EQ(k.fy, 601.0);
  EXPECT_EQ(k.cx, 300.0);
  EXPECT_EQ(k.cy, 200.0);

  WriteText(dir / "rowmajor.json", R"({"intrinsic_matrix": [600, 0, 300, 0, 601, 200, 0, 0, 1]})");
  k = ReadIntrinsicsJson((dir / "rowmajor.json").string());
  EXPECT_EQ(k.cx, 300.0);
  EXPECT_EQ(k.cy, 200.0);
}

// Writes `text` to dir/name and expects ReadIntrinsicsJson to refuse it, naming the file and
// saying `what`.
void ExpectRefused(const std::filesystem::path& dir, const std::string& name,
                   const std::string& text, const std::string& what) {
  const std::string path = (dir / name).string();
  WriteText(path, text);
  ExpectFailure([&] { ReadIntrinsicsJson(path); }, path, what);
}

TEST(IntrinsicsJsonTest, ErrorsNameFileAndKey) {
  const auto dir = testing::ScratchDir("json_errors");
  auto expect = [&](const std::string& name, const std::string& text, const std::string& what) {
    ExpectRefused(dir, name, text, what);
  };
  expect("empty.json", "", "empty file");
  expect("missing_fx.json", R"({"fy": 1, "cx": 2, "cy": 3})", "missing key 'fx'");
  expect("string_fx.json", R"({"fx": "525", "fy": 1, "cx": 2, "cy": 3})",
         "key 'fx' is not a number");
  expect("bad_fx.json", R"({"fx": -5, "fy": 1, "cx": 2, "cy": 3})", "fx");
  expect("bad_width.json", R"({"fx": 5, "fy": 1, "cx": 2, "cy": 3, "width": 640.5})",
         "key 'width'");
  expect("trailing_comma.json", R"({"fx": 5, "fy": 1,})", "line 1, column 19");
  expect("unterminated.json", "{\"fx\": 5,\n \"fy", "line 2");
  expect("garbage.json", "{\"fx\": 5} trailing", "line 1, column 13: ");
  expect("garbage2.json", "{\"fx\": 5} {}", "expected end of input");
  expect("duplicate.json", R"({"fx": 5, "fx": 6})", "duplicate key");
  expect("deep.json", std::string(100, '[') + std::string(100, ']'), "nesting deeper");
  expect("array.json", "[1, 2]", "top level is not a JSON object");
  expect("matrix.json", R"({"K": [1, 2, 3, 4, 5, 6, 7, 8, 9]})", "not a pinhole camera matrix");
  expect("number.json", R"({"fx": 01})", "line 1");
  expect("huge.json", R"({"fx": 1e999})", "number out of range");
}

// Valid intrinsics (the default Kinect's) in the members of a JSON object.
constexpr const char* kValidMembers = R"("fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5)";

// A FIFO (or device) given as an intrinsics JSON, a PNG or a PCD used to block the reader's
// open until a writer came: clutterseg-segment --intrinsics FIFO, the daemon's
// camera.intrinsics_file / camera.extrinsics_file and a FIFO named as a frame hung. Each
// reader now refuses what is not a regular file, naming it, without waiting.
TEST(IntrinsicsJsonTest, FifosAndDevicesAreRefusedWithoutBlocking) {
  const auto dir = testing::ScratchDir("fifo_inputs");
  for (const char* name : {"k.json", "depth.png", "cloud.pcd"}) {
    const std::string fifo = (dir / name).string();
    std::filesystem::remove(fifo);
    ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0) << fifo;
  }
  ExpectFailure([&] { ReadIntrinsicsJson((dir / "k.json").string()); }, (dir / "k.json").string(),
                "not a regular file");
  ExpectFailure([&] { ReadDepthPng((dir / "depth.png").string()); }, (dir / "depth.png").string(),
                "not a regular file");
  core::PointCloud cloud;
  ExpectFailure([&] { ReadPcd((dir / "cloud.pcd").string(), ReadLimits{}, &cloud); },
                (dir / "cloud.pcd").string(), "not a regular file");
  ExpectFailure([&] { ReadIntrinsicsJson("/dev/zero"); }, "/dev/zero", "not a regular file");
}

TEST(IntrinsicsJsonTest, DecodesEscapesAndEveryNumberForm) {
  const auto dir = testing::ScratchDir("json_values");
  const std::string path = (dir / "values.json").string();
  // Keys spelled with escapes; the other members hold every kind of value.
  WriteText(
      path,
      " {\"f\\u0078\": 5.25e2, \"fy\": 52500E-2, \"c\\u0078\": 319.5, \"\\u0063y\": 2395e-1,"
      " \"name\": \"q\\\"\\\\\\/\\b\\f\\n\\r\\t\\u0041\\u00e9\\ud83d\\ude00 \xc3\xa9\","
      " \"extra\": {\"a\": [1, -2.5e-3, 0, 1E+2, -0], \"c\": null, \"d\": true, \"e\": false},"
      " \"big\": 18446744073709551616, \"neg\": -9223372036854775808}\r\n\t");
  const core::CameraIntrinsics k = ReadIntrinsicsJson(path);
  EXPECT_EQ(k.fx, 525.0);
  EXPECT_EQ(k.fy, 525.0);
  EXPECT_EQ(k.cx, 319.5);
  EXPECT_EQ(k.cy, 239.5);
}

TEST(IntrinsicsJsonTest, RefusesMalformedJson) {
  const auto dir = testing::ScratchDir("json_malformed");
  int n = 0;
  for (const std::string bad :
       {"{",           "{\"a\" 1}",   "{\"a\": 1,}",   "[1 2]",
        "[01]",        "[1.]",        "[.5]",          "[1e]",
        "[-]",         "\"abc",       "\"a\tb\"",      "\"\\x\"",
        "\"\\ud800\"", "\"\\udc00\"", "\"\\u12g4\"",   "tru",
        "nul",         "{} {}",       "{1: 2}",        "{'fx': 1}",
        "[NaN]",       "[Infinity]",  "[+1]",          "[0x10]",
        "\"\xff\"",    "\"\xc3\"",    "{} // comment", "/* comment */ {}"}) {
    ExpectRefused(dir, "bad" + std::to_string(n++) + ".json", bad,
                  "malformed JSON: line 1, column ");
  }
  ExpectRefused(dir, "overflow.json", "{" + std::string(kValidMembers) + ", \"x\": [1e400]}",
                "malformed JSON: number out of range");
}

TEST(IntrinsicsJsonTest, SyntaxErrorsGiveLineAndColumn) {
  const auto dir = testing::ScratchDir("json_position");
  ExpectRefused(dir, "lines.json", "{\n  \"a\": [1,\n  ]\n}", "malformed JSON: line 3, column 3: ");
  // The position is that of the last character of the token at fault ("cx" here).
  ExpectRefused(dir, "crlf.json", "{\"fx\": 1,\r\n\r\n   \"fy\": 2 \"cx\": 3}",
                "malformed JSON: line 3, column 15: ");
}

TEST(IntrinsicsJsonTest, RefusesDuplicateKeysInEveryObject) {
  const auto dir = testing::ScratchDir("json_duplicates");
  auto expect = [&](const std::string& name, const std::string& text, const std::string& what) {
    ExpectRefused(dir, name, text, what);
  };
  const std::string valid = kValidMembers;
  expect("top.json", "{" + valid + ", \"cy\": 240}", "malformed JSON: duplicate key \"cy\"");
  expect("camera.json", "{\"camera\": {" + valid + ", \"fx\": 1}}", "duplicate key \"fx\"");
  expect("ignored.json", "{" + valid + ", \"extra\": [{\"a\": 1, \"a\": 1}]}",
         "duplicate key \"a\"");
  expect("escaped.json", "{" + valid + ", \"c\\u0078\": 1}", "duplicate key \"cx\"");

  // The same key in different objects is no duplicate.
  const std::string path = (dir / "siblings.json").string();
  WriteText(path, "{\"fx\": 1, \"camera\": {" + valid +
                      "}, \"extra\": [{\"fx\": 2}, {\"fx\": 3, \"camera\": {\"fx\": 4}}]}");
  EXPECT_EQ(ReadIntrinsicsJson(path).fx, 525.0);
}

TEST(IntrinsicsJsonTest, LimitsNestingTo64Levels) {
  const auto dir = testing::ScratchDir("json_depth");
  // Arrays nested `levels` deep inside the top-level object.
  auto nested = [&](int levels) {
    return "{" + std::string(kValidMembers) + ", \"x\": " + std::string(levels, '[') +
           std::string(levels, ']') + "}";
  };
  const std::string path = (dir / "depth64.json").string();
  WriteText(path, nested(64));
  EXPECT_EQ(ReadIntrinsicsJson(path).fx, 525.0);
  ExpectRefused(dir, "depth65.json", nested(65), "malformed JSON: nesting deeper than 64 levels");
  // Deep enough to exhaust a recursive parser's stack.
  ExpectRefused(dir, "deepest.json", std::string(500000, '['), "nesting deeper than 64 levels");
}

TEST(IntrinsicsJsonTest, RefusesFilesOver1MiB) {
  const auto dir = testing::ScratchDir("json_size");
  const std::string members = "{" + std::string(kValidMembers) + "}";
  const std::string path = (dir / "padded.json").string();
  WriteText(path, members + std::string((1u << 20) - members.size(), ' '));
  EXPECT_EQ(ReadIntrinsicsJson(path).fx, 525.0) << "exactly 1 MiB is read";
  ExpectRefused(dir, "over.json", members + std::string((1u << 20) - members.size() + 1, ' '),
                "larger than 1048576 bytes");
}

TEST(IntrinsicsJsonRealData, ReadsTumAndUcnFiles) {
  CLUTTERSEG_REQUIRE_DATA("tum-frame/camera_primesense.json");
  CLUTTERSEG_REQUIRE_DATA("ucn-demo/camera_params.json");
  const core::CameraIntrinsics tum =
      ReadIntrinsicsJson((testing::DataDir() / "tum-frame/camera_primesense.json").string());
  EXPECT_EQ(tum.width, 640);
  EXPECT_EQ(tum.height, 480);
  EXPECT_EQ(tum.fx, 525.0);
  EXPECT_EQ(tum.fy, 525.0);
  EXPECT_EQ(tum.cx, 319.5);
  EXPECT_EQ(tum.cy, 239.5);
  const core::CameraIntrinsics ucn =
      ReadIntrinsicsJson((testing::DataDir() / "ucn-demo/camera_params.json").string());
  EXPECT_EQ(ucn.width, 640);
  EXPECT_EQ(ucn.height, 480);
  EXPECT_EQ(ucn.fx, 612.937);
  EXPECT_EQ(ucn.fy, 613.173);
  EXPECT_EQ(ucn.cx, 322.549);
  EXPECT_EQ(ucn.cy, 248.158);
}

// Fraction of valid points and the z range of a cloud.
struct CloudStats {
  size_t valid{0};
  float min_z{1e9f};
  float max_z{-1e9f};
};

CloudStats Stats(const core::PointCloud& cloud) {
  CloudStats s;
  for (const core::Vec3f& p : cloud.xyz) {
    if (!core::IsValid(p)) continue;
    ++s.valid;
    s.min_z = std::min(s.min_z, p.z);
    s.max_z = std::max(s.max_z, p.z);
  }
  return s;
}

TEST(DepthPngCloudRealData, TumFrame) {
  CLUTTERSEG_REQUIRE_DATA("tum-frame/TUM_depth.png");
  const std::filesystem::path dir = testing::DataDir() / "tum-frame";
  const core::CameraIntrinsics k = ReadIntrinsicsJson((dir / "camera_primesense.json").string());
  const core::PointCloud cloud =
      ReadDepthPngCloud((dir / "TUM_depth.png").string(), k, (dir / "TUM_color.png").string(), 0.2);
  EXPECT_EQ(cloud.width, 640);
  EXPECT_EQ(cloud.height, 480);
  EXPECT_TRUE(cloud.has_color());
  const CloudStats s = Stats(cloud);
  EXPECT_GT(s.valid, cloud.size() / 2);
  EXPECT_GT(s.min_z, 0.2f);
  EXPECT_LT(s.max_z, 10.f);
}

TEST(DepthPngCloudRealData, UcnFrames) {
  CLUTTERSEG_REQUIRE_DATA("ucn-demo/000000-depth.png");
  const std::filesystem::path dir = testing::DataDir() / "ucn-demo";
  const core::CameraIntrinsics k = ReadIntrinsicsJson((dir / "camera_params.json").string());
  for (int i = 0; i < 9; ++i) {
    const std::string stem = "00000" + std::to_string(i);
    SCOPED_TRACE(stem);
    const core::PointCloud cloud = ReadDepthPngCloud((dir / (stem + "-depth.png")).string(), k,
                                                     (dir / (stem + "-color.png")).string());
    EXPECT_EQ(cloud.size(), 640u * 480u);
    EXPECT_TRUE(cloud.has_color());
    const CloudStats s = Stats(cloud);
    EXPECT_GT(s.valid, cloud.size() / 2);
    EXPECT_GT(s.min_z, 0.1f);
    EXPECT_LT(s.max_z, 10.f);
  }
}

TEST(DepthPngCloudTest, SizeMismatchNamesTheFile) {
  const std::string depth = (testing::ScratchDir("png_size_mismatch") / "depth.png").string();
  WriteDepthPng(depth, core::DepthImage(640, 480));
  core::CameraIntrinsics k;
  k.width = 320;
  k.height = 240;
  ExpectFailure([&] { ReadDepthPngCloud(depth, k); }, depth, "intrinsics are for 320x240");
}

// The OSD learn6 depth PNG and the mOSD learn6 PCD come from the same frame: where both are
// finite, back-projecting the PNG with fx = fy = 525 must reproduce the PCD's points.
TEST(DepthPngCloudRealData, OsdLearn6MatchesMosdPcd) {
  CLUTTERSEG_REQUIRE_DATA("osd-png/depth/learn6.png");
  CLUTTERSEG_REQUIRE_DATA("mosd-learn/learn6.pcd");
  const core::PointCloud pcd = ReadPcd((testing::DataDir() / "mosd-learn/learn6.pcd").string());
  const core::PointCloud png = ReadDepthPngCloud(
      (testing::DataDir() / "osd-png/depth/learn6.png").string(), core::DefaultKinectIntrinsics(),
      (testing::DataDir() / "osd-png/image_color/learn6.png").string());
  ASSERT_EQ(png.size(), pcd.size());
  size_t common = 0;
  float max_dz = 0.f;
  float max_dxy = 0.f;
  double sum_dcolor = 0.0;
  size_t large_dcolor = 0;
  for (size_t i = 0; i < png.size(); ++i) {
    if (!core::IsValid(png.xyz[i]) || !core::IsValid(pcd.xyz[i])) continue;
    ++common;
    max_dz = std::max(max_dz, std::abs(png.xyz[i].z - pcd.xyz[i].z));
    max_dxy = std::max(
        {max_dxy, std::abs(png.xyz[i].x - pcd.xyz[i].x), std::abs(png.xyz[i].y - pcd.xyz[i].y)});
    const core::Rgb8 a = core::UnpackRgba(png.rgba[i]);
    const core::Rgb8 b = core::UnpackRgba(pcd.rgba[i]);
    const int dr = std::abs(a.r - b.r);
    const int dg = std::abs(a.g - b.g);
    const int db = std::abs(a.b - b.b);
    sum_dcolor += dr + dg + db;
    if (std::max({dr, dg, db}) > 20) ++large_dcolor;
  }
  const double mean_dcolor = sum_dcolor / (3.0 * static_cast<double>(common));
  std::printf(
      "[ info     ] learn6: %zu common points, max |dz| %.3g m, max |dx|,|dy| %.3g m, "
      "mean colour diff %.2f, %zu pixels differ by more than 20\n",
      common, max_dz, max_dxy, mean_dcolor, large_dcolor);
  EXPECT_GT(common, 200000u);
  // The PNG holds the PCD's depth in whole millimetres, and the back-projection matches the
  // PCD's to float rounding (measured: 1.2e-7 m).
  EXPECT_LE(max_dz, 1e-6f);
  EXPECT_LE(max_dxy, 1e-6f);
  // The colour images went through different encoders: measured mean 1.65 per channel, with
  // a few hundred pixels (of 209002) off by more than 20.
  EXPECT_LT(mean_dcolor, 2.5);
  EXPECT_LT(large_dcolor, common / 200);
}

}  // namespace
}  // namespace clutterseg::io
