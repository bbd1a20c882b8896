#include "clutterseg/io/pcd.h"

#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/io/lzf.h"
#include "tests/testing/test_data.h"

namespace clutterseg::io {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// CPU time of the calling thread (informational output only; nothing asserts on it).
double ThreadCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}

core::PointCloud MakeCloud(int width, int height, bool color, bool label, uint32_t seed) {
  core::PointCloud cloud;
  cloud.width = width;
  cloud.height = height;
  const size_t n = static_cast<size_t>(width) * height;
  cloud.xyz.resize(n);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> coord(-2.f, 2.f);
  for (size_t i = 0; i < n; ++i) {
    if (rng() % 4 == 0) {
      cloud.xyz[i] = core::Vec3f{kNaN, kNaN, kNaN};
    } else {
      cloud.xyz[i] = core::Vec3f{coord(rng), coord(rng), 0.4f + std::abs(coord(rng))};
    }
  }
  cloud.xyz[1] = core::Vec3f{-0.f, 1e-30f, 3.4e38f};  // sign of zero, tiny and huge values
  if (color) {
    cloud.rgba.resize(n);
    for (uint32_t& c : cloud.rgba) c = static_cast<uint32_t>(rng());
  }
  if (label) {
    cloud.label.resize(n);
    for (uint32_t& l : cloud.label) l = rng() % 3 == 0 ? 0u : static_cast<uint32_t>(rng());
  }
  return cloud;
}

// Exact equality of coordinates, except that any NaN matches any NaN.
void ExpectSamePoints(const core::PointCloud& a, const core::PointCloud& b) {
  ASSERT_EQ(a.size(), b.size());
  size_t mismatches = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const float* pa = &a.xyz[i].x;
    const float* pb = &b.xyz[i].x;
    for (int c = 0; c < 3; ++c) {
      const bool same = std::isnan(pa[c])
                            ? std::isnan(pb[c])
                            : std::bit_cast<uint32_t>(pa[c]) == std::bit_cast<uint32_t>(pb[c]);
      if (!same && ++mismatches < 5) {
        ADD_FAILURE() << "point " << i << " coord " << c << ": " << pa[c] << " vs " << pb[c];
      }
    }
  }
  EXPECT_EQ(mismatches, 0u);
}

std::string ReadFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void WriteFileBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

class PcdRoundTripTest : public ::testing::TestWithParam<PcdEncoding> {};

TEST_P(PcdRoundTripTest, OrganizedCloudWithNansColoursAndLabels) {
  const core::PointCloud cloud = MakeCloud(640, 480, true, true, 1);
  const std::string path =
      (testing::ScratchDir("pcd_organized_" + std::to_string(static_cast<int>(GetParam()))) /
       "cloud.pcd")
          .string();
  WritePcd(path, cloud, GetParam());
  const core::PointCloud back = ReadPcd(path);
  EXPECT_EQ(back.width, 640);
  EXPECT_EQ(back.height, 480);
  EXPECT_TRUE(back.organized());
  ExpectSamePoints(cloud, back);
  EXPECT_EQ(back.rgba, cloud.rgba);
  EXPECT_EQ(back.label, cloud.label);
  EXPECT_EQ(back.CountValid(), cloud.CountValid());
  if (GetParam() != PcdEncoding::kAscii) {
    // Binary encodings keep even the NaN bit patterns.
    EXPECT_EQ(std::memcmp(back.xyz.data(), cloud.xyz.data(), cloud.size() * sizeof(core::Vec3f)),
              0);
  }
}

TEST_P(PcdRoundTripTest, UnorganizedCloudWithoutColourOrLabel) {
  const core::PointCloud cloud = MakeCloud(1000, 1, false, false, 2);
  const std::string path =
      (testing::ScratchDir("pcd_unorganized_" + std::to_string(static_cast<int>(GetParam()))) /
       "cloud.pcd")
          .string();
  WritePcd(path, cloud, GetParam());
  const core::PointCloud back = ReadPcd(path);
  EXPECT_EQ(back.width, 1000);
  EXPECT_EQ(back.height, 1);
  EXPECT_FALSE(back.organized());
  ExpectSamePoints(cloud, back);
  // The writer always stores rgba and label: opaque black and 0 when the cloud has none.
  ASSERT_EQ(back.rgba.size(), cloud.size());
  ASSERT_EQ(back.label.size(), cloud.size());
  EXPECT_EQ(back.rgba[17], 0xff000000u);
  EXPECT_EQ(back.label[17], 0u);
}

