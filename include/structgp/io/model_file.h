#ifndef STRUCTGP_IO_MODEL_FILE_H_
#define STRUCTGP_IO_MODEL_FILE_H_

/// @file
/// Saving a fitted RobotModel to a file and loading it back, exactly: the loaded model gives
/// bit-identical predictions, components, coefficients and evidence, and it keeps learning
/// (GaussianProcess::Add) exactly as the saved one would have.
///
/// Format (version 2; version 1 is the same layout). One JSON object, written atomically
/// (WriteTextAtomically):
///
///     {
///       "format": "structgp-model",  "version": 2,
///       "checksum": "crc32:1a2b3c4d",
///       "model": "pol+fri",  "effects": "coulomb@2",  "effect_list": [...],
///       "options": {"form": "auto", "friction_width": 0.01, "broad_prior_std": 10.0},
///       "num_joints": 2,  "uses_time": false,  "input_dim": 6,  "num_features": 139,
///       "form": "weight_space",
///       "hyperparameters": {"shape": [...], "log_block_scale": [...], "log_noise_std": -4.6,
///                           "log_output_scale": [...], "kernel_parameters": [...]},
///       "log_marginal_likelihood": 1234.5,  "num_samples": 4000,
///       "weight_space": {...}        (weight-space models)
///       "function_space": {...}      (function-space models)
///     }
///
/// - Scalars are JSON numbers written with the shortest text that reads back to the same
///   double; hyper-parameter vectors are JSON arrays of such numbers.
/// - Matrices are objects {"rows", "cols", "layout", "encoding": "base64-f64le", "data"}: the
///   doubles in little-endian IEEE-754 binary64, column by column ("layout": "column_major"),
///   or only the upper triangle of each column ("upper_triangular"), base64-encoded.
/// - "weight_space" holds the WeightSpaceGPState (factor S, weights W and the evidence
///   counters); the model is rebuilt from it directly.
/// - "function_space" holds the stored inputs and targets; the model is rebuilt by fitting
///   them in one batch with the stored hyper-parameters (and kernel parameters). Predictions
///   are then bit-identical to those of a model that was fitted in one batch, as every model
///   made by Fit is; after online additions (GaussianProcess::Add) they agree to rounding.
/// - "checksum" is the CRC-32 of the compact JSON text of the object without "checksum", so
///   that any change to a number, a name or the payload is detected.
/// - "latent_variance_scale" (version 3, only when not all 1): RobotModel's factor on each
///   joint's latent variance (the calibration of FitOptions::calibrate_bands).
/// - "effect_list" holds each effect's name, joints and parameters; "model" and "effects" are
///   the same model in the text users write (ParseModelSpec, ParseEffectList).
///
/// A file written by a later format version, a file of another kind, a truncated, corrupted
/// or hand-edited file is refused with a DataError naming the file and the problem (with the
/// line and column for malformed JSON); loading never crashes on bad input.

#include <string>

#include "structgp/io/data_error.h"
#include "structgp/model/robot_model.h"

