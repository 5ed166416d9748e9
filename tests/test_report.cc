// The HTML report: self-contained (nothing loaded from anywhere), every string from the data
// escaped, series thinned to the limit with their extremes kept, non-finite numbers as null,
// the suggestions and the "no missing effect" verdict; and, in a real headless Chromium, the
// page runs without a script error and draws every plot (DOM markers written by the page's
// script, its zoom/hover self-test, and a screenshot that is not blank).

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_set>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <zlib.h>

#include "structgp/core/types.h"
#include "structgp/report/report.h"

namespace structgp {
namespace report {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr unsigned kSeed = 20240611;
// Strings that would break the page if written unescaped.
const char kHostileLabel[] = "</script><script>window.pwned=1</script><b>x</b>&amp;\"'";
const char kHostileFile[] = "<x>&\"";

int CountOf(const std::string& text, const std::string& needle) {
  int count = 0;
  for (std::size_t at = text.find(needle); at != std::string::npos;
       at = text.find(needle, at + 1)) {
    ++count;
  }
  return count;
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// A joint's log: a smooth torque with noise, a model that misses a Coulomb step, a second
// model that has it. `spike` (if < n) puts a large value into the measurements.
JointData MakeJoint(int joint, int n, std::mt19937* rng, std::size_t spike = SIZE_MAX) {
  std::normal_distribution<double> noise(0.0, 0.05);
  JointData d;
  d.joint = joint;
  PredictionSeries before{"pol", {}, {}}, after{"pol + coulomb@" + std::to_string(joint), {}, {}};
  for (int i = 0; i < n; ++i) {
    const double t = 0.002 * i;
    const double q = std::sin(0.7 * t + joint), qd = 0.7 * std::cos(0.7 * t + joint);
    const double smooth = 2.0 * std::sin(q) + 0.5 * qd;
    const double coulomb = 0.4 * (qd > 0 ? 1.0 : -1.0);
    d.t.push_back(t);
    d.q.push_back(q);
    d.qd.push_back(qd);
    d.measured.push_back(smooth + coulomb + noise(*rng));
    before.mean.push_back(smooth);
    before.std.push_back(0.1);
    after.mean.push_back(smooth + coulomb);
  }
  if (spike < d.measured.size()) d.measured[spike] = 50.0;
  d.predictions = {before, after};
  return d;
}

Diagnosis MakeDiagnosis(int joints, bool with_suggestions) {
  Diagnosis d;
  d.num_samples = 1000;
  d.model = "pol";
  d.noise_std = 0.02;
  for (int j = 1; j <= joints; ++j) {
    JointFinding f;
    f.joint = j;
    f.rms = 0.4;
    f.nmse = 0.05;
    f.noise_std_estimate = 0.05;
    f.concentrations = {{"qd" + std::to_string(j), 0.8, -0.01, 0.01, 0.45}};
    d.joints.push_back(f);
  }
  if (with_suggestions) {
    Suggestion s;
    s.effect = "coulomb";
    s.joint = 1;
    s.score = 812.34;
    s.rms_before = 0.40;
    s.rms_after = 0.052;
    s.spec = "coulomb@1";
    d.suggestions.push_back(s);
    Suggestion c;
    c.effect = "cogging";
    c.joint = 2;
    c.score = 35.2;
    c.rms_before = 0.2;
    c.rms_after = 0.15;
    c.params = {{"period", 0.3}};
    c.spec = "cogging@2:period=0.3";
    d.suggestions.push_back(c);
  }
  return d;
}

ReportData MakeReport(int joints, int n, bool with_suggestions) {
  std::mt19937 rng(kSeed);
  ReportData data;
  data.data_source = "logs/run1.csv.gz";
  data.notes = {"synthetic data"};
  for (int j = 1; j <= joints; ++j) data.joints.push_back(MakeJoint(j, n, &rng));
  data.has_diagnosis = true;
  data.diagnosis = MakeDiagnosis(joints, with_suggestions);
  ModelErrors before{"pol", {}, {}, {}}, after{"pol + coulomb@1", {}, {}, {}};
  for (int j = 0; j < joints; ++j) {
    before.rms.push_back(0.4);
    before.nmse.push_back(0.05);
    after.rms.push_back(0.052);
    after.nmse.push_back(0.0009);
  }
  data.errors = {before, after};
  return data;
}

// The text of the plot data embedded in the page.
std::string PlotDataText(const std::string& html) {
  const std::string open = "<script type=\"application/json\" id=\"report-data\">";
  const std::size_t begin = html.find(open);
  const std::size_t end = html.find("</script>", begin);
  if (begin == std::string::npos || end == std::string::npos) {
    ADD_FAILURE() << "no plot data in the page";
    return "{}";
  }
  return html.substr(begin + open.size(), end - begin - open.size());
}

json PlotData(const std::string& html) { return json::parse(PlotDataText(html)); }

constexpr double kRipplePeriod = 0.3;     // rad, the cogging of suggestion 2
constexpr double kRippleAmplitude = 0.3;  // N m
constexpr double kCoulomb = 0.4;          // N m, the step MakeJoint puts into every joint

double Ripple(double q) { return std::sin(2.0 * M_PI * q / kRipplePeriod); }

Vector ToVector(const std::vector<double>& v) {
  return Eigen::Map<const Vector>(v.data(), static_cast<Eigen::Index>(v.size()));
}

// The residual rows of the two suggestions of MakeDiagnosis, from the joints' data: coulomb@1
// before = measured - the model without the step (the step shows), after = measured - the
// model with it; cogging@2 before = after + a ripple in q2, after = measured - the model with
// the step. Calibration and confirmation numbers too.
void AddSuggestionRows(ReportData* data) {
  ASSERT_GE(data->joints.size(), 2u);
  ASSERT_EQ(data->diagnosis.suggestions.size(), 2u);
  const JointData& j1 = data->joints[0];
  const JointData& j2 = data->joints[1];
  const std::size_t n = j1.measured.size();
  std::vector<double> before1(n), after1(n), before2(n), after2(n);
  for (std::size_t i = 0; i < n; ++i) {
    before1[i] = j1.measured[i] - j1.predictions[0].mean[i];
    after1[i] = j1.measured[i] - j1.predictions[1].mean[i];
    after2[i] = j2.measured[i] - j2.predictions[1].mean[i];
    before2[i] = after2[i] + kRippleAmplitude * Ripple(j2.q[i]);
  }
  Suggestion& s = data->diagnosis.suggestions[0];
  s.residual_before_rows = ToVector(before1);
  s.residual_after_rows = ToVector(after1);
  s.residual_rms_before = 0.41;
  s.residual_rms_after = 0.05;
  s.score_uncorrected = 5012.66;
  s.inflation = 6.17;
  s.effective_samples = 162.1;
  s.p_value = 1.2e-14;
  s.adjusted_p_value = 2.4e-13;
  s.effect_rms = 0.375;
  s.effect_to_noise = 7.5;
  s.z = 28.5;
  s.confirmation = "blocks";
  s.confirmation_folds = 5;
  s.confirmation_gap = 20;
  s.folds_improved = 4;
  s.fold_rms_ratio = 0.31;
  s.selection = "joint";
  Suggestion& c = data->diagnosis.suggestions[1];
  c.residual_before_rows = ToVector(before2);
  c.residual_after_rows = ToVector(after2);
  c.confirmation = "trajectories";
  c.confirmation_folds = 3;
  c.confirmation_gap = 0;
  c.folds_improved = 3;
  c.fold_rms_ratio = 0.87;
  c.scope = "log";
}

// A coverage finding with distances of `points` points for `joints` joints: joint k's
// distance is (k + 1) * 0.5 * (1 + sin(t)), so joint 1 stays at or under 1 and joint 2 goes over.
void AddCoverage(ReportData* data, int joints, int points) {
  CoverageFinding& c = data->diagnosis.coverage;
  c.verdict = Verdict::kCoverage;
  c.message = "the model does not extrapolate to these motions on joint 2";
  c.coverage_joints = {2};
  c.distance_time.resize(points);
  c.distance.resize(points, joints);
  for (int p = 0; p < points; ++p) {
    c.distance_time[p] = 0.01 * p;
    for (int k = 0; k < joints; ++k) c.distance(p, k) = (k + 1) * 0.5 * (1.0 + std::sin(0.01 * p));
  }
  for (JointFinding& f : data->diagnosis.joints) {
    f.refit_rms = 0.051;
    f.outside_fraction = f.joint == 2 ? 0.31 : 0.0;
    f.max_distance = f.joint == 2 ? 4.2 : 0.93;
  }
}

// The plot whose title is `title`, or null.
const json* PlotTitled(const json& plots, const std::string& title) {
  for (const json& p : plots) {
    if (p["title"] == title) return &p;
  }
  return nullptr;
}

// The part of the page from the element with id `id` to the end of its section.
std::string Section(const std::string& html, const std::string& id) {
  const std::size_t begin = html.find("id=\"" + id + "\"");
  if (begin == std::string::npos) return "";
  return html.substr(begin, html.find("</section>", begin) - begin);
}

// The data-plot indices in `text`, in order.
std::vector<int> PlotIndices(const std::string& text) {
  std::vector<int> indices;
  const std::regex pattern("data-plot=\"([0-9]+)\"");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), pattern);
       it != std::sregex_iterator(); ++it) {
    indices.push_back(std::stoi((*it)[1].str()));
  }
  return indices;
}