TEST_P(PcdRoundTripTest, EmptyCloud) {
  const core::PointCloud cloud;
  const std::string path =
      (testing::ScratchDir("pcd_empty_" + std::to_string(static_cast<int>(GetParam()))) /
       "cloud.pcd")
          .string();
  WritePcd(path, cloud, GetParam());
  const core::PointCloud back = ReadPcd(path);
  EXPECT_TRUE(back.empty());
  EXPECT_EQ(back.width, 0);
}

INSTANTIATE_TEST_SUITE_P(AllEncodings, PcdRoundTripTest,
                         ::testing::Values(PcdEncoding::kAscii, PcdEncoding::kBinary,
                                           PcdEncoding::kBinaryCompressed),
                         [](const ::testing::TestParamInfo<PcdEncoding>& param_info) {
                           switch (param_info.param) {
                             case PcdEncoding::kAscii:
                               return std::string("Ascii");
                             case PcdEncoding::kBinary:
                               return std::string("Binary");
                             case PcdEncoding::kBinaryCompressed:
                               break;
                           }
                           return std::string("BinaryCompressed");
                         });

TEST_P(PcdRoundTripTest, OverwritesALargerFileExactly) {
  // A 640x480 cloud (larger than the writer's block of points) first, then a small one to the
  // same path: the file must hold exactly the second one, nothing of the first past its end.
  const auto dir = testing::ScratchDir("pcd_overwrite");
  const std::string path = (dir / "cloud.pcd").string();
  const core::PointCloud big = MakeCloud(640, 480, true, true, 21);
  WritePcd(path, big, GetParam());
  const core::PointCloud back_big = ReadPcd(path);
  ExpectSamePoints(big, back_big);
  EXPECT_EQ(back_big.rgba, big.rgba);
  EXPECT_EQ(back_big.label, big.label);
  const core::PointCloud small = MakeCloud(5, 3, false, true, 22);
  WritePcd(path, small, GetParam());
  const std::string fresh = (dir / "fresh.pcd").string();
  WritePcd(fresh, small, GetParam());
  EXPECT_EQ(ReadFileBytes(path), ReadFileBytes(fresh));
  const core::PointCloud back = ReadPcd(path);
  ExpectSamePoints(small, back);
  EXPECT_EQ(back.label, small.label);
}

TEST(PcdWriterTest, WritesToAPipe) {
  // Not a regular file: nothing to cut to length, and no error for it.
  const core::PointCloud cloud = MakeCloud(3, 2, true, true, 5);
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  std::string received;
  std::thread reader([&] {
    char buf[4096];
    for (ssize_t n; (n = read(fds[0], buf, sizeof(buf))) > 0;)
      received.append(buf, static_cast<size_t>(n));
  });
  const std::string fd_path = "/proc/self/fd/" + std::to_string(fds[1]);
  EXPECT_NO_THROW(WritePcd(fd_path, cloud, PcdEncoding::kBinary));
  close(fds[1]);
  reader.join();
  close(fds[0]);
  const std::string path = (testing::ScratchDir("pcd_pipe") / "cloud.pcd").string();
  WritePcd(path, cloud, PcdEncoding::kBinary);
  EXPECT_EQ(received, ReadFileBytes(path));
}

TEST(PcdWriterTest, HeaderIsStandardV07) {
  const core::PointCloud cloud = MakeCloud(4, 2, true, true, 3);
  const std::string path = (testing::ScratchDir("pcd_header") / "cloud.pcd").string();
  WritePcd(path, cloud, PcdEncoding::kBinary);
  const std::string bytes = ReadFileBytes(path);
  const std::string expected_header =
      "# .PCD v0.7 - Point Cloud Data file format\n"
      "VERSION 0.7\n"
      "FIELDS x y z rgba label\n"
      "SIZE 4 4 4 4 4\n"
      "TYPE F F F U U\n"
      "COUNT 1 1 1 1 1\n"
      "WIDTH 4\n"
      "HEIGHT 2\n"
      "VIEWPOINT 0 0 0 1 0 0 0\n"
      "POINTS 8\n"
      "DATA binary\n";
  ASSERT_EQ(bytes.size(), expected_header.size() + 8 * 20);
  EXPECT_EQ(bytes.substr(0, expected_header.size()), expected_header);
}