namespace structgp {

/// The value of the "format" field.
inline constexpr const char* kModelFileFormat = "structgp-model";
/// The newest version, written by SaveModel for models with per-joint hyper-parameters
/// ("hyperparameters.per_joint", and in weight space "joint_weight_space") and for models
/// whose bands are calibrated ("latent_variance_scale" not all 1). LoadModel reads it
/// and every version from kOldestModelFileVersion, except 'lag' and 'lagk' models of version 1
/// (refused, naming the field "model": version 2 changed their Euler-Lagrange space, so they
/// must be fitted again).
inline constexpr int kModelFileVersion = 3;
/// The version SaveModel writes for models whose joints share their hyper-parameters and whose
/// bands are the posterior's own (their files are the same as in version 2, so builds that
/// read version 2 read them).
inline constexpr int kSharedModelFileVersion = 2;
inline constexpr int kOldestModelFileVersion = 1;

/// The complete text of the model file of `model` (what SaveModel writes). Throws
/// std::invalid_argument when the model is not fitted or holds a non-finite value.
std::string ModelFileText(const RobotModel& model);

/// The posterior file of a model file: `model_path` + ".posterior". A lagk model through
/// inducing states stores its data and inducing states in the model file, and computing its
/// posterior from them again takes minutes at 6-7 joints (a pass over every row). Its posterior
/// file holds what that pass computes (EulerLagrangeGP::DtcFactors: 8 (p N)(p N + 3) / 2
/// bytes, 125 MB for 800 inducing states of a 7-joint arm), bound to the model file by the
/// model file's checksum, so that LoadModel reads it instead. It is a cache: a model file
/// without it loads as before, to the same predictions.
///
/// Format (little-endian): the line "structgp posterior file\n", a uint32 version (1), a
/// uint32 length and the model file's "checksum" text, a uint64 p N, a float64 log p(Y),
/// alpha (p N float64), the lower triangle of B's factor column by column (float64), and a
/// uint32 CRC-32 of every byte before it.
std::string PosteriorFilePath(const std::string& model_path);

/// The bytes of the posterior file of `model` (PosteriorFilePath), bound to the model file
/// ModelFileText(model) writes; empty when the model has none (every model but lagk through
/// inducing states). Throws std::invalid_argument as ModelFileText.
std::string PosteriorFileBytes(const RobotModel& model);

/// How a model file is written.
struct SaveOptions {
  /// Write the posterior file too, when the model has one (PosteriorFileBytes). A posterior
  /// file at PosteriorFilePath(path) that this save does not write is removed (it belonged to
  /// the file being replaced).
  bool posterior_file = true;
};

/// Writes the model file atomically: readers (and a crash) see the old file or the complete
/// new one. Its posterior file, when written, is written first, atomically too. Throws
/// std::invalid_argument as ModelFileText, DataError when a file cannot be written (the
/// previous model file is then left untouched).
void SaveModel(const std::string& path, const RobotModel& model,
               const SaveOptions& options = SaveOptions());

/// How a model file is read.
struct LoadOptions {
  /// Workers of the posterior's factorisation where a model file holds the data rather than
  /// the posterior (lagk through inducing states: EulerLagrangeGP::Condition); the model's
  /// later batch fits (RobotModelOptions::batch) use them too. >= 1.
  int num_threads = 1;
  /// LoadModel: read the posterior file (PosteriorFilePath) when the model has one and it is
  /// there; when it is not used (absent, written for another model file, damaged) the
  /// posterior is computed from the rows, as without it.
  bool posterior_file = true;
};

/// What LoadModel did beyond reading the model file.
struct LoadSummary {
  /// The posterior was read from the posterior file.
  bool posterior_file_read = false;
  /// Why a posterior file that is there was not read (empty otherwise): "written for another
  /// model file (...)", "damaged: ...". The posterior was then computed from the rows.
  std::string posterior_file_note;
};

/// Reads a model file. `path` only names the source in error messages. Throws DataError
/// naming `path` and the problem, std::invalid_argument when options.num_threads < 1.
RobotModel ParseModelFile(const std::string& text, const std::string& path,
                          const LoadOptions& options = LoadOptions());

/// Reads a model file written by SaveModel, and its posterior file when it has one (see
/// LoadOptions::posterior_file; summary, when not null, says whether it was read and why not).
/// Throws DataError naming the file and the problem: it cannot be read, is not JSON (with line
/// and column), is not a structgp model file, has an unsupported version, fails its checksum,
/// or holds an inconsistent model; std::invalid_argument when options.num_threads < 1. A
/// posterior file that cannot be used is not an error (summary->posterior_file_note).
RobotModel LoadModel(const std::string& path, const LoadOptions& options = LoadOptions(),
                     LoadSummary* summary = nullptr);

/// What a model file says about its model, without rebuilding it: the model and its effects,
/// the joints, the form it was fitted in and the hyper-parameters (a kernel model's kernel
/// parameters in `shape`, as RobotModel::hyperparameters() has them). The file's format,
/// version and checksum are checked as LoadModel checks them, and these fields as LoadModel
/// reads them; the rest is not read (a lagk model's posterior is not factorised again): what
/// starting a search from a model needs (`structgp fit --start-from`).
struct ModelFileHeader {
  ModelSpec spec;
  int num_joints = 0;
  Form form = Form::kAuto;
  Hyperparameters hyperparameters;
};

/// Reads the header of a model file's text; `path` names the source in error messages.
/// Throws DataError as ParseModelFile.
ModelFileHeader ParseModelFileHeader(const std::string& text, const std::string& path);
/// Reads the header of a model file. Throws DataError as LoadModel.
ModelFileHeader ReadModelFileHeader(const std::string& path);

}  // namespace structgp

#endif  // STRUCTGP_IO_MODEL_FILE_H_