// Least-squares coefficient of `basis` in y (the size of that component of y).
double Coefficient(const std::vector<double>& y, const std::vector<double>& basis) {
  double yb = 0, bb = 0;
  for (std::size_t i = 0; i < y.size(); ++i) {
    yb += y[i] * basis[i];
    bb += basis[i] * basis[i];
  }
  return yb / bb;
}

// Mean of y where x > 0 minus where x < 0: the height of a step at x = 0.
double StepAtZero(const std::vector<double>& x, const std::vector<double>& y) {
  double up = 0, down = 0;
  int n_up = 0, n_down = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (x[i] > 0) {
      up += y[i];
      ++n_up;
    } else if (x[i] < 0) {
      down += y[i];
      ++n_down;
    }
  }
  return up / n_up - down / n_down;
}

TEST(Report, HasNoExternalReference) {
  const std::string html = Lower(RenderHtml(MakeReport(2, 500, true)));
  for (const char* bad : {"http://", "https://", "src=", "url(", "@import", "<link", "<iframe",
                          "<img", "<object", "<embed"}) {
    EXPECT_EQ(html.find(bad), std::string::npos) << "found '" << bad << "'";
  }
  // In-page links only.
  const std::regex href("href\\s*=\\s*\"([^\"]*)\"");
  int links = 0;
  for (auto it = std::sregex_iterator(html.begin(), html.end(), href); it != std::sregex_iterator();
       ++it, ++links) {
    EXPECT_EQ((*it)[1].str().rfind('#', 0), 0u) << (*it)[1].str();
  }
  EXPECT_EQ(links, 2);  // the two joints in the navigation
  // The content security policy forbids loading anything.
  EXPECT_NE(html.find("default-src 'none'"), std::string::npos);
}

TEST(Report, EscapesEveryStringFromTheData) {
  ReportData data = MakeReport(1, 100, true);
  data.title = kHostileLabel;
  data.data_source = kHostileFile;
  data.notes = {kHostileLabel};
  data.joints[0].predictions[0].label = kHostileLabel;
  data.errors[0].label = kHostileLabel;
  data.diagnosis.model = kHostileFile;
  data.diagnosis.suggestions[0].effect = kHostileLabel;
  data.diagnosis.suggestions[0].spec = kHostileFile;
  data.diagnosis.suggestions[1].params = {{kHostileLabel, 1.0}};
  data.diagnosis.joints[0].concentrations[0].variable = kHostileFile;
  const std::string html = RenderHtml(data);

  EXPECT_EQ(html.find("pwned=1</script>"), std::string::npos);
  EXPECT_EQ(html.find("<b>x</b>"), std::string::npos);
  EXPECT_EQ(html.find(kHostileFile), std::string::npos);
  EXPECT_NE(html.find("&lt;x&gt;&amp;&quot;"), std::string::npos);
  EXPECT_NE(html.find("<title>&lt;/script&gt;&lt;script&gt;window.pwned=1"), std::string::npos);
  // Exactly the page's own three script elements: error handler, data, plots.
  EXPECT_EQ(CountOf(html, "<script"), 3);
  EXPECT_EQ(CountOf(html, "</script>"), 3);
  // The label comes back intact from the embedded data.
  const json plots = PlotData(html);
  EXPECT_EQ(plots["plots"][0]["series"][1]["label"], kHostileLabel);
  EXPECT_EQ(plots["plots"][1]["series"][0]["label"], std::string("measured - ") + kHostileLabel);

  // The suggestion plots' heading and the verdict's message are escaped too.
  ReportData two = MakeReport(2, 100, true);
  AddSuggestionRows(&two);
  two.diagnosis.suggestions[0].spec = kHostileLabel;
  two.diagnosis.suggestions[0].confirmation = kHostileFile;
  two.diagnosis.suggestions[0].selection = kHostileFile;
  two.diagnosis.coverage.message = kHostileLabel;
  const std::string page = RenderHtml(two);
  EXPECT_EQ(page.find("pwned=1</script>"), std::string::npos);
  EXPECT_EQ(page.find("<b>x</b>"), std::string::npos);
  EXPECT_EQ(page.find(kHostileFile), std::string::npos);
  EXPECT_EQ(CountOf(page, "<script"), 3);
  EXPECT_NE(page.find("Suggestion 1: <code>&lt;/script&gt;&lt;script&gt;window.pwned=1"),
            std::string::npos);
  const json page_plots = PlotData(page)["plots"];
  const json* plot = PlotTitled(page_plots,
                                std::string("Suggestion 1 (") + kHostileLabel +
                                    "): residual vs qd1, before and after");
  ASSERT_NE(plot, nullptr);
  EXPECT_EQ((*plot)["series"][1]["label"], std::string("after: refitted with ") + kHostileLabel);
}