// label x rgb _ y z extra: U2, F4, packed F4, 3 padding bytes, F8, F4, F4 x3.
constexpr char kOddHeader[] =
    "# hand-written\n"
    "VERSION .7\n"
    "FIELDS label x rgb _ y z extra\n"
    "SIZE 2 4 4 1 8 4 4\n"
    "TYPE U F F U F F F\n"
    "COUNT 1 1 1 3 1 1 3\n"
    "WIDTH 3\n"
    "HEIGHT 1\n"
    "VIEWPOINT 0 0 0 1 0 0 0\n"
    "POINTS 3\n";

struct OddPoint {
  uint16_t label;
  float x;
  uint32_t rgb;
  double y;
  float z;
};

const OddPoint kOddPoints[3] = {{7, 0.25f, 0x00102030u, -1.5, 0.75f},
                                {65535, -3.125f, 0x00ffffffu, 2.0e-3, 1.0f},
                                {0, kNaN, 0x00000000u, std::nan(""), kNaN}};

void ExpectOddPoints(const core::PointCloud& cloud) {
  ASSERT_EQ(cloud.size(), 3u);
  ASSERT_TRUE(cloud.has_color());
  ASSERT_TRUE(cloud.has_label());
  EXPECT_EQ(cloud.width, 3);
  EXPECT_EQ(cloud.height, 1);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(cloud.label[i], kOddPoints[i].label);
    EXPECT_EQ(cloud.xyz[i].x, kOddPoints[i].x);
    EXPECT_EQ(cloud.xyz[i].y, static_cast<float>(kOddPoints[i].y));
    EXPECT_EQ(cloud.xyz[i].z, kOddPoints[i].z);
    // Packed "rgb" has no alpha; the reader reports it opaque.
    EXPECT_EQ(cloud.rgba[i], kOddPoints[i].rgb | 0xff000000u);
  }
  EXPECT_TRUE(std::isnan(cloud.xyz[2].x));
  EXPECT_TRUE(std::isnan(cloud.xyz[2].y));
  EXPECT_TRUE(std::isnan(cloud.xyz[2].z));
  EXPECT_EQ(cloud.CountValid(), 2u);
}

TEST(PcdReaderTest, OddFieldOrderBinary) {
  std::string bytes = std::string(kOddHeader) + "DATA binary\n";
  for (const OddPoint& p : kOddPoints) {
    auto put = [&](const void* v, size_t n) { bytes.append(static_cast<const char*>(v), n); };
    put(&p.label, 2);
    put(&p.x, 4);
    const float rgb = std::bit_cast<float>(p.rgb);
    put(&rgb, 4);
    bytes.append("\x01\x02\x03", 3);
    put(&p.y, 8);
    put(&p.z, 4);
    const float extra[3] = {9.f, 8.f, 7.f};
    put(extra, 12);
  }
  ExpectOddPoints(ReadPcdFromMemory(bytes.data(), bytes.size(), "odd.pcd"));
}

TEST(PcdReaderTest, OddFieldOrderBinaryCompressed) {
  // Planar: all labels, all x, all rgb, all padding, all y, all z, all extras.
  std::string planes;
  auto put = [&](const void* v, size_t n) { planes.append(static_cast<const char*>(v), n); };
  for (const OddPoint& p : kOddPoints) put(&p.label, 2);
  for (const OddPoint& p : kOddPoints) put(&p.x, 4);
  for (const OddPoint& p : kOddPoints) put(&p.rgb, 4);
  planes.append(9, '\0');
  for (const OddPoint& p : kOddPoints) put(&p.y, 8);
  for (const OddPoint& p : kOddPoints) put(&p.z, 4);
  planes.append(36, '\x11');
  std::vector<uint8_t> packed;
  LzfCompress(planes.data(), planes.size(), &packed);
  std::string bytes = std::string(kOddHeader) + "DATA binary_compressed\n";
  const uint32_t sizes[2] = {static_cast<uint32_t>(packed.size()),
                             static_cast<uint32_t>(planes.size())};
  bytes.append(reinterpret_cast<const char*>(sizes), 8);
  bytes.append(reinterpret_cast<const char*>(packed.data()), packed.size());
  ExpectOddPoints(ReadPcdFromMemory(bytes.data(), bytes.size(), "odd.pcd"));
}

