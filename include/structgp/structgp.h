#ifndef STRUCTGP_STRUCTGP_H_
#define STRUCTGP_STRUCTGP_H_

/// @file
/// Umbrella header: the whole public API of the structgp library (not the simulator, which
/// is the separate structgp_sim target with headers under structgp/sim/). Including the one
/// header a program needs is cheaper to compile; this one is for convenience.
/// Not included: structgp/testing/ (test utilities for your own feature maps; they need
/// GoogleTest).

// Core: status codes, matrix types, input checks.
#include "structgp/core/status.h"
#include "structgp/core/row_subset.h"
#include "structgp/core/types.h"
#include "structgp/core/validate.h"
#include "structgp/core/hyperparameters.h"
#include "structgp/core/version.h"

// Rigid bodies: chains from URDF, KDL dynamics, the inertial-parameter regressor.
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/rigid_body/physical_consistency.h"

// Feature maps: the structured kernels as explicit features, effects, sums, Nystrom.
#include "structgp/feature/feature_map.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/feature/pol_feature_map.h"
#include "structgp/feature/pol_kernel_formula.h"
#include "structgp/feature/gravity_basis_feature_map.h"
#include "structgp/feature/friction_feature_map.h"
#include "structgp/feature/motor_feature_map.h"
#include "structgp/feature/effect_parameter.h"
#include "structgp/feature/effect_residual.h"
#include "structgp/feature/effect.h"
#include "structgp/feature/effects.h"
#include "structgp/feature/effect_feature_map.h"
#include "structgp/feature/sum_feature_map.h"

// Kernels for the function-space (kernel) form.
#include "structgp/kernel/kernel.h"
#include "structgp/kernel/kernel_hyperparameters.h"
#include "structgp/kernel/rbf_kernel.h"
#include "structgp/kernel/pol_chain_kernel.h"
#include "structgp/kernel/pol_kernel.h"
#include "structgp/kernel/feature_kernel.h"
#include "structgp/kernel/leading_inputs_kernel.h"
#include "structgp/kernel/sum_kernel.h"
#include "structgp/kernel/nystrom_feature_map.h"

// Models: weight space (rank-one updates), kernel form, automatic choice, robot models from specs.
#include "structgp/model/sufficient_statistics.h"
#include "structgp/model/weight_space_gp.h"
#include "structgp/model/kernel_gp.h"
#include "structgp/model/gaussian_process.h"
#include "structgp/model/model_spec.h"
#include "structgp/model/robot_model.h"

// Hyper-parameters: type-II maximum likelihood (Ceres) and blocked cross-validation.
#include "structgp/hyper/hyperparameter_layout.h"
#include "structgp/hyper/evidence.h"
#include "structgp/hyper/hyperprior.h"
#include "structgp/hyper/marginal_likelihood.h"
#include "structgp/hyper/cross_validation.h"

// Diagnosis: which physical effect the model is missing.
#include "structgp/fit/fit_model.h"
#include "structgp/diagnose/autocorrelation.h"
#include "structgp/diagnose/diagnosis.h"
#include "structgp/diagnose/diagnosis_loop.h"
#include "structgp/diagnose/diagnosis_report.h"

// Online learning next to a control loop.
#include "structgp/online/triple_buffer.h"
#include "structgp/online/online_learner.h"
#include "structgp/online/replay.h"

// Files: robot data CSV, atomic writes, model files.
#include "structgp/io/data_error.h"
#include "structgp/io/csv.h"
#include "structgp/io/robot_data.h"
#include "structgp/io/atomic_file.h"
#include "structgp/io/model_file.h"

// Raw logs to data files: zero-phase filtering and differentiation.
#include "structgp/prepare/butterworth.h"
#include "structgp/prepare/raw_log.h"
#include "structgp/prepare/prepare.h"

// The HTML diagnosis report.
#include "structgp/report/report.h"
#include "structgp/report/report_data.h"

#endif  // STRUCTGP_STRUCTGP_H_
