#ifndef STRUCTGP_TESTS_URDF_TEST_UTIL_H_
#define STRUCTGP_TESTS_URDF_TEST_UTIL_H_

// Random URDF documents for the rigid-body tests: serial chains of revolute joints with random
// origins, axes and physical inertials, optionally with fixed links in the chain and fixed
// branches hanging off it.

#include <cmath>
#include <cstdint>
#include <iomanip>
#include <random>
#include <sstream>
#include <string>

#include <Eigen/Core>

namespace structgp {
namespace testing {

struct RandomUrdfOptions {
  int num_joints = 7;
  bool fixed_links = false;     // a fixed link after every second moving link
  bool fixed_branches = false;  // a fixed sensor branch on every third moving link
  std::uint64_t seed = 1;
};

inline std::string RandomUrdf(const RandomUrdfOptions& options) {
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::ostringstream os;
  os << std::setprecision(17);
  auto triple = [&](double scale) {
    std::ostringstream t;
    t << std::setprecision(17) << scale * unit(rng) << " " << scale * unit(rng) << " "
      << scale * unit(rng);
    return t.str();
  };
  auto inertial = [&]() {
    const double m = 1.75 + 1.25 * unit(rng);
    const double ex = 0.22 + 0.18 * unit(rng), ey = 0.22 + 0.18 * unit(rng),
                 ez = 0.22 + 0.18 * unit(rng);
    std::ostringstream t;
    t << std::setprecision(17) << "<inertial><origin xyz=\"" << triple(0.15) << "\" rpy=\""
      << triple(3.0) << "\"/><mass value=\"" << m << "\"/><inertia ixx=\""
      << m / 12 * (ey * ey + ez * ez) << "\" iyy=\"" << m / 12 * (ex * ex + ez * ez)
      << "\" izz=\"" << m / 12 * (ex * ex + ey * ey)
      << "\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial>";
    return t.str();
  };
  auto axis = [&]() {
    Eigen::Vector3d a(unit(rng), unit(rng), unit(rng));
    a.normalize();
    std::ostringstream t;
    t << std::setprecision(17) << a.x() << " " << a.y() << " " << a.z();
    return t.str();
  };
  os << "<?xml version=\"1.0\"?>\n<robot name=\"random\">\n";
  os << "  <link name=\"world\"/>\n";
  // A fixed base link: before the first moving joint, it carries no torque.
  os << "  <link name=\"base\">" << inertial() << "</link>\n";
  os << "  <joint name=\"base_joint\" type=\"fixed\"><parent link=\"world\"/><child "
        "link=\"base\"/><origin xyz=\""
     << triple(0.2) << "\" rpy=\"" << triple(0.5) << "\"/></joint>\n";
  std::string parent = "base";
  for (int k = 1; k <= options.num_joints; ++k) {
    const std::string link = "link" + std::to_string(k);
    os << "  <link name=\"" << link << "\">" << inertial() << "</link>\n";
    os << "  <joint name=\"joint" << k << "\" type=\"" << (k % 2 ? "revolute" : "continuous")
       << "\"><parent link=\"" << parent << "\"/><child link=\"" << link << "\"/><origin xyz=\""
       << triple(0.4) << "\" rpy=\"" << triple(3.0) << "\"/><axis xyz=\"" << axis()
       << "\"/><limit lower=\"-3\" upper=\"3\" effort=\"100\" velocity=\"5\"/></joint>\n";
    parent = link;
    if (options.fixed_links && k % 2 == 0) {
      const std::string fixed = "flange" + std::to_string(k);
      os << "  <link name=\"" << fixed << "\">" << inertial() << "</link>\n";
      os << "  <joint name=\"" << fixed << "_joint\" type=\"fixed\"><parent link=\"" << parent
         << "\"/><child link=\"" << fixed << "\"/><origin xyz=\"" << triple(0.3) << "\" rpy=\""
         << triple(3.0) << "\"/></joint>\n";
      parent = fixed;
    }
    if (options.fixed_branches && k % 3 == 0) {
      for (int b = 0; b < 2; ++b) {  // a sensor and a bracket on it
        const std::string name = "sensor" + std::to_string(k) + "_" + std::to_string(b);
        const std::string on = b == 0 ? parent : "sensor" + std::to_string(k) + "_0";
        os << "  <link name=\"" << name << "\">" << inertial() << "</link>\n";
        os << "  <joint name=\"" << name << "_joint\" type=\"fixed\"><parent link=\"" << on
           << "\"/><child link=\"" << name << "\"/><origin xyz=\"" << triple(0.2) << "\" rpy=\""
           << triple(3.0) << "\"/></joint>\n";
      }
    }
  }
  os << "</robot>\n";
  return os.str();
}

}  // namespace testing
}  // namespace structgp

#endif  // STRUCTGP_TESTS_URDF_TEST_UTIL_H_