TEST(PcdReaderTest, OddFieldOrderAscii) {
  // PCL writes packed rgb as the unsigned integer of its bits; a float spelling also works.
  const std::string bytes = std::string(kOddHeader) +
                            "DATA ascii\n"
                            "7 0.25 1056816 1 2 3 -1.5 0.75 9 8 7\n"
                            "\n"
                            "65535   -3.125\t16777215 0 0 0 2.0e-3 1 9 8 7\r\n"
                            "0 nan 0 0 0 0 NaN nan 9 8 7";
  ExpectOddPoints(ReadPcdFromMemory(bytes.data(), bytes.size(), "odd.pcd"));
}

TEST(PcdReaderTest, AcceptsVersion05WithoutWidthAndHeight) {
  const std::string bytes =
      "VERSION .5\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 2\nDATA ascii\n"
      "1 2 3\n4 5 6\n";
  const core::PointCloud cloud = ReadPcdFromMemory(bytes.data(), bytes.size(), "old.pcd");
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.width, 2);
  EXPECT_EQ(cloud.height, 1);
  EXPECT_FALSE(cloud.has_color());
  EXPECT_FALSE(cloud.has_label());
  EXPECT_EQ(cloud.xyz[1].z, 6.f);
}

TEST(PcdReaderRealData, DecodesAllMosdLearnFrames) {
  CLUTTERSEG_REQUIRE_DATA("mosd-learn/learn0.pcd");
  double total_ms = 0.0;
  for (int frame = 0; frame < 45; ++frame) {
    SCOPED_TRACE("learn" + std::to_string(frame));
    const std::string path =
        (testing::DataDir() / "mosd-learn" / ("learn" + std::to_string(frame) + ".pcd")).string();
    const double start_ms = ThreadCpuMs();
    const core::PointCloud cloud = ReadPcd(path);
    total_ms += ThreadCpuMs() - start_ms;
    ASSERT_EQ(cloud.width, 640);
    ASSERT_EQ(cloud.height, 480);
    ASSERT_EQ(cloud.size(), 640u * 480u);
    ASSERT_TRUE(cloud.has_label());
    ASSERT_TRUE(cloud.has_color());
    size_t valid = 0;
    uint32_t max_label = 0;
    bool z_in_range = true;
    for (size_t i = 0; i < cloud.size(); ++i) {
      if (!core::IsValid(cloud.xyz[i])) continue;
      ++valid;
      const float z = cloud.xyz[i].z;
      if (z < 0.4f || z > 1.8f) z_in_range = false;
      max_label = std::max(max_label, cloud.label[i]);
    }
    EXPECT_GT(valid, 10000u);
    EXPECT_TRUE(z_in_range);
    EXPECT_GE(max_label, 10u) << "no object label";
  }
  std::printf("[ info     ] mean ReadPcd CPU time per mosd frame: %.2f ms\n", total_ms / 45.0);
}

// ---------------------------------------------------------------------------------------------
// Malformed input: every error is a std::runtime_error whose message starts with the path.

class PcdMalformedTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::ScratchDir("pcd_malformed"); }

  // Writes `bytes` to a file and expects ReadPcd to fail naming the file and `what`.
  void ExpectFails(const std::string& bytes, const std::string& what,
                   const ReadLimits& limits = {}) {
    const std::string path = (dir_ / ("case" + std::to_string(count_++) + ".pcd")).string();
    WriteFileBytes(path, bytes);
    try {
      ReadPcd(path, limits);
      ADD_FAILURE() << "no error for case expecting '" << what << "'";
    } catch (const std::runtime_error& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << msg;
      EXPECT_NE(msg.find(what), std::string::npos) << "expected '" << what << "' in: " << msg;
    }
  }

  static std::string Header(const std::string& points, const std::string& data,
                            const std::string& width = "") {
    return "VERSION 0.7\nFIELDS x y z rgba label\nSIZE 4 4 4 4 4\nTYPE F F F U U\n"
           "COUNT 1 1 1 1 1\nWIDTH " +
           (width.empty() ? points : width) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
           points + "\nDATA " + data + "\n";
  }

  std::string ValidFile(PcdEncoding encoding) {
    const std::string path = (dir_ / "valid.pcd").string();
    WritePcd(path, MakeCloud(64, 48, true, true, 9), encoding);
    return ReadFileBytes(path);
  }

  std::filesystem::path dir_;
  int count_{0};
};

