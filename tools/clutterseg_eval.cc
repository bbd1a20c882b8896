// clutterseg-eval: scores predicted segmentations against ground truth (METHOD.md section 7).
//
//   clutterseg-eval GT PRED [--gt-convention plain|mosd-parts|mosd-objects|ocid]
//                   [--ocid-background 0,1,2] [--coverage-percent 10] [--csv FILE]
//                   [--allow-missing] [--quiet]
//
// GT and PRED are two PCD files with a label field (points matched by index), or two
// directories whose *.pcd files are matched by name. stdout: a per-frame table and a summary
// (unless --quiet), then, as the last line, one JSON object. Besides WOv, precision and recall
// it says where the overlap is lost (loss_merged, loss_split, loss_boundary, loss_background,
// adding up to 1 - WOv; eval/metrics.h defines them). A pair that cannot be scored (a
// file that cannot be read, no label field, different point counts or image layouts) is
// reported on stderr and left out; the others are still scored, the JSON line then carries
// "failed": N and the exit code is 5. Exit codes (core/exit_codes.h): 0 ok, 5 some pairs
// could not be scored (the others were), 1 I/O or data error (no pair could be scored), 2 bad
// command line.

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/eval/metrics.h"
#include "clutterseg/eval/report.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/version.h"

namespace fs = std::filesystem;

namespace clutterseg::eval {
namespace {

constexpr int kExitOk = 0;
constexpr int kExitUsage = 2;             // I/O and data errors (1) are reported by main()
constexpr int kExitIncomplete = 5;        // some pairs could not be scored (core/exit_codes.h)
constexpr int kExitInputUnavailable = 3;  // GT or PRED does not exist (core/exit_codes.h)

// GT or PRED cannot be opened: exit 3, as for every tool whose input is missing.
struct InputUnavailable : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A command-line problem found after parsing (exit code 2).
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Options {
  std::string gt_path;
  std::string pred_path;
  std::string convention{"plain"};
  std::vector<uint32_t> ocid_background{0, 1, 2};
  int coverage_percent{10};
  std::string csv_path;
  bool allow_missing{false};
  bool quiet{false};
};

struct FramePair {
  std::string name;
  fs::path gt;
  fs::path pred;
  bool missing{false};
};

// Progress bar on stderr, drawn only when wanted and stderr is a terminal.
class Progress {
 public:
  Progress(size_t total, bool wanted)
      : total_(total), enabled_(wanted && isatty(STDERR_FILENO) == 1) {}
  ~Progress() { Clear(); }
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void Show(size_t done, const std::string& name) {
    if (!enabled_) return;
    constexpr int kWidth = 30;
    const int filled = total_ == 0 ? kWidth : static_cast<int>(kWidth * done / total_);
    std::string bar(static_cast<size_t>(filled), '#');
    bar.resize(kWidth, '.');
    std::fprintf(stderr, "\r\033[K[%s] %zu/%zu %s", bar.c_str(), done, total_, name.c_str());
    std::fflush(stderr);
    drawn_ = true;
  }
  void Clear() {
    if (!enabled_ || !drawn_) return;
    std::fprintf(stderr, "\r\033[K");
    std::fflush(stderr);
    drawn_ = false;
  }

