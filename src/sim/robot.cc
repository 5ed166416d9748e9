#include "structgp/sim/robot.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <kdl/chain.hpp>
#include <kdl/frames.hpp>
#include <kdl/joint.hpp>
#include <kdl/rigidbodyinertia.hpp>
#include <kdl/rotationalinertia.hpp>
#include <kdl/segment.hpp>

#include "structgp/core/validate.h"
#include "kdl_solvers.h"
#include "puma560_data.h"
#include "random.h"

namespace structgp {
namespace sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Relative tolerance for the symmetry and semi-definiteness of a link inertia and for the
// orthonormality of the base rotation: a few hundred ulps, so that inertias computed as
// R D R^T in double precision pass while genuinely wrong input does not.
constexpr double kParameterTolerance = 1e-10;

// ForwardDynamics refuses M(q) when a Cholesky pivot squared falls below this fraction of the
// largest diagonal entry: M is then singular to working precision (a joint moving no mass)
// and the accelerations would be meaningless.
constexpr double kMinRelativePivot = 1e-14;

void ValidateLink(const LinkParameters& link, int index) {
  const std::string what = "link " + std::to_string(index + 1);
  if (!std::isfinite(link.a) || !std::isfinite(link.alpha) || !std::isfinite(link.d) ||
      !std::isfinite(link.theta_offset)) {
    throw std::invalid_argument(what + ": DH parameters must be finite");
  }
  RequireInRange(what + " mass (kg)", link.mass, 0.0, HUGE_VAL, /*closed_lo=*/true);
  RequireInRange(what + " armature (kg m^2)", link.armature, 0.0, HUGE_VAL, /*closed_lo=*/true);
  RequireFinite(what + " centre of mass", link.com);
  RequireFinite(what + " inertia", link.inertia);
  const double scale = link.inertia.cwiseAbs().maxCoeff();
  if ((link.inertia - link.inertia.transpose()).cwiseAbs().maxCoeff() >
      kParameterTolerance * scale) {
    throw std::invalid_argument(what + ": inertia must be symmetric");
  }
  const Eigen::Vector3d moments =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(link.inertia, Eigen::EigenvaluesOnly)
          .eigenvalues();
  if (moments.minCoeff() < -kParameterTolerance * scale) {
    std::ostringstream os;
    os << what << ": inertia must be positive semi-definite, got principal moments "
       << moments.transpose() << " kg m^2";
    throw std::invalid_argument(os.str());
  }
}

void ValidateRotation(const Eigen::Matrix3d& r) {
  RequireFinite("base_rotation", r);
  const double orthogonality_error =
      (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (orthogonality_error > kParameterTolerance || r.determinant() < 0.0) {
    throw std::invalid_argument(
        "base_rotation: expected a rotation matrix (orthonormal, determinant +1)");
  }
}

KDL::Chain BuildChain(const std::vector<LinkParameters>& links, DhConvention convention) {
  KDL::Chain chain;
  for (std::size_t i = 0; i < links.size(); ++i) {
    const LinkParameters& link = links[i];
    const Eigen::Matrix3d& in = link.inertia;
    // In both conventions the segment's tip frame is link frame i, and a KDL segment's inertia
    // is expressed in its tip frame, which is where LinkParameters states it.
    const KDL::RotationalInertia rotational(in(0, 0), in(1, 1), in(2, 2), in(0, 1), in(0, 2),
                                            in(1, 2));
    const KDL::RigidBodyInertia body(
        link.mass, KDL::Vector(link.com.x(), link.com.y(), link.com.z()), rotational);
    const std::string joint_name = "joint" + std::to_string(i + 1);
    if (convention == DhConvention::kStandard) {
      // The joint turns about z of frame i-1 before the rest of the link's transform.
      chain.addSegment(KDL::Segment(
          "link" + std::to_string(i + 1),
          KDL::Joint(joint_name, KDL::Joint::RotZ, /*scale=*/1.0, /*offset=*/0.0, link.armature),
          KDL::Frame::DH(link.a, link.alpha, link.d, link.theta_offset), body));
    } else {
      // Modified DH: frame i-1 -> i is F RotZ(q) RotZ(theta_offset) TransZ(d) with
      // F = RotX(alpha) TransX(a). F RotZ(q) = R(q) F, R(q) the turn by q about F's z axis
      // through F's origin, both in frame i-1: that is the joint, and the segment's tip frame
      // at q = 0 is F RotZ(theta_offset) TransZ(d) (KDL::Frame::DH_Craig1989).
      const KDL::Frame f(KDL::Rotation::RotX(link.alpha), KDL::Vector(link.a, 0.0, 0.0));
      chain.addSegment(KDL::Segment(
          "link" + std::to_string(i + 1),
          KDL::Joint(joint_name, f.p, f.M.UnitZ(), KDL::Joint::RotAxis, /*scale=*/1.0,
                     /*offset=*/0.0, link.armature),
          KDL::Frame::DH_Craig1989(link.a, link.alpha, link.d, link.theta_offset), body));
    }
  }
  return chain;
}

Eigen::Matrix3d RotationAboutX(double angle) {
  Eigen::Matrix3d r;
  r << 1.0, 0.0, 0.0,                          //
      0.0, std::cos(angle), -std::sin(angle),  //
      0.0, std::sin(angle), std::cos(angle);
  return r;
}

// Inertia about the centre of mass of a solid cylinder of radius `radius` and length
// `length` whose axis is coordinate axis `axis` (0 = x, 1 = y, 2 = z), kg m^2.
Eigen::Matrix3d RodInertia(double mass, double length, double radius, int axis) {
  const double along = 0.5 * mass * radius * radius;
  const double across = mass * (3.0 * radius * radius + length * length) / 12.0;
  Eigen::Matrix3d inertia = Eigen::Vector3d::Constant(across).asDiagonal();
  inertia(axis, axis) = along;
  return inertia;
}

// A row of a published table: DH parameters, mass and centre of mass (inertia and armature
// left to the caller).
LinkParameters TableLink(double a, double alpha, double d, double mass, const double (&com)[3]) {
  LinkParameters link;
  link.a = a;
  link.alpha = alpha;
  link.d = d;
  link.mass = mass;
  link.com = Eigen::Vector3d(com[0], com[1], com[2]);
  return link;
}

}  // namespace

struct Robot::Model {
  std::string name;
  std::vector<LinkParameters> links;
  DhConvention convention = DhConvention::kStandard;
  Eigen::Matrix3d base_rotation;
  Eigen::Vector3d gravity_in_base;
  KDL::Chain chain;  // KDL solvers built on it keep a reference: the Model never moves.
};

Robot::Robot(std::shared_ptr<const Model> model) : model_(std::move(model)) {}

Robot Robot::FromUrdf(const std::string& path, const UrdfOptions& options) {
  return FromRigidBodyChain(RigidBodyChain::FromUrdfFile(path, options));
}

Robot Robot::FromRigidBodyChain(const RigidBodyChain& chain, std::string name) {
  auto model = std::make_shared<Model>();
  model->name = name.empty() ? chain.robot_name() : std::move(name);
  model->base_rotation = Eigen::Matrix3d::Identity();
  model->gravity_in_base = chain.gravity();
  model->chain = chain.kdl_chain();
  return Robot(std::move(model));
}

Robot::Robot(std::string name, std::vector<LinkParameters> links,
             const Eigen::Matrix3d& base_rotation, DhConvention convention) {
  if (links.empty()) {
    throw std::invalid_argument("Robot: expected at least 1 link, got 0");
  }
  for (std::size_t i = 0; i < links.size(); ++i) ValidateLink(links[i], static_cast<int>(i));
  ValidateRotation(base_rotation);
  auto model = std::make_shared<Model>();
  model->name = std::move(name);
  model->chain = BuildChain(links, convention);
  model->links = std::move(links);
  model->convention = convention;
  model->base_rotation = base_rotation;
  model->gravity_in_base = base_rotation.transpose() * Eigen::Vector3d(0.0, 0.0, -kStandardGravity);
  model_ = std::move(model);
}

const std::string& Robot::name() const { return model_->name; }
int Robot::num_joints() const { return static_cast<int>(model_->chain.getNrOfJoints()); }
const std::vector<LinkParameters>& Robot::links() const { return model_->links; }
const Eigen::Matrix3d& Robot::base_rotation() const { return model_->base_rotation; }
DhConvention Robot::convention() const { return model_->convention; }
Eigen::Vector3d Robot::gravity_in_base() const { return model_->gravity_in_base; }
const KDL::Chain& Robot::chain() const { return model_->chain; }

Eigen::VectorXd Robot::InverseDynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                       const Eigen::VectorXd& qdd) const {
  RequireSize("InverseDynamics: q", q.size(), num_joints());
  RequireSize("InverseDynamics: qd", qd.size(), num_joints());
  RequireSize("InverseDynamics: qdd", qdd.size(), num_joints());
  internal::KdlSolvers solvers(model_->chain, model_->gravity_in_base);
  Eigen::VectorXd tau;
  solvers.InverseDynamics(q, qd, qdd, &tau);
  return tau;
}

