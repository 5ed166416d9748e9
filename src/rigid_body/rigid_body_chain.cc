#include "structgp/rigid_body/rigid_body_chain.h"

#include <cmath>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <kdl/chain.hpp>
#include <kdl/chaindynparam.hpp>
#include <kdl/chainidsolver_recursive_newton_euler.hpp>
#include <kdl/frames.hpp>
#include <kdl/jntarray.hpp>
#include <kdl/jntspaceinertiamatrix.hpp>
#include <kdl/joint.hpp>
#include <kdl/segment.hpp>

#include "structgp/core/validate.h"
#include "kdl_inertia.h"
#include "urdf_reader.h"

namespace structgp {
namespace {

using internal::kLinkParameters;

KDL::Vector ToKdl(const Eigen::Vector3d& v) { return KDL::Vector(v.x(), v.y(), v.z()); }

void CheckKdl(int code, const char* what) {
  if (code < 0) {
    throw std::logic_error(std::string("RigidBodyChain: KDL ") + what + " failed with code " +
                           std::to_string(code));
  }
}

// `joint` with its inertia (KDL adds inertia * qdd to the joint's torque in both the recursive
// Newton-Euler solver and ChainDynParam's mass matrix: the armature). KDL does not expose a
// joint's scale and offset; kdl_parser makes every joint with scale 1 and offset 0, which the
// poses confirm.
KDL::Joint WithInertia(const KDL::Joint& joint, double inertia) {
  const KDL::Joint out =
      (joint.getType() == KDL::Joint::RotAxis || joint.getType() == KDL::Joint::TransAxis)
          ? KDL::Joint(joint.getName(), joint.JointOrigin(), joint.JointAxis(), joint.getType(),
                       /*scale=*/1.0, /*offset=*/0.0, inertia, joint.getDamping(),
                       joint.getStiffness())
          : KDL::Joint(joint.getName(), joint.getType(), /*scale=*/1.0, /*offset=*/0.0, inertia,
                       joint.getDamping(), joint.getStiffness());
  for (const double q : {0.0, 0.7}) {
    if (!KDL::Equal(out.pose(q), joint.pose(q), 1e-15)) {
      throw std::logic_error("RigidBodyChain: joint '" + joint.getName() +
                             "' has a scale or offset other than 1 and 0");
    }
  }
  return out;
}

}  // namespace

// What WithParameters keeps: the kinematics, with zero inertia everywhere.
struct RigidBodyChain::Kinematics {
  KDL::Chain zero_chain;
  std::vector<int> moving_segments;
  std::vector<std::string> joint_names, link_names;
  std::string robot_name, root, tip, source;
  std::string urdf;  // the document it was read from
  Eigen::Vector3d gravity;
};

struct RigidBodyChain::Model {
  std::shared_ptr<const Kinematics> kinematics;
  Vector parameters;
  KDL::Chain chain;  // KDL solvers built on it keep a reference: the Model never moves.
};

// Link k's inertia moves only joints 1..k, and the recursive Newton-Euler solver on the chain
// cut after link k gives those torques at about k/N of the cost: one truncated chain per link.
struct RigidBodyChain::Workspace::Impl {
  struct Truncated {
    Truncated(const KDL::Chain& full, int last_segment, const Eigen::Vector3d& gravity)
        : chain(Cut(full, last_segment)),
          rne_gravity(chain, ToKdl(gravity)),
          rne_no_gravity(chain, KDL::Vector::Zero()),
          q(chain.getNrOfJoints()),
          qd(chain.getNrOfJoints()),
          qdd(chain.getNrOfJoints()),
          zero(chain.getNrOfJoints()),
          tau(chain.getNrOfJoints()),
          no_external_wrenches(chain.getNrOfSegments(), KDL::Wrench::Zero()) {}
    static KDL::Chain Cut(const KDL::Chain& full, int last_segment) {
      KDL::Chain out;
      for (int i = 0; i <= last_segment; ++i) out.addSegment(full.getSegment(i));
      return out;
    }
    KDL::Chain chain;  // zero inertia except the one basis inertia being evaluated
    KDL::ChainIdSolver_RNE rne_gravity, rne_no_gravity;
    KDL::JntArray q, qd, qdd, zero, tau;
    KDL::Wrenches no_external_wrenches;
  };
  explicit Impl(std::shared_ptr<const Kinematics> kin) : kinematics(std::move(kin)) {
    for (const int segment : kinematics->moving_segments) {
      truncated.push_back(
          std::make_unique<Truncated>(kinematics->zero_chain, segment, kinematics->gravity));
    }
  }
  std::shared_ptr<const Kinematics> kinematics;
  // KDL's solvers keep a reference to their chain: each Truncated stays where it was made.
  std::vector<std::unique_ptr<Truncated>> truncated;
};

RigidBodyChain::Workspace::Workspace(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
RigidBodyChain::Workspace::Workspace(Workspace&&) noexcept = default;
RigidBodyChain::Workspace& RigidBodyChain::Workspace::operator=(Workspace&&) noexcept = default;
RigidBodyChain::Workspace::~Workspace() = default;

RigidBodyChain::RigidBodyChain(std::shared_ptr<const Model> model) : model_(std::move(model)) {}

RigidBodyChain RigidBodyChain::FromUrdfFile(const std::string& path, const UrdfOptions& options) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw std::invalid_argument("URDF file '" + path + "': cannot open (" +
                                std::strerror(errno) + ")");
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) {
    throw std::invalid_argument("URDF file '" + path + "': read error");
  }
  return FromUrdfString(text.str(), options, path);
}