TEST(Report, ThinsEachSeriesToTheLimitKeepingExtremes) {
  SCOPED_TRACE("seed " + std::to_string(kSeed));
  std::mt19937 rng(kSeed);
  const int n = 10000, max_points = 1000;
  const std::size_t spike = 6789;
  ReportData data;
  data.joints.push_back(MakeJoint(1, n, &rng, spike));
  data.joints.push_back(MakeJoint(2, n, &rng));
  data.joints[1].q.clear();  // no q: no residual-vs-q plot for joint 2
  const json plots = PlotData(RenderHtml(data, max_points))["plots"];

  // Joint 1: time, residual vs qd, residual vs q; joint 2: time, residual vs qd.
  ASSERT_EQ(plots.size(), 5u);
  EXPECT_EQ(plots[0]["type"], "line");
  EXPECT_EQ(plots[1]["type"], "scatter");
  EXPECT_EQ(plots[1]["xLabel"], "qd1");
  EXPECT_EQ(plots[2]["xLabel"], "q1");
  EXPECT_EQ(plots[4]["xLabel"], "qd2");
  ASSERT_EQ(plots[0]["series"].size(), 3u);  // measured and the two predictions
  int series = 0;
  for (const json& plot : plots) {
    for (const json& s : plot["series"]) {
      ++series;
      EXPECT_EQ(s["samples"], n);
      // Noisy data: each of the max_points / 2 buckets has a distinct minimum and maximum.
      EXPECT_EQ(s["x"].size(), static_cast<std::size_t>(max_points));
      EXPECT_EQ(s["y"].size(), static_cast<std::size_t>(max_points));
      EXPECT_EQ(s.contains("lo"), s["label"] == "pol" && plot["type"] == "line");
      if (s.contains("lo")) {
        EXPECT_EQ(s["lo"].size(), s["y"].size());
        EXPECT_EQ(s["hi"].size(), s["y"].size());
        for (std::size_t i = 0; i < s["y"].size(); ++i) {
          EXPECT_NEAR(s["hi"][i].get<double>() - s["lo"][i].get<double>(), 0.4, 1e-6);
        }
      }
      // Samples stay in time order.
      if (plot["type"] == "line") {
        EXPECT_TRUE(std::is_sorted(s["x"].begin(), s["x"].end()));
      }
    }
  }
  EXPECT_EQ(series, 3 + 1 + 1 + 3 + 1);

  // The spike survives the thinning, in the time plot and in the residual plots.
  const json& measured = plots[0]["series"][0];
  const auto peak = std::max_element(measured["y"].begin(), measured["y"].end());
  EXPECT_EQ(*peak, 50.0);
  const std::size_t at = std::distance(measured["y"].begin(), peak);
  EXPECT_NEAR(measured["x"][at].get<double>(), 0.002 * spike, 1e-9);
  const json& residual = plots[1]["series"][0]["y"];
  EXPECT_GT(*std::max_element(residual.begin(), residual.end()), 45.0);
}

TEST(Report, KeepsEverySampleUnderTheLimit) {
  std::mt19937 rng(kSeed);
  ReportData data;
  data.joints.push_back(MakeJoint(3, 300, &rng));
  const json plots = PlotData(RenderHtml(data))["plots"];
  ASSERT_EQ(plots.size(), 3u);
  const json& measured = plots[0]["series"][0];
  ASSERT_EQ(measured["y"].size(), 300u);
  for (int i = 0; i < 300; ++i) {
    // Eight significant digits.
    EXPECT_NEAR(measured["y"][i].get<double>(), data.joints[0].measured[i],
                1e-7 * std::abs(data.joints[0].measured[i]));
    EXPECT_NEAR(measured["x"][i].get<double>(), data.joints[0].t[i], 1e-12 + 1e-7 * 0.002 * i);
  }
}

TEST(Report, WritesNonFiniteNumbersAsNull) {
  std::mt19937 rng(kSeed);
  ReportData data;
  data.joints.push_back(MakeJoint(1, 50, &rng));
  JointData& j = data.joints[0];
  j.measured[3] = std::numeric_limits<double>::quiet_NaN();
  j.measured[4] = std::numeric_limits<double>::infinity();
  j.qd[5] = -std::numeric_limits<double>::infinity();
  j.predictions[0].std[6] = std::numeric_limits<double>::quiet_NaN();
  const std::string html = RenderHtml(data);
  const std::string lower = Lower(PlotDataText(html));
  EXPECT_EQ(lower.find("nan"), std::string::npos);
  EXPECT_EQ(lower.find("inf"), std::string::npos);
  const json plots = PlotData(html)["plots"];  // parses: strict JSON
  EXPECT_TRUE(plots[0]["series"][0]["y"][3].is_null());
  EXPECT_TRUE(plots[0]["series"][0]["y"][4].is_null());
  EXPECT_TRUE(plots[0]["series"][1]["lo"][6].is_null());
  EXPECT_TRUE(plots[1]["series"][0]["x"][5].is_null());
  EXPECT_TRUE(plots[1]["series"][0]["y"][3].is_null());

  // Thinned: a bucket without a finite sample keeps a gap.
  ReportData gap;
  gap.joints.push_back(MakeJoint(1, 1000, &rng));
  for (int i = 500; i < 600; ++i) {
    gap.joints[0].measured[i] = std::numeric_limits<double>::quiet_NaN();
  }
  const json thinned = PlotData(RenderHtml(gap, 100))["plots"][0]["series"][0]["y"];
  EXPECT_EQ(std::count(thinned.begin(), thinned.end(), nullptr), 5);  // 5 buckets of 20
}

TEST(Report, RendersSuggestions) {
  const std::string html = RenderHtml(MakeReport(2, 200, true));
  EXPECT_EQ(html.find("No missing effect"), std::string::npos);
  EXPECT_NE(html.find("2 missing effects found"), std::string::npos);
  EXPECT_NE(html.find("<code>--effects coulomb@1,cogging@2:period=0.3</code>"), std::string::npos);
  EXPECT_NE(html.find("<code>cogging@2:period=0.3</code>"), std::string::npos);
  EXPECT_NE(html.find("812.3"), std::string::npos);  // score, nats
  EXPECT_NE(html.find("period = 0.3"), std::string::npos);
  // Held-out RMS 0.4 -> 0.052: -87%.
  EXPECT_NE(html.find("0.4 &rarr; 0.052<span class=\"chg better\">-87%</span>"), std::string::npos);
  // Findings per joint: where the residual concentrates.
  EXPECT_NE(html.find("<b>qd2</b>: 80% of the residual variance"), std::string::npos);
  // The suggestion listed again in its joint's section.
  EXPECT_NE(html.find("Suggested: <code>coulomb@1</code>"), std::string::npos);
}

