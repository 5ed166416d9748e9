#include "structgp/rigid_body/dh_chain.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <locale>
#include <sstream>
#include <stdexcept>

#include <kdl/frames.hpp>

#include "structgp/internal/text.h"
#include "structgp/rigid_body/rigid_body_chain.h"

namespace structgp {
namespace {

// The comment's legend above the DH numbers of each joint (ChainKinematicsOfUrdf reads them).
constexpr char kDhLegend[] = "modified Denavit-Hartenberg, joint i: alpha a theta d\n";

// Numbers that read back to the same double.
std::string Num(double value) { return internal::ShortestDecimal(value); }

// Modified DH of one joint.
struct Dh {
  double alpha = 0.0, a = 0.0, theta = 0.0, d = 0.0;
};

// The same document, numbers to 1e-9 relative (another build's libm may round the origins'
// angles otherwise in the last digit), the rest character for character.
bool SameDocument(const std::string& a, const std::string& b) {
  auto tokens = [](const std::string& text) {
    std::vector<std::string> t;
    std::string current;
    for (char c : text) {
      if (std::isspace(static_cast<unsigned char>(c)) || c == '"') {
        if (!current.empty()) t.push_back(std::move(current));
        current.clear();
        t.push_back(std::string(1, c));
      } else {
        current += c;
      }
    }
    if (!current.empty()) t.push_back(std::move(current));
    return t;
  };
  auto number = [](const std::string& token, double* value) {
    std::istringstream in(token);
    in.imbue(std::locale::classic());
    return static_cast<bool>(in >> *value) && in.peek() == std::char_traits<char>::eof();
  };
  const std::vector<std::string> ta = tokens(a), tb = tokens(b);
  if (ta.size() != tb.size()) return false;
  for (size_t i = 0; i < ta.size(); ++i) {
    if (ta[i] == tb[i]) continue;
    double x = 0.0, y = 0.0;
    if (!number(ta[i], &x) || !number(tb[i], &y)) return false;
    if (!(std::abs(x - y) <= 1e-9 * std::max(1.0, std::abs(x)))) return false;
  }
  return true;
}

std::vector<Dh> DhOf(int N, const ConstVectorRef& k) {
  std::vector<Dh> dh(static_cast<size_t>(N));
  const std::vector<ChainKinematicParameter> layout = ChainKinematicLayout(N);
  for (size_t i = 0; i < layout.size(); ++i) {
    Dh& j = dh[static_cast<size_t>(layout[i].joint)];
    double* field[] = {&j.alpha, &j.a, &j.theta, &j.d};
    *field[static_cast<int>(layout[i].field)] = k[static_cast<Eigen::Index>(i)];
  }
  return dh;
}

}  // namespace

std::vector<ChainKinematicParameter> ChainKinematicLayout(int num_joints) {
  const int N = num_joints;
  if (N < 1) throw std::invalid_argument("chain: at least one joint, got " + std::to_string(N));
  using Field = ChainKinematicParameter::Field;
  static const char* const kFields[] = {"alpha", "a", "theta", "d"};
  std::vector<ChainKinematicParameter> layout;
  auto add = [&](int joint, Field field) {
    layout.push_back({joint, field,
                      layout.empty() ? std::string("tilt")
                                     : kFields[static_cast<int>(field)] + std::to_string(joint + 1)});
  };
  add(0, Field::kAlpha);
  if (N >= 2) {
    add(0, Field::kTheta);
    add(1, Field::kAlpha);
    add(1, Field::kA);
  }
  for (int i = 1; i < N - 1; ++i) {
    add(i, Field::kTheta);
    add(i, Field::kD);
    add(i + 1, Field::kAlpha);
    add(i + 1, Field::kA);
  }
  return layout;
}

int NumChainKinematicParameters(int num_joints) {
  return static_cast<int>(ChainKinematicLayout(num_joints).size());
}

std::vector<std::string> ChainKinematicNames(int num_joints) {
  std::vector<std::string> names;
  for (const ChainKinematicParameter& p : ChainKinematicLayout(num_joints)) names.push_back(p.name);
  return names;
}

void CheckRobotName(const std::string& where, const std::string& name) {
  for (char c : name) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) {
      throw std::invalid_argument(where + ": robot name '" + name +
                                  "': letters, digits, '_', '-' and '.' only (it is written "
                                  "into the URDF)");
    }
  }
}

