#include "structgp/feature/effects.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <Eigen/Cholesky>

#include "structgp/feature/friction_feature_map.h"

namespace structgp {

// ---- parameter descriptions ------------------------------------------------------------------

namespace {

std::string Number(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// Characters of the effect-list grammar (model/model_spec.h); not allowed in names.
constexpr const char* kGrammarCharacters = "@:,;=+/ \t";

bool ValidName(const std::string& name) {
  return !name.empty() && name.find_first_of(kGrammarCharacters) == std::string::npos;
}

}  // namespace

std::string EffectParameter::ExpectedText() const {
  const bool lo = std::isfinite(valid.min), hi = std::isfinite(valid.max);
  std::string text;
  if (lo && hi) {
    text = "in [" + Number(valid.min) + ", " + Number(valid.max) + "]";
  } else if (lo) {
    text = ">= " + Number(valid.min);
  } else if (hi) {
    text = "<= " + Number(valid.max);
  }
  if (integer) return text.empty() ? "an integer" : "an integer " + text;
  if (text.empty()) return unit.empty() ? "a finite number" : "a finite number of " + unit;
  return unit.empty() ? text : text + " " + unit;
}

void EffectParameter::Check(const std::string& effect, double value) const {
  if (std::isfinite(value) && valid.Contains(value) && (!integer || value == std::floor(value))) {
    return;
  }
  throw std::invalid_argument("effect '" + effect + "': parameter '" + name + "' expected " +
                              ExpectedText() + ", got " + Number(value));
}

EffectParameters ResolveEffectParameters(const std::string& effect,
                                         const std::vector<EffectParameter>& info,
                                         const EffectParameters& given) {
  for (const auto& [key, value] : given) {
    bool known = false;
    for (const EffectParameter& p : info) known = known || p.name == key;
    if (!known) {
      std::string list;
      for (const EffectParameter& p : info) list += (list.empty() ? "" : ", ") + p.name;
      throw std::invalid_argument("effect '" + effect + "' has no parameter '" + key +
                                  "' (accepted: " + (list.empty() ? "none" : list) + ")");
    }
  }
  EffectParameters out;
  for (const EffectParameter& p : info) {
    const auto it = given.find(p.name);
    if (it == given.end()) {
      if (p.required) {
        throw std::invalid_argument("effect '" + effect + "': parameter '" + p.name +
                                    "' is required (e.g. " + effect + "@1:" + p.name + "=" +
                                    Number(p.default_value) + ")");
      }
      out[p.name] = p.default_value;
    } else {
      p.Check(effect, it->second);
      out[p.name] = it->second;
    }
  }
  return out;
}

// ---- Effect defaults -------------------------------------------------------------------------

std::vector<std::string> Effect::basis_names() const {
  if (num_bases() == 1) return {name()};
  std::vector<std::string> names;
  for (int i = 1; i <= num_bases(); ++i) names.push_back(name() + "." + std::to_string(i));
  return names;
}

std::vector<EffectParameters> Effect::ProposeParameters(const ResidualContext&) const {
  for (const EffectParameter& p : parameter_info()) {
    if (p.required) return {};
  }
  return {EffectParameters{}};
}

// ---- the built-in effects --------------------------------------------------------------------

namespace {

constexpr double kTwoPi = 6.283185307179586;

EffectParameter Param(std::string name, std::string unit, double default_value, double min,
                      double max, std::string description) {
  EffectParameter p;
  p.name = std::move(name);
  p.unit = std::move(unit);
  p.default_value = default_value;
  p.valid = ParameterRange{min, max};
  p.description = std::move(description);
  return p;
}

// The width of a tanh step in velocity (Coulomb, Stribeck, drift).
EffectParameter WidthParam() {
  return Param("width", "rad/s", 0.01, 1e-9, 1e9, "velocity scale of the tanh step");
}

std::vector<std::string> FrictionBlock() { return {FrictionFeatureMap::kBlockName}; }

class ViscousEffect : public Effect {
 public:
  static std::vector<EffectParameter> Parameters() { return {}; }
  explicit ViscousEffect(const EffectParameters&) {}
  std::string name() const override { return "viscous"; }
  int num_bases() const override { return 1; }
  void Evaluate(double, double qd, double, double, double* out) const override { out[0] = qd; }
  std::string Describe() const override { return "viscous friction"; }
  std::vector<std::string> spanned_by() const override { return FrictionBlock(); }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<ViscousEffect>(*this); }
};

class CoulombEffect : public Effect {
 public:
  static std::vector<EffectParameter> Parameters() { return {WidthParam()}; }
  explicit CoulombEffect(const EffectParameters& p) : width_(p.at("width")) {}
  std::string name() const override { return "coulomb"; }
  int num_bases() const override { return 1; }
  void Evaluate(double, double qd, double, double, double* out) const override {
    out[0] = std::tanh(qd / width_);
  }
  std::vector<EffectParameter> parameter_info() const override { return Parameters(); }
  EffectParameters parameters() const override { return {{"width", width_}}; }
  std::string Describe() const override { return "Coulomb friction"; }
  std::vector<std::string> spanned_by() const override { return FrictionBlock(); }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<CoulombEffect>(*this); }

