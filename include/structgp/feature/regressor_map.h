#ifndef STRUCTGP_FEATURE_REGRESSOR_MAP_H_
#define STRUCTGP_FEATURE_REGRESSOR_MAP_H_

/// @file
/// A regressor x -> Psi(x), an N x P matrix, for models whose N outputs share one parameter
/// vector theta:
///     y = Psi(x) theta + noise,   theta ~ N(mu, diag(lambda)).
/// The rigid-body regressor of a serial chain is one (every joint torque is linear in the same
/// inertial parameters of the links); joint-local friction and effects add columns that are
/// nonzero only in their own joint's row. With the Gaussian prior it defines the matrix-valued
/// kernel K(a, b) = Psi(a) diag(lambda) Psi(b)^T and a Bayesian linear model (RegressorGP,
/// model/regressor_gp.h).
///
/// Compare FeatureMap (feature_map.h): there one phi(x) serves every output and each output
/// has weights of its own, so outputs share no parameter; here the outputs are coupled through
/// theta, and each output may have its own noise level.
///
/// Invariants a regressor keeps: its sizes never change; Evaluate is a pure function of x and
/// safe to call concurrently, each thread with its own Scratch (MakeScratch: the solvers of a
/// rigid-body chain, say), and with it does not allocate; blocks() tile [0, dim()) in order;
/// the components' matrices add up to Psi(x).

#include <memory>

#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"

namespace structgp {

class RegressorMap {
 public:
  virtual ~RegressorMap() = default;

  /// Length of the input x (3N for a robot state, 3N + 1 when the time is used).
  virtual int input_dim() const = 0;
  /// Number of outputs N (rows of Psi).
  virtual int num_outputs() const = 0;
  /// Number of parameters P (columns of Psi).
  virtual int dim() const = 0;
  /// Per-thread scratch memory of the evaluations, made by MakeScratch (null when a map needs
  /// none, the default).
  class Scratch {
   public:
    virtual ~Scratch() = default;
  };
  virtual std::unique_ptr<Scratch> MakeScratch() const { return nullptr; }

  /// Psi(x) into psi (num_outputs() x dim()), with scratch from this map's MakeScratch. Must
  /// not allocate.
  virtual void Evaluate(const ConstVectorRef& x, MatrixRef psi, Scratch* scratch) const = 0;
  /// The same with scratch made for the call (allocates when the map needs scratch).
  void Evaluate(const ConstVectorRef& x, MatrixRef psi) const;

  /// Column blocks that share one prior scale, in order ("rigid_body", "friction", effects).
  virtual std::vector<FeatureBlock> blocks() const = 0;
  /// One name per parameter (dim()), e.g. "m@3", "coulomb@2".
  virtual std::vector<std::string> parameter_names() const = 0;
  /// Prior mean mu (dim()). Default: zero.
  virtual Vector prior_mean() const;
  /// Prior standard deviation of each parameter before the block scales (dim()): the prior
  /// variance of parameter k of block b is (prior_std_k exp(log_block_scale_b))^2. Default:
  /// ones.
  virtual Vector prior_std() const;

  /// Names of the physical components of a prediction ("inertial", "coriolis", "gravity",
  /// "friction", effects). Default: the block names.
  virtual std::vector<std::string> component_names() const;
  /// The part of Psi(x) that belongs to component c, into psi (N x P; the sum over all
  /// components is Psi(x)). Default: the columns of block c, zero elsewhere (allocates: not for
  /// a real-time path). Throws std::invalid_argument for a component out of range.
  virtual void EvaluateComponent(int component, const ConstVectorRef& x, MatrixRef psi,
                                 Scratch* scratch) const;
};

/// The prior variances lambda (dim()) of a regressor for one log scale per block.
/// Throws std::invalid_argument when log_block_scale does not have one entry per block.
Vector RegressorPriorVariance(const RegressorMap& map, const ConstVectorRef& log_block_scale);

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_REGRESSOR_MAP_H_
