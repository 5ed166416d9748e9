#ifndef STRUCTGP_SRC_RIGID_BODY_URDF_READER_H_
#define STRUCTGP_SRC_RIGID_BODY_URDF_READER_H_

// A URDF document to a KDL chain with lumped inertias. Not part of the API: it exposes KDL
// types.

#include <string>
#include <vector>

#include <kdl/chain.hpp>

#include "structgp/rigid_body/rigid_body_chain.h"

namespace structgp {
namespace internal {

struct UrdfChain {
  // The KDL segments from root (excluded) to tip, as kdl_parser builds them. A moving
  // segment's inertia is its link's with every link behind a fixed joint lumped into it (in its
  // frame); fixed segments carry zero inertia. Every joint's inertia is 0.
  KDL::Chain chain;
  std::vector<int> moving_segments;  // KDL segment index of moving joint k
  std::vector<std::string> joint_names, link_names;
  std::string robot_name, root, tip;
};

// Throws std::invalid_argument naming `source` on every problem listed at
// RigidBodyChain::FromUrdfString (except gravity, checked by the caller).
UrdfChain ReadUrdfChain(const std::string& xml, const UrdfOptions& options,
                        const std::string& source);

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_SRC_RIGID_BODY_URDF_READER_H_
