#include "structgp/feature/effects.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace structgp {

std::vector<std::string> Effect::basis_names() const {
  if (num_bases() == 1) return {name()};
  std::vector<std::string> names;
  for (int i = 1; i <= num_bases(); ++i) names.push_back(name() + "." + std::to_string(i));
  return names;
}

namespace {

constexpr double kTwoPi = 6.283185307179586;

// Reads parameters with defaults; rejects unknown keys and out-of-range values.
class ParameterReader {
 public:
  ParameterReader(std::string effect, const EffectParameters& params)
      : effect_(std::move(effect)), params_(params) {}

  double Get(const std::string& key, double fallback, double lo, double hi) {
    known_.push_back(key);
    auto it = params_.find(key);
    const double v = it == params_.end() ? fallback : it->second;
    if (!std::isfinite(v) || v < lo || v > hi) {
      std::ostringstream os;
      os << "effect '" << effect_ << "': parameter " << key << " must be in [" << lo << ", "
         << hi << "], got " << v;
      throw std::invalid_argument(os.str());
    }
    return v;
  }
  double Require(const std::string& key, double lo, double hi) {
    if (params_.find(key) == params_.end()) {
      throw std::invalid_argument("effect '" + effect_ + "': parameter " + key +
                                  " is required (e.g. " + effect_ + "@1:" + key + "=0.5)");
    }
    return Get(key, 0.0, lo, hi);
  }
  // Call after all Get/Require: throws on a key the effect does not know.
  void Finish() const {
    for (const auto& [key, value] : params_) {
      bool ok = false;
      for (const auto& k : known_) ok = ok || k == key;
      if (!ok) {
        std::string list;
        for (const auto& k : known_) list += (list.empty() ? "" : ", ") + k;
        throw std::invalid_argument("effect '" + effect_ + "' has no parameter '" + key +
                                    "' (accepted: " + (list.empty() ? "none" : list) + ")");
      }
    }
  }

 private:
  std::string effect_;
  const EffectParameters& params_;
  std::vector<std::string> known_;
};

class ViscousEffect : public Effect {
 public:
  std::string name() const override { return "viscous"; }
  int num_bases() const override { return 1; }
  void Evaluate(double, double qd, double, double, double* out) const override { out[0] = qd; }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<ViscousEffect>(*this); }
};

class CoulombEffect : public Effect {
 public:
  explicit CoulombEffect(double width) : width_(width) {}
  std::string name() const override { return "coulomb"; }
  int num_bases() const override { return 1; }
  void Evaluate(double, double qd, double, double, double* out) const override {
    out[0] = std::tanh(qd / width_);
  }
  std::map<std::string, double> parameters() const override { return {{"width", width_}}; }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<CoulombEffect>(*this); }

 private:
  double width_;
};

class StribeckEffect : public Effect {
 public:
  StribeckEffect(double velocity, double width) : velocity_(velocity), width_(width) {}
  std::string name() const override { return "stribeck"; }
  int num_bases() const override { return 1; }
  void Evaluate(double, double qd, double, double, double* out) const override {
    const double r = qd / velocity_;
    out[0] = std::exp(-r * r) * std::tanh(qd / width_);
  }
  std::map<std::string, double> parameters() const override {
    return {{"velocity", velocity_}, {"width", width_}};
  }
  std::unique_ptr<Effect> Clone() const override {
    return std::make_unique<StribeckEffect>(*this);
  }

 private:
  double velocity_, width_;
};

class OffsetEffect : public Effect {
 public:
  std::string name() const override { return "offset"; }
  int num_bases() const override { return 1; }
  bool joint_independent() const override { return true; }
  void Evaluate(double, double, double, double, double* out) const override { out[0] = 1.0; }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<OffsetEffect>(*this); }
};

class CoggingEffect : public Effect {
 public:
  CoggingEffect(double period, int harmonics) : period_(period), harmonics_(harmonics) {}
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
  std::map<std::string, double> parameters() const override {
    return {{"period", period_}, {"harmonics", static_cast<double>(harmonics_)}};
  }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<CoggingEffect>(*this); }

 private:
  double period_;
  int harmonics_;
};