 private:
  double width_;
};

class StribeckEffect : public Effect {
 public:
  static std::vector<EffectParameter> Parameters() {
    return {Param("velocity", "rad/s", 0.1, 1e-9, 1e9,
                  "Stribeck velocity: the friction falls off as exp(-(qd / velocity)^2)"),
            WidthParam()};
  }
  explicit StribeckEffect(const EffectParameters& p)
      : velocity_(p.at("velocity")), width_(p.at("width")) {}
  std::string name() const override { return "stribeck"; }
  int num_bases() const override { return 1; }
  void Evaluate(double, double qd, double, double, double* out) const override {
    const double r = qd / velocity_;
    out[0] = std::exp(-r * r) * std::tanh(qd / width_);
  }
  std::vector<EffectParameter> parameter_info() const override { return Parameters(); }
  EffectParameters parameters() const override {
    return {{"velocity", velocity_}, {"width", width_}};
  }
  std::string Describe() const override { return "Stribeck friction"; }
  /// The velocity on a grid relative to the joint's largest speed; the diagnosis chooses among
  /// them by evidence.
  std::vector<EffectParameters> ProposeParameters(const ResidualContext& c) const override {
    const double qd_scale = c.qd.size() ? std::max(1e-6, c.qd.cwiseAbs().maxCoeff()) : 1e-6;
    std::vector<EffectParameters> out;
    for (double rel : {0.02, 0.05, 0.1, 0.2}) out.push_back({{"velocity", rel * qd_scale}});
    return out;
  }
  std::unique_ptr<Effect> Clone() const override {
    return std::make_unique<StribeckEffect>(*this);
  }

 private:
  double velocity_, width_;
};

class OffsetEffect : public Effect {
 public:
  static std::vector<EffectParameter> Parameters() { return {}; }
  explicit OffsetEffect(const EffectParameters&) {}
  std::string name() const override { return "offset"; }
  int num_bases() const override { return 1; }
  bool joint_independent() const override { return true; }
  void Evaluate(double, double, double, double, double* out) const override { out[0] = 1.0; }
  std::string Describe() const override { return "a torque offset"; }
  std::vector<std::string> spanned_by() const override { return FrictionBlock(); }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<OffsetEffect>(*this); }
};

