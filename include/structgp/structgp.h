#ifndef STRUCTGP_STRUCTGP_H_
#define STRUCTGP_STRUCTGP_H_

/// @file
/// Umbrella header: the whole public API of the structgp library (not the simulator, which
/// is the separate structgp_sim target with headers under structgp/sim/).

#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/core/validate.h"
#include "structgp/feature/feature_map.h"
#include "structgp/hyper/evidence.h"
#include "structgp/hyper/hyperparameters.h"
#include "structgp/kernel/kernel.h"
#include "structgp/model/sufficient_statistics.h"
#include "structgp/model/weight_space_gp.h"

#endif  // STRUCTGP_STRUCTGP_H_