class SpringEffect : public Effect {
 public:
  std::string name() const override { return "spring"; }
  int num_bases() const override { return 1; }
  void Evaluate(double q, double, double, double, double* out) const override { out[0] = q; }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<SpringEffect>(*this); }
};

class DriftEffect : public Effect {
 public:
  DriftEffect(double t0, double span, double width) : t0_(t0), span_(span), width_(width) {}
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
  std::map<std::string, double> parameters() const override {
    return {{"t0", t0_}, {"span", span_}, {"width", width_}};
  }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<DriftEffect>(*this); }

 private:
  double t0_, span_, width_;
};

using Factory = std::function<std::unique_ptr<Effect>(const EffectParameters&)>;

std::vector<std::pair<std::string, Factory>>& Registry() {
  static std::vector<std::pair<std::string, Factory>> registry = {
      {"viscous",
       [](const EffectParameters& p) {
         ParameterReader("viscous", p).Finish();
         return std::unique_ptr<Effect>(new ViscousEffect());
       }},
      {"coulomb",
       [](const EffectParameters& p) {
         ParameterReader r("coulomb", p);
         const double width = r.Get("width", 0.01, 1e-9, 1e9);
         r.Finish();
         return std::unique_ptr<Effect>(new CoulombEffect(width));
       }},
      {"stribeck",
       [](const EffectParameters& p) {
         ParameterReader r("stribeck", p);
         const double velocity = r.Get("velocity", 0.1, 1e-9, 1e9);
         const double width = r.Get("width", 0.01, 1e-9, 1e9);
         r.Finish();
         return std::unique_ptr<Effect>(new StribeckEffect(velocity, width));
       }},
      {"offset",
       [](const EffectParameters& p) {
         ParameterReader("offset", p).Finish();
         return std::unique_ptr<Effect>(new OffsetEffect());
       }},
      {"cogging",
       [](const EffectParameters& p) {
         ParameterReader r("cogging", p);
         const double period = r.Require("period", 1e-6, 1e6);
         const double harmonics = r.Get("harmonics", 1.0, 1.0, 20.0);
         r.Finish();
         if (harmonics != std::floor(harmonics)) {
           throw std::invalid_argument("effect 'cogging': harmonics must be an integer, got " +
                                       std::to_string(harmonics));
         }
         return std::unique_ptr<Effect>(new CoggingEffect(period, static_cast<int>(harmonics)));
       }},
      {"spring",
       [](const EffectParameters& p) {
         ParameterReader("spring", p).Finish();
         return std::unique_ptr<Effect>(new SpringEffect());
       }},
      {"drift",
       [](const EffectParameters& p) {
         ParameterReader r("drift", p);
         const double t0 = r.Get("t0", 0.0, -1e12, 1e12);
         const double span = r.Get("span", 1.0, 1e-9, 1e12);
         const double width = r.Get("width", 0.01, 1e-9, 1e9);
         r.Finish();
         return std::unique_ptr<Effect>(new DriftEffect(t0, span, width));
       }},
  };
  return registry;
}

}  // namespace

std::unique_ptr<Effect> MakeEffect(const std::string& name, const EffectParameters& params) {
  for (const auto& [key, factory] : Registry()) {
    if (key == name) return factory(params);
  }
  std::string list;
  for (const auto& n : EffectNames()) list += (list.empty() ? "" : ", ") + n;
  throw std::invalid_argument("unknown effect '" + name + "' (known: " + list + ")");
}

std::vector<std::string> EffectNames() {
  std::vector<std::string> names;
  for (const auto& entry : Registry()) names.push_back(entry.first);
  return names;
}

void RegisterEffect(const std::string& name, Factory factory) {
  if (name.empty() || name.find_first_of("@:,=+ ") != std::string::npos) {
    throw std::invalid_argument("RegisterEffect: '" + name +
                                "' is not a valid effect name (no spaces or @ : , = +)");
  }
  for (const auto& entry : Registry()) {
    if (entry.first == name) {
      throw std::invalid_argument("RegisterEffect: effect '" + name + "' already exists");
    }
  }
  Registry().emplace_back(name, std::move(factory));
}

}  // namespace structgp
