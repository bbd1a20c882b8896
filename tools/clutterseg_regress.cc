// clutterseg-regress A.lcmlog B.lcmlog [--centroid-tol-m 0.01] [--min-iou 0.9]
// Compares two recorded daemon runs frame by frame (paired by frame_seq): object counts,
// centroids (greedy nearest match) and label-mask IoU. Exit 0 within tolerance, 1 outside,
// 2 on a usage or read error.
#include <cstdio>
#include <exception>

#include <CLI/CLI.hpp>

#include "clutterseg/daemon/regress.h"
#include "clutterseg/version.h"

int main(int argc, char** argv) {
  clutterseg::daemon::RegressOptions options;
  std::string a, b;
  CLI::App app{"clutterseg-regress: compare two LCM logs of clutterseg runs"};
  app.add_option("A", a, "reference LCM log")->required();
  app.add_option("B", b, "LCM log to check")->required();
  app.add_option("--centroid-tol-m", options.centroid_tol_m,
                 "allowed centroid difference of matched objects, metres (default 0.01)");
  app.add_option("--min-iou", options.min_iou,
                 "minimum mean mask IoU of matched objects per frame (default 0.9)");
  app.add_option("--objects-channel", options.objects_channel, "objects_t channel");
  app.add_option("--labels-channel", options.labels_channel, "label_image_t channel");
  app.set_version_flag("--version", std::string("clutterseg-regress ") + clutterseg::kVersion);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    const auto report = clutterseg::daemon::CompareLogs(a, b, options);
    std::fputs(report.ToString(options).c_str(), stdout);
    return report.ok ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "clutterseg-regress: %s\n", e.what());
    return 2;
  }
}