// Periods in [lo, hi] at which a sinusoid in q explains most of the residual r (least squares
// on sin, cos, 1): the largest local maxima of that periodogram on a log grid of 400 periods,
// each refined by a ternary search around it, the best first.
std::vector<double> EstimateCoggingPeriods(const ConstVectorRef& q, const ConstVectorRef& r,
                                           double lo, double hi, int max_peaks) {
  const int n = static_cast<int>(q.size());
  auto explained = [&](double period) {
    Eigen::Matrix3d G = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    for (int i = 0; i < n; ++i) {
      const double a = kTwoPi * q[i] / period;
      const Eigen::Vector3d f(std::sin(a), std::cos(a), 1.0);
      G += f * f.transpose();
      b += f * r[i];
    }
    G.diagonal().array() += 1e-9 * (G.trace() + 1.0);
    return b.dot(G.ldlt().solve(b));
  };
  const int grid = 400;
  const double step = std::pow(hi / lo, 1.0 / (grid - 1.0));
  std::vector<double> period(grid), value(grid);
  for (int g = 0; g < grid; ++g) {
    period[g] = lo * std::pow(hi / lo, g / (grid - 1.0));
    value[g] = explained(period[g]);
  }
  std::vector<int> peaks;
  for (int g = 0; g < grid; ++g) {
    const bool left = g == 0 || value[g] >= value[g - 1];
    const bool right = g + 1 == grid || value[g] > value[g + 1];
    if (left && right) peaks.push_back(g);
  }
  std::sort(peaks.begin(), peaks.end(), [&](int a, int b) { return value[a] > value[b]; });
  if (static_cast<int>(peaks.size()) > max_peaks) peaks.resize(static_cast<size_t>(max_peaks));
  std::vector<double> out;
  for (int g : peaks) {
    double a = std::max(lo, period[g] / step), c = std::min(hi, period[g] * step);
    for (int it = 0; it < 40; ++it) {
      const double m1 = a + (c - a) / 3, m2 = c - (c - a) / 3;
      if (explained(m1) > explained(m2)) c = m2; else a = m1;
    }
    out.push_back(0.5 * (a + c));
  }
  return out;
}

class CoggingEffect : public Effect {
 public:
  static std::vector<EffectParameter> Parameters() {
    EffectParameter period = Param("period", "rad", 0.5, 1e-6, 1e6,
                                   "period of the ripple in the joint position");
    period.required = true;
    period.search = ParameterRange{0.02, 3.0};
    EffectParameter harmonics =
        Param("harmonics", "", 1.0, 1.0, 20.0, "number of harmonics of the ripple");
    harmonics.integer = true;
    return {period, harmonics};
  }
  explicit CoggingEffect(const EffectParameters& p)
      : period_(p.at("period")), harmonics_(static_cast<int>(p.at("harmonics"))) {}
  std::string name() const override { return "cogging"; }
  int num_bases() const override { return 2 * harmonics_; }
  std::vector<std::string> basis_names() const override {
    std::vector<std::string> names;
    for (int k = 1; k <= harmonics_; ++k) {
      const std::string suffix = k == 1 ? "" : std::to_string(k);
      names.push_back("sin" + suffix);
      names.push_back("cos" + suffix);
    }
    return names;
  }
  void Evaluate(double q, double, double, double, double* out) const override {
    for (int k = 1; k <= harmonics_; ++k) {
      const double a = kTwoPi * k * q / period_;
      out[2 * (k - 1)] = std::sin(a);
      out[2 * (k - 1) + 1] = std::cos(a);
    }
  }
  std::vector<EffectParameter> parameter_info() const override { return Parameters(); }
  EffectParameters parameters() const override {
    return {{"period", period_}, {"harmonics", static_cast<double>(harmonics_)}};
  }
  std::string Describe() const override {
    char text[64];
    std::snprintf(text, sizeof(text), "cogging (period %.3g rad)", period_);
    return text;
  }
  /// The period whose sinusoid in q best explains the residual (searched in
  /// context.SearchRange("period"), up to half the range q sweeps on the rows: a ripple needs
  /// two periods to be told from a smooth function of q): of the five largest peaks of that periodogram, the one of
  /// highest context.score (the largest when there is no score). The residual of a refit is
  /// distorted where the model absorbed part of the ripple, so the estimate comes with
  /// alternatives on a +-15% grid around it (within the search range), among which the
  /// diagnosis chooses by evidence.
  std::vector<EffectParameters> ProposeParameters(const ResidualContext& c) const override {
    if (c.q.size() == 0 || c.residual.size() != c.q.size()) return {};
    ParameterRange range = c.SearchRange("period");
    // A ripple is told from the model's smooth functions of q only where q sweeps at least
    // two of its periods on these rows: longer periods are not tried.
    range.max = std::min(range.max, 0.5 * (c.q.maxCoeff() - c.q.minCoeff()));
    if (!(range.max > range.min)) return {};
    // A residual much larger than the ripple (a model far from the data) has periodogram
    // peaks of its own; the largest few are scored by evidence when the caller can score.
    const std::vector<double> peaks =
        EstimateCoggingPeriods(c.q, c.residual, range.min, range.max, c.score ? 5 : 1);
    if (peaks.empty()) return {};
    double period = peaks.front(), best = -HUGE_VAL;
    if (c.score) {
      for (double p : peaks) {
        const double gain = c.score({{"period", p}});
        if (gain > best) best = gain, period = p;
      }
    }
    std::vector<EffectParameters> out;
    // The grid stays inside the search range (an estimate at its edge gets a one-sided grid).
    for (int g = -6; g <= 6; ++g) {
      const double p = period * (1.0 + 0.025 * g);
      if (p >= range.min && p <= range.max) out.push_back({{"period", p}});
    }
    if (out.empty()) out.push_back({{"period", period}});
    return out;
  }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<CoggingEffect>(*this); }

 private:
  double period_;
  int harmonics_;
};