TEST(Report, SaysWhenNoMissingEffectIsFound) {
  const std::string html = RenderHtml(MakeReport(2, 200, false));
  EXPECT_NE(html.find("No missing effect was found."), std::string::npos);
  EXPECT_EQ(html.find("--effects "), std::string::npos);

  // Without a diagnosis there is no verdict at all.
  ReportData data = MakeReport(1, 100, false);
  data.has_diagnosis = false;
  const std::string plain = RenderHtml(data);
  EXPECT_EQ(plain.find("No missing effect"), std::string::npos);
  EXPECT_EQ(plain.find("id=\"suggestions\""), std::string::npos);
}

// The closest refused candidates, with the bar each failed, under the verdict: with
// suggestions and without; their strings escaped.
TEST(Report, ListsTheRefusedCandidatesWithTheirBar) {
  for (const bool with_suggestions : {true, false}) {
    ReportData data = MakeReport(2, 200, with_suggestions);
    EXPECT_EQ(RenderHtml(data).find("Not suggested"), std::string::npos);
    Refusal r;
    r.candidate.effect = "drift";
    r.candidate.joint = 2;
    r.candidate.scope = "log";
    r.candidate.spec = "drift@2:span=8;t0=79";
    r.candidate.score_uncorrected = 358.9;
    r.candidate.fold_rms_ratio = 0.95;
    r.candidate.residual_rms_before = 10.6;
    r.candidate.residual_rms_after = 7.02;
    r.bar = "calibrated_evidence";
    r.reason = "calibrated evidence -2.3 nats <= 10 (inflation 15.4)";
    data.diagnosis.refused = {r};
    std::string html = RenderHtml(data);
    const std::string section = Section(html, "suggestions");
    EXPECT_NE(section.find("Not suggested: the 1 closest candidates"), std::string::npos) << section;
    EXPECT_NE(section.find("<td class=\"text\">calibrated evidence -2.3 nats &lt;= 10 (inflation "
                           "15.4)</td><td>358.9</td><td>0.95</td><td>10.6 &rarr; 7.02</td>"),
              std::string::npos)
        << section;
    EXPECT_NE(section.find("<code>drift@2:span=8;t0=79</code>"), std::string::npos);
    EXPECT_NE(section.find("<b>drift</b><br><span class=\"muted small\">in this log only"),
              std::string::npos);
    data.diagnosis.refused[0].reason = kHostileLabel;
    data.diagnosis.refused[0].candidate.spec = kHostileFile;
    html = RenderHtml(data);
    EXPECT_EQ(html.find(kHostileFile), std::string::npos);
    EXPECT_EQ(html.find("pwned=1</script>"), std::string::npos);
  }
}

TEST(Report, ComparesErrorsOfTheModels) {
  ReportData data = MakeReport(2, 100, false);
  data.errors[1].rms[1] = 0.42;  // worse on joint 2
  const std::string html = RenderHtml(data);
  EXPECT_NE(html.find("<th class=\"text\" colspan=\"2\">pol + coulomb@1</th>"), std::string::npos);
  EXPECT_NE(html.find("0.052<span class=\"chg better\">-87%</span>"), std::string::npos);
  EXPECT_NE(html.find("0.42<span class=\"chg worse\">+5.0%</span>"), std::string::npos);
  EXPECT_NE(html.find("0.0009<span class=\"chg better\">-98%</span>"), std::string::npos);
  // No band coverage given: no column for it.
  EXPECT_EQ(html.find("band</th>"), std::string::npos);
  // With it (here for the second model only), a third column per model, the mean on "all".
  data.errors[1].coverage = {0.25, 0.95};
  const std::string with_band = RenderHtml(data);
  EXPECT_NE(with_band.find("<th class=\"text\" colspan=\"3\">pol + coulomb@1</th>"),
            std::string::npos);
  EXPECT_NE(with_band.find("band</th>"), std::string::npos);
  EXPECT_NE(with_band.find("<td>25%</td>"), std::string::npos) << with_band;
  EXPECT_NE(with_band.find("<td>95%</td>"), std::string::npos);
  EXPECT_NE(with_band.find("<td>60%</td>"), std::string::npos);  // all: (25 + 95) / 2
  data.errors[1].coverage = {0.25};
  EXPECT_THROW(RenderHtml(data), std::invalid_argument);
  // Without errors, no table.
  data.errors.clear();
  EXPECT_EQ(RenderHtml(data).find("id=\"errors\""), std::string::npos);
}

TEST(Report, RejectsInconsistentInput) {
  std::mt19937 rng(kSeed);
  ReportData data;
  data.joints.push_back(MakeJoint(1, 20, &rng));
  EXPECT_THROW(RenderHtml(data, 1), std::invalid_argument);
  data.joints[0].predictions[1].mean.pop_back();
  try {
    RenderHtml(data);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("has 19 values, expected 20"), std::string::npos)
        << e.what();
  }
  data.joints[0].predictions[1].mean.push_back(0.0);
  data.joints[0].q.resize(3);
  EXPECT_THROW(RenderHtml(data), std::invalid_argument);
  data.joints[0].q.clear();  // empty is allowed: no residual-vs-q plot
  EXPECT_NO_THROW(RenderHtml(data));
  // A signal over time must have one value per measured sample.
  data.joints[0].signal_plots.push_back({"one-step-ahead error", "torque error",
                                         {{"error", std::vector<double>(19, 0.0)}}});
  try {
    RenderHtml(data);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("the signal 'error' has 19 values, expected 20"),
              std::string::npos)
        << e.what();
  }
  data.joints[0].signal_plots[0].series[0].values.push_back(1.0);
  const json plots = PlotData(RenderHtml(data))["plots"];
  // The torque plot, then the signal plot (wide, with a zero line), then the residual vs qd.
  ASSERT_GE(plots.size(), 2u);
  EXPECT_EQ(plots[1]["title"], "Joint 1: one-step-ahead error");
  EXPECT_EQ(plots[1]["zeroLine"], true);
  EXPECT_EQ(plots[1]["series"][0]["y"].size(), 20u);
  EXPECT_EQ(plots[1]["series"][0]["y"][19], 1.0);
}

