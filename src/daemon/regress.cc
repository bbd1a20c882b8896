#include "clutterseg/daemon/regress.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <sstream>
#include <stdexcept>

#include <lcm/lcm-cpp.hpp>

#include "clutterseg/daemon/lcm_log_file.h"
#include "clutterseg/daemon/messages.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/wire_check.hpp"

namespace clutterseg::daemon {
namespace {

// Decodes one event of a log after its bounds check (a corrupt log must not make lcm-gen's
// decoder allocate what the message claims); false when either refuses it.
template <typename Message>
bool Decode(const lcm::LogEvent& ev, std::string (*check)(const uint8_t*, size_t), Message* msg) {
  const auto* data = static_cast<const uint8_t*>(ev.data);
  const size_t size = static_cast<size_t>(ev.datalen);
  if (size < 8 || size > static_cast<size_t>(INT32_MAX) || !check(data + 8, size - 8).empty()) {
    return false;
  }
  try {
    return msg->decode(data, 0, static_cast<int>(size)) >= 0;
  } catch (const std::length_error&) {  // lcm-gen's decoders throw on some malformed strings
    return false;
  }
}

struct RunFrames {
  std::map<int64_t, clutterseg::objects_t> objects;
  std::map<int64_t, clutterseg::label_image_t> labels;
};

RunFrames ReadRun(const std::string& path, const RegressOptions& o) {
  // liblcm's reader stops without a word at the first damaged event (a run would be compared
  // in part) and allocates whatever an event header claims: only whole logs, whose every
  // event lies within the file, are read.
  const LcmLogScan scan = ScanLcmLog(path);
  if (!scan.complete) {
    throw std::runtime_error(path + ": not a whole LCM log: " + scan.problem + " (after " +
                             std::to_string(scan.events) + " whole events of " +
                             std::to_string(scan.file_bytes) + " bytes)");
  }
  lcm::LogFile log(path, "r");
  if (!log.good()) throw std::runtime_error(path + ": cannot open LCM log");
  RunFrames run;
  while (const lcm::LogEvent* ev = log.readNextEvent()) {
    if (ev->channel == o.objects_channel) {
      clutterseg::objects_t m;
      if (!Decode(*ev, wire::CheckObjects, &m)) {
        throw std::runtime_error(path + ": undecodable objects_t on " + ev->channel);
      }
      run.objects[m.frame_seq] = std::move(m);
    } else if (ev->channel == o.labels_channel) {
      clutterseg::label_image_t m;
      if (!Decode(*ev, wire::CheckLabels, &m)) {
        throw std::runtime_error(path + ": undecodable label_image_t on " + ev->channel);
      }
      run.labels[m.frame_seq] = std::move(m);
    }
  }
  return run;
}

double Distance(const float* a, const float* b) {
  const double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// Greedy nearest matching: repeatedly take the closest unmatched pair.
std::vector<std::pair<size_t, size_t>> GreedyMatch(const clutterseg::objects_t& a,
                                                   const clutterseg::objects_t& b,
                                                   std::vector<double>* distances) {
  struct Pair {
    double d;
    size_t i, j;
  };
  std::vector<Pair> pairs;
  for (size_t i = 0; i < a.objects.size(); ++i) {
    for (size_t j = 0; j < b.objects.size(); ++j) {
      pairs.push_back({Distance(a.objects[i].centroid, b.objects[j].centroid), i, j});
    }
  }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& x, const Pair& y) {
    return x.d < y.d || (x.d == y.d && (x.i < y.i || (x.i == y.i && x.j < y.j)));
  });
  std::vector<bool> used_a(a.objects.size()), used_b(b.objects.size());
  std::vector<std::pair<size_t, size_t>> out;
  for (const Pair& p : pairs) {
    if (used_a[p.i] || used_b[p.j]) continue;
    used_a[p.i] = used_b[p.j] = true;
    out.emplace_back(p.i, p.j);
    distances->push_back(p.d);
  }
  return out;
}

}  // namespace