DynamicsComponents Robot::Components(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                     const Eigen::VectorXd& qdd) const {
  RequireSize("Components: q", q.size(), num_joints());
  RequireSize("Components: qd", qd.size(), num_joints());
  RequireSize("Components: qdd", qdd.size(), num_joints());
  internal::KdlSolvers solvers(model_->chain, model_->gravity_in_base);
  Eigen::MatrixXd mass;
  solvers.MassMatrix(q, &mass);
  DynamicsComponents components;
  components.inertial = mass * qdd;
  solvers.Coriolis(q, qd, &components.coriolis);
  solvers.Gravity(q, &components.gravity);
  return components;
}

Eigen::MatrixXd Robot::MassMatrix(const Eigen::VectorXd& q) const {
  RequireSize("MassMatrix: q", q.size(), num_joints());
  internal::KdlSolvers solvers(model_->chain, model_->gravity_in_base);
  Eigen::MatrixXd mass;
  solvers.MassMatrix(q, &mass);
  return mass;
}

Eigen::VectorXd Robot::ForwardDynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                       const Eigen::VectorXd& tau) const {
  RequireSize("ForwardDynamics: q", q.size(), num_joints());
  RequireSize("ForwardDynamics: qd", qd.size(), num_joints());
  RequireSize("ForwardDynamics: tau", tau.size(), num_joints());
  internal::KdlSolvers solvers(model_->chain, model_->gravity_in_base);
  Eigen::MatrixXd mass;
  Eigen::VectorXd coriolis, gravity;
  solvers.MassMatrix(q, &mass);
  solvers.Coriolis(q, qd, &coriolis);
  solvers.Gravity(q, &gravity);
  const Eigen::LLT<Eigen::MatrixXd> llt(mass);
  const double min_pivot = llt.matrixLLT().diagonal().minCoeff();
  if (llt.info() != Eigen::Success ||
      !(min_pivot * min_pivot >= kMinRelativePivot * mass.diagonal().maxCoeff())) {
    throw std::runtime_error("ForwardDynamics: the mass matrix of robot '" + name() +
                             "' is not positive definite at this q (does every joint move "
                             "some mass?)");
  }
  return llt.solve(tau - coriolis - gravity);
}

