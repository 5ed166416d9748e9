#include "structgp/sim/urdf.h"

#include <sstream>
#include <stdexcept>

#include <kdl/frames.hpp>

#include "structgp/internal/text.h"

namespace structgp {
namespace sim {
namespace {

// Numbers that read back to the same double.
std::string Num(double value) { return internal::ShortestDecimal(value); }

// Pose of the URDF frame of link i in DH frame i, the rest of the DH link after the joint's turn.
KDL::Frame AfterJoint(const LinkParameters& link) {
  return KDL::Frame(KDL::Rotation::RotX(link.alpha), KDL::Vector(link.a, 0.0, link.d));
}

std::string Origin(const KDL::Frame& frame) {
  double roll = 0.0, pitch = 0.0, yaw = 0.0;
  frame.M.GetRPY(roll, pitch, yaw);  // URDF's rpy: R = Rz(yaw) Ry(pitch) Rx(roll), as KDL's
  return "<origin xyz=\"" + Num(frame.p.x()) + " " + Num(frame.p.y()) + " " + Num(frame.p.z()) +
         "\" rpy=\"" + Num(roll) + " " + Num(pitch) + " " + Num(yaw) + "\"/>";
}

void RequireDh(const Robot& robot, const char* what) {
  if (robot.links().empty()) {
    throw std::invalid_argument(std::string(what) + ": robot '" + robot.name() +
                                "' was read from a URDF and has no DH parameters");
  }
}

}  // namespace

std::string ToUrdf(const Robot& robot) {
  RequireDh(robot, "ToUrdf");
  const std::vector<LinkParameters>& links = robot.links();
  const Eigen::Matrix3d& r = robot.base_rotation();
  const KDL::Frame base(KDL::Rotation(r(0, 0), r(0, 1), r(0, 2), r(1, 0), r(1, 1), r(1, 2),
                                      r(2, 0), r(2, 1), r(2, 2)));
  std::ostringstream os;
  os << "<?xml version=\"1.0\"?>\n"
     << "<!-- Robot '" << robot.name()
     << "' of structgp's simulator, written by structgp::sim::ToUrdf\n"
        "     from its "
     << (robot.convention() == DhConvention::kModified ? "modified" : "standard")
     << "-DH parameters (include/structgp/sim/urdf.h says how).\n"
        "     URDF has no armature (reflected rotor inertia); the simulator's, kg m^2:";
  for (std::size_t i = 0; i < links.size(); ++i) {
    os << "\n       joint" << i + 1 << " " << Num(links[i].armature);
  }
  os << "\n-->\n";
  os << "<robot name=\"" << robot.name() << "\">\n";
  os << "  <link name=\"world\"/>\n";
  os << "  <joint name=\"base_joint\" type=\"fixed\">\n    <parent link=\"world\"/>\n"
     << "    <child link=\"base\"/>\n    " << Origin(base) << "\n  </joint>\n";
  os << "  <link name=\"base\"/>\n";
  std::string parent = "base";
  const bool modified = robot.convention() == DhConvention::kModified;
  // Standard DH: B_{i-1}, DH frame i-1 in the parent's URDF frame. Modified DH: the URDF frame
  // of link i is DH frame i (on joint i's axis), so B stays the identity.
  KDL::Frame before = KDL::Frame::Identity();
  for (std::size_t i = 0; i < links.size(); ++i) {
    const LinkParameters& link = links[i];
    const std::string name = "link" + std::to_string(i + 1);
    const KDL::Frame joint =
        modified ? KDL::Frame::DH_Craig1989(link.a, link.alpha, link.d, link.theta_offset)
                 : before * KDL::Frame(KDL::Rotation::RotZ(link.theta_offset));
    os << "  <joint name=\"joint" << i + 1 << "\" type=\"continuous\">\n"
       << "    <parent link=\"" << parent << "\"/>\n    <child link=\"" << name << "\"/>\n"
       << "    " << Origin(joint) << "\n"
       << "    <axis xyz=\"0 0 1\"/>\n  </joint>\n";
    const KDL::Frame after = modified ? KDL::Frame::Identity() : AfterJoint(link);
    const KDL::Frame inertial = after * KDL::Frame(KDL::Vector(link.com.x(), link.com.y(), link.com.z()));
    const Eigen::Matrix3d& in = link.inertia;
    os << "  <link name=\"" << name << "\">\n    <inertial>\n      " << Origin(inertial) << "\n"
       << "      <mass value=\"" << Num(link.mass) << "\"/>\n"
       << "      <inertia ixx=\"" << Num(in(0, 0)) << "\" ixy=\"" << Num(in(0, 1)) << "\" ixz=\""
       << Num(in(0, 2)) << "\" iyy=\"" << Num(in(1, 1)) << "\" iyz=\"" << Num(in(1, 2))
       << "\" izz=\"" << Num(in(2, 2)) << "\"/>\n    </inertial>\n  </link>\n";
    parent = name;
    before = after;
  }
  os << "  <joint name=\"tool_joint\" type=\"fixed\">\n    <parent link=\"" << parent
     << "\"/>\n    <child link=\"tool\"/>\n    " << Origin(before) << "\n  </joint>\n";
  os << "  <link name=\"tool\"/>\n</robot>\n";
  return os.str();
}

RigidBodyChain ToRigidBodyChain(const Robot& robot) {
  RequireDh(robot, "ToRigidBodyChain");
  const RigidBodyChain chain =
      RigidBodyChain::FromUrdfString(ToUrdf(robot), {}, "ToUrdf(" + robot.name() + ")");
  Vector pi = chain.parameters();
  const int n = robot.num_joints();
  for (int k = 0; k < n; ++k) pi(10 * n + k) = robot.links()[k].armature;
  return chain.WithParameters(pi);
}

}  // namespace sim
}  // namespace structgp
