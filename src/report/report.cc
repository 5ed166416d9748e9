#include "structgp/report/report.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <map>
#include <numeric>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "report/report_assets.h"
#include "structgp/internal/text.h"

namespace structgp {
namespace report {
namespace {

// Significant digits of the numbers embedded for the plots: finer than a screen resolves and
// than the sensors' own precision, and short enough to keep reports of long logs light.
constexpr int kPlotDigits = 8;
// Significant digits of the numbers in the tables.
constexpr int kTableDigits = 4;
// Smallest max_points_per_plot: a single bucket keeps its minimum and maximum.
constexpr int kMinPointsPerPlot = 2;
// A relative change smaller than this (in percent) is shown with one decimal.
constexpr double kOneDecimalBelowPercent = 9.95;
// Shown in place of a missing or non-finite number.
constexpr char kMissing[] = "\xE2\x80\x93";  // en dash

// ---- text -----------------------------------------------------------------------------------

// Escapes text for HTML element content and for quoted attribute values.
std::string Escape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// Shortest text of `value` with at most `digits` significant digits (locale independent).
std::string FormatNumber(double value, int digits) {
  if (!std::isfinite(value)) return kMissing;
  char buffer[64];
  const auto result =
      std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::general, digits);
  return std::string(buffer, result.ptr);
}

std::string FormatFixed(double value, int decimals) {
  if (!std::isfinite(value)) return kMissing;
  char buffer[64];
  const auto result =
      std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::fixed, decimals);
  return std::string(buffer, result.ptr);
}

// The relative change from `before` to `after` of an error ("-87%"), as a badge coloured by
// whether the error fell. Empty when the change is undefined (missing values, before <= 0).
std::string ChangeBadge(double before, double after) {
  if (!std::isfinite(before) || !std::isfinite(after) || !(before > 0)) return "";
  const double percent = 100.0 * (after - before) / before;
  const int decimals = std::abs(percent) < kOneDecimalBelowPercent ? 1 : 0;
  std::string text = FormatFixed(std::abs(percent), decimals);
  const bool zero = text.find_first_not_of("0.") == std::string::npos;
  const char* kind = zero ? "same" : percent < 0 ? "better" : "worse";
  if (zero) {
    text = "0";
  } else {
    text.insert(0, percent < 0 ? "-" : "+");
  }
  return std::string("<span class=\"chg ") + kind + "\">" + text + "%</span>";
}

// ---- JSON for the plots -----------------------------------------------------------------------

// A JSON string literal that is also safe inside a <script> element: '<', '>' and '&' are
// written as \u escapes, so that no "</script>" can end the element early.
void AppendJsonString(std::string_view text, std::string* out) {
  static constexpr char kHex[] = "0123456789abcdef";
  *out += '"';
  for (const char c : text) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      *out += '\\';
      *out += c;
    } else if (u < 0x20 || c == '<' || c == '>' || c == '&') {
      *out += "\\u00";
      *out += kHex[u >> 4];
      *out += kHex[u & 0xF];
    } else {
      *out += c;
    }
  }
  *out += '"';
}

// A number, or null when it is not finite (JSON has no NaN or infinity).
void AppendJsonNumber(double value, std::string* out) {
  if (!std::isfinite(value)) {
    *out += "null";
    return;
  }
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value,
                                    std::chars_format::general, kPlotDigits);
  out->append(buffer, result.ptr);
}

void AppendJsonArray(const std::vector<double>& values, const std::vector<std::size_t>& keep,
                     std::string* out) {
  *out += '[';
  for (std::size_t i = 0; i < keep.size(); ++i) {
    if (i > 0) *out += ',';
    AppendJsonNumber(values[keep[i]], out);
  }
  *out += ']';
}

