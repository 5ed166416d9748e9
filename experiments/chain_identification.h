// A serial chain identified from its torques alone: the kinematics (where each joint axis lies
// relative to the one before it, and how the first leans against gravity) and the inertial
// parameters, with no URDF. The hypothesis space is the rigid-body dynamics of every N-joint
// chain of revolute joints: 4N - 4 kinematic numbers and 11 N inertial parameters (with
// armature), against the tens of thousands of an energy kernel's space at 7 joints.
//
// Kinematics, modified Denavit-Hartenberg (sim::DhConvention::kModified): axis i+1 lies relative
// to axis i by theta_i, d_i (the common normal's angle and place along axis i), alpha_{i+1} and
// a_{i+1}; d_1 moves the whole arm along axis 1 and changes nothing, so it is 0; axis 1 leans by
// beta from the vertical (gravity -z). For fixed kinematics the torques are linear in the
// inertial parameters (and the friction coefficients), which least squares eliminates (variable
// projection); the kinematics are searched by Levenberg-Marquardt (Ceres, forward differences)
// from several starts, on --chain-rows evenly spaced rows, each joint's torque divided by its
// RMS. The best start's kinematics then give the inertial parameters on every row.

#ifndef STRUCTGP_EXPERIMENTS_CHAIN_IDENTIFICATION_H_
#define STRUCTGP_EXPERIMENTS_CHAIN_IDENTIFICATION_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/rigid_body/rigid_body_chain.h"

namespace structgp {

struct ChainIdentificationOptions {
  bool friction = false;      // viscous and Coulomb columns per joint
  double friction_width = 0.01;
  int search_rows = 400;      // rows of the kinematic search
  int starts = 8;
  int threads = 1;
  int max_iterations = 100;
  std::uint64_t seed = 1;
  double ridge = 1e-9;        // relative to the normal matrix's mean diagonal
};

struct ChainIdentificationResult {
  Vector kinematics;               // 4N - 4 numbers (layout above)
  Vector theta;                    // inertial parameters, then friction
  Vector noise_std;                // per joint, from the residual on every row
  std::vector<double> start_costs; // each start's final cost (sum of squared scaled residuals)
  int best_start = -1;
  std::string note;
};

// The chain with kinematics `kappa` (unit inertias: only its regressor is used).
RigidBodyChain ChainFromKinematics(int num_joints, const Vector& kappa);

// Regressor rows of `X` for the chain and the friction columns, stacked joint by joint per row:
// row i * N + j. Columns: 11 N inertial, then 2 N friction (viscous, Coulomb) when asked.
Matrix ChainDesign(const RigidBodyChain& chain, const Matrix& X, bool friction, double width);

ChainIdentificationResult IdentifyChain(const Matrix& X, const Matrix& Y,
                                        const ChainIdentificationOptions& options);

// tau = Phi(x) theta at every row of X.
Matrix PredictChain(int num_joints, const ChainIdentificationResult& r, const Matrix& X,
                    const ChainIdentificationOptions& options);

}  // namespace structgp

#endif  // STRUCTGP_EXPERIMENTS_CHAIN_IDENTIFICATION_H_