RigidBodyChain RigidBodyChain::FromUrdfString(const std::string& xml, const UrdfOptions& options,
                                              const std::string& source) {
  if (!AllFinite(options.gravity)) {
    std::ostringstream os;
    os << source << ": gravity must be finite, got (" << options.gravity.x() << ", "
       << options.gravity.y() << ", " << options.gravity.z() << ") m/s^2";
    throw std::invalid_argument(os.str());
  }
  internal::UrdfChain read = internal::ReadUrdfChain(xml, options, source);
  const int n = static_cast<int>(read.moving_segments.size());

  // The URDF's parameters: the lumped inertias, armature 0.
  Vector pi = Vector::Zero(11 * n);
  for (int k = 0; k < n; ++k) {
    internal::ParametersFromInertia(read.chain.getSegment(read.moving_segments[k]).getInertia(),
                                    pi.data() + kLinkParameters * k);
  }

  auto kinematics = std::make_shared<Kinematics>();
  kinematics->zero_chain = read.chain;
  for (KDL::Segment& segment : kinematics->zero_chain.segments) {
    segment.setInertia(KDL::RigidBodyInertia::Zero());
  }
  kinematics->moving_segments = std::move(read.moving_segments);
  kinematics->joint_names = std::move(read.joint_names);
  kinematics->link_names = std::move(read.link_names);
  kinematics->robot_name = std::move(read.robot_name);
  kinematics->root = std::move(read.root);
  kinematics->tip = std::move(read.tip);
  kinematics->source = source;
  kinematics->urdf = xml;
  kinematics->gravity = options.gravity;

  auto model = std::make_shared<Model>();
  model->kinematics = std::move(kinematics);
  model->parameters = std::move(pi);
  // The chain as kdl_parser built it (its inertias from the URDF's own numbers, not rebuilt from
  // the parameters): WithParameters(parameters()) is an independent construction of the same.
  model->chain = std::move(read.chain);
  return RigidBodyChain(std::move(model));
}

int RigidBodyChain::num_joints() const {
  return static_cast<int>(model_->kinematics->moving_segments.size());
}
const std::vector<std::string>& RigidBodyChain::joint_names() const {
  return model_->kinematics->joint_names;
}
const std::vector<std::string>& RigidBodyChain::link_names() const {
  return model_->kinematics->link_names;
}
const std::string& RigidBodyChain::robot_name() const {
  return model_->kinematics->robot_name;
}
const std::string& RigidBodyChain::root() const { return model_->kinematics->root; }
const std::string& RigidBodyChain::tip() const { return model_->kinematics->tip; }
const std::string& RigidBodyChain::source() const { return model_->kinematics->source; }
const std::string& RigidBodyChain::urdf() const { return model_->kinematics->urdf; }
const Eigen::Vector3d& RigidBodyChain::gravity() const { return model_->kinematics->gravity; }
int RigidBodyChain::num_parameters() const { return 11 * num_joints(); }

