// libFuzzer target for LCM log files a user hands the tools and the daemon:
//  - clutterseg-regress (cdaemon::CompareLogs): liblcm's log reader, then every objects_t and
//    label_image_t through its bounds check and decode; the log compared with itself must
//    pair every frame with itself. Parses or throws std::runtime_error naming the file.
//  - the daemon's `--lcm-url file://LOG?mode=a` (cdaemon::LcmLogFile): an existing log is
//    scanned, a torn end cut off, and one event appended; the log must then verify whole
//    (Verify() == "") and scan complete with exactly one event more than the scan found. A
//    log damaged inside (a whole event after the bad bytes) is refused and left as it was.
// The input goes through a memfd (both read a path).

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "clutterseg/daemon/lcm_log_file.h"
#include "clutterseg/daemon/regress.h"
#include "tests/fuzz/fuzz_check.h"
#include "tests/fuzz/memfd_input.h"

namespace cdaemon = clutterseg::daemon;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = clutterseg::fuzz::MemfdPath(data, size);
  const cdaemon::RegressOptions options;
  clutterseg::fuzz::ReadOrRefuse(
      "CompareLogs", [&] { return cdaemon::CompareLogs(path, path, options); },
      [&](const cdaemon::RegressReport& report) {
        CLUTTERSEG_FUZZ_CHECK(report.only_in_a.empty() && report.only_in_b.empty());
        (void)report.ToString(options);
      });

  // Append to the log as the daemon does (this changes the memfd: last).
  const cdaemon::LcmLogScan before = cdaemon::ScanLcmLog(path);
  cdaemon::FileLogUrl url;
  url.path = path;
  url.append = true;
  try {
    cdaemon::LcmLogFile log(url);
    CLUTTERSEG_FUZZ_CHECK(log.events_before() == before.events);
    CLUTTERSEG_FUZZ_CHECK(log.Write("FUZZ", "event", 5));
    const std::string problem = log.Verify();
    if (!problem.empty()) {
      std::fprintf(stderr, "appended log does not verify: %s\n", problem.c_str());
      std::abort();
    }
  } catch (const std::runtime_error& e) {
    // The one refusal of a regular file: damage inside the log, which is left as it was.
    if (std::string(e.what()).find("is damaged inside") == std::string::npos) {
      std::fprintf(stderr, "LcmLogFile refused a regular file: %s\n", e.what());
      std::abort();
    }
    CLUTTERSEG_FUZZ_CHECK(!before.complete);
    const cdaemon::LcmLogScan unchanged = cdaemon::ScanLcmLog(path);
    CLUTTERSEG_FUZZ_CHECK(unchanged.file_bytes == size && unchanged.events == before.events);
    return 0;
  }
  const cdaemon::LcmLogScan after = cdaemon::ScanLcmLog(path);
  CLUTTERSEG_FUZZ_CHECK(after.complete);
  CLUTTERSEG_FUZZ_CHECK(after.events == before.events + 1);
  return 0;
}