TEST(Report, PlotsEachSuggestionsResidualBeforeAndAfterAgainstQdAndQ) {
  const int n = 600;
  ReportData data = MakeReport(2, n, true);
  const std::string plain = RenderHtml(data);
  // Without residual rows, no suggestion plot.
  EXPECT_EQ(PlotData(plain)["plots"].size(), 6u);
  EXPECT_EQ(plain.find("<h3 class=\"plot-heading\""), std::string::npos);

  AddSuggestionRows(&data);
  const std::string html = RenderHtml(data);
  const json plots = PlotData(html)["plots"];
  ASSERT_EQ(plots.size(), 6u + 4u);  // two per suggestion: vs qd and vs q

  struct Expected {
    std::string title;
    const std::vector<double>* x;
    const Suggestion* s;
  };
  const Suggestion& coulomb = data.diagnosis.suggestions[0];
  const Suggestion& cogging = data.diagnosis.suggestions[1];
  const std::vector<Expected> expected = {
      {"Suggestion 1 (coulomb@1): residual vs qd1, before and after", &data.joints[0].qd,
       &coulomb},
      {"Suggestion 1 (coulomb@1): residual vs q1, before and after", &data.joints[0].q, &coulomb},
      {"Suggestion 2 (cogging@2:period=0.3): residual vs qd2, before and after",
       &data.joints[1].qd, &cogging},
      {"Suggestion 2 (cogging@2:period=0.3): residual vs q2, before and after", &data.joints[1].q,
       &cogging}};
  for (const Expected& e : expected) {
    SCOPED_TRACE(e.title);
    const json* plot = PlotTitled(plots, e.title);
    ASSERT_NE(plot, nullptr);
    EXPECT_EQ((*plot)["type"], "scatter");
    EXPECT_TRUE((*plot)["zeroLine"].get<bool>());
    ASSERT_EQ((*plot)["series"].size(), 2u);
    EXPECT_EQ((*plot)["series"][0]["label"], "before: refitted without " + e.s->spec);
    EXPECT_EQ((*plot)["series"][1]["label"], "after: refitted with " + e.s->spec);
    for (int k = 0; k < 2; ++k) {
      const json& series = (*plot)["series"][k];
      const Vector& rows = k == 0 ? e.s->residual_before_rows : e.s->residual_after_rows;
      ASSERT_EQ(series["x"].size(), static_cast<std::size_t>(n));
      ASSERT_EQ(series["y"].size(), static_cast<std::size_t>(n));
      for (int i = 0; i < n; ++i) {
        EXPECT_NEAR(series["x"][i].get<double>(), (*e.x)[i], 1e-7 * std::abs((*e.x)[i]) + 1e-15);
        EXPECT_NEAR(series["y"][i].get<double>(), rows[i], 1e-7 * std::abs(rows[i]) + 1e-15);
      }
    }
  }

  // What the eye sees, from the embedded data: the Coulomb step of 2 x 0.4 N m at qd1 = 0
  // before the suggestion and none after; the cogging ripple in q2 before and none after.
  const json& step = *PlotTitled(plots, expected[0].title);
  const auto values = [](const json& a) { return a.get<std::vector<double>>(); };
  EXPECT_NEAR(StepAtZero(values(step["series"][0]["x"]), values(step["series"][0]["y"])),
              2 * kCoulomb, 0.02);
  EXPECT_NEAR(StepAtZero(values(step["series"][1]["x"]), values(step["series"][1]["y"])), 0.0,
              0.02);
  const json& ripple = *PlotTitled(plots, expected[3].title);
  std::vector<double> basis;
  for (const double q : values(ripple["series"][0]["x"])) basis.push_back(Ripple(q));
  EXPECT_NEAR(Coefficient(values(ripple["series"][0]["y"]), basis), kRippleAmplitude, 0.03);
  EXPECT_NEAR(Coefficient(values(ripple["series"][1]["y"]), basis), 0.0, 0.03);

  // Each suggestion's plots are drawn in its joint's section, under a heading that names it.
  const std::string joint1 = Section(html, "joint-1"), joint2 = Section(html, "joint-2");
  EXPECT_NE(joint1.find("<h3 class=\"plot-heading\">Suggestion 1: <code>coulomb@1</code>"),
            std::string::npos);
  EXPECT_NE(joint2.find("<h3 class=\"plot-heading\">Suggestion 2: "
                        "<code>cogging@2:period=0.3</code>"),
            std::string::npos);
  EXPECT_NE(joint1.find("(RMS 0.41 &rarr; 0.05)"), std::string::npos);
  for (const auto& [section, joint] : {std::pair{joint1, 1}, std::pair{joint2, 2}}) {
    const std::vector<int> indices = PlotIndices(section);
    ASSERT_EQ(indices.size(), 5u);
    for (const int k : indices) {
      const std::string title = plots[k]["title"];
      const bool own = title.rfind("Joint " + std::to_string(joint) + ":", 0) == 0 ||
                       title.rfind("Suggestion " + std::to_string(joint) + " ", 0) == 0;
      EXPECT_TRUE(own) << "joint " << joint << " section shows '" << title << "'";
    }
  }

  // Rows that do not match the joint's samples are refused.
  ReportData bad = data;
  bad.diagnosis.suggestions[1].residual_after_rows.resize(n - 1);
  EXPECT_THROW(RenderHtml(bad), std::invalid_argument);
  bad.diagnosis.suggestions[1].residual_before_rows.resize(n - 1);
  try {
    RenderHtml(bad);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("suggestion 'cogging@2:period=0.3': residual_before_rows "
                                         "has 599 values, expected 600"),
              std::string::npos)
        << e.what();
  }

  // A report whose joints show other data than the diagnosed log (the demo: diagnosis on the
  // training log, plots of the test log): the suggestions' residuals are plotted against the
  // diagnosed log's states.
  ReportData other = MakeReport(2, 250, true);
  std::vector<JointStates> states(2);
  for (int j = 0; j < 2; ++j) {
    states[j].joint = j + 1;
    states[j].q = data.joints[j].q;
    states[j].qd = data.joints[j].qd;
  }
  other.diagnosis = data.diagnosis;
  EXPECT_THROW(RenderHtml(other), std::invalid_argument);  // 600 rows, 250 samples
  other.diagnosed_states = states;
  const json other_plots = PlotData(RenderHtml(other))["plots"];
  ASSERT_EQ(other_plots.size(), 10u);
  const json* shown = PlotTitled(other_plots, expected[0].title);
  ASSERT_NE(shown, nullptr);
  ASSERT_EQ((*shown)["series"][0]["x"].size(), static_cast<std::size_t>(n));
  EXPECT_NEAR((*shown)["series"][0]["x"][17].get<double>(), data.joints[0].qd[17],
              1e-7 * std::abs(data.joints[0].qd[17]));
  EXPECT_EQ(other_plots[0]["series"][0]["y"].size(), 250u);  // the joints' own plots
  other.diagnosed_states[1].q.pop_back();
  EXPECT_THROW(RenderHtml(other), std::invalid_argument);  // q and qd of different lengths
}

