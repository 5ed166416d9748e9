#include "urdf_reader.h"

#include <algorithm>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <console_bridge/console.h>
#include <kdl/frames.hpp>
#include <kdl/rigidbodyinertia.hpp>
#include <kdl/segment.hpp>
#include <kdl/tree.hpp>
#include <kdl_parser/kdl_parser.hpp>
#include <urdf_model/joint.h>
#include <urdf_model/link.h>
#include <urdf_model/model.h>
#include <urdf_parser/urdf_parser.h>

namespace structgp {
namespace internal {
namespace {

// urdfdom reports why a document does not parse through console_bridge's log. While it parses,
// the messages are collected here to go into the exception (console_bridge's handler is global:
// a mutex keeps two readers from interleaving).
class MessageCollector : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char* /*filename*/,
           int /*line*/) override {
    if (level < console_bridge::CONSOLE_BRIDGE_LOG_WARN) return;
    if (!messages_.empty()) messages_ += "; ";
    messages_ += text;
  }
  const std::string& messages() const { return messages_; }

 private:
  std::string messages_;
};

std::mutex& ConsoleMutex() {
  static std::mutex mutex;
  return mutex;
}

std::string JoinNames(std::vector<std::string> names) {
  std::sort(names.begin(), names.end());
  std::string out;
  for (const std::string& name : names) {
    if (!out.empty()) out += ", ";
    out += "'" + name + "'";
  }
  return out;
}

std::string LinkList(const urdf::ModelInterface& model) {
  std::vector<std::string> names;
  for (const auto& entry : model.links_) names.push_back(entry.first);
  return JoinNames(std::move(names));
}

const char* JointTypeName(int type) {
  switch (type) {
    case urdf::Joint::REVOLUTE: return "revolute";
    case urdf::Joint::CONTINUOUS: return "continuous";
    case urdf::Joint::PRISMATIC: return "prismatic";
    case urdf::Joint::FLOATING: return "floating";
    case urdf::Joint::PLANAR: return "planar";
    case urdf::Joint::FIXED: return "fixed";
    default: return "unknown";
  }
}

bool IsMoving(const urdf::Joint& joint) {
  return joint.type == urdf::Joint::REVOLUTE || joint.type == urdf::Joint::CONTINUOUS;
}

void RequireSupported(const urdf::Joint& joint, const std::string& source) {
  if (IsMoving(joint) || joint.type == urdf::Joint::FIXED) return;
  throw std::invalid_argument(source + ": joint '" + joint.name + "' is " +
                              JointTypeName(joint.type) +
                              ": only revolute and continuous joints are supported (and fixed "
                              "ones, whose links are lumped)");
}

// The inertia of `link` and of every link behind a fixed joint below it that is not on the
// chain, in the frame of `link` (KDL's Frame * RigidBodyInertia moves an inertia into the parent
// frame). `on_chain` holds the names of the chain's links; branches behind a moving joint are
// not part of the model.
KDL::RigidBodyInertia LumpedInertia(const KDL::Tree& tree, const urdf::Link& link,
                                    const std::map<std::string, bool>& on_chain) {
  const auto element = tree.getSegment(link.name);
  KDL::RigidBodyInertia inertia = GetTreeElementSegment(element->second).getInertia();
  for (const urdf::LinkSharedPtr& child : link.child_links) {
    if (on_chain.count(child->name) != 0) continue;
    const urdf::Joint& joint = *child->parent_joint;
    if (joint.type != urdf::Joint::FIXED) continue;
    const KDL::Frame pose = GetTreeElementSegment(tree.getSegment(child->name)->second).pose(0.0);
    inertia = inertia + pose * LumpedInertia(tree, *child, on_chain);
  }
  return inertia;
}

}  // namespace