 private:
  size_t total_;
  bool enabled_;
  bool drawn_{false};
};

std::vector<FramePair> ListPairs(const Options& opt) {
  const fs::path gt(opt.gt_path);
  const fs::path pred(opt.pred_path);
  std::error_code ec;
  if (!fs::exists(gt, ec)) throw InputUnavailable("ground truth '" + gt.string() + "' not found");
  if (!fs::exists(pred, ec)) {
    throw InputUnavailable("prediction '" + pred.string() + "' not found");
  }
  const bool gt_dir = fs::is_directory(gt);
  const bool pred_dir = fs::is_directory(pred);
  if (gt_dir != pred_dir) {
    throw UsageError("GT and PRED must both be files or both be directories ('" + gt.string() +
                     "' is " + (gt_dir ? "a directory" : "a file") + ", '" + pred.string() +
                     "' is " + (pred_dir ? "a directory" : "a file") + ")");
  }
  std::vector<FramePair> pairs;
  if (!gt_dir) {
    pairs.push_back(FramePair{gt.filename().string(), gt, pred, false});
    return pairs;
  }
  for (const fs::directory_entry& entry : fs::directory_iterator(gt)) {
    if (!entry.is_regular_file() || entry.path().extension() != ".pcd") continue;
    FramePair p;
    p.name = entry.path().filename().string();
    p.gt = entry.path();
    p.pred = pred / p.name;
    if (!fs::exists(p.pred, ec)) {
      if (!opt.allow_missing) {
        throw std::runtime_error("no prediction for ground truth '" + p.gt.string() + "': '" +
                                 p.pred.string() +
                                 "' not found (use --allow-missing to score "
                                 "it as an empty prediction)");
      }
      p.missing = true;
    }
    pairs.push_back(std::move(p));
  }
  if (pairs.empty()) throw std::runtime_error("no *.pcd files in '" + gt.string() + "'");
  std::sort(pairs.begin(), pairs.end(),
            [](const FramePair& a, const FramePair& b) { return a.name < b.name; });
  return pairs;
}

// Reads one pair and checks that it can be scored; errors name the files.
void LoadPair(const FramePair& pair, core::PointCloud* gt, core::PointCloud* pred) {
  *gt = io::ReadPcd(pair.gt.string());
  if (!gt->has_label()) {
    throw std::runtime_error("ground truth '" + pair.gt.string() + "' has no label field");
  }
  if (pair.missing) {
    // An empty prediction: every point "no object" (coordinates are never used).
    pred->xyz.assign(gt->size(), core::Vec3f{});
    pred->rgba.clear();
    pred->label.assign(gt->size(), 0u);
  } else {
    *pred = io::ReadPcd(pair.pred.string());
    if (!pred->has_label()) {
      throw std::runtime_error("prediction '" + pair.pred.string() + "' has no label field");
    }
    if (pred->size() != gt->size()) {
      throw std::runtime_error("point counts differ: ground truth '" + pair.gt.string() + "' has " +
                               std::to_string(gt->size()) + " points, prediction '" +
                               pair.pred.string() + "' has " + std::to_string(pred->size()));
    }
    // Points are matched by index: two organized clouds must share the image layout.
    if (gt->organized() && pred->organized() &&
        (gt->width != pred->width || gt->height != pred->height)) {
      throw std::runtime_error("image layouts differ: ground truth '" + pair.gt.string() + "' is " +
                               std::to_string(gt->width) + "x" + std::to_string(gt->height) +
                               ", prediction '" + pair.pred.string() + "' is " +
                               std::to_string(pred->width) + "x" + std::to_string(pred->height));
    }
  }
}

std::string Fixed(double v, bool scored) {
  if (!scored) return "-";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.4f", v);
  return buf;
}

void PrintTable(const std::vector<FramePair>& pairs, const std::vector<FrameMetrics>& frames) {
  size_t name_width = 5;
  for (const FramePair& p : pairs) name_width = std::max(name_width, p.name.size());
  std::printf("%-*s %8s %4s %4s %7s %7s %7s %7s %5s %5s\n", static_cast<int>(name_width), "frame",
              "valid", "gt", "seg", "WOv", "P", "R", "F1", "over", "under");
  for (size_t i = 0; i < pairs.size(); ++i) {
    const FrameMetrics& m = frames[i];
    std::printf("%-*s %8zu %4d %4d %7s %7s %7s %7s %5d %5d%s\n", static_cast<int>(name_width),
                pairs[i].name.c_str(), m.num_valid_points, m.num_gt_objects, m.num_segments,
                Fixed(m.wov, m.scored).c_str(), Fixed(m.precision, m.scored).c_str(),
                Fixed(m.recall, m.scored).c_str(), Fixed(m.f1, m.scored).c_str(), m.over_segmented,
                m.under_segmented, pairs[i].missing ? "  (missing prediction)" : "");
  }
}

void PrintSummary(const Summary& s, const EvalParams& params, int missing, double eval_ms) {
  const bool scored = s.frames_scored > 0;
  std::printf("\nconvention %s: %d frames (%d with ground-truth objects",
              std::string(GtConventionName(params.gt_convention)).c_str(), s.frames,
              s.frames_scored);
  if (missing > 0) std::printf(", %d with missing prediction", missing);
  std::printf(")\n");
  std::printf("  WOv %s   precision %s   recall %s   F1 %s   (means over frames)\n",
              Fixed(s.wov, scored).c_str(), Fixed(s.precision, scored).c_str(),
              Fixed(s.recall, scored).c_str(), Fixed(s.f1, scored).c_str());
  std::printf("  TP %s   FP %s   FN %s\n", Fixed(s.tp, scored).c_str(), Fixed(s.fp, scored).c_str(),
              Fixed(s.fn, scored).c_str());
  std::printf(
      "  1 - WOv lost to merges %s, split objects %s, borders between objects %s, "
      "borders with the background %s\n",
      Fixed(s.loss_merged, scored).c_str(), Fixed(s.loss_split, scored).c_str(),
      Fixed(s.loss_boundary, scored).c_str(), Fixed(s.loss_background, scored).c_str());
  std::printf(
      "  per frame: %.2f objects, %.2f segments, %.2f over-segmented, %.2f "
      "under-segmented (coverage >= %d%%)\n",
      s.mean_gt_objects, s.mean_segments, s.mean_over_segmented, s.mean_under_segmented,
      params.min_coverage_percent);
  std::printf("  metric time %.3f ms per frame\n", s.frames > 0 ? eval_ms / s.frames : 0.0);
}

int Run(int argc, char** argv) {
  Options opt;
  CLI::App app{
      "Scores predicted segmentations (label field of PCD files) against ground truth "
      "with the metrics of METHOD.md section 7: WOv, precision, recall, F1."};
  app.add_option("GT", opt.gt_path, "ground-truth PCD file or directory of *.pcd")->required();
  app.add_option("PRED", opt.pred_path,
                 "predicted PCD file or directory (files matched by name); label 0 = no object, "
                 "its coordinates are ignored (validity comes from GT)")
      ->required();
  app.add_option("--gt-convention", opt.convention, "ground-truth label convention")
      ->check(CLI::IsMember({"plain", "mosd-parts", "mosd-objects", "ocid"}))
      ->capture_default_str();
  app.add_option("--ocid-background", opt.ocid_background,
                 "comma-separated raw labels that are background under --gt-convention ocid")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--coverage-percent", opt.coverage_percent,
                 "share of an object a segment must hold to count for over/under-segmentation")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--csv", opt.csv_path, "write per-frame metrics to this CSV file");
  app.add_flag("--allow-missing", opt.allow_missing,
               "score a ground-truth file without prediction as an empty prediction");
  app.add_flag("--quiet,-q", opt.quiet, "print only the JSON line on stdout");
  app.set_version_flag("--version", std::string("clutterseg-eval ") + clutterseg::kVersion);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kExitUsage;
  }

