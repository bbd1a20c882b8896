// libFuzzer target for the segmenter configuration a user hands clutterseg-segment (--config)
// and the Python binding (Segmenter(config=...)): config::LoadSegmenterParams reads the
// `segmenter:` section of a YAML file (through a memfd). It either fills parameters or throws
// config::ConfigError naming the file and key; the parameters then either validate or
// SegmenterParams::ValidateOrThrow throws std::invalid_argument naming the key (as both
// callers do next). Anything else (another exception, a crash, a sanitizer report, a hang) is
// a finding.

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "clutterseg/config/key_table.h"
#include "clutterseg/config/segmenter_keys.h"
#include "clutterseg/pipeline/segmenter_params.h"
#include "tests/fuzz/fuzz_check.h"
#include "tests/fuzz/memfd_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = clutterseg::fuzz::MemfdPath(data, size);
  clutterseg::fuzz::ReadOrRefuse<clutterseg::config::ConfigError>(
      "LoadSegmenterParams",
      [&] {
        clutterseg::pipeline::SegmenterParams params;
        clutterseg::config::LoadSegmenterParams(path, &params);
        return params;
      },
      [](const clutterseg::pipeline::SegmenterParams& params) {
        clutterseg::fuzz::ReadOrRefuse<std::invalid_argument>(
            "SegmenterParams::ValidateOrThrow",
            [&] {
              params.ValidateOrThrow();
              return 0;
            },
            [](int) {});
      });
  return 0;
}