UrdfChain ReadUrdfChain(const std::string& xml, const UrdfOptions& options,
                        const std::string& source) {
  urdf::ModelInterfaceSharedPtr model;
  KDL::Tree tree;
  bool tree_ok = false;
  std::string messages;
  {
    const std::lock_guard<std::mutex> lock(ConsoleMutex());
    MessageCollector collector;
    console_bridge::useOutputHandler(&collector);
    try {
      model = urdf::parseURDF(xml);
      if (model) tree_ok = kdl_parser::treeFromUrdfModel(*model, tree);
    } catch (...) {
      console_bridge::restorePreviousOutputHandler();
      throw;
    }
    console_bridge::restorePreviousOutputHandler();
    messages = collector.messages();
  }
  if (!model) {
    throw std::invalid_argument(source + ": not a valid URDF (urdfdom's parser failed" +
                                (messages.empty() ? std::string() : ": " + messages) + ")");
  }
  if (!tree_ok) {
    throw std::invalid_argument(source + ": kdl_parser could not make a KDL tree of the URDF" +
                                (messages.empty() ? std::string() : ": " + messages));
  }

  UrdfChain out;
  out.robot_name = model->getName();
  out.root = options.root.empty() ? model->getRoot()->name : options.root;
  const urdf::LinkConstSharedPtr root = model->getLink(out.root);
  if (!root) {
    throw std::invalid_argument(source + ": root link '" + out.root +
                                "' not found; the links are " + LinkList(*model));
  }
  if (options.tip.empty()) {
    std::vector<std::string> leaves;
    std::vector<urdf::LinkConstSharedPtr> stack{root};
    while (!stack.empty()) {
      const urdf::LinkConstSharedPtr link = stack.back();
      stack.pop_back();
      if (link->child_links.empty()) leaves.push_back(link->name);
      for (const urdf::LinkSharedPtr& child : link->child_links) stack.push_back(child);
    }
    if (leaves.size() > 1) {
      throw std::invalid_argument(source + ": the tree below '" + out.root + "' has " +
                                  std::to_string(leaves.size()) + " leaves (" +
                                  JoinNames(leaves) + "): name the chain's tip link");
    }
    out.tip = leaves.front();
  } else {
    out.tip = options.tip;
  }
  const urdf::LinkConstSharedPtr tip = model->getLink(out.tip);
  if (!tip) {
    throw std::invalid_argument(source + ": tip link '" + out.tip +
                                "' not found; the links are " + LinkList(*model));
  }

  // The links from root to tip, walking up from the tip.
  std::vector<urdf::LinkConstSharedPtr> path;
  for (urdf::LinkConstSharedPtr link = tip; link; link = link->getParent()) {
    path.push_back(link);
    if (link->name == out.root) break;
  }
  if (path.back()->name != out.root) {
    throw std::invalid_argument(source + ": no chain from root '" + out.root + "' to tip '" +
                                out.tip + "': '" + out.tip + "' is not below '" + out.root +
                                "'");
  }
  std::reverse(path.begin(), path.end());
  std::map<std::string, bool> on_chain;
  for (const auto& link : path) on_chain[link->name] = true;

  if (!tree.getChain(out.root, out.tip, out.chain) ||
      out.chain.getNrOfSegments() + 1 != path.size()) {
    throw std::logic_error(source + ": KDL's chain from '" + out.root + "' to '" + out.tip +
                           "' does not follow the URDF's links");
  }

  // Inertias: each segment's lumped inertia goes to the last moving segment at or before it,
  // moved into that segment's frame by the fixed segments in between.
  std::vector<KDL::RigidBodyInertia> lumped(out.chain.getNrOfSegments(),
                                            KDL::RigidBodyInertia::Zero());
  int owner = -1;
  KDL::Frame owner_to_segment = KDL::Frame::Identity();
  for (std::size_t i = 0; i + 1 < path.size(); ++i) {
    const urdf::Link& link = *path[i + 1];
    const urdf::Joint& joint = *link.parent_joint;
    RequireSupported(joint, source);
    KDL::Segment& segment = out.chain.segments[i];
    if (IsMoving(joint)) {
      owner = static_cast<int>(i);
      owner_to_segment = KDL::Frame::Identity();
      out.moving_segments.push_back(owner);
      out.joint_names.push_back(joint.name);
      out.link_names.push_back(link.name);
    } else {
      owner_to_segment = owner_to_segment * segment.pose(0.0);
    }
    if (owner >= 0) {
      lumped[owner] = lumped[owner] + owner_to_segment * LumpedInertia(tree, link, on_chain);
    }
  }
  for (std::size_t i = 0; i < lumped.size(); ++i) out.chain.segments[i].setInertia(lumped[i]);
  if (out.moving_segments.empty()) {
    throw std::invalid_argument(source + ": the chain from '" + out.root + "' to '" + out.tip +
                                "' has no moving (revolute or continuous) joint");
  }
  return out;
}

}  // namespace internal
}  // namespace structgp