// The row of suggestion `number` in the suggestions table.
std::string SuggestionRow(const std::string& html, int number) {
  const std::string table = Section(html, "suggestions");
  const std::size_t begin = table.find("<tr><td>" + std::to_string(number) + "</td>");
  if (begin == std::string::npos) return "";
  return table.substr(begin, table.find("</tr>", begin) - begin);
}

TEST(Report, ShowsCalibrationAndConfirmationInTheSuggestionsTable) {
  ReportData data = MakeReport(2, 200, true);
  AddSuggestionRows(&data);
  const std::string html = RenderHtml(data);
  const std::string row = SuggestionRow(html, 1);
  ASSERT_FALSE(row.empty());
  for (const char* part : {
           "<td class=\"evidence\">812.3<br><span class=\"muted small\">uncorrected 5012.7",
           "inflation &times;6.17<br><span class=\"muted small\">n<sub>eff</sub> = 162<",
           "<td class=\"p\">2.4e-13<br><span class=\"muted small\">p = 1.2e-14<",
           "<td class=\"size\">7.5<br><span class=\"muted small\">z = 28.5<",
           "0.41 &rarr; 0.05<span class=\"chg better\">-88%</span>",
           "<td class=\"confirmation\">0.4 &rarr; 0.052<span class=\"chg better\">-87%</span>"
           "<br><span class=\"muted small\">blocks: 4/5 folds better (mean ratio 0.31), gap 20 rows<",
           "<td class=\"text\">joint</td>", "<code>coulomb@1</code>"}) {
    EXPECT_NE(row.find(part), std::string::npos) << "missing: " << part << "\nrow: " << row;
  }
  const std::string row2 = SuggestionRow(html, 2);
  EXPECT_NE(row2.find("trajectories: 3/3 folds better (mean ratio 0.87), gap 0 rows"), std::string::npos) << row2;
  // A change that only the diagnosed log has says so under its selection.
  EXPECT_NE(row2.find("<td class=\"text\">greedy<br><span class=\"muted small\">in this log only<"),
            std::string::npos) << row2;
  EXPECT_EQ(row.find("in this log only"), std::string::npos) << row;
  EXPECT_EQ(row2.find("blocks"), std::string::npos) << row2;
}

TEST(Report, ShowsTheVerdictFirstWithItsMessage) {
  struct Case {
    Verdict verdict;
    const char* name;
    const char* headline;
  };
  for (const Case& c : {Case{Verdict::kExplained, "explained", "Explained:"},
                        Case{Verdict::kCoverage, "coverage", "Coverage, not missing physics"},
                        Case{Verdict::kMissingEffect, "missing_effect", "Missing effects:"},
                        Case{Verdict::kUnexplained, "unexplained", "Unexplained:"},
                        Case{Verdict::kMissingEffect, "missing_effect",
                             "Missing effects, and error they do not explain:"}}) {
    SCOPED_TRACE(c.headline);
    ReportData data = MakeReport(2, 100, c.verdict == Verdict::kMissingEffect);
    data.diagnosis.coverage.verdict = c.verdict;
    // The second missing-effect case: a joint the suggestions do not explain.
    if (std::string(c.headline).find("and error") != std::string::npos) {
      data.diagnosis.coverage.unexplained_joints = {1};
    }
    data.diagnosis.coverage.message = std::string("because ") + kHostileFile;
    const std::string html = RenderHtml(data);
    const std::size_t verdict = html.find("<section id=\"verdict\">");
    ASSERT_NE(verdict, std::string::npos);
    // First in the page's main part, before the errors and the suggestions.
    EXPECT_LT(verdict, html.find("id=\"errors\""));
    EXPECT_LT(verdict, html.find("id=\"suggestions\""));
    const std::string section = Section(html, "verdict");
    EXPECT_NE(section.find(std::string("class=\"verdict big verdict-") + c.name +
                           "\" data-verdict=\"" + c.name + "\"><b>" + c.headline),
              std::string::npos)
        << section;
    EXPECT_NE(section.find("<span class=\"message\">because &lt;x&gt;&amp;&quot;</span>"),
              std::string::npos)
        << section;
    // No distances: no coverage section, nor a link to it.
    EXPECT_EQ(html.find("id=\"coverage\""), std::string::npos);
    EXPECT_EQ(html.find("href=\"#coverage\""), std::string::npos);
    if (c.verdict == Verdict::kCoverage) {
      EXPECT_NE(Section(html, "suggestions").find("the error is coverage, not a missing effect"),
                std::string::npos);
    }
    // No torque held at rest: no line for it.
    EXPECT_EQ(section.find("At rest:"), std::string::npos);
  }
  // Stops at one configuration that hold other torques: under the verdict, escaped.
  ReportData held = MakeReport(2, 100, false);
  held.diagnosis.holding.message = std::string("stops differ ") + kHostileFile;
  EXPECT_NE(Section(RenderHtml(held), "verdict")
                .find("<p class=\"holding-torque\"><b>At rest:</b> stops differ "
                      "&lt;x&gt;&amp;&quot;</p>"),
            std::string::npos);
  // A failed diagnosis says so, with its message.
  ReportData failed = MakeReport(1, 50, false);
  failed.diagnosis.status = DiagnosisStatus::kNumericalFailure;
  failed.diagnosis.message = "refit not positive definite";
  EXPECT_NE(Section(RenderHtml(failed), "verdict")
                .find("<b>The diagnosis failed.</b> refit not positive definite"),
            std::string::npos);
  // Without a diagnosis, no verdict.
  failed.has_diagnosis = false;
  EXPECT_EQ(RenderHtml(failed).find("id=\"verdict\""), std::string::npos);
}