TEST_F(PcdMalformedTest, EmptyGarbageAndHeaderOnly) {
  ExpectFails("", "empty file");
  std::string garbage(4096, '\0');
  std::mt19937 rng(5);
  for (char& c : garbage) c = static_cast<char>(rng());
  ExpectFails(garbage, "header");
  ExpectFails("hello world\n", "unknown header key 'hello'");
  ExpectFails(Header("10", "binary"), "truncated binary data");
  ExpectFails(Header("10", "ascii"), "truncated ascii data");
  ExpectFails(Header("10", "binary_compressed"), "truncated binary_compressed");
  ExpectFails("VERSION 0.7\nFIELDS x y z\n", "without a DATA line");
}

TEST_F(PcdMalformedTest, MissingDuplicateAndInconsistentKeys) {
  ExpectFails(
      "VERSION 0.7\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2 3\n",
      "no FIELDS");
  ExpectFails("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n",
              "no HEIGHT");
  ExpectFails("FIELDS x y z\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nDATA ascii\n", "duplicate");
  ExpectFails("FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n",
              "SIZE has 2 entries but FIELDS has 3");
  ExpectFails(
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\n"
      "DATA ascii\n",
      "COUNT has 2 entries");
  ExpectFails(Header("10", "binary", "9"), "does not equal POINTS");
  ExpectFails(Header("10", "lzma"), "unknown DATA encoding 'lzma'");
  ExpectFails(Header("ten", "binary"), "not a non-negative integer");
  ExpectFails("FIELDS x y z\nSIZE 4 4 4\nTYPE F F X\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n",
              "unsupported TYPE 'X'");
  ExpectFails("FIELDS x y z\nSIZE 4 4 3\nTYPE F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n",
              "unsupported SIZE '3'");
  ExpectFails("FIELDS x y z\nSIZE 4 4 2\nTYPE F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n",
              "unsupported floating-point SIZE 2");
  ExpectFails("FIELDS x y z\nSIZE 4 4 4\nTYPE F F U\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n",
              "field 'z' must be F4 or F8");
  ExpectFails("FIELDS x y w\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n",
              "no x, y and z");
  ExpectFails(
      "FIELDS x y z x\nSIZE 4 4 4 4\nTYPE F F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\n"
      "DATA ascii\n",
      "duplicate field 'x'");
  ExpectFails("VERSION 2.0\nFIELDS x y z\n", "unsupported VERSION");
}

TEST_F(PcdMalformedTest, OverlongHeader) {
  std::string bytes = "# " + std::string(70000, 'c') + "\n" + Header("1", "ascii") + "1 2 3 4 5\n";
  ExpectFails(bytes, "header is longer than the limit");
  std::string many_comments;
  for (int i = 0; i < 10000; ++i) many_comments += "# comment line\n";
  ExpectFails(many_comments + Header("1", "ascii") + "1 2 3 4 5\n", "header is longer");
}

TEST_F(PcdMalformedTest, HugePointCountsFailWithoutAllocating) {
  // Beyond the limits.
  ExpectFails(Header("4000000000000", "binary"), "exceeds the limit");
  ExpectFails(Header("18446744073709551615", "binary_compressed"), "exceeds the limit");
  ExpectFails(Header("99999999999999999999999", "binary"), "not a non-negative integer");
  // With the limit lifted, the size checks must still refuse before allocating: an attempt
  // to allocate would surface as std::bad_alloc, not std::runtime_error.
  ReadLimits unlimited;
  unlimited.max_points = std::numeric_limits<size_t>::max();
  unlimited.max_width = std::numeric_limits<int>::max();
  unlimited.max_height = std::numeric_limits<int>::max();
  unlimited.max_bytes = std::numeric_limits<uint64_t>::max();
  auto organized = [](const std::string& data) {
    return "VERSION 0.7\nFIELDS x y z rgba label\nSIZE 4 4 4 4 4\nTYPE F F F U U\n"
           "COUNT 1 1 1 1 1\nWIDTH 2000000\nHEIGHT 2000000\nPOINTS 4000000000000\nDATA " +
           data + "\n";
  };
  ExpectFails(organized("binary"), "truncated binary data", unlimited);
  ExpectFails(organized("ascii") + "1 2 3 4 5\n", "truncated ascii data", unlimited);
  ExpectFails(Header("4000000000000", "binary"), "WIDTH or HEIGHT is too large", unlimited);
  std::string compressed = organized("binary_compressed");
  const uint32_t sizes[2] = {16, 0xffffffffu};
  compressed.append(reinterpret_cast<const char*>(sizes), 8);
  compressed.append(16, '\0');
  ExpectFails(compressed, "uncompressed bytes but POINTS*point size", unlimited);
}