std::vector<std::string> RigidBodyChain::parameter_names() const {
  static const char* const kNames[kLinkParameters] = {"m",   "mcx", "mcy", "mcz", "Ixx",
                                                      "Ixy", "Ixz", "Iyy", "Iyz", "Izz"};
  std::vector<std::string> names;
  names.reserve(num_parameters());
  for (int k = 1; k <= num_joints(); ++k) {
    for (const char* name : kNames) names.push_back(std::string(name) + "@" + std::to_string(k));
  }
  for (int k = 1; k <= num_joints(); ++k) names.push_back("armature@" + std::to_string(k));
  return names;
}

const Vector& RigidBodyChain::parameters() const { return model_->parameters; }

RigidBodyChain RigidBodyChain::WithPayload(double mass, const Eigen::Vector3d& c) const {
  if (!(mass >= 0.0) || !std::isfinite(mass) || !c.allFinite()) {
    throw std::invalid_argument("RigidBodyChain::WithPayload: expected a finite mass >= 0 and a "
                                "finite position");
  }
  Vector pi = parameters();
  const int k = 10 * (num_joints() - 1);  // m, m c, then Ixx Ixy Ixz Iyy Iyz Izz of the link
  pi[k] += mass;
  pi.segment(k + 1, 3) += mass * c;
  const Eigen::Matrix3d I =
      mass * (c.squaredNorm() * Eigen::Matrix3d::Identity() - c * c.transpose());
  pi[k + 4] += I(0, 0);
  pi[k + 5] += I(0, 1);
  pi[k + 6] += I(0, 2);
  pi[k + 7] += I(1, 1);
  pi[k + 8] += I(1, 2);
  pi[k + 9] += I(2, 2);
  return WithParameters(pi);
}

RigidBodyChain RigidBodyChain::WithParameters(const Vector& pi) const {
  RequireSize("RigidBodyChain::WithParameters: parameters", pi.size(), num_parameters());
  RequireFinite("RigidBodyChain::WithParameters: parameters", pi);
  const Kinematics& kin = *model_->kinematics;
  const int n = num_joints();
  auto model = std::make_shared<Model>();
  model->kinematics = model_->kinematics;
  model->parameters = pi;
  model->chain = kin.zero_chain;
  for (int k = 0; k < n; ++k) {
    KDL::Segment& segment = model->chain.segments[kin.moving_segments[k]];
    segment = KDL::Segment(segment.getName(), WithInertia(segment.getJoint(), pi(10 * n + k)),
                           segment.getFrameToTip(),
                           internal::InertiaFromParameters(pi.data() + kLinkParameters * k));
  }
  return RigidBodyChain(std::move(model));
}

void RigidBodyChain::RequireState(const char* what, const ConstVectorRef& v) const {
  if (v.size() != num_joints()) {
    RequireSize(std::string("RigidBodyChain: ") + what, v.size(), num_joints());
  }
  if (!AllFinite(v)) RequireFinite(std::string("RigidBodyChain: ") + what, v);
}

Vector RigidBodyChain::InverseDynamics(const ConstVectorRef& q, const ConstVectorRef& qd,
                                       const ConstVectorRef& qdd) const {
  RequireState("q", q);
  RequireState("qd", qd);
  RequireState("qdd", qdd);
  const KDL::Chain& chain = model_->chain;
  KDL::ChainIdSolver_RNE rne(chain, ToKdl(gravity()));
  KDL::JntArray kq(num_joints()), kqd(num_joints()), kqdd(num_joints()), tau(num_joints());
  kq.data = q;
  kqd.data = qd;
  kqdd.data = qdd;
  CheckKdl(rne.CartToJnt(kq, kqd, kqdd,
                         KDL::Wrenches(chain.getNrOfSegments(), KDL::Wrench::Zero()), tau),
           "ChainIdSolver_RNE::CartToJnt");
  return tau.data;
}

Matrix RigidBodyChain::MassMatrix(const ConstVectorRef& q) const {
  RequireState("q", q);
  KDL::ChainDynParam dyn(model_->chain, ToKdl(gravity()));
  KDL::JntArray kq(num_joints());
  kq.data = q;
  KDL::JntSpaceInertiaMatrix mass(num_joints());
  CheckKdl(dyn.JntToMass(kq, mass), "ChainDynParam::JntToMass");
  return mass.data;
}