class SpringEffect : public Effect {
 public:
  static std::vector<EffectParameter> Parameters() { return {}; }
  explicit SpringEffect(const EffectParameters&) {}
  std::string name() const override { return "spring"; }
  int num_bases() const override { return 1; }
  void Evaluate(double q, double, double, double, double* out) const override { out[0] = q; }
  std::string Describe() const override { return "a spring"; }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<SpringEffect>(*this); }
};

class DriftEffect : public Effect {
 public:
  static std::vector<EffectParameter> Parameters() {
    return {Param("t0", "s", 0.0, -1e12, 1e12, "time at which the drift is zero"),
            Param("span", "s", 1.0, 1e-9, 1e12, "time over which the drift grows by one unit"),
            WidthParam()};
  }
  explicit DriftEffect(const EffectParameters& p)
      : t0_(p.at("t0")), span_(p.at("span")), width_(p.at("width")) {}
  std::string name() const override { return "drift"; }
  int num_bases() const override { return 3; }
  std::vector<std::string> basis_names() const override { return {"coulomb", "viscous", "offset"}; }
  bool uses_time() const override { return true; }
  void Evaluate(double, double qd, double, double t, double* out) const override {
    const double s = (t - t0_) / span_;
    out[0] = s * std::tanh(qd / width_);
    out[1] = s * qd;
    out[2] = s;
  }
  std::vector<EffectParameter> parameter_info() const override { return Parameters(); }
  EffectParameters parameters() const override {
    return {{"t0", t0_}, {"span", span_}, {"width", width_}};
  }
  std::string Describe() const override { return "drifting friction"; }
  /// t0 and span of the log (nothing without a time column).
  std::vector<EffectParameters> ProposeParameters(const ResidualContext& c) const override {
    if (c.t.size() == 0) return {};
    const double t0 = c.t.minCoeff();
    const double span = std::max(c.t.maxCoeff() - t0, 1e-9);
    return {{{"t0", t0}, {"span", span}}};
  }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<DriftEffect>(*this); }

 private:
  double t0_, span_, width_;
};

struct Entry {
  std::string name;
  std::vector<EffectParameter> parameters;
  EffectFactory factory;
};

template <class E>
Entry BuiltIn(const std::string& name) {
  return Entry{name, E::Parameters(),
               [](const EffectParameters& p) { return std::unique_ptr<Effect>(new E(p)); }};
}

// The one list of built-in effects, in the order of the table in effects.h.
std::vector<Entry>& Registry() {
  static std::vector<Entry> registry = {
      BuiltIn<ViscousEffect>("viscous"), BuiltIn<CoulombEffect>("coulomb"),
      BuiltIn<StribeckEffect>("stribeck"), BuiltIn<OffsetEffect>("offset"),
      BuiltIn<CoggingEffect>("cogging"), BuiltIn<SpringEffect>("spring"),
      BuiltIn<DriftEffect>("drift"),
  };
  return registry;
}

