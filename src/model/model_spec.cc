#include "structgp/model/model_spec.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "structgp/feature/effects.h"

namespace structgp {
namespace {

std::string Trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t");
  return s.substr(b, e - b + 1);
}

// The items of a model text between its '+' signs, as written (not trimmed).
std::vector<std::string> SplitAtPlus(const std::string& text) {
  std::vector<std::string> items;
  for (size_t start = 0;;) {
    const size_t plus = text.find('+', start);
    items.push_back(text.substr(start, plus == std::string::npos ? std::string::npos
                                                                 : plus - start));
    if (plus == std::string::npos) return items;
    start = plus + 1;
  }
}

// A base that "rbd+" may precede (a URDF's torques beside it).
bool IsKernelBase(const std::string& base) {
  return base == "pol" || base == "rbf" || base == "rbfs" || base == "motor";
}

[[noreturn]] void Fail(const std::string& text, size_t position, const std::string& message) {
  std::ostringstream os;
  os << "effect list '" << text << "', character " << position + 1 << ": " << message;
  throw std::invalid_argument(os.str());
}

bool ParseInt(const std::string& s, int* value) {
  if (s.empty() || s.size() > 9) return false;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
  }
  *value = std::atoi(s.c_str());
  return true;
}

bool ParseDouble(const std::string& s, double* value) {
  if (s.empty()) return false;
  errno = 0;
  char* end = nullptr;
  *value = std::strtod(s.c_str(), &end);
  return errno == 0 && end == s.c_str() + s.size() && std::isfinite(*value);
}

}  // namespace

const char* ToString(BaseModel base) {
  switch (base) {
    case BaseModel::kPol: return "pol";
    case BaseModel::kRbf: return "rbf";
    case BaseModel::kRbfs: return "rbfs";
    case BaseModel::kMotor: return "motor";
    case BaseModel::kRbd: return "rbd";
    case BaseModel::kLag: return "lag";
    case BaseModel::kLagk: return "lagk";
  }
  return "unknown";
}

const std::vector<BaseModel>& BaseModels() {
  static const std::vector<BaseModel> kAll = {BaseModel::kPol,   BaseModel::kRbf,
                                              BaseModel::kRbfs,  BaseModel::kMotor,
                                              BaseModel::kRbd,   BaseModel::kLag,
                                              BaseModel::kLagk};
  return kAll;
}

const char* Describe(BaseModel base) {
  switch (base) {
    case BaseModel::kPol:
      return "the structured kernel k_pol of the rigid-body dynamics (no robot parameters needed)";
    case BaseModel::kRbf: return "squared-exponential kernel on (q, qd, qdd)";
    case BaseModel::kRbfs: return "squared-exponential kernel on (cos q, sin q, qd, qdd)";
    case BaseModel::kMotor: return "the linear motor model c1 qdd + c2 qd per joint";
    case BaseModel::kRbd:
      return "the rigid-body regressor of a URDF chain, inertial parameters identified (--urdf; "
             "without one, structgp identify writes it from the torques)";
    case BaseModel::kLag:
      return "a Lagrangian regressor of a serial chain, kinematics unknown (up to 5 joints)";
    case BaseModel::kLagk:
      return "one GP of all joints on the Euler-Lagrange kernel of a serial chain, kinematics "
             "unknown (any number of joints)";
  }
  return "unknown";
}

ModelSpec ParseModelSpec(const std::string& model) {
  const std::string text = Trim(model);
  ModelSpec spec;
  // base, or "rbd+" base; then "+fri" optionally.
  std::vector<std::string> tokens = SplitAtPlus(text);
  for (std::string& token : tokens) token = Trim(token);
  size_t next = 0;
  std::string base = tokens[next++];
  if (base == "rbd" && next < tokens.size() && IsKernelBase(tokens[next])) {
    spec.rigid_body_features = true;
    base = tokens[next++];
  }
  if (next < tokens.size()) {
    const std::string rest = tokens[next++];
    if (rest != "fri" || next < tokens.size()) {
      std::string after;
      for (size_t k = next - 1; k < tokens.size(); ++k) after += (after.empty() ? "" : "+") + tokens[k];
      throw std::invalid_argument(
          "model '" + model + "': after '" + (spec.rigid_body_features ? "rbd+" : "") + base +
          "+' only 'fri' is accepted, got '" + after +
          "' (effects go in --effects, e.g. coulomb@2; a URDF's torques beside a kernel: "
          "rbd+pol, rbd+rbf, rbd+rbfs, rbd+motor)");
    }
    spec.friction = true;
  }
  bool found = false;
  std::string names;
  for (BaseModel b : BaseModels()) {
    names += (names.empty() ? "" : ", ") + std::string(ToString(b));
    if (base == ToString(b)) {
      spec.base = b;
      found = true;
    }
  }
  if (!found) {
    throw std::invalid_argument("model '" + model + "': unknown base '" + base +
                                "' (expected one of " + names +
                                ", or rbd+pol, rbd+rbf, rbd+rbfs, rbd+motor; each optionally +fri)");
  }
  return spec;
}

