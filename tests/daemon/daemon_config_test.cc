#include "clutterseg/daemon/daemon_config.h"

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

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

std::string ParseError(const std::string& yaml) {
  return ErrorOf([&] { ParseConfig(yaml, "test.yaml"); });
}

bool IsNumber(const std::string& s) {
  if (s.empty()) return false;
  char* end = nullptr;
  std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size();
}

bool IsReal(const std::string& s) {
  return IsNumber(s) && s.find_first_of(".eE") != std::string::npos;
}

// "a.b.c" + "v" -> "a:\n  b:\n    c: v\n"
std::string NestedYaml(const std::string& path, const std::string& value) {
  std::stringstream ss(path);
  std::string out;
  std::vector<std::string> parts;
  for (std::string p; std::getline(ss, p, '.');) parts.push_back(p);
  for (size_t i = 0; i < parts.size(); ++i) {
    out += std::string(2 * i, ' ') + parts[i] + ":" + (i + 1 == parts.size() ? " " + value : "") +
           "\n";
  }
  return out;
}

TEST(DaemonConfig, EmptyDocumentGivesDefaults) {
  const DaemonConfig dut = ParseConfig("", "empty.yaml");
  EXPECT_EQ(ConfigToYaml(dut), ConfigToYaml(DaemonConfig{}));
  EXPECT_EQ(dut.lcm.url, "") << "empty: LCM_DEFAULT_URL, else LCM's default";
  EXPECT_EQ(dut.lcm.objects_channel, "CLUTTERSEG_OBJECTS");
  EXPECT_EQ(dut.lcm.labels_channel, "CLUTTERSEG_LABELS");
  EXPECT_EQ(dut.lcm.status_channel, "CLUTTERSEG_STATUS");
}

TEST(DaemonConfig, ShippedFileDocumentsEveryKeyWithItsDefault) {
  const std::string path = std::string(CLUTTERSEG_SOURCE_DIR) + "/config/clutterseg.yaml";
  const DaemonConfig dut = LoadConfig(path);
  EXPECT_EQ(ConfigToYaml(dut), ConfigToYaml(DaemonConfig{}));
  const YAML::Node root = YAML::LoadFile(path);
  for (const std::string& key : ConfigKeys()) {
    std::stringstream ss(key);
    YAML::Node node = YAML::Clone(root);
    for (std::string part; std::getline(ss, part, '.');) {
      ASSERT_TRUE(node.IsMap()) << key;
      node = node[part];
      ASSERT_TRUE(node.IsDefined()) << "config/clutterseg.yaml lacks key " << key;
    }
    EXPECT_TRUE(node.IsScalar()) << key;
  }
}

TEST(DaemonConfig, EveryKeyIsParsedFromYaml) {
  const DaemonConfig defaults;
  for (const std::string& key : ConfigKeys()) {
    const std::string def = GetKey(key, defaults);
    std::vector<std::string> candidates;
    if (def == "true" || def == "false") {
      candidates = {def == "true" ? "false" : "true"};
    } else if (key == "speed") {
      candidates = {"max"};
    } else if (key == "log.level") {
      candidates = {"debug"};
    } else if (key == "lcm.label_compression") {
      candidates = {"rle", "none"};
    } else if (IsReal(def)) {
      const double v = std::stod(def);
      for (double c : {v * 2, v * 1.5, v * 0.5, v + 1, v + 0.5, v + 0.01, 0.5, 1.0, 2.0}) {
        std::ostringstream os;
        os << c;
        candidates.push_back(os.str());
      }
    } else if (IsNumber(def)) {
      const long long v = std::stoll(def);
      for (long long c : {v + 1, v * 2, v + 5, v - 1}) candidates.push_back(std::to_string(c));
    } else {
      candidates = {"changed_value"};
    }
    bool parsed = false;
    for (const std::string& value : candidates) {
      try {
        const DaemonConfig dut = ParseConfig(NestedYaml(key, value), "keys.yaml");
        const std::string got = GetKey(key, dut);
        if (got == def) continue;
        if (IsReal(def)) {
          EXPECT_NEAR(std::stod(got), std::stod(value), 1e-6 * std::max(1.0, std::stod(value)))
              << key;
        } else {
          EXPECT_EQ(got, value) << key;
        }
        // Everything else keeps its default.
        for (const std::string& other : ConfigKeys()) {
          if (other != key) {
            EXPECT_EQ(GetKey(other, dut), GetKey(other, defaults)) << other;
          }
        }
        parsed = true;
        break;
      } catch (const ConfigError&) {
        // Out of range for this key: try the next candidate.
      }
    }
    EXPECT_TRUE(parsed) << "no non-default value of '" << key << "' was accepted";
  }
}