TEST(Report, PlotsTheDistanceToTheTrainingStatesWithLevelOne) {
  const int points = 300;
  ReportData data = MakeReport(2, 200, false);
  AddCoverage(&data, 2, points);
  const std::string html = RenderHtml(data);
  const json plots = PlotData(html)["plots"];
  const json* plot = PlotTitled(plots, "Distance of the log's states to the training states");
  ASSERT_NE(plot, nullptr);
  EXPECT_EQ((*plot)["type"], "line");
  EXPECT_EQ((*plot)["xLabel"], "t");
  ASSERT_EQ((*plot)["levels"].size(), 1u);
  EXPECT_EQ((*plot)["levels"][0]["y"], 1.0);
  ASSERT_EQ((*plot)["series"].size(), 2u);
  const CoverageFinding& c = data.diagnosis.coverage;
  for (int k = 0; k < 2; ++k) {
    const json& s = (*plot)["series"][k];
    EXPECT_EQ(s["label"], "joint " + std::to_string(k + 1));
    ASSERT_EQ(s["y"].size(), static_cast<std::size_t>(points));
    for (int p = 0; p < points; ++p) {
      EXPECT_NEAR(s["x"][p].get<double>(), c.distance_time[p], 1e-9);
      EXPECT_NEAR(s["y"][p].get<double>(), c.distance(p, k), 1e-7 * c.distance(p, k) + 1e-15);
    }
  }
  // Drawn in the coverage section, which the verdict links to; the other plots have no levels.
  const std::string section = Section(html, "coverage");
  ASSERT_FALSE(section.empty());
  const std::vector<int> indices = PlotIndices(section);
  ASSERT_EQ(indices.size(), 1u);
  EXPECT_EQ(&plots[indices[0]], plot);
  EXPECT_NE(section.find("Error from coverage on joint 2."), std::string::npos);
  EXPECT_NE(Section(html, "verdict").find("<a href=\"#coverage\">"), std::string::npos);
  int with_levels = 0;
  for (const json& p : plots) with_levels += p.contains("levels");
  EXPECT_EQ(with_levels, 1);
  // The findings table: the refit RMS, how much of the log is outside the training data.
  const std::string findings = Section(html, "findings");
  EXPECT_NE(findings.find("<th title=\"Rows of the log farther"), std::string::npos);
  EXPECT_NE(findings.find("<tr class=\"coverage\"><td>2</td>"), std::string::npos) << findings;
  EXPECT_NE(findings.find("31% of rows, up to 4.2 sd"), std::string::npos) << findings;
  EXPECT_NE(findings.find("0% of rows, up to 0.93 sd"), std::string::npos) << findings;
  EXPECT_NE(findings.find("<td>0.051<br><span class=\"muted small\">coverage</span>"),
            std::string::npos)
      << findings;
  // Joint 2's section says its error is coverage; joint 1's does not.
  EXPECT_NE(Section(html, "joint-2").find("<b>Coverage:</b> refitted on the log, the model "
                                          "reaches 0.051 against 0.4"),
            std::string::npos);
  EXPECT_EQ(Section(html, "joint-1").find("<b>Coverage:</b>"), std::string::npos);

  // Thinned like every series.
  const json thinned = PlotData(RenderHtml(data, 100))["plots"];
  EXPECT_EQ(PlotTitled(thinned, (*plot)["title"])->at("series")[1]["y"].size(), 100u);

  // Times and distances that disagree are refused.
  data.diagnosis.coverage.distance_time.resize(points - 1);
  EXPECT_THROW(RenderHtml(data), std::invalid_argument);
}

// ---- headless browser -------------------------------------------------------------------------

// Chromium's path: $STRUCTGP_CHROMIUM, else chromium or chromium-browser on the PATH; empty
// when there is none.
std::string FindChromium() {
  if (const char* env = std::getenv("STRUCTGP_CHROMIUM"); env != nullptr && *env != '\0') {
    return env;
  }
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path != nullptr ? path : "");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    for (const char* name : {"chromium", "chromium-browser"}) {
      const fs::path candidate = fs::path(dir) / name;
      if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    }
  }
  return "";
}

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// The argument quoted for the shell (the paths used here hold no single quote).
std::string Quoted(const std::string& argument) {
  EXPECT_EQ(argument.find('\''), std::string::npos) << argument;
  return "'" + argument + "'";
}