  EvalParams params;
  try {
    params.gt_convention = ParseGtConvention(opt.convention);
    params.ocid_background_labels = opt.ocid_background;
    params.min_coverage_percent = opt.coverage_percent;
    params.ValidateOrThrow();
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "clutterseg-eval: %s\n", e.what());
    return kExitUsage;
  }

  std::vector<FramePair> pairs;
  try {
    pairs = ListPairs(opt);
  } catch (const UsageError& e) {
    std::fprintf(stderr, "clutterseg-eval: %s\n", e.what());
    return kExitUsage;
  }

  std::ofstream csv;
  if (!opt.csv_path.empty()) {
    csv.open(opt.csv_path, std::ios::out | std::ios::trunc);
    if (!csv) throw std::runtime_error("cannot open CSV file '" + opt.csv_path + "' for writing");
    csv << CsvHeader() << '\n';
  }

  FrameEvaluator evaluator(params);
  std::vector<FrameMetrics> frames;
  std::vector<FramePair> scored_pairs;
  core::PointCloud gt;
  core::PointCloud pred;
  int missing = 0;
  int failed = 0;
  double eval_ms = 0.0;
  {
    Progress progress(pairs.size(), fs::is_directory(opt.gt_path));
    for (size_t i = 0; i < pairs.size(); ++i) {
      progress.Show(i, pairs[i].name);
      try {
        LoadPair(pairs[i], &gt, &pred);
      } catch (const std::exception& e) {
        // Reported and left out; the other pairs are still scored.
        ++failed;
        progress.Clear();
        std::fprintf(stderr, "clutterseg-eval: cannot score '%s': %s\n", pairs[i].name.c_str(),
                     e.what());
        continue;
      }
      FrameMetrics& m = frames.emplace_back();
      scored_pairs.push_back(pairs[i]);
      const auto t0 = std::chrono::steady_clock::now();
      evaluator.Evaluate(gt, pred, &m);
      eval_ms +=
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      if (pairs[i].missing) {
        ++missing;
        progress.Clear();
        std::fprintf(stderr, "clutterseg-eval: no prediction for '%s', scored as empty\n",
                     pairs[i].gt.string().c_str());
      }
      if (csv.is_open()) csv << CsvRow(pairs[i].name, m, pairs[i].missing) << '\n';
    }
    progress.Show(pairs.size(), "");
  }
  if (csv.is_open()) {
    csv.close();
    if (!csv) throw std::runtime_error("cannot write CSV file '" + opt.csv_path + "'");
  }

  const Summary summary = Summarize(frames);
  if (!opt.quiet) {
    PrintTable(scored_pairs, frames);
    PrintSummary(summary, params, missing, eval_ms);
  }
  std::string json = SummaryToJson(summary, params, missing);
  if (failed > 0 && !json.empty() && json.back() == '}') {
    json.insert(json.size() - 1, ",\"failed\":" + std::to_string(failed));
  }
  std::printf("%s\n", json.c_str());
  if (std::fflush(stdout) != 0 || std::ferror(stdout) != 0) {
    std::fprintf(stderr, "clutterseg-eval: cannot write the results to stdout\n");
    return 1;
  }
  if (failed > 0) {
    std::fprintf(stderr, "clutterseg-eval: %d of %zu pair(s) could not be scored\n", failed,
                 pairs.size());
    return frames.empty() ? 1 : kExitIncomplete;
  }
  return kExitOk;
}

}  // namespace
}  // namespace clutterseg::eval

int main(int argc, char** argv) {
  try {
    return clutterseg::eval::Run(argc, argv);
  } catch (const clutterseg::eval::InputUnavailable& e) {
    std::fprintf(stderr, "clutterseg-eval: error: %s\n", e.what());
    return clutterseg::eval::kExitInputUnavailable;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "clutterseg-eval: error: %s\n", e.what());
    return 1;  // I/O or data error
  }
}