TEST(DaemonConfig, RoundTripsThroughYaml) {
  DaemonConfig dut;
  dut.source = "/data/run 1.oni";
  dut.capture.speed = Speed::kMax;
  dut.lcm.url = "file:///tmp/x.lcmlog?mode=w";
  dut.capture.queue_capacity = 7;
  dut.segmenter.supervoxel.grid.voxel_resolution_m = 0.011f;
  dut.segmenter.planes.max_planes = 3;
  const DaemonConfig back = ParseConfig(ConfigToYaml(dut), "roundtrip.yaml");
  EXPECT_EQ(ConfigToYaml(back), ConfigToYaml(dut));
  EXPECT_EQ(back.source, "/data/run 1.oni");
  EXPECT_FLOAT_EQ(back.segmenter.supervoxel.grid.voxel_resolution_m, 0.011f);
}

TEST(DaemonConfig, UnknownKeysAreNamedWithFileAndLine) {
  std::string e = ParseError("source: device\nthreads: 2\n");
  EXPECT_NE(e.find("test.yaml:2"), std::string::npos) << e;
  EXPECT_NE(e.find("unknown key 'threads'"), std::string::npos) << e;
  EXPECT_NE(e.find("processing.threads"), std::string::npos) << "a hint: " << e;

  e = ParseError("segmenter:\n  planes:\n    max_plane: 3\n");
  EXPECT_NE(e.find("test.yaml:3"), std::string::npos) << e;
  EXPECT_NE(e.find("'segmenter.planes.max_plane'"), std::string::npos) << e;
  EXPECT_NE(e.find("max_planes"), std::string::npos) << "lists the section's keys: " << e;

  e = ParseError("segmenter:\n  bogus_section:\n    x: 1\n");
  EXPECT_NE(e.find("'segmenter.bogus_section'"), std::string::npos) << e;
}

TEST(DaemonConfig, WrongTypesAreNamedWithTheValue) {
  std::string e = ParseError("processing:\n  threads: many\n");
  EXPECT_NE(e.find("test.yaml:2"), std::string::npos) << e;
  EXPECT_NE(e.find("'processing.threads'"), std::string::npos) << e;
  EXPECT_NE(e.find("'many'"), std::string::npos) << e;
  EXPECT_NE(e.find("integer"), std::string::npos) << e;

  e = ParseError("processing:\n  pipeline_depth: 1.5\n");
  EXPECT_NE(e.find("'processing.pipeline_depth'"), std::string::npos) << e;
  EXPECT_NE(e.find("'1.5'"), std::string::npos) << e;

  e = ParseError("loop: maybe\n");
  EXPECT_NE(e.find("'loop'"), std::string::npos) << e;
  EXPECT_NE(e.find("boolean"), std::string::npos) << e;

  e = ParseError("speed: fast\n");
  EXPECT_NE(e.find("'speed'"), std::string::npos) << e;
  EXPECT_NE(e.find("realtime|max"), std::string::npos) << e;

  e = ParseError("segmenter:\n  supervoxel:\n    voxel_resolution_m: 1cm\n");
  EXPECT_NE(e.find("'segmenter.supervoxel.voxel_resolution_m'"), std::string::npos) << e;
  EXPECT_NE(e.find("'1cm'"), std::string::npos) << e;

  e = ParseError("segmenter:\n  supervoxel:\n    voxel_resolution_m: [1, 2]\n");
  EXPECT_NE(e.find("'segmenter.supervoxel.voxel_resolution_m'"), std::string::npos) << e;
  EXPECT_NE(e.find("list"), std::string::npos) << e;

  e = ParseError("lcm: memq://\n");
  EXPECT_NE(e.find("'lcm' is a section"), std::string::npos) << e;

  e = ParseError("processing:\n  threads:\n");
  EXPECT_NE(e.find("'processing.threads' has no value"), std::string::npos) << e;

  e = ParseError("processing:\n  max_frames: 99999999999999999999999\n");
  EXPECT_NE(e.find("'processing.max_frames'"), std::string::npos) << e;
}

