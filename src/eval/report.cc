#include "clutterseg/eval/report.h"

#include <cstdio>
#include <string>

namespace clutterseg::eval {
namespace {

std::string Number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.12g", v);
  return buf;
}

std::string JsonString(std::string_view s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\u%04x", static_cast<unsigned>(c));
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string CsvField(std::string_view s) {
  if (s.find_first_of(",\"\n\r") == std::string_view::npos) return std::string(s);
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

void AppendField(std::string* json, std::string_view key, const std::string& value) {
  *json += ",\"";
  *json += key;
  *json += "\":";
  *json += value;
}

void AppendCsv(std::string* row, const std::string& value) {
  *row += ',';
  *row += value;
}

}  // namespace

std::string SummaryToJson(const Summary& summary, const EvalParams& params,
                          int missing_predictions) {
  const bool scored = summary.frames_scored > 0;
  const auto quality = [scored](double v) { return scored ? Number(v) : std::string("null"); };
  std::string j = "{";
  j += "\"convention\":";
  j += JsonString(GtConventionName(params.gt_convention));
  AppendField(&j, "frames", std::to_string(summary.frames));
  AppendField(&j, "frames_scored", std::to_string(summary.frames_scored));
  AppendField(&j, "missing", std::to_string(missing_predictions));
  AppendField(&j, "wov", quality(summary.wov));
  AppendField(&j, "precision", quality(summary.precision));
  AppendField(&j, "recall", quality(summary.recall));
  AppendField(&j, "f1", quality(summary.f1));
  AppendField(&j, "tp", quality(summary.tp));
  AppendField(&j, "fp", quality(summary.fp));
  AppendField(&j, "fn", quality(summary.fn));
  AppendField(&j, "loss_merged", quality(summary.loss_merged));
  AppendField(&j, "loss_split", quality(summary.loss_split));
  AppendField(&j, "loss_boundary", quality(summary.loss_boundary));
  AppendField(&j, "loss_background", quality(summary.loss_background));
  AppendField(&j, "gt_objects", std::to_string(summary.gt_objects));
  AppendField(&j, "segments", std::to_string(summary.segments));
  AppendField(&j, "over_segmented", std::to_string(summary.over_segmented));
  AppendField(&j, "under_segmented", std::to_string(summary.under_segmented));
  AppendField(&j, "mean_gt_objects", Number(summary.mean_gt_objects));
  AppendField(&j, "mean_segments", Number(summary.mean_segments));
  AppendField(&j, "mean_over_segmented", Number(summary.mean_over_segmented));
  AppendField(&j, "mean_under_segmented", Number(summary.mean_under_segmented));
  j += "}";
  return j;
}

std::string CsvHeader() {
  return "frame,points,valid_points,gt_objects,segments,wov,precision,recall,f1,tp,fp,fn,"
         "over_segmented,under_segmented,missing_prediction,loss_merged,loss_split,loss_boundary,"
         "loss_background";
}

std::string CsvRow(std::string_view frame, const FrameMetrics& m, bool missing_prediction) {
  const auto quality = [&m](double v) { return m.scored ? Number(v) : std::string(); };
  std::string r = CsvField(frame);
  AppendCsv(&r, std::to_string(m.num_points));
  AppendCsv(&r, std::to_string(m.num_valid_points));
  AppendCsv(&r, std::to_string(m.num_gt_objects));
  AppendCsv(&r, std::to_string(m.num_segments));
  AppendCsv(&r, quality(m.wov));
  AppendCsv(&r, quality(m.precision));
  AppendCsv(&r, quality(m.recall));
  AppendCsv(&r, quality(m.f1));
  AppendCsv(&r, quality(m.tp));
  AppendCsv(&r, quality(m.fp));
  AppendCsv(&r, quality(m.fn));
  AppendCsv(&r, std::to_string(m.over_segmented));
  AppendCsv(&r, std::to_string(m.under_segmented));
  r += missing_prediction ? ",1" : ",0";
  AppendCsv(&r, quality(m.loss_merged));
  AppendCsv(&r, quality(m.loss_split));
  AppendCsv(&r, quality(m.loss_boundary));
  AppendCsv(&r, quality(m.loss_background));
  return r;
}

}  // namespace clutterseg::eval