RegressReport CompareLogs(const std::string& log_a, const std::string& log_b,
                          const RegressOptions& options) {
  const RunFrames a = ReadRun(log_a, options);
  const RunFrames b = ReadRun(log_b, options);
  RegressReport report;
  for (const auto& [seq, m] : a.objects) {
    if (!b.objects.count(seq)) report.only_in_a.push_back(seq);
  }
  for (const auto& [seq, m] : b.objects) {
    if (!a.objects.count(seq)) report.only_in_b.push_back(seq);
  }
  if (!report.only_in_a.empty() || !report.only_in_b.empty()) report.ok = false;
  if (a.objects.empty() && b.objects.empty()) report.ok = false;

  core::LabelImage la, lb;
  for (const auto& [seq, ma] : a.objects) {
    auto itb = b.objects.find(seq);
    if (itb == b.objects.end()) continue;
    const clutterseg::objects_t& mb = itb->second;
    FrameComparison f;
    f.frame_seq = seq;
    f.objects_a = ma.num_objects;
    f.objects_b = mb.num_objects;
    std::vector<double> dist;
    const auto pairs = GreedyMatch(ma, mb, &dist);
    for (double d : dist) {
      f.max_centroid_error_m = std::max(f.max_centroid_error_m, d);
      if (d <= options.centroid_tol_m) ++f.matched;
    }
    std::ostringstream problem;
    if (f.objects_a != f.objects_b)
      problem << "object count " << f.objects_a << " vs " << f.objects_b << "; ";
    if (f.max_centroid_error_m > options.centroid_tol_m) {
      problem << "centroid error " << f.max_centroid_error_m << " m > " << options.centroid_tol_m
              << " m; ";
    }
    auto ita = a.labels.find(seq);
    auto itl = b.labels.find(seq);
    if (ita != a.labels.end() && itl != b.labels.end()) {
      DecodeLabelImage(ita->second, &la);
      DecodeLabelImage(itl->second, &lb);
      if (la.width != lb.width || la.height != lb.height) {
        problem << "label image size differs; ";
        f.mean_iou = 0.0;
      } else {
        // IoU of each matched pair's masks; unmatched objects on either side count as 0.
        double sum = 0.0;
        for (const auto& [i, j] : pairs) {
          const uint32_t ia = static_cast<uint32_t>(ma.objects[i].id);
          const uint32_t ib = static_cast<uint32_t>(mb.objects[j].id);
          size_t inter = 0, uni = 0;
          for (size_t p = 0; p < la.data.size(); ++p) {
            const bool x = la.data[p] == ia, y = lb.data[p] == ib;
            inter += (x && y) ? 1 : 0;
            uni += (x || y) ? 1 : 0;
          }
          sum += uni == 0 ? 1.0 : static_cast<double>(inter) / static_cast<double>(uni);
        }
        const size_t n = std::max(ma.objects.size(), mb.objects.size());
        f.mean_iou = n == 0 ? 1.0 : sum / static_cast<double>(n);
      }
      if (f.mean_iou < options.min_iou) {
        problem << "label IoU " << f.mean_iou << " < " << options.min_iou << "; ";
      }
    } else {
      f.mean_iou = -1.0;  // no label images to compare
    }
    f.problem = problem.str();
    f.ok = f.problem.empty();
    if (!f.ok) report.ok = false;
    report.frames.push_back(f);
  }
  return report;
}

std::string RegressReport::ToString(const RegressOptions& options) const {
  std::ostringstream out;
  int bad = 0;
  double max_err = 0.0, min_iou = 1.0, iou_sum = 0.0;
  int iou_n = 0;
  for (const FrameComparison& f : frames) {
    max_err = std::max(max_err, f.max_centroid_error_m);
    if (f.mean_iou >= 0) {
      min_iou = std::min(min_iou, f.mean_iou);
      iou_sum += f.mean_iou;
      ++iou_n;
    }
    if (!f.ok) {
      ++bad;
      out << "frame " << f.frame_seq << ": " << f.problem << "\n";
    }
  }
  for (int64_t s : only_in_a) out << "frame " << s << ": only in the first log\n";
  for (int64_t s : only_in_b) out << "frame " << s << ": only in the second log\n";
  char line[512];
  std::snprintf(line, sizeof(line),
                "%zu frames compared, %d outside tolerance, %zu/%zu unpaired; max centroid "
                "error %.4f m (tol %.4f); label IoU min %.3f mean %.3f (min %.3f)%s\n",
                frames.size(), bad, only_in_a.size(), only_in_b.size(), max_err,
                options.centroid_tol_m, iou_n ? min_iou : 0.0, iou_n ? iou_sum / iou_n : 0.0,
                options.min_iou, iou_n ? "" : " [no label images]");
  out << line << (ok ? "PASS" : "FAIL") << "\n";
  return out.str();
}

}  // namespace clutterseg::daemon