Robot RandomRobot(int num_joints, std::uint64_t seed) {
  if (num_joints < 1 || num_joints > 7) {
    throw std::invalid_argument("RandomRobot: expected 1 to 7 joints, got " +
                                std::to_string(num_joints));
  }
  std::mt19937_64 rng(seed);
  std::vector<LinkParameters> links(num_joints);
  for (int i = 0; i < num_joints; ++i) {
    LinkParameters& link = links[i];
    link.a = internal::Uniform(rng, 0.1, 0.5);
    link.alpha = (i % 2 == 0) ? 0.5 * kPi : -0.5 * kPi;
    link.d = internal::Uniform(rng, 0.0, 0.3);
    link.theta_offset = internal::Uniform(rng, -0.25 * kPi, 0.25 * kPi);
    link.mass = internal::Uniform(rng, 0.5, 5.0);
    for (int k = 0; k < 3; ++k) link.com(k) = internal::Uniform(rng, -0.15, 0.15);
    // A solid box of edges (ex, ey, ez) has principal moments m/12 (ey^2 + ez^2), ... :
    // positive and satisfying the triangle inequalities by construction.
    Eigen::Vector3d edges;
    for (int k = 0; k < 3; ++k) edges(k) = internal::Uniform(rng, 0.04, 0.4);
    const Eigen::Vector3d sq = edges.cwiseProduct(edges);
    const Eigen::Vector3d moments =
        (link.mass / 12.0) * Eigen::Vector3d(sq.y() + sq.z(), sq.x() + sq.z(), sq.x() + sq.y());
    const Eigen::Matrix3d rotation = internal::RandomRotation(rng);
    link.inertia = rotation * moments.asDiagonal() * rotation.transpose();
    link.inertia = 0.5 * (link.inertia + link.inertia.transpose()).eval();
  }
  return Robot("random" + std::to_string(num_joints) + "_seed" + std::to_string(seed),
               std::move(links), RotationAboutX(0.5 * kPi));
}