TEST_F(PcdMalformedTest, TruncatedData) {
  const std::string binary = ValidFile(PcdEncoding::kBinary);
  ExpectFails(binary.substr(0, binary.size() - 1), "truncated binary data");
  const std::string compressed = ValidFile(PcdEncoding::kBinaryCompressed);
  ExpectFails(compressed.substr(0, compressed.size() - 1), "truncated binary_compressed data");
  ExpectFails(compressed.substr(0, compressed.find("binary_compressed\n") + 20),
              "missing the two size words");
  const std::string ascii = ValidFile(PcdEncoding::kAscii);
  const size_t last_line = ascii.rfind('\n', ascii.size() - 2);
  ExpectFails(ascii.substr(0, last_line + 1), "truncated ascii data");
  // A cut inside the last line leaves a line with too few values.
  ExpectFails(ascii.substr(0, last_line + 5), "values, expected 5");
  std::string bad_value = ascii;
  bad_value.replace(bad_value.find("DATA ascii\n") + 11, 1, "x");
  ExpectFails(bad_value, "bad value");
}

TEST_F(PcdMalformedTest, CompressedSizesThatDoNotMatch) {
  const std::string valid = ValidFile(PcdEncoding::kBinaryCompressed);
  const size_t sizes_at = valid.find("binary_compressed\n") + 18;
  uint32_t compressed = 0;
  uint32_t raw = 0;
  std::memcpy(&compressed, valid.data() + sizes_at, 4);
  std::memcpy(&raw, valid.data() + sizes_at + 4, 4);
  ASSERT_EQ(raw, 64u * 48u * 20u);

  auto with_sizes = [&](uint32_t c, uint32_t r) {
    std::string bytes = valid;
    std::memcpy(bytes.data() + sizes_at, &c, 4);
    std::memcpy(bytes.data() + sizes_at + 4, &r, 4);
    return bytes;
  };
  ExpectFails(with_sizes(compressed + 1, raw), "truncated binary_compressed data");
  ExpectFails(with_sizes(compressed, raw + 20), "uncompressed bytes but POINTS*point size");
  ExpectFails(with_sizes(compressed, raw - 1), "uncompressed bytes but POINTS*point size");
  // A shorter stream is a valid prefix that stops early (or ends inside a token).
  ExpectFails(with_sizes(compressed / 2, raw), "");
}

TEST_F(PcdMalformedTest, CorruptLzfStreams) {
  const std::string header = Header("10", "binary_compressed");
  auto with_stream = [&](const std::vector<uint8_t>& stream, uint32_t raw) {
    std::string bytes = header;
    const uint32_t sizes[2] = {static_cast<uint32_t>(stream.size()), raw};
    bytes.append(reinterpret_cast<const char*>(sizes), 8);
    bytes.append(stream.begin(), stream.end());
    return bytes;
  };
  // A back reference before anything was written.
  ExpectFails(with_stream({0xe0, 0xff, 0x10, 0x00, 0x00}, 200), "points before the start");
  // A stream that decodes to more than the declared 200 bytes.
  std::vector<uint8_t> overrun = {0x00, 0x00};
  for (int i = 0; i < 10; ++i) overrun.insert(overrun.end(), {0xe0, 0xff, 0x00});
  ExpectFails(with_stream(overrun, 200), "overruns the output");
  // A well-formed stream that ends early: 1 + (7 + 16 + 2) bytes instead of 200.
  ExpectFails(with_stream({0x00, 0x00, 0xe0, 0x10, 0x00}, 200), "decodes to 26 bytes");
  // A literal run that promises more bytes than the stream holds.
  ExpectFails(with_stream({0x1f, 0x01, 0x02, 0x03}, 200), "runs past the end of the stream");
}

