// libFuzzer target for the daemon's YAML configuration parser: any text either parses into a
// valid configuration or throws config::ConfigError (any other exception is a finding). A
// parsed configuration must survive a round trip through ConfigToYaml unchanged.

#include <cstddef>
#include <cstdint>
#include <string>

#include "clutterseg/daemon/daemon_config.h"
#include "tests/fuzz/fuzz_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  clutterseg::daemon::DaemonConfig config;
  try {
    config = clutterseg::daemon::ParseConfig(text, "fuzz.yaml");
  } catch (const clutterseg::config::ConfigError&) {
    return 0;
  }
  config.ValidateOrThrow();  // ParseConfig validated it: throwing here is a finding.
  const std::string yaml = clutterseg::daemon::ConfigToYaml(config);
  clutterseg::daemon::DaemonConfig again;
  try {
    again = clutterseg::daemon::ParseConfig(yaml, "round-trip.yaml");
  } catch (const clutterseg::config::ConfigError& e) {
    std::fprintf(stderr, "round trip failed: %s\n--- yaml ---\n%s\n", e.what(), yaml.c_str());
    std::abort();
  }
  CLUTTERSEG_FUZZ_CHECK(clutterseg::daemon::ConfigToYaml(again) == yaml);
  return 0;
}
