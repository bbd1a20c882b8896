#include "clutterseg/config/key_table.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <sys/stat.h>

#include "clutterseg/config/segmenter_keys.h"
#include "tests/testing/test_data.h"

namespace clutterseg::config {
namespace {

namespace fs = std::filesystem;

// The message of the ConfigError thrown by `fn`, or "" when nothing was thrown.
template <typename Fn>
std::string ErrorOf(Fn fn) {
  try {
    fn();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

struct Sample {
  int a{1};
  double b{2.0};
  std::string name{"x"};
};

KeyTable<Sample> SampleTable() {
  return KeyTable<Sample>({MakeKey("section.a", &Sample::a), MakeKey("section.b", &Sample::b),
                           MakeKey("name", &Sample::name)});
}

std::string ParseError(const std::string& yaml) {
  Sample s;
  return ErrorOf([&] { SampleTable().ParseYaml(yaml, "t.yaml", &s); });
}

fs::path TempDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("clutterseg_key_table_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

TEST(KeyTable, ParsesNestedKeysAndKeepsDefaults) {
  Sample s;
  SampleTable().ParseYaml("section:\n  a: 7\n", "t.yaml", &s);
  EXPECT_EQ(s.a, 7);
  EXPECT_EQ(s.b, 2.0);
  EXPECT_EQ(s.name, "x");
  EXPECT_EQ(SampleTable().Get("section.a", s), "7");
  EXPECT_EQ(SampleTable().ToYaml(s), "section:\n  a: 7\n  b: 2.0\nname: x\n");
}

TEST(KeyTable, DuplicateKeysAreErrors) {
  std::string e = ParseError("section:\n  a: 1\n  a: 2\n");
  EXPECT_NE(e.find("t.yaml:3"), std::string::npos) << e;
  EXPECT_NE(e.find("'section.a' appears twice"), std::string::npos) << e;
  e = ParseError("section:\n  a: 1\nsection:\n  b: 3\n");
  EXPECT_NE(e.find("'section' appears twice"), std::string::npos) << e;
}

TEST(KeyTable, ASecondDocumentIsAnError) {
  const std::string e = ParseError("name: a\n---\nname: b\n");
  EXPECT_NE(e.find("second YAML document"), std::string::npos) << e;
}

// yaml-cpp 0.7's LoadAll never returns on this text (found by the camera_calibration fuzz
// target); the documents are counted two at the most, so it is refused at once.
TEST(KeyTable, TextOnWhichYamlCppsLoadAllNeverEndsIsRefused) {
  const std::string e = ParseError(",\"kmg_height\":481,\"fx\":1e6fsoft\":248.1}\n");
  EXPECT_NE(e.find("second YAML document"), std::string::npos) << e;
  EXPECT_EQ(internal::SecondYamlDocumentLine("a: 1\n---\nb: 2\n"), 2);
  EXPECT_EQ(internal::SecondYamlDocumentLine("a: 1\n"), 0);
  EXPECT_EQ(internal::SecondYamlDocumentLine(""), 0);
}

TEST(KeyTable, UnknownKeysGetASuggestion) {
  std::string e = ParseError("a: 1\n");
  EXPECT_NE(e.find("unknown key 'a'"), std::string::npos) << e;
  EXPECT_NE(e.find("did you mean 'section.a'"), std::string::npos) << e;
  e = ParseError("section:\n  c: 1\n");
  EXPECT_NE(e.find("keys of 'section': a, b"), std::string::npos) << e;
}

TEST(KeyTable, OnlySectionIgnoresTheOthers) {
  Sample s;
  SampleTable().ParseYaml("other:\n  whatever: [1, 2]\nsection:\n  a: 5\n", "t.yaml", &s,
                          "section");
  EXPECT_EQ(s.a, 5);
  EXPECT_NE(ParseError("other: 1\n").find("unknown key 'other'"), std::string::npos);
}

TEST(KeyTable, FilesMustBeRegularAndSmall) {
  const fs::path dir = TempDir("files");
  Sample s;
  // A directory.
  std::string e = ErrorOf([&] { SampleTable().LoadYaml(dir.string(), &s); });
  EXPECT_NE(e.find("is a directory"), std::string::npos) << e;
  // A FIFO with no writer: refused at once, never a blocking open.
  const fs::path fifo = dir / "fifo.yaml";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  e = ErrorOf([&] { SampleTable().LoadYaml(fifo.string(), &s); });
  EXPECT_NE(e.find("not a regular file"), std::string::npos) << e;
  // Missing.
  e = ErrorOf([&] { SampleTable().LoadYaml((dir / "missing.yaml").string(), &s); });
  EXPECT_NE(e.find("cannot open"), std::string::npos) << e;
  // Too large.
  const fs::path big = dir / "big.yaml";
  {
    std::ofstream out(big);
    out << "name: \"" << std::string((1 << 20) + 10, 'x') << "\"\n";
  }
  e = ErrorOf([&] { SampleTable().LoadYaml(big.string(), &s); });
  EXPECT_NE(e.find("1 MiB"), std::string::npos) << e;
  // A good file.
  const fs::path good = dir / "good.yaml";
  std::ofstream(good) << "section:\n  b: 0.5\n";
  SampleTable().LoadYaml(good.string(), &s);
  EXPECT_EQ(s.b, 0.5);
  fs::remove_all(dir);
}

TEST(KeyTable, OverridesNameTheCommandLine) {
  Sample s;
  SampleTable().ApplyOverride("section.a=3", &s);
  EXPECT_EQ(s.a, 3);
  std::string e = ErrorOf([&] { SampleTable().ApplyOverride("section.a=x", &s); });
  EXPECT_NE(e.find("command line: key 'section.a'"), std::string::npos) << e;
  EXPECT_NE(e.find("'x'"), std::string::npos) << e;
  e = ErrorOf([&] { SampleTable().ApplyOverride("section.a", &s); });
  EXPECT_NE(e.find("key=value"), std::string::npos) << e;
}

TEST(SegmenterKeys, LoadTheSegmenterSectionOfADaemonFile) {
  // clutterseg-segment and the bench read the daemon's file for its segmenter section only.
  const std::string path = std::string(CLUTTERSEG_SOURCE_DIR) + "/config/paper.yaml";
  pipeline::SegmenterParams p;
  LoadSegmenterParams(path, &p);
  EXPECT_EQ(p.linkage.concavity_tolerance_deg, 10.f);
  EXPECT_EQ(p.supervoxel.growth_regions, 1);
  ApplySegmenterOverride("supervoxel.voxel_resolution_m=0.01", &p);
  ApplySegmenterOverride("segmenter.points.max_depth_m=2.5", &p);
  EXPECT_EQ(p.supervoxel.grid.voxel_resolution_m, 0.01f);
  EXPECT_EQ(p.points.max_depth_m, 2.5f);
  const std::string e = ErrorOf([&] { ApplySegmenterOverride("supervoxel.voxel_res=1", &p); });
  EXPECT_NE(e.find("keys of 'segmenter.supervoxel': voxel_resolution_m"), std::string::npos) << e;
}

TEST(SegmenterKeys, PaperConfigurationTurnsOffEveryAdditionToThePaper) {
  // The measured additions of docs/method.md are on by default and off in config/paper.yaml,
  // which keeps reproducing the paper.
  const pipeline::SegmenterParams defaults;
  EXPECT_EQ(defaults.supervoxel.normal_importance, 6.f);
  EXPECT_EQ(defaults.linkage.sanity_min_angle_deg, 20.f);
  EXPECT_GT(defaults.linkage.depth_jump_rel, 0.f);
  EXPECT_LT(defaults.objects.plane_merge_max_pair_angle_deg, 180.f);
  EXPECT_GT(defaults.objects.support_release_fraction, 0.f);
  EXPECT_GT(defaults.objects.support_reclaim_passes, 0);
  EXPECT_TRUE(defaults.objects.merge_small_groups);
  EXPECT_GT(defaults.linkage.color_threshold, 0.f);
  EXPECT_EQ(defaults.linkage.color_concavity_tolerance_deg, 0.f);  // measured, not kept
  EXPECT_GT(defaults.linkage.bridge_max_edges, 0);
  EXPECT_TRUE(defaults.temporal.enabled);
  pipeline::SegmenterParams p;
  LoadSegmenterParams(std::string(CLUTTERSEG_SOURCE_DIR) + "/config/paper.yaml", &p);
  EXPECT_EQ(p.supervoxel.normal_importance, 4.f);
  EXPECT_EQ(p.linkage.sanity_min_angle_deg, 0.f);
  EXPECT_EQ(p.linkage.depth_jump_rel, 0.f);
  EXPECT_EQ(p.linkage.crease_min_angle_deg, 0.f);
  EXPECT_EQ(p.linkage.color_threshold, 0.f);
  EXPECT_EQ(p.linkage.color_concavity_tolerance_deg, 0.f);
  EXPECT_EQ(p.linkage.bridge_max_edges, 0);
  EXPECT_EQ(p.objects.plane_merge_max_pair_angle_deg, 180.f);
  EXPECT_EQ(p.objects.support_release_fraction, 0.f);
  EXPECT_EQ(p.objects.support_reclaim_passes, 0);
  EXPECT_FALSE(p.objects.merge_small_groups);
  EXPECT_FALSE(p.temporal.enabled);  // the paper segments each frame on its own
  // config/previous-defaults.yaml: the same additions off, everything else the defaults.
  pipeline::SegmenterParams q;
  LoadSegmenterParams(std::string(CLUTTERSEG_SOURCE_DIR) + "/config/previous-defaults.yaml", &q);
  EXPECT_EQ(q.supervoxel.normal_importance, 4.f);
  EXPECT_EQ(q.linkage.sanity_min_angle_deg, 0.f);
  EXPECT_EQ(q.linkage.depth_jump_rel, 0.f);
  EXPECT_EQ(q.objects.plane_merge_max_pair_angle_deg, 180.f);
  EXPECT_EQ(q.objects.support_release_fraction, 0.f);
  EXPECT_EQ(q.objects.support_reclaim_passes, 0);
  EXPECT_FALSE(q.objects.merge_small_groups);
  EXPECT_EQ(q.linkage.color_threshold, 0.f);
  EXPECT_EQ(q.linkage.color_concavity_tolerance_deg, 0.f);
  EXPECT_EQ(q.linkage.bridge_max_edges, 0);
  EXPECT_EQ(q.linkage.concavity_tolerance_deg, defaults.linkage.concavity_tolerance_deg);
  EXPECT_EQ(q.supervoxel.growth_regions, defaults.supervoxel.growth_regions);
  EXPECT_EQ(q.planes.inlier_distance_m, defaults.planes.inlier_distance_m);
}

TEST(SegmenterKeys, ValidationMessagesNameTheYamlKey) {
  pipeline::SegmenterParams p;
  p.supervoxel.grid.voxel_resolution_m = 2.f;
  try {
    p.ValidateOrThrow();
    FAIL() << "accepted a 2 m voxel";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("segmenter.supervoxel.voxel_resolution_m = 2 is invalid"),
              std::string::npos)
        << e.what();
    // The key it names is one the table accepts.
    pipeline::SegmenterParams q;
    EXPECT_NO_THROW(
        SegmenterKeyTable().Set("segmenter.supervoxel.voxel_resolution_m", "0.01", "test", &q));
  }
  p = {};
  p.planes.refit_iterations = 1 << 30;
  EXPECT_THROW(p.ValidateOrThrow(), std::invalid_argument) << "iteration counts are bounded";
}

// The key table is written by hand; this catches a parameter added to a params struct
// without its line in src/config/segmenter_keys.cc.
TEST(SegmenterKeys, CoverEveryFieldOfTheParamsStructs) {
  struct Source {
    const char* file;
    const char* struct_name;
    const char* section;
  };
  const Source sources[] = {
      {"src/pipeline/working_cloud.h", "PointsParams", "points"},
      {"src/geometry/voxel_grid.h", "VoxelGridParams", "supervoxel"},
      {"src/supervoxel/supervoxel_params.h", "SupervoxelParams", "supervoxel"},
      {"src/graph/linkage_params.h", "LinkageParams", "linkage"},
      {"src/optimize/plane_params.h", "PlaneParams", "planes"},
      {"src/pipeline/segmenter_params.h", "ObjectParams", "objects"},
  };
  const std::vector<std::string>& all = SegmenterKeyTable().paths();
  const std::set<std::string> keys(all.begin(), all.end());
  const std::regex field(R"(^\s*(bool|int|float|double|int32_t|int64_t|uint32_t)\s+(\w+)\s*\{)");
  for (const Source& src : sources) {
    std::ifstream in(std::string(CLUTTERSEG_SOURCE_DIR) + "/" + src.file);
    ASSERT_TRUE(in) << src.file;
    bool inside = false;
    int fields = 0;
    for (std::string line; std::getline(in, line);) {
      if (line.find(std::string("struct ") + src.struct_name + " {") != std::string::npos) {
        inside = true;
      } else if (inside && line.rfind("};", 0) == 0) {
        break;
      } else if (std::smatch m; inside && std::regex_search(line, m, field)) {
        ++fields;
        const std::string key = std::string("segmenter.") + src.section + "." + m[2].str();
        EXPECT_TRUE(keys.count(key))
            << key << " (" << src.file << ") has no line in src/config/segmenter_keys.cc";
      }
    }
    EXPECT_GT(fields, 0) << "no field found in " << src.struct_name;
  }
}

}  // namespace
}  // namespace clutterseg::config