// Indices of the samples drawn for one series: all of them when there are at most
// max_points; otherwise the samples are cut into max_points / 2 contiguous buckets and each
// bucket keeps the sample with its smallest and the one with its largest y (in sample order),
// so that spikes stay visible however much the series is thinned. Samples whose x or y is not
// finite are never chosen; a bucket without a finite sample keeps its first one, drawn as a gap.
std::vector<std::size_t> ThinnedIndices(const std::vector<double>& x, const std::vector<double>& y,
                                        int max_points) {
  const std::size_t n = y.size();
  std::vector<std::size_t> keep;
  if (n <= static_cast<std::size_t>(max_points)) {
    keep.resize(n);
    std::iota(keep.begin(), keep.end(), std::size_t{0});
    return keep;
  }
  const std::size_t buckets = static_cast<std::size_t>(max_points) / 2;
  keep.reserve(2 * buckets);
  for (std::size_t b = 0; b < buckets; ++b) {
    const std::size_t begin = n * b / buckets;
    const std::size_t end = n * (b + 1) / buckets;
    std::size_t low = end, high = end;  // end: none found yet
    for (std::size_t i = begin; i < end; ++i) {
      if (!std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
      if (low == end || y[i] < y[low]) low = i;
      if (high == end || y[i] > y[high]) high = i;
    }
    if (low == end) {
      keep.push_back(begin);
      continue;
    }
    keep.push_back(std::min(low, high));
    if (low != high) keep.push_back(std::max(low, high));
  }
  return keep;
}

// One series of a plot, all samples (thinned when written).
struct Series {
  std::string label;
  const char* role = "";  // "measured", "prediction" or "residual"
  std::vector<double> x, y;
  std::vector<double> lo, hi;  // the +-2 sigma band, empty when there is none
};

struct Plot {
  const char* type = "line";  // "line" or "scatter"
  std::string title, x_label, y_label;
  bool zero_line = false;
  bool wide = false;  // spans the page's width
  // Horizontal reference lines (y, label), always inside the automatic y range.
  std::vector<std::pair<double, std::string>> levels;
  // A heading shown across the page's width before the plot (empty: none).
  std::string heading;
  std::vector<Series> series;
};

void AppendPlotJson(const Plot& plot, int max_points, std::string* out) {
  *out += "{\"type\":";
  AppendJsonString(plot.type, out);
  *out += ",\"title\":";
  AppendJsonString(plot.title, out);
  *out += ",\"xLabel\":";
  AppendJsonString(plot.x_label, out);
  *out += ",\"yLabel\":";
  AppendJsonString(plot.y_label, out);
  *out += ",\"zeroLine\":";
  *out += plot.zero_line ? "true" : "false";
  if (!plot.levels.empty()) {
    *out += ",\"levels\":[";
    for (std::size_t l = 0; l < plot.levels.size(); ++l) {
      if (l > 0) *out += ',';
      *out += "{\"y\":";
      AppendJsonNumber(plot.levels[l].first, out);
      *out += ",\"label\":";
      AppendJsonString(plot.levels[l].second, out);
      *out += '}';
    }
    *out += ']';
  }
  *out += ",\"series\":[";
  for (std::size_t s = 0; s < plot.series.size(); ++s) {
    const Series& series = plot.series[s];
    const std::vector<std::size_t> keep = ThinnedIndices(series.x, series.y, max_points);
    if (s > 0) *out += ',';
    *out += "{\"label\":";
    AppendJsonString(series.label, out);
    *out += ",\"role\":";
    AppendJsonString(series.role, out);
    *out += ",\"samples\":" + std::to_string(series.y.size());
    *out += ",\"x\":";
    AppendJsonArray(series.x, keep, out);
    *out += ",\"y\":";
    AppendJsonArray(series.y, keep, out);
    if (!series.lo.empty()) {
      *out += ",\"lo\":";
      AppendJsonArray(series.lo, keep, out);
      *out += ",\"hi\":";
      AppendJsonArray(series.hi, keep, out);
    }
    *out += '}';
  }
  *out += "]}";
}

// ---- input checks ---------------------------------------------------------------------------

// The states of joint `joint` (1-based) on the diagnosed log: ReportData::diagnosed_states when
// given, else the joint's series; false when the report has none.
bool DiagnosedStates(const ReportData& data, int joint, const std::vector<double>** q,
                     const std::vector<double>** qd) {
  if (!data.diagnosed_states.empty()) {
    for (const JointStates& s : data.diagnosed_states) {
      if (s.joint != joint) continue;
      *q = &s.q;
      *qd = &s.qd;
      return true;
    }
    return false;
  }
  for (const JointData& j : data.joints) {
    if (j.joint != joint) continue;
    *q = &j.q;
    *qd = &j.qd;
    return true;
  }
  return false;
}

void CheckLength(const JointData& joint, const std::string& what, std::size_t got,
                 bool may_be_empty) {
  const std::size_t expected = joint.measured.size();
  if (got == expected || (may_be_empty && got == 0)) return;
  throw std::invalid_argument("RenderHtml: joint " + std::to_string(joint.joint) + ": " + what +
                              " has " + std::to_string(got) + " values, expected " +
                              std::to_string(expected) + " (one per measured sample)" +
                              (may_be_empty ? " or none" : ""));
}

void CheckInput(const ReportData& data, int max_points_per_plot) {
  if (max_points_per_plot < kMinPointsPerPlot) {
    throw std::invalid_argument("RenderHtml: max_points_per_plot: expected at least " +
                                std::to_string(kMinPointsPerPlot) + ", got " +
                                std::to_string(max_points_per_plot));
  }
  for (const JointData& joint : data.joints) {
    CheckLength(joint, "t", joint.t.size(), true);
    CheckLength(joint, "q", joint.q.size(), true);
    CheckLength(joint, "qd", joint.qd.size(), true);
    for (const PredictionSeries& p : joint.predictions) {
      CheckLength(joint, "the mean of '" + p.label + "'", p.mean.size(), false);
      CheckLength(joint, "the std of '" + p.label + "'", p.std.size(), true);
    }
    for (const SignalPlot& plot : joint.signal_plots) {
      for (const TimeSeries& series : plot.series) {
        CheckLength(joint, "the signal '" + series.label + "'", series.values.size(), false);
      }
    }
  }
  for (const JointStates& s : data.diagnosed_states) {
    if (!s.q.empty() && !s.qd.empty() && s.q.size() != s.qd.size()) {
      throw std::invalid_argument("RenderHtml: diagnosed_states of joint " +
                                  std::to_string(s.joint) + ": q has " +
                                  std::to_string(s.q.size()) + " values, qd " +
                                  std::to_string(s.qd.size()) + " (expected the same)");
    }
  }
  if (data.has_diagnosis) {
    const Diagnosis& d = data.diagnosis;
    for (const Suggestion& s : d.suggestions) {
      const std::string what = "RenderHtml: suggestion '" + s.spec + "': ";
      const Eigen::Index before = s.residual_before_rows.size();
      const Eigen::Index after = s.residual_after_rows.size();
      if (before != after) {
        throw std::invalid_argument(what + "residual_before_rows has " + std::to_string(before) +
                                    " values, residual_after_rows " + std::to_string(after) +
                                    " (expected the same)");
      }
      const std::vector<double>*q = nullptr, *qd = nullptr;
      if (before == 0 || !DiagnosedStates(data, s.joint, &q, &qd)) continue;
      const std::size_t states = std::max(q->size(), qd->size());
      if (static_cast<std::size_t>(before) != states) {
        throw std::invalid_argument(
            what + "residual_before_rows has " + std::to_string(before) + " values, expected " +
            std::to_string(states) + " (one per row of the diagnosed log: the " +
            (data.diagnosed_states.empty() ? "samples of joint " + std::to_string(s.joint)
                                           : "diagnosed_states of joint " +
                                                 std::to_string(s.joint)) +
            ") or none");
      }
    }
    const CoverageFinding& c = d.coverage;
    if (c.distance.size() != 0 && c.distance_time.size() != c.distance.rows()) {
      throw std::invalid_argument("RenderHtml: coverage: distance has " +
                                  std::to_string(c.distance.rows()) + " rows, distance_time " +
                                  std::to_string(c.distance_time.size()) +
                                  " values (expected the same)");
    }
  }
  for (const ModelErrors& e : data.errors) {
    if (e.rms.size() != e.nmse.size()) {
      throw std::invalid_argument("RenderHtml: errors of '" + e.label + "': rms has " +
                                  std::to_string(e.rms.size()) + " joints, nmse has " +
                                  std::to_string(e.nmse.size()) + " (expected the same)");
    }
    if (!e.coverage.empty() && e.coverage.size() != e.rms.size()) {
      throw std::invalid_argument("RenderHtml: errors of '" + e.label + "': coverage has " +
                                  std::to_string(e.coverage.size()) + " joints, rms has " +
                                  std::to_string(e.rms.size()) + " (expected the same, or none)");
    }
  }
}

// ---- plots of one joint -----------------------------------------------------------------------

// Torque over time (measured and every prediction, with bands); the signal plots over time;
// then, when there is a prediction, the residual of the first against qd and against q (where
// friction and cogging show).
std::vector<Plot> JointPlots(const JointData& joint) {
  const std::size_t n = joint.measured.size();
  const std::string j = std::to_string(joint.joint);
  std::vector<Plot> plots;
  if (n == 0) return plots;

  std::vector<double> t = joint.t;
  if (t.empty()) {
    t.resize(n);
    std::iota(t.begin(), t.end(), 0.0);
  }
  Plot time;
  time.title = "Joint " + j + ": measured and predicted torque";
  time.x_label = joint.t.empty() ? "sample" : "t";
  time.y_label = "torque";
  time.wide = true;
  time.series.push_back({"measured", "measured", t, joint.measured, {}, {}});
  for (const PredictionSeries& p : joint.predictions) {
    Series s{p.label, "prediction", t, p.mean, {}, {}};
    if (!p.std.empty()) {
      s.lo.resize(n);
      s.hi.resize(n);
      for (std::size_t i = 0; i < n; ++i) {
        s.lo[i] = p.mean[i] - 2.0 * p.std[i];
        s.hi[i] = p.mean[i] + 2.0 * p.std[i];
      }
    }
    time.series.push_back(std::move(s));
  }
  plots.push_back(std::move(time));
  for (const SignalPlot& signal : joint.signal_plots) {
    Plot plot;
    plot.title = "Joint " + j + ": " + signal.title;
    plot.x_label = joint.t.empty() ? "sample" : "t";
    plot.y_label = signal.y_label;
    plot.zero_line = true;
    plot.wide = true;
    for (const TimeSeries& series : signal.series) {
      plot.series.push_back({series.label, "prediction", t, series.values, {}, {}});
    }
    plots.push_back(std::move(plot));
  }
  if (joint.predictions.empty()) return plots;

  const PredictionSeries& first = joint.predictions.front();
  std::vector<double> residual(n);
  for (std::size_t i = 0; i < n; ++i) residual[i] = joint.measured[i] - first.mean[i];
  const std::string label = "measured - " + first.label;
  const auto residual_plot = [&](const std::vector<double>& x, const std::string& variable) {
    Plot plot;
    plot.type = "scatter";
    plot.title = "Joint " + j + ": residual vs " + variable;
    plot.x_label = variable;
    plot.y_label = "residual torque";
    plot.zero_line = true;
    plot.series.push_back({label, "residual", x, residual, {}, {}});
    return plot;
  };
  if (!joint.qd.empty()) plots.push_back(residual_plot(joint.qd, "qd" + j));
  if (!joint.q.empty()) plots.push_back(residual_plot(joint.q, "q" + j));
  return plots;
}

std::vector<double> ToStd(const Vector& v) { return std::vector<double>(v.data(), v.data() + v.size()); }

// Suggestion `number` (1-based) of the diagnosis, on its joint: the joint's residual on the
// diagnosed log against the joint's qd and q there (DiagnosedStates), the model refitted there without and with the effect, on one plot
// (the same axes: a Coulomb step or a cogging ripple in the first series, gone in the second).
// None when the suggestion has no residual rows.
std::vector<Plot> SuggestionPlots(const ReportData& data, const Suggestion& s, int number) {
  std::vector<Plot> plots;
  const std::vector<double>*q = nullptr, *qd = nullptr;
  if (s.residual_before_rows.size() == 0 || !DiagnosedStates(data, s.joint, &q, &qd)) {
    return plots;
  }
  const std::string j = std::to_string(s.joint);
  const std::vector<double> before = ToStd(s.residual_before_rows);
  const std::vector<double> after = ToStd(s.residual_after_rows);
  const auto plot = [&](const std::vector<double>& x, const std::string& variable) {
    Plot p;
    p.type = "scatter";
    p.title = "Suggestion " + std::to_string(number) + " (" + s.spec + "): residual vs " +
              variable + ", before and after";
    p.x_label = variable;
    p.y_label = "residual torque";
    p.zero_line = true;
    p.series.push_back({"before: refitted without " + s.spec, "residual", x, before, {}, {}});
    p.series.push_back({"after: refitted with " + s.spec, "residual", x, after, {}, {}});
    return p;
  };
  if (!qd->empty()) plots.push_back(plot(*qd, "qd" + j));
  if (!q->empty()) plots.push_back(plot(*q, "q" + j));
  if (!plots.empty()) {
    plots.front().heading = "Suggestion " + std::to_string(number) + ": <code>" +
                            Escape(s.spec) + "</code> &mdash; residual of joint " + j +
                            " on the diagnosed log, the model refitted there without and with the effect "
                            "(RMS " + FormatNumber(s.residual_rms_before, kTableDigits) +
                            " &rarr; " + FormatNumber(s.residual_rms_after, kTableDigits) + ")";
  }
  return plots;
}

// Distance of the log's states to the nearest training state, per joint, over time, with the
// level 1 (one training standard deviation) marked. None without the distances.
std::vector<Plot> CoveragePlots(const ReportData& data) {
  const CoverageFinding& c = data.diagnosis.coverage;
  std::vector<Plot> plots;
  if (!data.has_diagnosis || c.distance.size() == 0) return plots;
  Plot p;
  p.title = "Distance of the log's states to the training states";
  const bool has_time = !data.joints.empty() && !data.joints.front().t.empty();
  p.x_label = has_time ? "t" : "sample";
  p.y_label = "distance (training sd)";
  p.wide = true;
  p.levels.push_back({1.0, "1 = one training sd"});
  const std::vector<double> t = ToStd(c.distance_time);
  for (Eigen::Index k = 0; k < c.distance.cols(); ++k) {
    std::vector<double> y(static_cast<std::size_t>(c.distance.rows()));
    for (Eigen::Index r = 0; r < c.distance.rows(); ++r) y[static_cast<std::size_t>(r)] = c.distance(r, k);
    p.series.push_back({"joint " + std::to_string(k + 1), "distance", t, std::move(y), {}, {}});
  }
  plots.push_back(std::move(p));
  return plots;
}

// ---- HTML sections ----------------------------------------------------------------------------

void AppendHeader(const ReportData& data, std::string* html) {
  *html += "<header>\n<h1>" + Escape(data.title) + "</h1>\n<dl class=\"meta\">\n";
  if (!data.data_source.empty()) {
    *html += "<dt>Data</dt><dd><code>" + Escape(data.data_source) + "</code></dd>\n";
  }
  if (data.has_diagnosis) {
    const Diagnosis& d = data.diagnosis;
    if (!d.model.empty()) *html += "<dt>Model</dt><dd><code>" + Escape(d.model) + "</code></dd>\n";
    *html += "<dt>Samples</dt><dd>" + std::to_string(d.num_samples) + "</dd>\n";
    *html += "<dt>Noise level</dt><dd>" + FormatNumber(d.noise_std, kTableDigits) +
             " <span class=\"muted\">(relative &sigma;<sub>n</sub> by evidence)</span></dd>\n";
  }
  *html += "</dl>\n";
  if (!data.notes.empty()) {
    *html += "<ul class=\"notes\">\n";
    for (const std::string& note : data.notes) *html += "<li>" + Escape(note) + "</li>\n";
    *html += "</ul>\n";
  }
  if (!data.joints.empty()) {
    *html += "<nav>";
    for (const JointData& joint : data.joints) {
      const std::string j = std::to_string(joint.joint);
      *html += "<a href=\"#joint-" + j + "\">Joint " + j + "</a>";
    }
    *html += "</nav>\n";
  }
  *html += "</header>\n";
}

// Rows: joints (and all joints together); columns: RMS and nMSE of each model, with the change
// from the first model for the others, and the 2 sigma band's coverage when a model has it.
void AppendErrors(const ReportData& data, std::string* html) {
  if (data.errors.empty()) return;
  std::size_t num_joints = 0;
  for (const ModelErrors& e : data.errors) num_joints = std::max(num_joints, e.rms.size());
  const ModelErrors& base = data.errors.front();
  const auto value = [](const std::vector<double>& v, std::size_t i) {
    return i < v.size() ? v[i] : std::nan("");
  };
  // Quadratic mean of the RMS and mean of the nMSE over the joints.
  const auto total = [num_joints](const std::vector<double>& v, bool quadratic) {
    if (v.size() != num_joints || v.empty()) return std::nan("");
    double sum = 0;
    for (const double x : v) sum += quadratic ? x * x : x;
    return quadratic ? std::sqrt(sum / v.size()) : sum / v.size();
  };
  const bool with_coverage =
      std::any_of(data.errors.begin(), data.errors.end(),
                  [](const ModelErrors& e) { return !e.coverage.empty(); });
  const auto cells = [&](std::size_t m, double rms, double nmse, double base_rms,
                         double base_nmse, double coverage) {
    std::string s = "<td>" + FormatNumber(rms, kTableDigits);
    if (m > 0) s += ChangeBadge(base_rms, rms);
    s += "</td><td>" + FormatNumber(nmse, kTableDigits);
    if (m > 0) s += ChangeBadge(base_nmse, nmse);
    s += "</td>";
    if (with_coverage) {
      s += "<td>" + FormatNumber(100.0 * coverage, 3) + (std::isfinite(coverage) ? "%" : "") +
           "</td>";
    }
    return s;
  };

  *html +=
      "<section id=\"errors\">\n<h2>Errors per joint</h2>\n<table>\n<thead><tr>"
      "<th class=\"text\" rowspan=\"2\">Joint</th>";
  for (const ModelErrors& e : data.errors) {
    *html += std::string("<th class=\"text\" colspan=\"") + (with_coverage ? "3" : "2") +
             "\">" + Escape(e.label) + "</th>";
  }
  *html += "</tr>\n<tr>";
  for (std::size_t m = 0; m < data.errors.size(); ++m) {
    *html += "<th>RMS</th><th>nMSE</th>";
    if (with_coverage) {
      *html += "<th title=\"fraction of the measured torques within 2 standard deviations of "
               "the noisy prediction; about 95% when calibrated\">2&sigma; band</th>";
    }
  }
  *html += "</tr></thead>\n<tbody>\n";
  for (std::size_t i = 0; i < num_joints; ++i) {
    *html += "<tr><td class=\"text\">" + std::to_string(i + 1) + "</td>";
    for (std::size_t m = 0; m < data.errors.size(); ++m) {
      const ModelErrors& e = data.errors[m];
      *html += cells(m, value(e.rms, i), value(e.nmse, i), value(base.rms, i), value(base.nmse, i),
                     value(e.coverage, i));
    }
    *html += "</tr>\n";
  }
  if (num_joints > 1) {
    *html +=
        "<tr class=\"total\"><td class=\"text\" title=\"RMS: quadratic mean over the "
        "joints; nMSE: mean\">all</td>";
    for (std::size_t m = 0; m < data.errors.size(); ++m) {
      const ModelErrors& e = data.errors[m];
      *html += cells(m, total(e.rms, true), total(e.nmse, false), total(base.rms, true),
                     total(base.nmse, false), total(e.coverage, false));
    }
    *html += "</tr>\n";
  }
  *html += "</tbody>\n</table>\n";
  if (data.errors.size() > 1) {
    *html += "<p class=\"hint\">Changes are relative to <b>" + Escape(base.label) +
             "</b>; a fall of the error is shown in green.</p>\n";
  }
  *html += "</section>\n";
}

std::string Parameters(const std::map<std::string, double>& params) {
  if (params.empty()) return "<span class=\"muted\">none</span>";
  std::string s;
  for (const auto& [name, value] : params) {
    if (!s.empty()) s += ", ";
    s += Escape(name) + " = " + FormatNumber(value, kTableDigits);
  }
  return s;
}

// The verdict of the diagnosis, first on the page: what the error on the log is about.
void AppendVerdict(const ReportData& data, std::string* html) {
  const Diagnosis& d = data.diagnosis;
  *html += "<section id=\"verdict\">\n<h2>Verdict</h2>\n";
  if (d.status != DiagnosisStatus::kOk) {
    *html += "<p class=\"verdict big verdict-unexplained\" data-verdict=\"" +
             std::string(ToString(d.status)) + "\"><b>The diagnosis failed.</b> " +
             Escape(d.message) + "</p>\n</section>\n";
    return;
  }
  const CoverageFinding& c = d.coverage;
  const char* headline = "";
  switch (c.verdict) {
    case Verdict::kExplained:
      headline = "Explained: the model predicts this log to the noise.";
      break;
    case Verdict::kCoverage:
      headline =
          "Coverage, not missing physics: the training data do not reach these motions. "
          "Retrain with them.";
      break;
    case Verdict::kMissingEffect:
      headline = c.unexplained_joints.empty()
                     ? "Missing effects: the model lacks physics that the suggestions below add."
                     : "Missing effects, and error they do not explain: the suggestions below "
                       "add physics the model lacks, and part of the error stays above the "
                       "noise even with them.";
      break;
    case Verdict::kUnexplained:
      headline =
          "Unexplained: the error stays above the noise, and no candidate effect explains it.";
      break;
  }
  const std::string verdict = ToString(c.verdict);
  *html += "<p class=\"verdict big verdict-" + verdict + "\" data-verdict=\"" + verdict +
           "\"><b>" + headline + "</b>";
  if (!c.message.empty()) *html += "<br><span class=\"message\">" + Escape(c.message) + "</span>";
  *html += "</p>\n";
  if (d.chain) {
    *html += std::string("<p class=\"chain\" data-changed=\"") +
             (d.chain->changed ? "true" : "false") + "\"><b>Chain:</b> " +
             Escape(d.chain->message) + "</p>\n";
  }
  if (!d.holding.message.empty()) {
    *html += "<p class=\"holding-torque\"><b>At rest:</b> " + Escape(d.holding.message) +
             "</p>\n";
  }
  if (c.distance.size() != 0) {
    *html +=
        "<p><a href=\"#coverage\">Where the log leaves the training states</a>: distance to "
        "the training data per joint, over time.</p>\n";
  }
  *html += "</section>\n";
}

// "1.23e-05" for p-values, "<1e-300" when it underflowed.
std::string FormatP(double p) {
  if (p == 0.0) return "&lt;1e-300";
  return FormatNumber(p, 2);
}


// The closest candidates that were not suggested, each with the bar that refused it.
std::string RefusedTable(const Diagnosis& d) {
  if (d.refused.empty()) return "";
  std::string html =
      "<details class=\"refused\"><summary>Not suggested: the " +
      std::to_string(d.refused.size()) +
      " closest candidates, and the bar that refused each</summary>\n<table>\n<thead><tr>"
      "<th class=\"text\">Effect</th><th>Joint</th><th class=\"text\">Refused by</th>"
      "<th title=\"With every row an independent sample\">Evidence gain (nats, "
      "uncorrected)</th><th title=\"Mean over the folds of the held-out RMS with / without "
      "the effect\">Held-out fold ratio</th><th>Residual RMS before &rarr; after</th>"
      "<th class=\"text\">--effects</th></tr></thead>\n<tbody>\n";
  for (const Refusal& r : d.refused) {
    const Suggestion& c = r.candidate;
    html += "<tr><td class=\"text\"><b>" + Escape(c.effect) + "</b>" +
            (c.scope == "log" ? "<br><span class=\"muted small\">in this log only</span>"
                              : std::string()) +
            "</td><td>" + std::to_string(c.joint) + "</td><td class=\"text\">" +
            Escape(r.reason) + "</td><td>" + FormatFixed(c.score_uncorrected, 1) + "</td><td>" +
            FormatFixed(c.fold_rms_ratio, 2) + "</td><td>" +
            FormatNumber(c.residual_rms_before, kTableDigits) + " &rarr; " +
            FormatNumber(c.residual_rms_after, kTableDigits) + "</td><td class=\"text\"><code>" +
            Escape(c.spec) + "</code></td></tr>\n";
  }
  return html + "</tbody>\n</table>\n</details>\n";
}

void AppendSuggestions(const Diagnosis& d, std::string* html) {
  *html += "<section id=\"suggestions\">\n<h2>Suggested effects</h2>\n";
  if (d.suggestions.empty()) {
    std::string why =
        "No candidate effect raised the calibrated evidence, passed the multiplicity-controlled "
        "test and the effect-size bars, and lowered the error on unseen data enough to be "
        "suggested";
    switch (d.coverage.verdict) {
      case Verdict::kCoverage:
        why += ": the error is coverage, not a missing effect (see the verdict).";
        break;
      case Verdict::kUnexplained:
        why += ", although the model refitted on the log stays above the noise.";
        break;
      default:
        why += ": the model explains these data as far as the candidates can tell.";
    }
    *html += "<p class=\"verdict\"><b>No missing effect was found.</b> " + why + "</p>\n" +
             RefusedTable(d) + "</section>\n";
    return;
  }
  std::string all_specs;
  for (const Suggestion& s : d.suggestions) all_specs += (all_specs.empty() ? "" : ",") + s.spec;
  *html += "<p class=\"verdict found\"><b>" + std::to_string(d.suggestions.size()) +
           (d.suggestions.size() == 1 ? " missing effect" : " missing effects") +
           " found</b>, best first. To add them all: <code>--effects " + Escape(all_specs) +
           "</code></p>\n";
  *html +=
      "<table class=\"suggestions\">\n<thead><tr><th>#</th><th class=\"text\">Effect</th>"
      "<th>Joint</th>"
      "<th title=\"Gain in log marginal likelihood of the joint's torque, its data term "
      "corrected for autocorrelated residuals; below: with every row an independent "
      "sample\">Evidence gain (nats)</th>"
      "<th title=\"Factor by which autocorrelation overstates the uncorrected evidence (rows / "
      "effective samples), and the effective number of independent samples\">Autocorrelation"
      "</th>"
      "<th title=\"p-value of the calibrated statistic after the multiplicity correction over "
      "every candidate on every joint; below: before it\">p (adjusted)</th>"
      "<th title=\"RMS of the change the effect makes to the fitted torque over the joint's "
      "noise; below: the effect against its posterior std\">Effect / noise</th>"
      "<th title=\"The model refitted on all these data without and with the effect\">Residual "
      "RMS before &rarr; after</th>"
      "<th title=\"Confirmation on unseen data: each trajectory (or contiguous block, with a "
      "gap on each side) predicted from the others\">Held-out RMS before &rarr; after</th>"
      "<th class=\"text\" title=\"greedy: chosen one at a time; joint: chosen together with the "
      "joint's other friction-like effects\">Selection</th>"
      "<th class=\"text\">Parameters</th><th class=\"text\">--effects</th>"
      "</tr></thead>\n<tbody>\n";
  const auto below = [](const std::string& text) {
    return "<br><span class=\"muted small\">" + text + "</span>";
  };
  // The effects the log cannot tell well apart from a suggestion (Suggestion::alternatives).
  const auto alternatives = [&](const Suggestion& s) {
    if (s.alternatives.empty()) return std::string();
    std::string text = "also explained by it: ";
    for (std::size_t k = 0; k < s.alternatives.size(); ++k) {
      const AlternativeEffect& a = s.alternatives[k];
      text += (k > 0 ? ", " : "") + std::string("<code>") + Escape(a.spec) + "</code> (" +
              FormatFixed(a.score, 1) + " nats)";
    }
    return below(text);
  };
  for (std::size_t i = 0; i < d.suggestions.size(); ++i) {
    const Suggestion& s = d.suggestions[i];
    std::string confirmation;
    if (!s.confirmation.empty()) {
      confirmation = Escape(s.confirmation) + ": " + std::to_string(s.folds_improved) + "/" +
                     std::to_string(s.confirmation_folds) + " folds better (mean ratio " +
                     FormatFixed(s.fold_rms_ratio, 2) + "), gap " +
                     std::to_string(s.confirmation_gap) + " rows";
    }
    *html += "<tr><td>" + std::to_string(i + 1) + "</td><td class=\"text\"><b>" +
             Escape(s.effect) + "</b></td><td>" + std::to_string(s.joint) + "</td>";
    *html += "<td class=\"evidence\">" + FormatFixed(s.score, 1) +
             below("uncorrected " + FormatFixed(s.score_uncorrected, 1)) + "</td>";
    *html += "<td class=\"autocorrelation\">inflation &times;" +
             FormatNumber(s.inflation, 3) +
             below("n<sub>eff</sub> = " + FormatFixed(s.effective_samples, 0)) + "</td>";
    *html += "<td class=\"p\">" + FormatP(s.adjusted_p_value) + below("p = " + FormatP(s.p_value)) +
             "</td>";
    *html += "<td class=\"size\">" + FormatNumber(s.effect_to_noise, 3) +
             below("z = " + FormatNumber(s.z, 3)) + "</td>";
    *html += "<td>" + FormatNumber(s.residual_rms_before, kTableDigits) + " &rarr; " +
             FormatNumber(s.residual_rms_after, kTableDigits) +
             ChangeBadge(s.residual_rms_before, s.residual_rms_after) + "</td>";
    *html += "<td class=\"confirmation\">" + FormatNumber(s.rms_before, kTableDigits) +
             " &rarr; " + FormatNumber(s.rms_after, kTableDigits) +
             ChangeBadge(s.rms_before, s.rms_after) +
             (confirmation.empty() ? std::string() : below(confirmation)) + "</td>";
    *html += "<td class=\"text\">" + Escape(s.selection) +
             (s.scope == "log" ? below("in this log only") : std::string()) +
             (s.passed_by == "held_out" ? below("on its held-out fall") : std::string()) +
             "</td><td class=\"text\">" +
             Parameters(s.params) + "</td><td class=\"text\"><code>" + Escape(s.spec) +
             "</code>" + alternatives(s) + "</td></tr>\n";
  }
  *html += "</tbody>\n</table>\n" + RefusedTable(d) + "</section>\n";
}

std::string Concentrations(const JointFinding& f) {
  if (f.concentrations.empty()) return "<span class=\"muted\">nowhere in particular</span>";
  std::string s;
  for (const Concentration& c : f.concentrations) {
    if (!s.empty()) s += "<br>";
    s += "<b>" + Escape(c.variable) + "</b>: " + FormatFixed(100.0 * c.explained, 0) +
         "% of the residual variance; worst bin [" + FormatNumber(c.bin_low, kTableDigits) + ", " +
         FormatNumber(c.bin_high, kTableDigits) + "] with RMS " +
         FormatNumber(c.bin_rms, kTableDigits);
  }
  return s;
}

bool IsCoverageJoint(const Diagnosis& d, int joint) {
  const std::vector<int>& j = d.coverage.coverage_joints;
  return std::find(j.begin(), j.end(), joint) != j.end();
}

void AppendFindings(const Diagnosis& d, std::string* html) {
  if (d.joints.empty()) return;
  bool distances = false;
  for (const JointFinding& f : d.joints) distances = distances || f.max_distance >= 0;
  *html +=
      "<section id=\"findings\">\n<h2>Findings per joint</h2>\n<table>\n<thead><tr>"
      "<th>Joint</th><th>Residual RMS</th><th>nMSE</th><th title=\"From successive "
      "differences of the residual\">Noise std (estimate)</th><th title=\"The model refitted "
      "on the log, without any effect: near the noise when the model class explains the "
      "log\">Refit RMS</th>";
  if (distances) {
    *html +=
        "<th title=\"Rows of the log farther than one training standard deviation from every "
        "training state, and the largest distance\">Outside the training data</th>";
  }
  *html += "<th class=\"text\">Residual concentrates along</th></tr></thead>\n<tbody>\n";
  for (const JointFinding& f : d.joints) {
    const bool coverage = IsCoverageJoint(d, f.joint);
    *html += std::string("<tr") + (coverage ? " class=\"coverage\"" : "") + "><td>" +
             std::to_string(f.joint) + "</td><td>" + FormatNumber(f.rms, kTableDigits) +
             "</td><td>" + FormatNumber(f.nmse, kTableDigits) + "</td><td>" +
             FormatNumber(f.noise_std_estimate, kTableDigits) + "</td><td>" +
             FormatNumber(f.refit_rms, kTableDigits) +
             (coverage ? "<br><span class=\"muted small\">coverage</span>" : "") + "</td>";
    if (distances) {
      *html += "<td>" +
               (f.max_distance >= 0 ? FormatFixed(100.0 * f.outside_fraction, 0) +
                                          "% of rows, up to " +
                                          FormatNumber(f.max_distance, 3) + " sd"
                                    : std::string(kMissing)) +
               "</td>";
    }
    *html += "<td class=\"text\">" + Concentrations(f) + "</td></tr>\n";
  }
  *html += "</tbody>\n</table>\n</section>\n";
}

// Where a plot goes on the page: whether it spans the page's width, and the heading (HTML)
// shown before it.
struct Slot {
  bool wide = false;
  std::string heading;
};

void AppendPlotSlots(const std::vector<Slot>& slots, int* next_plot, std::string* html) {
  *html += "<div class=\"plots\">\n";
  for (const Slot& slot : slots) {
    if (!slot.heading.empty()) *html += "<h3 class=\"plot-heading\">" + slot.heading + "</h3>\n";
    *html += std::string("<div class=\"plot") + (slot.wide ? " wide" : "") + "\" data-plot=\"" +
             std::to_string((*next_plot)++) + "\"></div>\n";
  }
  *html += "</div>\n";
}

// The coverage section: the distance of the log to the training states over time.
void AppendCoverage(const Diagnosis& d, const std::vector<Slot>& slots, int* next_plot,
                    std::string* html) {
  if (slots.empty()) return;
  *html +=
      "<section id=\"coverage\">\n<h2>Where the log leaves the training data</h2>\n<p>Distance "
      "of each state of the log to the nearest training state, per joint, in the joint's "
      "(q, qd, qdd) standardised by the training data (the largest of each stretch of rows). "
      "Above 1 (dashed line), the log is more than one training standard deviation from "
      "anything the model was trained on: there it extrapolates.</p>\n";
  if (!d.coverage.coverage_joints.empty()) {
    *html += "<p>Error from coverage on " + structgp::internal::JointsText(d.coverage.coverage_joints) +
             ".</p>\n";
  }
  AppendPlotSlots(slots, next_plot, html);
  *html += "</section>\n";
}

// One section per joint with its plots; `next_plot` numbers the plots across the page.
void AppendJoint(const ReportData& data, const JointData& joint, const std::vector<Slot>& slots,
                 int* next_plot, std::string* html) {
  const std::string j = std::to_string(joint.joint);
  *html += "<section class=\"joint\" id=\"joint-" + j + "\">\n<h2>Joint " + j + "</h2>\n";
  if (data.has_diagnosis) {
    for (const JointFinding& f : data.diagnosis.joints) {
      if (f.joint != joint.joint) continue;
      *html += "<p>Residual RMS " + FormatNumber(f.rms, kTableDigits) + ", nMSE " +
               FormatNumber(f.nmse, kTableDigits) + ", noise std about " +
               FormatNumber(f.noise_std_estimate, kTableDigits) + ".";
      if (!f.concentrations.empty()) {
        *html += " The residual concentrates along <b>" +
                 Escape(f.concentrations.front().variable) + "</b>.";
      }
      *html += "</p>\n";
      if (IsCoverageJoint(data.diagnosis, f.joint)) {
        *html += "<p class=\"verdict verdict-coverage\"><b>Coverage:</b> refitted on the log, "
                 "the model reaches " + FormatNumber(f.refit_rms, kTableDigits) +
                 " against " + FormatNumber(f.rms, kTableDigits) +
                 " as trained: the training data do not cover these motions.</p>\n";
      }
    }
    for (const Suggestion& s : data.diagnosis.suggestions) {
      if (s.joint != joint.joint) continue;
      *html += "<p>Suggested: <code>" + Escape(s.spec) + "</code> (evidence gain " +
               FormatFixed(s.score, 1) + " nats).</p>\n";
    }
  }
  if (slots.empty()) {
    *html += "<p class=\"muted\">No samples.</p>\n</section>\n";
    return;
  }
  AppendPlotSlots(slots, next_plot, html);
  *html += "</section>\n";
}

}  // namespace