ModelSpec ParseModelLabel(const std::string& text) {
  // The model as ParseModelSpec reads it ("rbd+" before a kernel base, then "+fri", each only
  // as a whole item, so an effect whose name starts with "fri" still reads as an effect), then
  // after the next '+' the effect list.
  const std::vector<std::string> items = SplitAtPlus(text);
  const auto item_is = [&](size_t k, const char* word) {
    return k < items.size() && Trim(items[k]) == word;
  };
  size_t taken = 1;
  if (item_is(0, "rbd") && items.size() > 1 && IsKernelBase(Trim(items[1]))) taken = 2;
  if (item_is(taken, "fri")) ++taken;
  // items [from, to) joined again by '+'.
  const auto join = [&items](size_t from, size_t to) {
    std::string joined;
    for (size_t k = from; k < to; ++k) joined += (k > from ? "+" : "") + items[k];
    return joined;
  };
  const std::string model = join(0, taken);
  const std::string rest = join(taken, items.size());
  if (taken < items.size() && Trim(rest).empty()) {
    throw std::invalid_argument("model '" + text + "': '+' must be followed by " +
                                (item_is(taken - 1, "fri") ? "" : "'fri' or ") +
                                "effects, e.g. coulomb@2");
  }
  ModelSpec spec = ParseModelSpec(model);
  spec.effects = ParseEffectList(Trim(rest));
  return spec;
}

std::string ModelLabel(const ModelSpec& spec) {
  return ToString(spec) + (spec.effects.empty() ? "" : " + " + ToString(spec.effects));
}

std::vector<EffectSpec> ParseEffectList(const std::string& text) {
  std::vector<EffectSpec> effects;
  if (Trim(text).empty()) return effects;
  size_t start = 0;
  while (start <= text.size()) {
    size_t end = text.find(',', start);
    if (end == std::string::npos) end = text.size();
    const std::string item = text.substr(start, end - start);
    if (Trim(item).empty()) Fail(text, start, "empty item (two commas in a row, or a trailing comma?)");
    EffectSpec spec;
    std::string head = item, params;
    const auto colon = item.find(':');
    if (colon != std::string::npos) {
      head = item.substr(0, colon);
      params = item.substr(colon + 1);
    }
    std::string name = head, joints;
    const auto at = head.find('@');
    if (at != std::string::npos) {
      name = head.substr(0, at);
      joints = head.substr(at + 1);
      if (Trim(joints).empty()) Fail(text, start + at, "'@' must be followed by a joint number");
    }
    spec.name = Trim(name);
    bool known = false;
    for (const auto& n : EffectNames()) known = known || n == spec.name;
    if (!known) {
      std::string list;
      for (const auto& n : EffectNames()) list += (list.empty() ? "" : ", ") + n;
      Fail(text, start, "unknown effect '" + spec.name + "' (known: " + list + ")");
    }
    if (!joints.empty()) {
      size_t js = 0;
      while (js <= joints.size()) {
        size_t je = joints.find('/', js);
        if (je == std::string::npos) je = joints.size();
        int j = 0;
        const std::string token = Trim(joints.substr(js, je - js));
        if (!ParseInt(token, &j) || j < 1) {
          Fail(text, start + at + 1 + js,
               "joint must be a positive integer (1-based), got '" + token + "'");
        }
        spec.joints.push_back(j);
        js = je + 1;
      }
    }
    if (colon != std::string::npos) {
      size_t ps = 0;
      while (ps <= params.size()) {
        size_t pe = params.find(';', ps);
        if (pe == std::string::npos) pe = params.size();
        const std::string kv = params.substr(ps, pe - ps);
        const auto eq = kv.find('=');
        double value = 0.0;
        if (eq == std::string::npos || Trim(kv.substr(0, eq)).empty()) {
          Fail(text, start + colon + 1 + ps, "expected key=value, got '" + kv + "'");
        }
        const std::string key = Trim(kv.substr(0, eq));
        const std::string val = Trim(kv.substr(eq + 1));
        if (!ParseDouble(val, &value)) {
          Fail(text, start + colon + 1 + ps + eq + 1,
               "value of " + key + " must be a finite number, got '" + val + "'");
        }
        if (spec.params.count(key)) Fail(text, start + colon + 1 + ps, key + " given twice");
        spec.params[key] = value;
        ps = pe + 1;
      }
    }
    // Let the effect's factory check its parameters now, at the boundary.
    try {
      MakeEffect(spec.name, spec.params);
    } catch (const std::invalid_argument& e) {
      Fail(text, start, e.what());
    }
    effects.push_back(std::move(spec));
    start = end + 1;
  }
  return effects;
}

std::string ToString(const ModelSpec& spec) {
  return std::string(spec.rigid_body_features ? "rbd+" : "") + ToString(spec.base) +
         (spec.friction ? "+fri" : "");
}

std::string ToString(const EffectSpec& effect) {
  std::ostringstream os;
  os << effect.name;
  for (size_t i = 0; i < effect.joints.size(); ++i) os << (i == 0 ? "@" : "/") << effect.joints[i];
  bool first = true;
  for (const auto& [key, value] : effect.params) {
    os << (first ? ":" : ";") << key << "=";
    os.precision(17);
    os << value;
    first = false;
  }
  return os.str();
}

std::string ToString(const std::vector<EffectSpec>& effects) {
  std::string out;
  for (const auto& e : effects) out += (out.empty() ? "" : ",") + ToString(e);
  return out;
}

}  // namespace structgp
