// clutterseg-eval as a process on hostile and mismatched files: a pair that cannot be scored
// is reported and left out, the others are still scored, and the exit code says so.

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/io/pcd.h"
#include "tests/testing/run_process.h"
#include "tests/testing/test_data.h"

namespace clutterseg::eval {
namespace {

namespace fs = std::filesystem;
using testing::ProcessResult;

// An organized w x h cloud labelled 1 on its left half, 2 on its right half.
core::PointCloud Labelled(int w, int h) {
  core::PointCloud c;
  c.width = w;
  c.height = h;
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      c.xyz.push_back(core::Vec3f{0.01f * u, 0.01f * v, 1.f});
      c.label.push_back(u < w / 2 ? 1u : 2u);
    }
  }
  return c;
}

std::string Name(const char* prefix, int i, const char* suffix) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%s%d%s", prefix, i, suffix);
  return buf;
}

ProcessResult Eval(std::vector<std::string> args) {
  args.insert(args.begin(), CLUTTERSEG_EVAL_TOOL);
  const ProcessResult r = testing::RunProcess(args, std::chrono::seconds(120));
  EXPECT_FALSE(r.timed_out) << "clutterseg-eval hung";
  return r;
}

// The same number of points in another image layout was scored point by point as if the
// images matched.
TEST(EvalTool, OrganizedCloudsOfAnotherLayoutAreRefused) {
  const fs::path dir = testing::ScratchDir("eval_tool_layout");
  io::WritePcd((dir / "gt.pcd").string(), Labelled(20, 10));
  io::WritePcd((dir / "pred.pcd").string(), Labelled(10, 20));
  const ProcessResult r = Eval({(dir / "gt.pcd").string(), (dir / "pred.pcd").string(), "-q"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("image layouts differ"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("20x10"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("10x20"), std::string::npos) << r.err;
}

// A ground truth or prediction that does not exist is an input that cannot be opened: exit 3,
// as for clutterseg-segment and the daemon (it was 1, the code of a data error).
TEST(EvalTool, MissingInputsExitThreeNamingThem) {
  const fs::path dir = testing::ScratchDir("eval_tool_missing");
  io::WritePcd((dir / "gt.pcd").string(), Labelled(20, 10));
  ProcessResult r = Eval({(dir / "none.pcd").string(), (dir / "gt.pcd").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("ground truth '" + (dir / "none.pcd").string() + "' not found"),
            std::string::npos)
      << r.err;
  r = Eval({(dir / "gt.pcd").string(), (dir / "none.pcd").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("prediction '" + (dir / "none.pcd").string() + "' not found"),
            std::string::npos)
      << r.err;
}

TEST(EvalTool, BadPairsAreReportedAndTheOthersScored) {
  const fs::path dir = testing::ScratchDir("eval_tool_dirs");
  fs::create_directories(dir / "gt");
  fs::create_directories(dir / "pred");
  for (int i = 0; i < 4; ++i) {
    io::WritePcd((dir / "gt" / Name("f", i, ".pcd")).string(), Labelled(20, 10));
    io::WritePcd((dir / "pred" / Name("f", i, ".pcd")).string(), Labelled(20, 10));
  }
  // f1: a truncated prediction; f2: a header declaring 10^10 points; f3 a point count apart.
  const fs::path f1 = dir / "pred" / "f1.pcd";
  std::ifstream in(f1, std::ios::binary);
  const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  in.close();
  std::ofstream(f1, std::ios::binary | std::ios::trunc) << bytes.substr(0, bytes.size() - 100);
  std::ofstream(dir / "gt" / "f2.pcd", std::ios::binary | std::ios::trunc)
      << "VERSION 0.7\nFIELDS x y z label\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
         "WIDTH 100000\nHEIGHT 100000\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 10000000000\n"
         "DATA binary\n";
  io::WritePcd((dir / "pred" / "f3.pcd").string(), Labelled(20, 11));
  const ProcessResult r = Eval({(dir / "gt").string(), (dir / "pred").string(), "-q"});
  EXPECT_EQ(r.exit_code, 5) << "one pair scored, three not: " << r.err;
  EXPECT_NE(r.err.find("cannot score 'f1.pcd'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("cannot score 'f2.pcd'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("exceed"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("cannot score 'f3.pcd'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("3 of 4 pair(s) could not be scored"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("\"failed\":3"), std::string::npos) << r.out;
  EXPECT_LT(r.max_rss_kib, 256 * 1024) << "KiB";
}

}  // namespace
}  // namespace clutterseg::eval