Robot TwoLinkArm() {
  constexpr double kLength[2] = {0.4, 0.3};  // m
  constexpr double kMass[2] = {2.0, 1.0};    // kg
  constexpr double kRadius = 0.03;           // m
  std::vector<LinkParameters> links(2);
  for (int i = 0; i < 2; ++i) {
    links[i].a = kLength[i];
    links[i].mass = kMass[i];
    links[i].com = Eigen::Vector3d(-0.5 * kLength[i], 0.0, 0.0);
    links[i].inertia = RodInertia(kMass[i], kLength[i], kRadius, /*axis=*/0);
  }
  // Base frame turned by +pi/2 about the world x axis: the joint axes (z) are horizontal and
  // y_0 points up, so q1 = 0 holds link 1 horizontal and positive q1 lifts it.
  return Robot("two_link_arm", std::move(links), RotationAboutX(0.5 * kPi));
}

Robot ThreeLinkArm() {
  std::vector<LinkParameters> links(3);
  // Waist: a vertical column of 0.3 m. Frame 1 sits on top of it with y_1 along the column,
  // so the column's centre is 0.15 m below, along -y_1.
  links[0].d = 0.3;
  links[0].alpha = 0.5 * kPi;
  links[0].mass = 3.0;
  links[0].com = Eigen::Vector3d(0.0, -0.15, 0.0);
  links[0].inertia = RodInertia(3.0, 0.3, 0.05, /*axis=*/1);
  // Upper arm and forearm: rods along x of their frames.
  links[1].a = 0.4;
  links[1].mass = 2.0;
  links[1].com = Eigen::Vector3d(-0.2, 0.0, 0.0);
  links[1].inertia = RodInertia(2.0, 0.4, 0.03, /*axis=*/0);
  links[2].a = 0.3;
  links[2].mass = 1.0;
  links[2].com = Eigen::Vector3d(-0.15, 0.0, 0.0);
  links[2].inertia = RodInertia(1.0, 0.3, 0.025, /*axis=*/0);
  return Robot("three_link_arm", std::move(links));
}

Robot Puma560() {
  // Link 1's mass is reported as 0: only its inertia about the joint-1 axis (y_1) matters.
  // The base height d1 has no effect on the dynamics and is set to 0.
  std::vector<LinkParameters> links(6);
  for (int i = 0; i < 6; ++i) {
    const internal::Puma560Row& row = internal::kPuma560[i];
    links[i].a = row.a;
    links[i].alpha = row.alpha;
    links[i].d = row.d;
    links[i].mass = row.mass;
    links[i].com = Eigen::Vector3d(row.cx, row.cy, row.cz);
    links[i].inertia = Eigen::Vector3d(row.ixx, row.iyy, row.izz).asDiagonal();
    links[i].armature = row.rotor_inertia * row.gear_ratio * row.gear_ratio;
  }
  return Robot("puma560", std::move(links));
}