std::string RenderHtml(const ReportData& data, int max_points_per_plot) {
  CheckInput(data, max_points_per_plot);

  // The plots' data, one joint at a time (so that only one joint's copies are held at once):
  // per joint its own plots, then those of each suggestion on it; the coverage plot last.
  std::string plot_json;
  std::vector<std::vector<Slot>> layout;  // per joint, per plot
  std::vector<Slot> coverage_layout;
  std::size_t num_plots = 0;
  const auto add = [&](const Plot& plot, std::vector<Slot>* slots) {
    if (num_plots++ > 0) plot_json += ",\n";
    AppendPlotJson(plot, max_points_per_plot, &plot_json);
    slots->push_back({plot.wide, plot.heading});
  };
  for (const JointData& joint : data.joints) {
    layout.emplace_back();
    for (const Plot& plot : JointPlots(joint)) add(plot, &layout.back());
    if (!data.has_diagnosis) continue;
    for (std::size_t k = 0; k < data.diagnosis.suggestions.size(); ++k) {
      const Suggestion& s = data.diagnosis.suggestions[k];
      if (s.joint != joint.joint) continue;
      for (const Plot& plot : SuggestionPlots(data, s, static_cast<int>(k) + 1)) {
        add(plot, &layout.back());
      }
    }
  }
  for (const Plot& plot : CoveragePlots(data)) add(plot, &coverage_layout);
  const int coverage_first_plot = static_cast<int>(num_plots - coverage_layout.size());

  std::string html;
  html += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  // Nothing may be loaded from anywhere: the report is one file.
  html +=
      "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; "
      "script-src 'unsafe-inline'; style-src 'unsafe-inline'\">\n";
  html += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n";
  html += "<title>" + Escape(data.title) + "</title>\n<style>";
  html += internal::kReportCss;
  html += "</style>\n</head>\n<body>\n";
  html +=
      "<div id=\"status\" class=\"status\" data-state=\"loading\" data-errors=\"0\" "
      "data-plots=\"" +
      std::to_string(num_plots) +
      "\" data-plots-rendered=\"0\" hidden>"
      "</div>\n<script>";
  html += internal::kReportErrorScript;
  html += "</script>\n";

  AppendHeader(data, &html);
  html += "<main>\n";
  if (data.has_diagnosis) AppendVerdict(data, &html);
  AppendErrors(data, &html);
  if (data.has_diagnosis) {
    AppendSuggestions(data.diagnosis, &html);
    AppendFindings(data.diagnosis, &html);
    int next = coverage_first_plot;
    AppendCoverage(data.diagnosis, coverage_layout, &next, &html);
  }
  if (num_plots > 0) {
    html +=
        "<p class=\"hint\">Plots: drag to zoom (time range, or a box on the residual "
        "plots), double-click to reset, hover for values, click a legend entry to hide or "
        "show it. Residual = measured - the first prediction; a suggestion's plots show the "
        "joint's residual with the model refitted on the log without and with the effect.</p>\n"
        "<noscript><p>The plots need JavaScript.</p></noscript>\n";
  }
  int next_plot = 0;
  for (std::size_t j = 0; j < data.joints.size(); ++j) {
    AppendJoint(data, data.joints[j], layout[j], &next_plot, &html);
  }
  html += "</main>\n<footer>structgp report</footer>\n";

  html += "<script type=\"application/json\" id=\"report-data\">{\"plots\":[";
  html += plot_json;
  html += "]}</script>\n<script>";
  html += internal::kReportScript;
  html += "</script>\n</body>\n</html>\n";
  return html;
}

}  // namespace report
}  // namespace structgp
