// The frame limits shared by the readers and writers (core::FrameLimits), on real files: a
// declared size beyond them is refused before anything is allocated, and the writers refuse
// what the readers would refuse. Write errors (a full device) are reported.

#include <zlib.h>

#include <cerrno>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/frame_limits.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/io/png_io.h"
#include "tests/testing/run_process.h"
#include "tests/testing/test_data.h"

namespace clutterseg::io {
namespace {

namespace fs = std::filesystem;

void PutBe32(std::string* s, uint32_t v) {
  for (int b = 3; b >= 0; --b) s->push_back(static_cast<char>((v >> (8 * b)) & 0xff));
}

void AppendChunk(std::string* png, const char* type, const std::string& data) {
  PutBe32(png, static_cast<uint32_t>(data.size()));
  const std::string body = std::string(type, 4) + data;
  png->append(body);
  PutBe32(png, static_cast<uint32_t>(crc32(0, reinterpret_cast<const Bytef*>(body.data()),
                                           static_cast<uInt>(body.size()))));
}

// A 16-bit grey PNG that declares `w` x `h` px and carries `idat_bytes` of image data: the
// size of file (about 530 kB) that made the reader allocate gigabytes before.
std::string HugeDepthPng(uint32_t w, uint32_t h, size_t idat_bytes) {
  std::string png("\x89PNG\r\n\x1a\n", 8);
  std::string ihdr;
  PutBe32(&ihdr, w);
  PutBe32(&ihdr, h);
  ihdr += std::string("\x10\x00\x00\x00\x00", 5);  // 16 bit, grey, deflate, filter 0, no interlace
  AppendChunk(&png, "IHDR", ihdr);
  AppendChunk(&png, "IDAT", std::string(idat_bytes, '\0'));
  AppendChunk(&png, "IEND", "");
  return png;
}

std::string ReadText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

core::PointCloud Cloud(int w, int h) {
  core::PointCloud c;
  c.width = w;
  c.height = h;
  c.xyz.assign(static_cast<size_t>(w) * h, core::Vec3f{0.1f, 0.2f, 1.f});
  return c;
}

// Before: the 16000 x 16000 declaration was decoded (16384 px per side was the limit) and
// the reader alone allocated a gigabyte; now it is refused from the header.
TEST(ReadLimitsTest, HugeDeclaredPngIsRefusedBeforeAllocating) {
  const fs::path dir = testing::ScratchDir("limits_png");
  const fs::path path = dir / "huge-depth.png";
  std::ofstream(path, std::ios::binary) << HugeDepthPng(16000, 16000, 530 * 1024);
  const long before = testing::PeakRssKib();
  for (int colour = 0; colour < 2; ++colour) {
    try {
      if (colour == 0) {
        (void)ReadDepthPng(path.string());
      } else {
        (void)ReadColorPng(path.string());
      }
      ADD_FAILURE() << "decoded a 16000x16000 PNG";
    } catch (const core::FrameTooLargeError& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind(path.string() + ": ", 0), 0u) << msg;
      EXPECT_NE(msg.find("16000x16000 px exceeds the frame limit of 4096x4096 px"),
                std::string::npos)
          << msg;
    }
  }
  EXPECT_LT(testing::PeakRssKib() - before, 64 * 1024) << "KiB of peak RSS grown";
}

TEST(ReadLimitsTest, PngAtTheLimitsReadsAndTheWritersRefuseBeyond) {
  const fs::path dir = testing::ScratchDir("limits_png_edges");
  for (auto [w, h] : {std::pair{4096, 8}, {8, 4096}}) {
    const std::string path = (dir / "edge.png").string();
    WriteDepthPng(path, core::DepthImage(w, h, 1234));
    const core::DepthImage back = ReadDepthPng(path);
    EXPECT_EQ(back.width, w);
    EXPECT_EQ(back.height, h);
    EXPECT_EQ(back.at(w - 1, h - 1), 1234);
  }
  const std::string too_wide = (dir / "too_wide.png").string();
  EXPECT_THROW(WriteDepthPng(too_wide, core::DepthImage(4097, 2, 1)), core::FrameTooLargeError);
  EXPECT_THROW(WriteColorPng(too_wide, core::ColorImage(2, 4097)), core::FrameTooLargeError);
  EXPECT_FALSE(fs::exists(too_wide)) << "nothing is written for a refused image";
  // The same limits, made smaller, apply to both sides alike.
  core::FrameLimits small;
  small.max_width = 100;
  const std::string path = (dir / "small.png").string();
  WriteDepthPng(path, core::DepthImage(101, 4, 7));
  EXPECT_THROW(ReadDepthPng(path, 1.0, small), core::FrameTooLargeError);
  EXPECT_THROW(WriteDepthPng(path, core::DepthImage(101, 4, 7), small), core::FrameTooLargeError);
}

TEST(ReadLimitsTest, PcdWriterRefusesWhatTheReaderRefuses) {
  const fs::path dir = testing::ScratchDir("limits_pcd");
  const std::string path = (dir / "cloud.pcd").string();
  // Organized: the image limits (this aborted in WritePcd before, after the readers had
  // accepted a larger image).
  try {
    WritePcd(path, Cloud(4097, 2));
    ADD_FAILURE() << "wrote a 4097x2 organized cloud";
  } catch (const core::FrameTooLargeError& e) {
    EXPECT_NE(std::string(e.what()).find("4097x2 px exceeds the frame limit"), std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(fs::exists(path));
  WritePcd(path, Cloud(4096, 2));
  EXPECT_EQ(ReadPcd(path).width, 4096);
  // Unorganized and byte limits, with smaller limits on both sides.
  ReadLimits small;
  small.max_points = 1000;
  small.max_bytes = 1 << 14;
  EXPECT_THROW(WritePcd(path, Cloud(1001, 1), PcdEncoding::kBinary, small),
               core::FrameTooLargeError);
  WritePcd(path, Cloud(1000, 1), PcdEncoding::kBinary);
  EXPECT_THROW(ReadPcd(path, small), core::FrameTooLargeError);  // 20 kB of records > 16 KiB
  WritePcd(path, Cloud(500, 1), PcdEncoding::kBinary, small);
  EXPECT_EQ(ReadPcd(path, small).size(), 500u);
  // Ascii text is larger than the records it holds: refused when it would not read back.
  EXPECT_THROW(WritePcd(path, Cloud(800, 1), PcdEncoding::kAscii, small), core::FrameTooLargeError);
  WritePcd(path, Cloud(200, 1), PcdEncoding::kAscii, small);
  EXPECT_EQ(ReadPcd(path, small).size(), 200u);
}

TEST(ReadLimitsTest, PcdFileLargerThanTheLimitIsRefusedBeforeItIsRead) {
  const fs::path dir = testing::ScratchDir("limits_pcd_file");
  const std::string path = (dir / "big.pcd").string();
  WritePcd(path, Cloud(64, 48));
  ReadLimits small;
  small.max_bytes = 4096;
  try {
    (void)ReadPcd(path, small);
    ADD_FAILURE() << "read a file beyond the byte limit";
  } catch (const core::FrameTooLargeError& e) {
    EXPECT_NE(std::string(e.what()).find("exceeds the frame limit of 4096 bytes"),
              std::string::npos)
        << e.what();
  }
  const std::string bytes = ReadText(path);
  EXPECT_THROW(ReadPcdFromMemory(bytes.data(), bytes.size(), "memory", small),
               core::FrameTooLargeError);
}

// Write errors are reported, never silent: /dev/full fails every write with ENOSPC.
TEST(ReadLimitsTest, WritesToAFullDeviceFailNamingTheFile) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "/dev/full is not available";
  auto expect_failure = [](const std::function<void()>& write) {
    try {
      write();
      ADD_FAILURE() << "a write to /dev/full succeeded";
    } catch (const std::runtime_error& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind("/dev/full: ", 0), 0u) << msg;
      EXPECT_NE(msg.find("No space left on device"), std::string::npos) << msg;
    }
  };
  for (PcdEncoding e :
       {PcdEncoding::kAscii, PcdEncoding::kBinary, PcdEncoding::kBinaryCompressed}) {
    expect_failure([e] { WritePcd("/dev/full", Cloud(64, 48), e); });
  }
  expect_failure([] { WriteColorPng("/dev/full", core::ColorImage(64, 48)); });
  expect_failure([] { WriteDepthPng("/dev/full", core::DepthImage(64, 48, 5)); });
}

}  // namespace
}  // namespace clutterseg::io