Robot Panda() {
  // Modified DH (Craig): a_{i-1}, alpha_{i-1}, d_i of Franka's published table.
  constexpr double kA[7] = {0.0, 0.0, 0.0, 0.0825, -0.0825, 0.0, 0.088};
  constexpr double kD[7] = {0.333, 0.0, 0.316, 0.0, 0.384, 0.0, 0.0};
  constexpr double kAlpha[7] = {0.0, -0.5 * kPi, 0.5 * kPi, 0.5 * kPi, -0.5 * kPi, 0.5 * kPi,
                                0.5 * kPi};
  // Gaz et al. 2019: mass (kg) and centre of mass (m) in link frame i.
  constexpr double kMass[7] = {4.970684, 0.646926, 3.228604, 3.587895, 1.225946, 1.666555, 0.735522};
  constexpr double kCom[7][3] = {{3.875e-3, 2.081e-3, -0.1750},     {-3.141e-3, -2.872e-2, 3.495e-3},
                                 {2.7518e-2, 3.9252e-2, -6.6502e-2}, {-5.317e-2, 1.04419e-1, 2.7454e-2},
                                 {-1.1953e-2, 4.1065e-2, -3.8437e-2}, {6.0149e-2, -1.4117e-2, -1.0517e-2},
                                 {1.0517e-2, -4.252e-3, 6.1597e-2}};
  // Diaz Ledezma and Haddadin: Ixx, Ixy, Ixz, Iyy, Iyz, Izz about the centre of mass, kg m^2.
  constexpr double kInertia[7][6] = {{0.7470, -0.0002, 0.0086, 0.7503, 0.0201, 0.0092},
                                     {0.0085, -0.0040, 0.0103, 0.0281, 0.0008, 0.0265},
                                     {0.0565, -0.0082, -0.0055, 0.0529, -0.0044, 0.0182},
                                     {0.0677, 0.0277, 0.0039, 0.0324, -0.0016, 0.0776},
                                     {0.0394, -0.0015, -0.0046, 0.0315, 0.0022, 0.0109},
                                     {0.0025, 0.0015, -0.0001, 0.0106, 0.0001, 0.0118},
                                     {0.0308, 0.0004, -0.0007, 0.0284, -0.0005, 0.0067}};
  std::vector<LinkParameters> links(7);
  for (int i = 0; i < 7; ++i) {
    LinkParameters& link = links[i] = TableLink(kA[i], kAlpha[i], kD[i], kMass[i], kCom[i]);
    const double* in = kInertia[i];
    link.inertia << in[0], in[1], in[2],  //
        in[1], in[3], in[4],              //
        in[2], in[4], in[5];
  }
  return Robot("panda", std::move(links), Eigen::Matrix3d::Identity(), DhConvention::kModified);
}

Robot Ur10() {
  // Universal Robots' published standard-DH table and link masses and centres of mass (UR10,
  // CB-series), centres of mass in DH link frame i.
  constexpr double kA[6] = {0.0, -0.612, -0.5723, 0.0, 0.0, 0.0};
  constexpr double kD[6] = {0.1273, 0.0, 0.0, 0.163941, 0.1157, 0.0922};
  constexpr double kAlpha[6] = {0.5 * kPi, 0.0, 0.0, 0.5 * kPi, -0.5 * kPi, 0.0};
  constexpr double kMass[6] = {7.1, 12.7, 4.27, 2.0, 2.0, 0.365};
  constexpr double kCom[6][3] = {{0.021, 0.0, 0.027}, {0.38, 0.0, 0.158}, {0.24, 0.0, 0.068},
                                 {0.0, 0.007, 0.018}, {0.0, 0.007, 0.018}, {0.0, 0.0, -0.026}};
  // Not published: solid cylinders of the links' outer size (length, radius, axis in frame i):
  // the shoulder housing along y_1, the upper arm and forearm along x, the wrists along y.
  constexpr double kLength[6] = {0.18, 0.612, 0.572, 0.12, 0.12, 0.05};
  constexpr double kRadius[6] = {0.075, 0.06, 0.045, 0.045, 0.045, 0.045};
  constexpr int kAxis[6] = {1, 0, 0, 1, 1, 2};
  std::vector<LinkParameters> links(6);
  for (int i = 0; i < 6; ++i) {
    links[i] = TableLink(kA[i], kAlpha[i], kD[i], kMass[i], kCom[i]);
    links[i].inertia = RodInertia(kMass[i], kLength[i], kRadius[i], kAxis[i]);
  }
  return Robot("ur10", std::move(links));
}

Robot RobotByName(const std::string& name) {
  std::string key = name;
  std::replace(key.begin(), key.end(), '-', '_');
  if (key == "two_link") return TwoLinkArm();
  if (key == "three_link") return ThreeLinkArm();
  if (key == "puma560") return Puma560();
  if (key == "panda") return Panda();
  if (key == "ur10") return Ur10();
  if (key.size() == 7 && key.rfind("random", 0) == 0 && key[6] >= '1' && key[6] <= '7') {
    return RandomRobot(key[6] - '0', 1);
  }
  throw std::invalid_argument("unknown robot '" + name +
                              "' (expected two_link, three_link, puma560, panda, ur10, random1 .. "
                              "random7)");
}

}  // namespace sim
}  // namespace structgp