// Runs Chromium headless, with a fresh profile, on `url` with `action` (--dump-dom or
// --screenshot=...). Returns the exit status; stdout and stderr go to the files named.
int RunChromium(const std::string& chromium, const fs::path& dir, const std::string& url,
                const std::string& action, const fs::path& out, const fs::path& err) {
  const fs::path profile = dir / ("profile-" + out.stem().string());
  const std::vector<std::string> arguments = {
      "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
      "--disable-background-networking", "--disable-component-update", "--disable-sync",
      "--hide-scrollbars", "--window-size=1280,1600", "--user-data-dir=" + profile.string(),
      "--enable-logging=stderr", "--v=0", "--virtual-time-budget=5000", action, url};
  std::string command = "timeout 60 " + Quoted(chromium);
  for (const std::string& argument : arguments) command += " " + Quoted(argument);
  command += " > " + Quoted(out.string()) + " 2> " + Quoted(err.string());
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string Attribute(const std::string& tag, const std::string& name) {
  const std::regex pattern(name + "=\"([^\"]*)\"");
  std::smatch match;
  return std::regex_search(tag, match, pattern) ? match[1].str() : "<absent>";
}

// Pixels of a PNG file as 0xRRGGBB (8-bit RGB or RGBA, not interlaced: what Chromium writes).
std::vector<std::uint32_t> DecodePng(const std::string& png, int* width, int* height) {
  const auto u32 = [&](std::size_t at) {
    return (std::uint32_t{static_cast<unsigned char>(png[at])} << 24) |
           (std::uint32_t{static_cast<unsigned char>(png[at + 1])} << 16) |
           (std::uint32_t{static_cast<unsigned char>(png[at + 2])} << 8) |
           std::uint32_t{static_cast<unsigned char>(png[at + 3])};
  };
  if (png.size() < 8 || png.compare(0, 8, "\x89PNG\r\n\x1a\n") != 0) {
    throw std::runtime_error("not a PNG file");
  }
  std::string idat;
  int channels = 0;
  for (std::size_t at = 8; at + 8 <= png.size();) {
    const std::uint32_t length = u32(at);
    const std::string type = png.substr(at + 4, 4);
    if (at + 12 + length > png.size()) throw std::runtime_error("truncated PNG chunk");
    const std::size_t data = at + 8;
    if (type == "IHDR") {
      *width = static_cast<int>(u32(data));
      *height = static_cast<int>(u32(data + 4));
      const int depth = png[data + 8], color = png[data + 9], interlace = png[data + 12];
      if (depth != 8 || (color != 2 && color != 6) || interlace != 0) {
        throw std::runtime_error("unsupported PNG format");
      }
      channels = color == 6 ? 4 : 3;
    } else if (type == "IDAT") {
      idat.append(png, data, length);
    }
    at += 12 + length;
  }
  if (channels == 0) throw std::runtime_error("PNG without IHDR");
  const std::size_t stride = static_cast<std::size_t>(*width) * channels;
  std::vector<unsigned char> raw((stride + 1) * *height);
  uLongf raw_size = raw.size();
  if (uncompress(raw.data(), &raw_size, reinterpret_cast<const Bytef*>(idat.data()), idat.size()) !=
          Z_OK ||
      raw_size != raw.size()) {
    throw std::runtime_error("bad PNG image data");
  }
  // Undo the per-row filters (PNG specification, section 9).
  std::vector<unsigned char> image(stride * *height), zero(stride, 0);
  for (int y = 0; y < *height; ++y) {
    const unsigned char* in = &raw[y * (stride + 1) + 1];
    const int filter = raw[y * (stride + 1)];
    unsigned char* row = &image[y * stride];
    const unsigned char* up = y > 0 ? &image[(y - 1) * stride] : zero.data();
    for (std::size_t i = 0; i < stride; ++i) {
      const int a = i >= static_cast<std::size_t>(channels) ? row[i - channels] : 0;
      const int b = up[i];
      const int c = i >= static_cast<std::size_t>(channels) ? up[i - channels] : 0;
      int predictor = 0;
      switch (filter) {
        case 0:
          predictor = 0;
          break;
        case 1:
          predictor = a;
          break;
        case 2:
          predictor = b;
          break;
        case 3:
          predictor = (a + b) / 2;
          break;
        case 4: {
          const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
          predictor = (pa <= pb && pa <= pc) ? a : (pb <= pc ? b : c);
          break;
        }
        default:
          throw std::runtime_error("bad PNG filter");
      }
      row[i] = static_cast<unsigned char>(in[i] + predictor);
    }
  }
  std::vector<std::uint32_t> pixels(static_cast<std::size_t>(*width) * *height);
  for (std::size_t p = 0; p < pixels.size(); ++p) {
    const unsigned char* px = &image[p * channels];
    pixels[p] = (std::uint32_t{px[0]} << 16) | (std::uint32_t{px[1]} << 8) | px[2];
  }
  return pixels;
}

TEST(ReportBrowser, RendersEveryPlotWithoutScriptErrors) {
  const std::string chromium = FindChromium();
  if (chromium.empty()) {
    GTEST_SKIP() << "chromium is not installed (scripts/install-deps.sh installs it; or set "
                    "STRUCTGP_CHROMIUM): the report's browser test is skipped";
  }
  const fs::path dir =
      fs::temp_directory_path() / ("structgp-report-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);

  ReportData data = MakeReport(2, 5000, true);
  AddSuggestionRows(&data);
  AddCoverage(&data, 3, 400);
  data.title = kHostileLabel;
  data.data_source = kHostileFile;
  data.joints[1].predictions[1].label = kHostileLabel;
  data.joints[0].measured[1234] = std::numeric_limits<double>::quiet_NaN();
  // A joint with measurements only, and no time: plotted against the sample index.
  std::mt19937 rng(kSeed);
  data.joints.push_back(MakeJoint(3, 2000, &rng));
  data.joints.back().predictions.clear();
  data.joints.back().t.clear();
  // A signal over time on joint 1 (a replay's one-step-ahead error), with a gap.
  {
    TimeSeries error{"measured - one-step-ahead prediction", {}};
    for (std::size_t i = 0; i < data.joints[0].measured.size(); ++i) {
      error.values.push_back(data.joints[0].measured[i] - data.joints[0].predictions[0].mean[i]);
    }
    error.values[10] = std::numeric_limits<double>::quiet_NaN();
    data.joints[0].signal_plots.push_back({"one-step-ahead error over time", "torque error",
                                           {error}});
  }
  const fs::path page = dir / "report.html";
  {
    std::ofstream out(page, std::ios::binary);
    out << RenderHtml(data, 1500);
    ASSERT_TRUE(out.good());
  }
  // Joints 1 and 2: torque, residual vs qd and q, and their suggestion's two plots (joint 1
  // also the signal over time); joint 3: torque; the coverage plot.
  const int num_plots = 6 + 5 + 1 + 1;

  // 1. The DOM after the page's script has run, with its zoom/hover self-test.
  const int dom_status = RunChromium(chromium, dir, "file://" + page.string() + "#selftest",
                                     "--dump-dom", dir / "dom.html", dir / "dom.log");
  ASSERT_EQ(dom_status, 0) << ReadFile(dir / "dom.log");
  const std::string dom = ReadFile(dir / "dom.html");
  const std::string log = ReadFile(dir / "dom.log");
  std::smatch match;
  ASSERT_TRUE(std::regex_search(dom, match, std::regex("<div id=\"status\"[^>]*>")))
      << dom.substr(0, 2000);
  const std::string status = match[0].str();
  // The status element with the error messages the page wrote into it.
  const std::size_t status_at = static_cast<std::size_t>(match.position(0));
  const std::string messages = dom.substr(status_at, dom.find("<script", status_at) - status_at);
  EXPECT_EQ(Attribute(status, "data-state"), "done") << status;
  EXPECT_EQ(Attribute(status, "data-errors"), "0") << messages;
  EXPECT_EQ(Attribute(status, "data-plots"), std::to_string(num_plots));
  EXPECT_EQ(Attribute(status, "data-plots-rendered"), std::to_string(num_plots));
  EXPECT_EQ(Attribute(status, "data-selftest"), "passed");
  // Every plot drew marks.
  int plots = 0;
  const std::regex marks("data-marks=\"([0-9]+)\"");
  for (auto it = std::sregex_iterator(dom.begin(), dom.end(), marks); it != std::sregex_iterator();
       ++it, ++plots) {
    EXPECT_GT(std::stoi((*it)[1].str()), 0) << "plot " << plots << " is blank";
  }
  EXPECT_EQ(plots, num_plots);
  // The coverage plot drew its level-1 line (its distances of joint 1 reach 1 only, those of
  // joints 2 and 3 go above it).
  ASSERT_TRUE(std::regex_search(dom, match, std::regex("data-levels=\"([0-9]+)\"")));
  EXPECT_EQ(match[1].str(), "1");
  EXPECT_EQ(CountOf(dom, "data-levels="), 1);
  // The hostile label is text, not markup.
  EXPECT_EQ(dom.find("<script>window.pwned"), std::string::npos);
  EXPECT_EQ(dom.find("<b>x</b>"), std::string::npos);
  // Nothing on the console: no uncaught error, no message at all from the page.
  std::istringstream lines(log);
  std::string line;
  while (std::getline(lines, line)) {
    EXPECT_EQ(line.find("Uncaught"), std::string::npos) << line;
    EXPECT_EQ(line.find(":CONSOLE"), std::string::npos) << line;
  }

  // 2. A screenshot: the page is not one colour, and draws in many.
  const fs::path shot = dir / "report.png";
  const int shot_status =
      RunChromium(chromium, dir, "file://" + page.string(), "--screenshot=" + shot.string(),
                  dir / "shot.out", dir / "shot.log");
  ASSERT_EQ(shot_status, 0) << ReadFile(dir / "shot.log");
  int width = 0, height = 0;
  const std::vector<std::uint32_t> pixels = DecodePng(ReadFile(shot), &width, &height);
  EXPECT_EQ(width, 1280);
  EXPECT_EQ(height, 1600);
  const std::unordered_set<std::uint32_t> colours(pixels.begin(), pixels.end());
  EXPECT_GT(colours.size(), 50u);
  const auto background = std::count(pixels.begin(), pixels.end(), pixels.front());
  EXPECT_LT(background, static_cast<long>(0.97 * pixels.size()));

  if (!HasFailure()) {
    fs::remove_all(dir);
  } else {
    std::printf("browser test files kept in %s\n", dir.c_str());
  }
}

}  // namespace
}  // namespace report
}  // namespace structgp