TEST(DaemonConfig, OutOfRangeValuesAreNamed) {
  std::string e = ParseError("processing:\n  queue_capacity: 0\n");
  EXPECT_NE(e.find("test.yaml"), std::string::npos) << e;
  EXPECT_NE(e.find("processing.queue_capacity"), std::string::npos) << e;
  EXPECT_NE(e.find("= 0"), std::string::npos) << e;

  e = ParseError("reconnect:\n  backoff_min_s: 2.0\n  backoff_max_s: 1.0\n");
  EXPECT_NE(e.find("reconnect.backoff_max_s"), std::string::npos) << e;

  e = ParseError("segmenter:\n  objects:\n    min_object_points: 0\n");
  EXPECT_NE(e.find("test.yaml"), std::string::npos) << e;
  EXPECT_NE(e.find("min_object_points"), std::string::npos) << e;
  EXPECT_NE(e.find('0'), std::string::npos) << e;

  // A camera name LCM cannot carry whole (a control character): every message was refused at
  // publish, exit 5 after the run, until the hostile campaign.
  e = ParseError("camera_name: \"arm\\x01left\"\n");
  EXPECT_NE(e.find("camera_name"), std::string::npos) << e;
  EXPECT_NE(e.find("control character at byte 3"), std::string::npos) << e;

  // 99 belongs to the kernel's own threads; the capture path runs at the value + 1.
  e = ParseError("processing:\n  realtime_priority: 99\n");
  EXPECT_NE(e.find("processing.realtime_priority"), std::string::npos) << e;
  EXPECT_NE(e.find("= 99"), std::string::npos) << e;

  e = ParseError("status:\n  period_s: nan\n");
  EXPECT_NE(e.find("status.period_s"), std::string::npos) << e;

  // Channel names within LCM's limit (63 bytes, no spaces), one per message type.
  e = ParseError("lcm:\n  objects_channel: " + std::string(64, 'X') + "\n");
  EXPECT_NE(e.find("lcm.objects_channel"), std::string::npos) << e;
  EXPECT_NE(e.find("63"), std::string::npos) << e;
  e = ParseError("lcm:\n  status_channel: \"MY STATUS\"\n");
  EXPECT_NE(e.find("lcm.status_channel"), std::string::npos) << e;
  e = ParseError("lcm:\n  labels_channel: CLUTTERSEG_OBJECTS\n");
  EXPECT_NE(e.find("lcm.labels_channel"), std::string::npos) << e;
  EXPECT_NE(e.find("other than lcm.objects_channel"), std::string::npos) << e;
  EXPECT_EQ(ParseError("lcm:\n  objects_channel: " + std::string(63, 'X') + "\n"), "");
}

TEST(DaemonConfig, SyntaxErrorsAndMissingFilesNameTheFile) {
  std::string e = ParseError("lcm:\n  url: [unclosed\n");
  EXPECT_NE(e.find("test.yaml:"), std::string::npos) << e;
  EXPECT_NE(e.find("YAML syntax error"), std::string::npos) << e;

  e = ParseError("- a\n- b\n");
  EXPECT_NE(e.find("expected a map"), std::string::npos) << e;

  const std::string missing = (testing::ScratchDir("config_missing") / "nope.yaml").string();
  e = ErrorOf([&] { LoadConfig(missing); });
  EXPECT_NE(e.find(missing), std::string::npos) << e;
  EXPECT_NE(e.find("cannot open"), std::string::npos) << e;
}

TEST(DaemonConfig, LoadsAFile) {
  const auto path = testing::ScratchDir("config_load") / "daemon.yaml";
  std::ofstream(path) << "source: /data/a.oni\nspeed: max\nlcm:\n  url: memq://\n"
                         "segmenter:\n  planes:\n    max_planes: 2\n";
  const DaemonConfig dut = LoadConfig(path.string());
  EXPECT_EQ(dut.source, "/data/a.oni");
  EXPECT_EQ(dut.capture.speed, Speed::kMax);
  EXPECT_EQ(dut.lcm.url, "memq://");
  EXPECT_EQ(dut.segmenter.planes.max_planes, 2);

  std::ofstream(path) << "processing:\n  queue_capacity: -3\n";
  const std::string e = ErrorOf([&] { LoadConfig(path.string()); });
  EXPECT_NE(e.find(path.string()), std::string::npos) << e;
  EXPECT_NE(e.find("processing.queue_capacity"), std::string::npos) << e;
  EXPECT_NE(e.find("-3"), std::string::npos) << e;
}

TEST(DaemonConfig, CommandLineOverrides) {
  DaemonConfig dut;
  ApplyOverride("processing.threads=3", &dut);
  ApplyOverride("segmenter.linkage.use_type_filter=false", &dut);
  ApplyOverride("lcm.url=file:///tmp/a.lcmlog?mode=w", &dut);  // '=' inside the value
  EXPECT_EQ(dut.processing.threads, 3);
  EXPECT_FALSE(dut.segmenter.linkage.use_type_filter);
  EXPECT_EQ(dut.lcm.url, "file:///tmp/a.lcmlog?mode=w");

  std::string e = ErrorOf([&] { ApplyOverride("processing.thread=3", &dut); });
  EXPECT_NE(e.find("command line"), std::string::npos) << e;
  EXPECT_NE(e.find("'processing.thread'"), std::string::npos) << e;
  e = ErrorOf([&] { ApplyOverride("processing.threads=x", &dut); });
  EXPECT_NE(e.find("'x'"), std::string::npos) << e;
  e = ErrorOf([&] { ApplyOverride("threads", &dut); });
  EXPECT_NE(e.find("key=value"), std::string::npos) << e;
}

}  // namespace
}  // namespace clutterseg::daemon