std::string ChainUrdf(int num_joints, const ConstVectorRef& kinematics,
                      const std::string& robot_name) {
  const int N = num_joints;
  if (kinematics.size() != NumChainKinematicParameters(N)) {
    throw std::invalid_argument("ChainUrdf: " + std::to_string(kinematics.size()) +
                                " kinematic parameters, expected " +
                                std::to_string(NumChainKinematicParameters(N)) + " for " +
                                std::to_string(N) + " joints");
  }
  if (!kinematics.allFinite()) throw std::invalid_argument("ChainUrdf: a non-finite parameter");
  CheckRobotName("ChainUrdf", robot_name);
  const std::vector<Dh> dh = DhOf(N, kinematics);
  std::ostringstream os;
  os << "<?xml version=\"1.0\"?>\n"
     << "<!-- A serial chain identified from joint torques by structgp (structgp identify): its\n"
     << "     kinematics, " << kDhLegend;
  for (int i = 0; i < N; ++i) {
    const Dh& j = dh[static_cast<size_t>(i)];
    os << "       joint" << i + 1 << " " << Num(j.alpha) << " " << Num(j.a) << " " << Num(j.theta)
       << " " << Num(j.d) << "\n";
  }
  os << "     The inertial values are placeholders (1 kg, 0.01 kg m^2 at each link's origin):\n"
     << "     the rbd models identify them from the data. -->\n"
     << "<robot name=\"" << robot_name << "\">\n  <link name=\"base\"/>\n";
  for (int i = 0; i < N; ++i) {
    const Dh& j = dh[static_cast<size_t>(i)];
    const KDL::Frame f = KDL::Frame(KDL::Rotation::RotX(j.alpha)) *
                         KDL::Frame(KDL::Vector(j.a, 0.0, 0.0)) *
                         KDL::Frame(KDL::Rotation::RotZ(j.theta)) *
                         KDL::Frame(KDL::Vector(0.0, 0.0, j.d));
    double roll = 0.0, pitch = 0.0, yaw = 0.0;
    f.M.GetRPY(roll, pitch, yaw);
    const std::string parent = i == 0 ? "base" : "link" + std::to_string(i);
    const std::string child = "link" + std::to_string(i + 1);
    os << "  <joint name=\"joint" << i + 1 << "\" type=\"continuous\">\n"
       << "    <parent link=\"" << parent << "\"/>\n    <child link=\"" << child << "\"/>\n"
       << "    <origin xyz=\"" << Num(f.p.x()) << " " << Num(f.p.y()) << " " << Num(f.p.z())
       << "\" rpy=\"" << Num(roll) << " " << Num(pitch) << " " << Num(yaw) << "\"/>\n"
       << "    <axis xyz=\"0 0 1\"/>\n  </joint>\n"
       << "  <link name=\"" << child << "\">\n    <inertial>\n"
       << "      <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n      <mass value=\"1\"/>\n"
       << "      <inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.01\" iyz=\"0\" izz=\"0.01\"/>\n"
       << "    </inertial>\n  </link>\n";
  }
  os << "</robot>\n";
  return os.str();
}

std::optional<Vector> ChainKinematicsOfUrdf(const std::string& urdf) {
  const size_t legend = urdf.find(kDhLegend);
  const size_t name_at = urdf.find("<robot name=\"");
  if (legend == std::string::npos || name_at == std::string::npos) return std::nullopt;
  const size_t name_begin = name_at + std::string("<robot name=\"").size();
  const size_t name_end = urdf.find('"', name_begin);
  if (name_end == std::string::npos) return std::nullopt;
  const std::string name = urdf.substr(name_begin, name_end - name_begin);
  // The comment's lines "jointK alpha a theta d", K = 1, 2, ...
  std::istringstream lines(urdf.substr(legend + sizeof(kDhLegend) - 1));
  lines.imbue(std::locale::classic());
  std::vector<Dh> dh;
  std::string label;
  while (lines >> label && label == "joint" + std::to_string(dh.size() + 1)) {
    Dh j;
    if (!(lines >> j.alpha >> j.a >> j.theta >> j.d)) return std::nullopt;
    dh.push_back(j);
  }
  const int N = static_cast<int>(dh.size());
  if (N < 1) return std::nullopt;
  const std::vector<ChainKinematicParameter> layout = ChainKinematicLayout(N);
  Vector k(static_cast<Eigen::Index>(layout.size()));
  for (size_t i = 0; i < layout.size(); ++i) {
    const Dh& j = dh[static_cast<size_t>(layout[i].joint)];
    const double field[] = {j.alpha, j.a, j.theta, j.d};
    k[static_cast<Eigen::Index>(i)] = field[static_cast<int>(layout[i].field)];
  }
  try {
    if (!SameDocument(ChainUrdf(N, k, name), urdf)) return std::nullopt;
  } catch (const std::invalid_argument&) {
    return std::nullopt;  // a name or number ChainUrdf would not write
  }
  return k;
}

std::optional<Vector> ChainKinematicsOf(const RigidBodyChain& chain) {
  std::optional<Vector> k = ChainKinematicsOfUrdf(chain.urdf());
  const int N = chain.num_joints();
  if (!k || k->size() != NumChainKinematicParameters(N) || chain.root() != "base" ||
      chain.tip() != "link" + std::to_string(N) ||
      chain.gravity() != UrdfOptions().gravity) {
    return std::nullopt;
  }
  return k;
}

}  // namespace structgp
