// Writes the seed corpora of the fuzz targets (tests/fuzz/corpus/<target>/) with the
// project's own writers: tiny PCDs in each encoding, depth and colour PNGs, configuration
// texts, ONI recordings and segmenter frames. Usage: fuzz_make_seed_corpus <corpus_dir>.
// Regression inputs found by fuzzing live beside the seeds and are not touched.

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/types.h"
#include "clutterseg/daemon/daemon_config.h"
#include "clutterseg/drivers/oni/oni_writer.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/io/png_io.h"

namespace clutterseg::fuzz {
namespace {

namespace fs = std::filesystem;

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

void WriteBytes(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

// A tabletop in millimetres: a plane tilted away from the camera with a box on it.
core::DepthImage Tabletop(int width, int height) {
  core::DepthImage depth(width, height, 0);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      double z = 1400.0 - 600.0 * v / std::max(1, height - 1);
      if (u > width / 3 && u < 2 * width / 3 && v > height / 4 && v < height / 2) z -= 120.0;
      depth.at(u, v) = static_cast<uint16_t>(z);
    }
  }
  depth.at(0, 0) = 0;  // one invalid pixel
  return depth;
}

core::ColorImage Colors(int width, int height) {
  core::ColorImage color(width, height);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      color.at(u, v) = core::Rgb8{static_cast<uint8_t>(u * 40), static_cast<uint8_t>(v * 40),
                                  static_cast<uint8_t>(u * v)};
    }
  }
  return color;
}

void MakePcd(const fs::path& dir) {
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics().Scaled(4, 3);
  const core::DepthImage depth = Tabletop(4, 3);
  const core::ColorImage color = Colors(4, 3);
  core::PointCloud organized;
  core::DepthToPointCloud(depth, k, &color, &organized);
  organized.label.assign(organized.size(), 0);
  for (size_t i = 0; i < organized.size(); ++i) organized.label[i] = static_cast<uint32_t>(i % 3);
  core::PointCloud flat;
  flat.width = 5;
  flat.height = 1;
  for (int i = 0; i < 5; ++i) flat.xyz.push_back(core::Vec3f{0.1f * i, -0.2f, 1.f + 0.01f * i});
  const struct {
    const char* name;
    io::PcdEncoding encoding;
  } encodings[] = {{"ascii", io::PcdEncoding::kAscii},
                   {"binary", io::PcdEncoding::kBinary},
                   {"compressed", io::PcdEncoding::kBinaryCompressed}};
  for (const auto& e : encodings) {
    io::WritePcd((dir / (std::string("organized_") + e.name + ".pcd")).string(), organized,
                 e.encoding);
    io::WritePcd((dir / (std::string("unorganized_") + e.name + ".pcd")).string(), flat,
                 e.encoding);
  }
  // Hand-written headers for the layouts WritePcd does not produce: packed rgb, a label of
  // another size, an extra field with COUNT > 1, a v0.5-style header and an empty cloud.
  WriteText(dir / "rgb_u16label_ascii.pcd",
            "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb label\nSIZE 4 4 4 4 2\n"
            "TYPE F F F F U\nCOUNT 1 1 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
            "POINTS 2\nDATA ascii\n0.1 0.2 1.0 4.2108e+06 7\nnan nan nan 0 0\n");
  WriteText(dir / "extra_field_ascii.pcd",
            "VERSION .7\nFIELDS normal_x z y x intensity\nSIZE 4 4 4 4 4\nTYPE F F F F F\n"
            "COUNT 3 1 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n"
            "0 0 1 1.5 0.25 -0.5 9\n");
  WriteText(dir / "v05_ascii.pcd",
            "VERSION .5\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\n"
            "HEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n");
  WriteText(dir / "empty_binary.pcd",
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 0\n"
            "HEIGHT 1\nPOINTS 0\nDATA binary\n");
}

void MakePng(const fs::path& dir) {
  io::WriteDepthPng((dir / "depth_4x3.png").string(), Tabletop(4, 3));
  io::WriteDepthPng((dir / "depth_1x1.png").string(), core::DepthImage(1, 1, 65535));
  io::WriteColorPng((dir / "color_4x3.png").string(), Colors(4, 3));
}

void MakeConfig(const fs::path& dir) {
  WriteText(dir / "defaults.yaml", daemon::ConfigToYaml(daemon::DaemonConfig{}));
  WriteText(dir / "empty.yaml", "");
  WriteText(dir / "partial.yaml",
            "source: synthetic\nspeed: max\nprocessing:\n  threads: 2\n  max_frames: 10\n"
            "segmenter:\n  supervoxel:\n    voxel_resolution_m: 0.008\n");
  WriteText(dir / "flow.yaml", "{source: rec.oni, loop: true, lcm: {url: 'memq://'}}\n");
  WriteText(dir / "anchors.yaml", "base: &b {threads: 1}\nprocessing: *b\n");
}

void MakeOni(const fs::path& dir) {
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics().Scaled(8, 6);
  for (const bool with_color : {false, true}) {
    drivers::OniWriter writer;
    const fs::path path = dir / (with_color ? "rgbd_8x6.oni" : "depth_8x6.oni");
    writer.Open(path.string(), 8, 6, 30, k, with_color);
    const core::ColorImage color = Colors(8, 6);
    for (int f = 0; f < 2; ++f) {
      writer.WriteFrame(Tabletop(8, 6), with_color ? &color : nullptr, 33333 * f);
    }
    writer.Close();
  }
}

// Segmenter inputs: width-1 and height-1 as uint16 LE, a focal scale byte, then depths.
std::vector<uint8_t> SegmenterInput(const core::DepthImage& depth, uint8_t focal) {
  const int w = depth.width - 1;
  const int h = depth.height - 1;
  std::vector<uint8_t> bytes = {static_cast<uint8_t>(w & 0xff), static_cast<uint8_t>(w >> 8),
                                static_cast<uint8_t>(h & 0xff), static_cast<uint8_t>(h >> 8),
                                focal};
  for (const uint16_t d : depth.data) {
    bytes.push_back(static_cast<uint8_t>(d & 0xff));
    bytes.push_back(static_cast<uint8_t>(d >> 8));
  }
  return bytes;
}

void MakeSegmenter(const fs::path& dir) {
  WriteBytes(dir / "tabletop_40x30.bin", SegmenterInput(Tabletop(40, 30), 48));
  WriteBytes(dir / "tabletop_80x60.bin", SegmenterInput(Tabletop(80, 60), 48));
  WriteBytes(dir / "invalid_16x12.bin", SegmenterInput(core::DepthImage(16, 12, 0), 48));
  WriteBytes(dir / "wall_32x24.bin", SegmenterInput(core::DepthImage(32, 24, 900), 48));
  WriteBytes(dir / "far_8x8.bin", SegmenterInput(core::DepthImage(8, 8, 65535), 48));
}

}  // namespace
}  // namespace clutterseg::fuzz

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <corpus_dir>\n", argv[0]);
    return 2;
  }
  try {
    const fs::path root(argv[1]);
    const struct {
      const char* target;
      void (*make)(const fs::path&);
    } targets[] = {{"pcd_reader", clutterseg::fuzz::MakePcd},
                   {"depth_png", clutterseg::fuzz::MakePng},
                   {"config_parser", clutterseg::fuzz::MakeConfig},
                   {"oni_reader", clutterseg::fuzz::MakeOni},
                   {"segmenter", clutterseg::fuzz::MakeSegmenter}};
    for (const auto& t : targets) {
      fs::create_directories(root / t.target);
      t.make(root / t.target);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