Vector RigidBodyChain::Coriolis(const ConstVectorRef& q, const ConstVectorRef& qd) const {
  RequireState("q", q);
  RequireState("qd", qd);
  KDL::ChainDynParam dyn(model_->chain, ToKdl(gravity()));
  KDL::JntArray kq(num_joints()), kqd(num_joints()), out(num_joints());
  kq.data = q;
  kqd.data = qd;
  CheckKdl(dyn.JntToCoriolis(kq, kqd, out), "ChainDynParam::JntToCoriolis");
  return out.data;
}

Vector RigidBodyChain::Gravity(const ConstVectorRef& q) const {
  RequireState("q", q);
  KDL::ChainDynParam dyn(model_->chain, ToKdl(gravity()));
  KDL::JntArray kq(num_joints()), out(num_joints());
  kq.data = q;
  CheckKdl(dyn.JntToGravity(kq, out), "ChainDynParam::JntToGravity");
  return out.data;
}

RigidBodyChain::Workspace RigidBodyChain::MakeWorkspace() const {
  return Workspace(std::make_unique<Workspace::Impl>(model_->kinematics));
}

void RigidBodyChain::Regressor(const ConstVectorRef& q, const ConstVectorRef& qd,
                               const ConstVectorRef& qdd, Terms terms, MatrixRef Y,
                               Workspace& workspace) const {
  RequireState("q", q);
  RequireState("qd", qd);
  RequireState("qdd", qdd);
  const int n = num_joints();
  if (Y.rows() != n || Y.cols() != num_parameters()) {
    throw std::invalid_argument("RigidBodyChain::Regressor: Y must be " + std::to_string(n) +
                                " x " + std::to_string(num_parameters()) + ", got " +
                                std::to_string(Y.rows()) + " x " + std::to_string(Y.cols()));
  }
  if (!workspace.impl_ || workspace.impl_->kinematics != model_->kinematics) {
    throw std::invalid_argument(
        "RigidBodyChain::Regressor: the workspace was made by a chain of other kinematics "
        "(MakeWorkspace of this chain, or of one it was made from by WithParameters)");
  }
  Workspace::Impl& ws = *workspace.impl_;
  const bool with_gravity = terms == Terms::kAll || terms == Terms::kGravity;
  const bool with_velocity = terms == Terms::kAll || terms == Terms::kCoriolis;
  const bool with_acceleration = terms == Terms::kAll || terms == Terms::kInertial;
  const auto& basis = internal::BasisInertias();
  const std::vector<int>& moving = ws.kinematics->moving_segments;
  for (int k = 0; k < n; ++k) {
    Workspace::Impl::Truncated& t = *ws.truncated[k];
    const int joints = k + 1;
    t.q.data = q.head(joints);
    t.qd.data = qd.head(joints);
    t.qdd.data = qdd.head(joints);
    KDL::ChainIdSolver_RNE& rne = with_gravity ? t.rne_gravity : t.rne_no_gravity;
    const KDL::JntArray& velocity = with_velocity ? t.qd : t.zero;
    const KDL::JntArray& acceleration = with_acceleration ? t.qdd : t.zero;
    KDL::Segment& segment = t.chain.segments[moving[k]];
    for (int j = 0; j < kLinkParameters; ++j) {
      segment.setInertia(basis[j]);
      CheckKdl(rne.CartToJnt(t.q, velocity, acceleration, t.no_external_wrenches, t.tau),
               "ChainIdSolver_RNE::CartToJnt");
      auto column = Y.col(kLinkParameters * k + j);
      column.head(joints) = t.tau.data;
      column.tail(n - joints).setZero();
    }
    segment.setInertia(KDL::RigidBodyInertia::Zero());
  }
  // Armature: KDL adds joint inertia * qdd_j to tau_j.
  auto armature = Y.rightCols(n);
  armature.setZero();
  if (with_acceleration) armature.diagonal() = qdd;
}

Matrix RigidBodyChain::Regressor(const ConstVectorRef& q, const ConstVectorRef& qd,
                                 const ConstVectorRef& qdd, Terms terms) const {
  Workspace workspace = MakeWorkspace();
  Matrix Y(num_joints(), num_parameters());
  Regressor(q, qd, qdd, terms, Y, workspace);
  return Y;
}

const KDL::Chain& RigidBodyChain::kdl_chain() const { return model_->chain; }

}  // namespace structgp