const Entry& Find(const std::string& name) {
  for (const Entry& e : Registry()) {
    if (e.name == name) return e;
  }
  std::string list;
  for (const auto& n : EffectNames()) list += (list.empty() ? "" : ", ") + n;
  throw std::invalid_argument("unknown effect '" + name + "' (known: " + list + ")");
}

EffectParameters Defaults(const std::vector<EffectParameter>& info) {
  EffectParameters p;
  for (const EffectParameter& d : info) p[d.name] = d.default_value;
  return p;
}

}  // namespace

std::unique_ptr<Effect> MakeEffect(const std::string& name, const EffectParameters& params) {
  const Entry& e = Find(name);
  return e.factory(ResolveEffectParameters(name, e.parameters, params));
}

std::unique_ptr<Effect> MakeEffectPrototype(const std::string& name) {
  const Entry& e = Find(name);
  return e.factory(Defaults(e.parameters));
}

std::vector<EffectParameter> EffectParameterInfo(const std::string& name) {
  return Find(name).parameters;
}

std::vector<std::string> EffectNames() {
  std::vector<std::string> names;
  for (const Entry& entry : Registry()) names.push_back(entry.name);
  return names;
}

void RegisterEffect(const std::string& name, std::vector<EffectParameter> parameters,
                    EffectFactory factory) {
  const std::string what = "RegisterEffect('" + name + "'): ";
  if (!ValidName(name)) {
    throw std::invalid_argument(what + "not a valid effect name (expected a non-empty name "
                                       "without spaces or any of @ : , ; = + /)");
  }
  for (const Entry& entry : Registry()) {
    if (entry.name == name) throw std::invalid_argument(what + "the effect already exists");
  }
  if (!factory) throw std::invalid_argument(what + "null factory");
  std::set<std::string> names;
  for (const EffectParameter& p : parameters) {
    if (!ValidName(p.name)) {
      throw std::invalid_argument(what + "parameter name '" + p.name +
                                  "' is not valid (non-empty, no spaces or @ : , ; = + /)");
    }
    if (!names.insert(p.name).second) {
      throw std::invalid_argument(what + "parameter '" + p.name + "' declared twice");
    }
    if (!(p.valid.min <= p.valid.max)) {
      throw std::invalid_argument(what + "parameter '" + p.name + "': valid range [" +
                                  Number(p.valid.min) + ", " + Number(p.valid.max) +
                                  "] is empty");
    }
    if (p.search && !(p.search->min <= p.search->max)) {
      throw std::invalid_argument(what + "parameter '" + p.name + "': search range is empty");
    }
    // The default (a required parameter's example) must itself be valid: the prototype and
    // the "is required" message use it.
    p.Check(name, p.default_value);
  }
  const std::unique_ptr<Effect> prototype = factory(Defaults(parameters));
  if (!prototype) throw std::invalid_argument(what + "the factory returned null");
  if (prototype->name() != name) {
    throw std::invalid_argument(what + "the effect calls itself '" + prototype->name() + "'");
  }
  std::vector<std::string> declared, described, reported;
  for (const EffectParameter& p : parameters) declared.push_back(p.name);
  for (const EffectParameter& p : prototype->parameter_info()) described.push_back(p.name);
  for (const auto& kv : prototype->parameters()) reported.push_back(kv.first);
  if (described != declared) {
    throw std::invalid_argument(what + "the effect's parameter_info() does not list the "
                                       "registered parameters, in order");
  }
  std::sort(declared.begin(), declared.end());
  if (reported != declared) {
    throw std::invalid_argument(what + "the effect's parameters() does not report exactly the "
                                       "registered parameters (its suggestions would not parse "
                                       "back)");
  }
  Registry().push_back(Entry{name, std::move(parameters), std::move(factory)});
}

}  // namespace structgp
