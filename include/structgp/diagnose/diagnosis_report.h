#ifndef STRUCTGP_DIAGNOSE_DIAGNOSIS_REPORT_H_
#define STRUCTGP_DIAGNOSE_DIAGNOSIS_REPORT_H_

/// @file
/// A diagnosis for people: the per-joint table, each suggestion in words with the effect list
/// that adds it, and the model with every suggestion added.

#include <string>

#include "structgp/diagnose/diagnosis.h"
#include "structgp/model/model_spec.h"

namespace structgp {

/// "Coulomb friction", "cogging (period 0.3 rad)", ...
std::string DescribeEffect(const Suggestion& suggestion);

/// spec with every suggestion of the diagnosis added to its effects.
ModelSpec WithSuggestions(const ModelSpec& spec, const Diagnosis& diagnosis);

/// Per joint: residual RMS, nMSE, noise estimate and where the error concentrates; then each
/// suggestion ("joint 2: missing Coulomb friction (evidence +1052 nats): ...; add with
/// --effects coulomb@2"), or why none was made; then the closest refused candidates with the
/// bar each one failed (Diagnosis::refused). `spec` is the diagnosed model's, `options` those
/// of the diagnosis.
std::string DiagnosisReport(const Diagnosis& diagnosis, const ModelSpec& spec,
                            const DiagnosisOptions& options);

}  // namespace structgp

#endif  // STRUCTGP_DIAGNOSE_DIAGNOSIS_REPORT_H_