TEST(PcdReaderRealData, DecodesPclScenes) {
  CLUTTERSEG_REQUIRE_DATA("pcl-scenes/milk_cartoon_all_small_clorox.pcd");
  const std::filesystem::path dir = testing::DataDir() / "pcl-scenes";
  // rgba as U4, packed rgb as F4; all organized 640x480 binary_compressed Kinect-class frames.
  for (const std::filesystem::path& rel :
       {std::filesystem::path("milk_cartoon_all_small_clorox.pcd"),
        std::filesystem::path("region_growing_rgb_tutorial.pcd"),
        std::filesystem::path("table_scene_mug_stereo_textured.pcd")}) {
    SCOPED_TRACE(rel.string());
    const core::PointCloud cloud = ReadPcd((dir / rel).string());
    EXPECT_EQ(cloud.width, 640);
    EXPECT_EQ(cloud.height, 480);
    EXPECT_TRUE(cloud.has_color());
    EXPECT_FALSE(cloud.has_label());
    const size_t valid = cloud.CountValid();
    EXPECT_GT(valid, cloud.size() / 4);
    // Colours are real (not all one value) and opaque.
    size_t distinct_from_first = 0;
    for (uint32_t c : cloud.rgba) {
      EXPECT_EQ(c >> 24, 0xffu);
      distinct_from_first += c != cloud.rgba[0] ? 1 : 0;
      if (c >> 24 != 0xffu) break;
    }
    EXPECT_GT(distinct_from_first, cloud.size() / 2);
  }
}

// Random corruptions of valid files (bit flips, byte overwrites, cuts) must either decode or
// throw std::runtime_error; anything else (another exception, a crash, a sanitizer report)
// fails.
TEST(PcdReaderTest, SurvivesRandomCorruption) {
  std::mt19937 rng(2024);
  const core::PointCloud cloud = MakeCloud(16, 8, true, true, 11);
  const auto dir = testing::ScratchDir("pcd_mutation");
  for (PcdEncoding encoding :
       {PcdEncoding::kAscii, PcdEncoding::kBinary, PcdEncoding::kBinaryCompressed}) {
    const std::string path = (dir / "valid.pcd").string();
    WritePcd(path, cloud, encoding);
    const std::string valid = ReadFileBytes(path);
    int failures = 0;
    for (int trial = 0; trial < 3000; ++trial) {
      std::string bytes = valid;
      const int edits = 1 + static_cast<int>(rng() % 4);
      for (int e = 0; e < edits; ++e) {
        const size_t at = rng() % bytes.size();
        switch (rng() % 4) {
          case 0:
            bytes[at] = static_cast<char>(bytes[at] ^ (1 << (rng() % 8)));
            break;
          case 1:
            bytes[at] = static_cast<char>(rng());
            break;
          case 2:
            bytes[at] = "0123456789 \n-."[rng() % 15];
            break;
          default:
            bytes.resize(std::max<size_t>(1, at));
            break;
        }
      }
      core::PointCloud out;
      try {
        ReadPcdFromMemory(bytes.data(), bytes.size(), "mutant", {}, &out);
        EXPECT_EQ(out.size(), static_cast<size_t>(out.width) * static_cast<size_t>(out.height));
      } catch (const std::runtime_error& e) {
        ++failures;
        EXPECT_EQ(std::string(e.what()).rfind("mutant: ", 0), 0u) << e.what();
      }
    }
    EXPECT_GT(failures, 100) << "corruptions should mostly be detected";
  }
}

TEST(PcdReaderTest, ReadPcdFromMemoryNamesTheSource) {
  const std::string bytes = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nDATA binary\n";
  try {
    ReadPcdFromMemory(bytes.data(), bytes.size(), "camera-7");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("camera-7: ", 0), 0u) << e.what();
  }
}

TEST(PcdReaderTest, MissingFileNamesThePath) {
  const std::string path = "/nonexistent/dir/cloud.pcd";
  try {
    ReadPcd(path);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ": cannot open", 0), 0u) << e.what();
  }
}

}  // namespace
}  // namespace clutterseg::io
