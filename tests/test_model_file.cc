// Model files: a saved and loaded model predicts bit for bit what the original predicts, in
// weight space (pol+fri with effects, with and without time) and in function space (rbf, and
// pol with fewer samples than features); it keeps learning exactly as the original would; the
// WeightSpaceGP state round-trips; damaged files of every kind are refused with a DataError
// naming the file; saving is atomic.

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "model_file_checksum.h"
#include "temp_files.h"
#include "structgp/fit/fit_model.h"
#include "structgp/io/model_file.h"
#include "structgp/kernel/kernel.h"
#include "structgp/model/robot_model.h"
#include "structgp/sim/hidden_effect.h"

namespace structgp {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using testing::ReadFile;
using testing::WriteFile;

struct TempDir : testing::TempDir {
  TempDir() : testing::TempDir("test_model_file") {}
};

// Exact equality of every bit (a tolerance would hide a lossy round trip).
void ExpectBitIdentical(const Matrix& a, const Matrix& b, const std::string& what) {
  ASSERT_EQ(a.rows(), b.rows()) << what;
  ASSERT_EQ(a.cols(), b.cols()) << what;
  if (a.size() == 0) return;  // empty: data() may be null, and memcmp(null, ...) is undefined
  EXPECT_EQ(std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())), 0)
      << what << ": max difference " << (a - b).cwiseAbs().maxCoeff();
}

void ExpectSameDouble(double a, double b, const std::string& what) {
  EXPECT_EQ(std::memcmp(&a, &b, sizeof(double)), 0) << what << ": " << a << " vs " << b;
}

// A two-link arm with hidden Coulomb friction on joint 2 (seed 5): 600 slow training samples
// and 250 fast test samples, times included.
const sim::HiddenEffectScenario& Scenario() {
  static const sim::HiddenEffectScenario scenario = [] {
    sim::HiddenEffectOptions o;
    o.effect = sim::HiddenEffect::kCoulomb;
    o.joint = 2;
    o.train_duration = 6.0;
    o.test_duration = 2.5;
    o.seed = 5;
    return sim::MakeHiddenEffectScenario(sim::TwoLinkArm(), o);
  }();
  return scenario;
}

Matrix Inputs(const RobotModel& model, const sim::Dataset& d) {
  if (!model.uses_time()) return d.X;
  Matrix X(d.X.rows(), d.X.cols() + 1);
  X << d.X, d.t;
  return X;
}

RobotModel FitModel(const std::string& model_text, const std::string& effects, int rows,
                    const RobotModelOptions& options = {}) {
  ModelSpec spec = ParseModelSpec(model_text);
  spec.effects = ParseEffectList(effects);
  const sim::Dataset& train = Scenario().train;
  RobotModel model(spec, train.num_joints(), options);
  const Matrix X = Inputs(model, train).topRows(rows);
  const Matrix Y = train.Y.topRows(rows);
  Hyperparameters h = model.DefaultHyperparameters(Y);
  h.log_noise_std = std::log(0.05);
  if (model.feature_map() && h.shape.size() > 0) h.shape[0] = 0.3;
  EXPECT_EQ(model.Fit(X, Y, h), Status::kOk);
  return model;
}

// Every result of the two models agrees bit for bit on the test log.
void ExpectSamePredictions(const RobotModel& a, const RobotModel& b) {
  const Matrix X = Inputs(a, Scenario().test);
  Matrix mean_a, std_a, mean_b, std_b;
  a.PredictRows(X, &mean_a, &std_a);
  b.PredictRows(X, &mean_b, &std_b);
  ExpectBitIdentical(mean_a, mean_b, "predictive mean");
  ExpectBitIdentical(std_a, std_b, "predictive std");
  ExpectSameDouble(a.gp().LogMarginalLikelihood(), b.gp().LogMarginalLikelihood(), "evidence");
  if (a.gp().weight_space() != nullptr) {
    ASSERT_NE(b.gp().weight_space(), nullptr);
    std::vector<Component> ca, cb;
    for (Eigen::Index i = 0; i < X.rows(); i += 37) {
      ASSERT_EQ(a.PredictComponents(X.row(i).transpose(), &ca), Status::kOk);
      ASSERT_EQ(b.PredictComponents(X.row(i).transpose(), &cb), Status::kOk);
      ASSERT_EQ(ca.size(), cb.size());
      for (size_t k = 0; k < ca.size(); ++k) {
        EXPECT_EQ(ca[k].name, cb[k].name);
        ExpectBitIdentical(ca[k].mean, cb[k].mean, "component " + ca[k].name);
        ExpectBitIdentical(ca[k].latent_variance, cb[k].latent_variance,
                           "component variance " + ca[k].name);
      }
    }
    for (const auto& name : a.ParametricFeatureNames()) {
      for (int j = 1; j <= a.num_joints(); ++j) {
        const auto [va, sa] = a.Coefficient(name, j);
        const auto [vb, sb] = b.Coefficient(name, j);
        ExpectSameDouble(va, vb, "coefficient " + name);
        ExpectSameDouble(sa, sb, "coefficient std " + name);
      }
    }
  }
}

void ExpectSameModel(const RobotModel& a, const RobotModel& b) {
  EXPECT_EQ(ToString(a.spec()), ToString(b.spec()));
  EXPECT_EQ(ToString(a.spec().effects), ToString(b.spec().effects));
  EXPECT_EQ(a.num_joints(), b.num_joints());
  EXPECT_EQ(a.uses_time(), b.uses_time());
  EXPECT_EQ(a.options().form, b.options().form);
  ExpectSameDouble(a.options().friction_width, b.options().friction_width, "friction_width");
  ExpectSameDouble(a.options().broad_prior_std, b.options().broad_prior_std, "broad_prior_std");
  EXPECT_EQ(a.gp().form(), b.gp().form());
  const Hyperparameters& ha = a.hyperparameters();
  const Hyperparameters& hb = b.hyperparameters();
  ExpectBitIdentical(ha.shape, hb.shape, "shape");
  ExpectBitIdentical(ha.log_block_scale, hb.log_block_scale, "log_block_scale");
  ExpectBitIdentical(ha.log_output_scale, hb.log_output_scale, "log_output_scale");
  ExpectSameDouble(ha.log_noise_std, hb.log_noise_std, "log_noise_std");
  ExpectSamePredictions(a, b);
}

// Adds the test log's first rows online to both models; they must stay identical.
void ContinueLearning(RobotModel* a, RobotModel* b, int rows) {
  const Matrix X = Inputs(*a, Scenario().test);
  const Matrix& Y = Scenario().test.Y;
  for (RobotModel* m : {a, b}) {
    if (KernelGP* fs = m->mutable_gp().mutable_function_space()) fs->Reserve(fs->size() + rows);
    for (int i = 0; i < rows; ++i) {
      ASSERT_EQ(m->mutable_gp().Add(X.row(i).transpose(), Y.row(i).transpose()), Status::kOk);
    }
  }
}

TEST(ModelFile, WeightSpacePolWithFrictionAndEffectsRoundTripsExactly) {
  TempDir dir;
  RobotModel model = FitModel("pol+fri", "coulomb@2,viscous@1,cogging@1:period=0.3", 600);
  ASSERT_NE(model.gp().weight_space(), nullptr);
  const std::string path = dir.File("model.json");
  SaveModel(path, model);
  RobotModel loaded = LoadModel(path);
  ExpectSameModel(model, loaded);
  // Saving the loaded model gives the same file, byte for byte.
  EXPECT_EQ(ModelFileText(loaded), ReadFile(path));

  // Continuing to learn after loading equals continuing before saving.
  ContinueLearning(&model, &loaded, 40);
  ExpectSamePredictions(model, loaded);
  EXPECT_EQ(model.gp().weight_space()->num_samples(), 640);
  EXPECT_EQ(loaded.gp().weight_space()->num_samples(), 640);
}

TEST(ModelFile, TimeDependentDriftRoundTripsExactly) {
  TempDir dir;
  RobotModel model = FitModel("pol", "drift@2:span=10", 600);
  ASSERT_TRUE(model.uses_time());
  const std::string path = dir.File("drift.json");
  SaveModel(path, model);
  RobotModel loaded = LoadModel(path);
  ExpectSameModel(model, loaded);
}

TEST(ModelFile, MotorModelKeepsAForcedFormOption) {
  TempDir dir;
  RobotModelOptions options;
  options.form = Form::kWeightSpace;
  options.friction_width = 0.02;
  RobotModel model = FitModel("motor+fri", "offset", 300, options);
  SaveModel(dir.File("motor.json"), model);
  const RobotModel loaded = LoadModel(dir.File("motor.json"));
  ExpectSameModel(model, loaded);
}

TEST(ModelFile, FunctionSpaceRbfRoundTripsExactly) {
  TempDir dir;
  ModelSpec spec = ParseModelSpec("rbf+fri");
  const sim::Dataset& train = Scenario().train;
  RobotModel model(spec, train.num_joints());
  const Matrix X = train.X.topRows(300);
  const Matrix Y = train.Y.topRows(300);
  Hyperparameters h = model.DefaultHyperparameters(Y);
  // Kernel parameters away from their defaults, as a hyper-parameter fit leaves them.
  for (Eigen::Index i = 0; i < h.shape.size(); ++i) h.shape[i] += 0.1 * static_cast<double>(i % 3);
  h.log_noise_std = std::log(0.03);
  ASSERT_EQ(model.Fit(X, Y, h), Status::kOk);
  ASSERT_NE(model.gp().function_space(), nullptr);
  SaveModel(dir.File("rbf.json"), model);
  RobotModel loaded = LoadModel(dir.File("rbf.json"));
  ExpectBitIdentical(model.kernel()->parameters(), loaded.kernel()->parameters(), "kernel");
  ExpectSameModel(model, loaded);
  ContinueLearning(&model, &loaded, 25);
  ExpectSamePredictions(model, loaded);
}

// The header of a model file (ReadModelFileHeader: what starting a search from it needs)
// is what the loaded model says: its model and effects, joints, form and hyper-parameters,
// for a weight-space, a kernel and a lagk model; a corrupted file is refused as by LoadModel.
TEST(ModelFile, TheHeaderIsWhatTheLoadedModelSays) {
  TempDir dir;
  const sim::Dataset& train = Scenario().train;
  FitOptions fixed;
  fixed.method = HyperparameterMethod::kFixed;
  const FittedModel lagk = structgp::FitModel(ParseModelSpec("lagk+fri"), train.X.topRows(200),
                                              train.Y.topRows(200), Vector(), fixed);
  ASSERT_TRUE(lagk.summary.IsUsable()) << lagk.summary.message;
  SaveModel(dir.File("pol.json"), FitModel("pol+fri", "coulomb@2", 300));
  SaveModel(dir.File("rbf.json"), FitModel("rbf+fri", "", 300));
  SaveModel(dir.File("lagk.json"), lagk.model);
  for (const std::string file : {"pol.json", "rbf.json", "lagk.json"}) {
    const RobotModel loaded = LoadModel(dir.File(file));
    const ModelFileHeader header = ReadModelFileHeader(dir.File(file));
    EXPECT_EQ(ModelLabel(header.spec), ModelLabel(loaded.spec())) << file;
    EXPECT_EQ(header.num_joints, loaded.num_joints()) << file;
    EXPECT_EQ(header.form, loaded.gp().form()) << file;
    const Hyperparameters& h = loaded.hyperparameters();
    ExpectBitIdentical(header.hyperparameters.shape, h.shape, file + " shape");
    ExpectBitIdentical(header.hyperparameters.log_block_scale, h.log_block_scale, file);
    ExpectBitIdentical(header.hyperparameters.log_output_scale, h.log_output_scale, file);
    ExpectSameDouble(header.hyperparameters.log_noise_std, h.log_noise_std, file);
  }
  // lagk: the hyper-parameters of its Euler-Lagrange GP, as fit --start-from reads them.
  const ModelFileHeader header = ReadModelFileHeader(dir.File("lagk.json"));
  const EulerLagrangeGPHyperparameters read = EulerLagrangeFromHyperparameters(
      header.hyperparameters, header.num_joints, header.spec.friction);
  const EulerLagrangeGPHyperparameters& fitted = lagk.model.gp().euler_lagrange()->hyperparameters();
  EXPECT_EQ(read.sigma, fitted.sigma);
  ExpectBitIdentical(read.part_weights, fitted.part_weights, "part weights");
  ExpectBitIdentical(read.noise_std, fitted.noise_std, "noise");

  std::string text;
  {
    std::ifstream in(dir.File("lagk.json"));
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  const size_t at = text.find("\"num_samples\"");
  ASSERT_NE(at, std::string::npos);
  text.replace(at + 15, 1, text[at + 15] == '1' ? "2" : "1");
  std::ofstream(dir.File("bad.json")) << text;
  try {
    ReadModelFileHeader(dir.File("bad.json"));
    ADD_FAILURE() << "no exception";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("checksum"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ReadModelFileHeader(dir.File("missing.json")), DataError);
}

TEST(ModelFile, PolInFunctionSpaceRoundTripsExactly) {
  TempDir dir;
  // 100 samples < D = 133 features: Form::kAuto picks the function space.
  RobotModel model = FitModel("pol", "coulomb@2", 100);
  ASSERT_NE(model.gp().function_space(), nullptr);
  SaveModel(dir.File("pol_fs.json"), model);
  RobotModel loaded = LoadModel(dir.File("pol_fs.json"));
  ExpectSameModel(model, loaded);
  ContinueLearning(&model, &loaded, 20);
  ExpectSamePredictions(model, loaded);
  // Grown past D by online additions, it is still restored in function space.
  ContinueLearning(&model, &loaded, 60);
  SaveModel(dir.File("pol_fs_grown.json"), model);
  const RobotModel grown = LoadModel(dir.File("pol_fs_grown.json"));
  ASSERT_NE(grown.gp().function_space(), nullptr);
  EXPECT_EQ(grown.gp().function_space()->size(), 180);
}

TEST(WeightSpaceGPState, RestoresAStagedModelExactly) {
  const int D = 6, P = 2;
  Vector prior = Vector::LinSpaced(D, 0.5, 2.0);
  WeightSpaceGP a(prior, 0.01, P, Vector::Constant(P, 1.5));
  Matrix phi = Matrix::Zero(D, 30);
  Matrix y = Matrix::Zero(P, 30);
  for (int i = 0; i < 30; ++i) {
    for (int k = 0; k < D; ++k) phi(k, i) = std::sin(0.3 * i + k);
    y(0, i) = std::cos(0.2 * i);
    y(1, i) = 0.1 * i;
  }
  Vector mean(P), lv(P), nv(P);
  for (int i = 0; i < 20; ++i) {
    ASSERT_EQ(a.UpdateAndPredict(phi.col(i), y.col(i), phi.col(i + 1), mean, lv, nv, 0.99),
              Status::kOk);
  }
  // A change is staged now; State() applies it.
  const WeightSpaceGPState state = a.State();
  WeightSpaceGP b = WeightSpaceGP::FromState(state);
  for (int i = 20; i < 30; ++i) {
    Vector ma(P), mb(P), la(P), lb(P), na(P), nb(P);
    ASSERT_EQ(a.PredictWithVariance(phi.col(i), ma, la, na), Status::kOk);
    ASSERT_EQ(b.PredictWithVariance(phi.col(i), mb, lb, nb), Status::kOk);
    ExpectBitIdentical(ma, mb, "mean");
    ExpectBitIdentical(la, lb, "latent variance");
    ASSERT_EQ(a.Update(phi.col(i), y.col(i), 0.98), Status::kOk);
    ASSERT_EQ(b.Update(phi.col(i), y.col(i), 0.98), Status::kOk);
  }
  ExpectSameDouble(a.LogMarginalLikelihood(), b.LogMarginalLikelihood(), "evidence");
  ExpectBitIdentical(a.covariance_factor(), b.covariance_factor(), "factor");
  ExpectSameDouble(a.effective_count(), b.effective_count(), "effective count");
  EXPECT_EQ(a.num_samples(), b.num_samples());
}

TEST(WeightSpaceGPState, RefusesBrokenStates) {
  WeightSpaceGP a(Vector::Ones(3), 0.1, 1);
  const WeightSpaceGPState good = a.State();
  WeightSpaceGPState s = good;
  s.covariance_factor(2, 0) = 1e-3;
  EXPECT_THROW(WeightSpaceGP::FromState(s), std::invalid_argument);
  s = good;
  s.covariance_factor(1, 1) = -1.0;
  EXPECT_THROW(WeightSpaceGP::FromState(s), std::invalid_argument);
  s = good;
  s.weights.resize(2, 1);
  EXPECT_THROW(WeightSpaceGP::FromState(s), std::invalid_argument);
  s = good;
  s.y_squared[0] = std::nan("");
  EXPECT_THROW(WeightSpaceGP::FromState(s), std::invalid_argument);
  s = good;
  s.noise_variance = 0.0;
  EXPECT_THROW(WeightSpaceGP::FromState(s), std::invalid_argument);
  s = good;
  s.output_scales.resize(0);
  EXPECT_THROW(WeightSpaceGP::FromState(s), std::invalid_argument);
}

// ---- damaged files ------------------------------------------------------------------------

class ModelFileErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = dir_.File("model.json");
    SaveModel(path_, FitModel("pol", "coulomb@2", 300));
    text_ = ReadFile(path_);
  }

  // Loading `text` fails with a DataError naming the file and containing `expected`.
  DataError ExpectError(const std::string& text, const std::string& expected) {
    const std::string path = dir_.File("damaged.json");
    WriteFile(path, text);
    try {
      LoadModel(path);
    } catch (const DataError& e) {
      EXPECT_EQ(e.file(), path);
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos)
          << "message: " << e.what() << "\nexpected to contain: " << expected;
      EXPECT_EQ(std::string(e.what()).rfind(path, 0), 0u) << e.what();
      return e;
    }
    ADD_FAILURE() << "no error; expected: " << expected;
    return DataError(path, 0, 0, "");
  }

  // The file's JSON, changed by `edit`, with a correct checksum.
  std::string Edited(const std::function<void(Json*)>& edit) const {
    Json doc = Json::parse(text_);
    edit(&doc);
    testing::SetValidChecksum(&doc);
    return doc.dump(2);
  }

  TempDir dir_;
  std::string path_;
  std::string text_;
};

TEST_F(ModelFileErrors, MissingFile) {
  try {
    LoadModel(dir_.File("nope.json"));
    FAIL();
  } catch (const DataError& e) {
    EXPECT_EQ(e.file(), dir_.File("nope.json"));
    EXPECT_NE(std::string(e.what()).find("cannot open for reading: No such file"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(ModelFileErrors, EmptyFile) { ExpectError("", "the file is empty"); }

TEST_F(ModelFileErrors, TruncatedFileNamesTheEnd) {
  const std::string half = text_.substr(0, text_.size() / 2);
  const DataError e = ExpectError(half, "truncated model file");
  EXPECT_GT(e.line(), 1);
  EXPECT_GT(e.column(), 0);
}

TEST_F(ModelFileErrors, MalformedJsonNamesLineAndColumn) {
  std::string bad = text_;
  const size_t at = bad.find("\"model\"");
  ASSERT_NE(at, std::string::npos);
  bad.insert(at, "}");
  const DataError e = ExpectError(bad, "malformed model file");
  const int line = static_cast<int>(std::count(bad.begin(), bad.begin() + at, '\n')) + 1;
  EXPECT_EQ(e.line(), line);
}

TEST_F(ModelFileErrors, CsvGivenAsModel) {
  const DataError e = ExpectError("q1,qd1,qdd1,tau1\n0,0,0,0\n", "malformed model file");
  EXPECT_EQ(e.line(), 1);
}

TEST_F(ModelFileErrors, OtherJsonIsNotAModelFile) {
  ExpectError("[1, 2, 3]", "not a structgp model file");
  ExpectError("{\"joints\": []}", "not a structgp model file (no \"format\" field");
  ExpectError(Edited([](Json* d) { (*d)["format"] = "structgp-findings"; }),
              "not a structgp model file (\"format\" is \"structgp-findings\"");
}

TEST_F(ModelFileErrors, NewerVersion) {
  ASSERT_EQ(kModelFileVersion, 3);
  // A model whose joints share their hyper-parameters is written as version 2 (per-joint
  // models as 3: tests/test_per_joint.cc).
  EXPECT_EQ(Json::parse(text_)["version"], kSharedModelFileVersion);
  EXPECT_EQ(kSharedModelFileVersion, 2);
  ExpectError(Edited([](Json* d) { (*d)["version"] = 4; }),
              "unsupported model file version 4: this build reads versions 1 to 3 (the file was "
              "written by a newer structgp)");
  ExpectError(Edited([](Json* d) { (*d)["version"] = 0; }), "unsupported model file version 0");
}

// Version 1 files are read as they are, except the Euler-Lagrange models, whose space changed
// in version 2: refused by name, with what to do.
TEST_F(ModelFileErrors, VersionOneLoadsExceptTheEulerLagrangeModels) {
  const std::string old = dir_.File("old.json");
  WriteFile(old, Edited([](Json* d) { (*d)["version"] = 1; }));
  const RobotModel loaded = LoadModel(old);
  const RobotModel current = LoadModel(path_);
  const Vector x = Vector::Constant(current.input_dim(), 0.2);
  Vector a(current.num_joints()), b(current.num_joints());
  ASSERT_EQ(loaded.Predict(x, a), Status::kOk);
  ASSERT_EQ(current.Predict(x, b), Status::kOk);
  EXPECT_EQ(a, b);

  for (const char* model : {"lag", "lagk"}) {
    path_ = dir_.File(std::string(model) + ".json");
    SaveModel(path_, FitModel(model, "", 60));
    text_ = ReadFile(path_);
    ASSERT_NO_THROW(LoadModel(path_)) << model;
    ExpectError(Edited([](Json* d) { (*d)["version"] = 1; }),
                std::string("field 'model': a '") + model +
                    "' model of a version 1 file: its Euler-Lagrange space changed in version 2");
  }
}

TEST_F(ModelFileErrors, CorruptedPayloadFailsTheChecksum) {
  std::string bad = text_;
  const size_t data = bad.find("\"data\": \"");
  ASSERT_NE(data, std::string::npos);
  char& c = bad[data + 12];
  c = c == 'A' ? 'B' : 'A';
  ExpectError(bad, "checksum mismatch");
}

TEST_F(ModelFileErrors, EditedNumberFailsTheChecksum) {
  Json doc = Json::parse(text_);
  doc["hyperparameters"]["log_noise_std"] = -1.0;
  ExpectError(doc.dump(2), "checksum mismatch");
}

TEST_F(ModelFileErrors, MissingChecksum) {
  Json doc = Json::parse(text_);
  doc.erase("checksum");
  ExpectError(doc.dump(2), "without a \"checksum\"");
}

TEST_F(ModelFileErrors, InconsistentContentsWithAValidChecksum) {
  ExpectError(
      Edited([](Json* d) { (*d)["num_features"] = 12; }),
      "inconsistent model file: model 'pol + coulomb@2' has 134 features, the file says 12");
  ExpectError(Edited([](Json* d) { (*d)["model"] = "polx"; }), "field 'model'");
  ExpectError(Edited([](Json* d) { d->erase("weight_space"); }), "missing field 'weight_space'");
  ExpectError(Edited([](Json* d) { (*d)["weight_space"]["weights"]["data"] = "AAAA"; }),
              "field 'weight_space.weights': expected 268 doubles");
  ExpectError(Edited([](Json* d) { (*d)["weight_space"]["weights"]["data"] = "A*=="; }),
              "field 'weight_space.weights': the data are not valid base64");
  ExpectError(Edited([](Json* d) { (*d)["effect_list"][0]["joints"] = {7}; }),
              "names joint 7, but the robot has 2 joints");
  ExpectError(Edited([](Json* d) { (*d)["hyperparameters"]["log_noise_std"] = "x"; }),
              "field 'hyperparameters.log_noise_std': expected a number");
}

// A file of the right format whose "form" names the other form, or no form at all, with a
// checksum that matches: refused by name, never read as the wrong kind of model.
TEST_F(ModelFileErrors, WrongFormWithAValidChecksum) {
  ASSERT_EQ(Json::parse(text_)["form"], "weight_space");
  ExpectError(Edited([](Json* d) { (*d)["form"] = "function_space"; }),
              "missing field 'function_space'");
  ExpectError(Edited([](Json* d) { (*d)["form"] = "kernel"; }),
              "field 'form': expected 'weight_space', 'function_space', 'regressor' or 'euler_lagrange'");
  ExpectError(Edited([](Json* d) { (*d)["form"] = 1; }), "field 'form'");
}

TEST(ModelFileSave, IsAtomic) {
  TempDir dir;
  const std::string path = dir.File("model.json");
  const RobotModel first = FitModel("pol", "", 300);
  SaveModel(path, first);
  const std::string before = ReadFile(path);
  // A model that cannot be saved leaves the old file as it was.
  const RobotModel unfitted(ParseModelSpec("pol"), 2);
  EXPECT_THROW(SaveModel(path, unfitted), std::invalid_argument);
  EXPECT_EQ(ReadFile(path), before);
  // A save into a missing directory fails with the path named, and writes nothing.
  try {
    SaveModel(dir.File("missing/model.json"), first);
    FAIL();
  } catch (const DataError& e) {
    EXPECT_EQ(e.file(), dir.File("missing/model.json"));
  }
  // A new save replaces the file completely and leaves no temporary file behind.
  SaveModel(path, FitModel("pol", "coulomb@2", 300));
  EXPECT_NE(ReadFile(path), before);
  EXPECT_EQ(LoadModel(path).spec().effects.size(), 1u);
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"model.json"});
}

// RobotModel::State / FromState restore a model exactly and without a fit: a state whose
// posterior was changed by hand comes back changed (no data, and no fit of any data, gives
// that posterior), also through a file, and the model reports its own rows (a fit on
// placeholder rows would report the D rows of that fit).
TEST(RobotModelState, RestoresTheStateWithoutRefitting) {
  RobotModel model = FitModel("pol+fri", "coulomb@2", 600);
  ASSERT_NE(model.gp().weight_space(), nullptr);
  ASSERT_NE(model.feature_map()->dim(), 600);
  const RobotModel same = RobotModel::FromState(model.State());
  ExpectSameModel(model, same);
  EXPECT_EQ(same.gp().data_rows(), 600);

  // Doubling the weights doubles every mean exactly (a factor 2 commutes with rounding).
  RobotModelState state = model.State();
  state.weight_space.weights *= 2.0;
  const RobotModel doubled = RobotModel::FromState(state);
  const Matrix X = Inputs(model, Scenario().test);
  Matrix mean, mean_doubled, std, std_doubled;
  model.PredictRows(X, &mean, &std);
  doubled.PredictRows(X, &mean_doubled, &std_doubled);
  ExpectBitIdentical(2.0 * mean, mean_doubled, "means with doubled weights");
  ExpectBitIdentical(std, std_doubled, "standard deviations");

  TempDir dir;
  SaveModel(dir.File("doubled.json"), doubled);
  const RobotModel loaded = LoadModel(dir.File("doubled.json"));
  Matrix mean_loaded;
  loaded.PredictRows(X, &mean_loaded);
  ExpectBitIdentical(mean_doubled, mean_loaded, "means of the loaded model");
  EXPECT_EQ(loaded.gp().data_rows(), 600);
  EXPECT_EQ(loaded.gp().fit_rows(), 600);
}

TEST(RobotModelState, FunctionSpaceStateRoundTripsExactly) {
  ModelSpec spec = ParseModelSpec("rbf+fri");
  const sim::Dataset& train = Scenario().train;
  RobotModel model(spec, train.num_joints());
  const Matrix X = train.X.topRows(200);
  const Matrix Y = train.Y.topRows(200);
  Hyperparameters h = model.DefaultHyperparameters(Y);
  h.shape.array() += 0.05;
  ASSERT_EQ(model.Fit(X, Y, h), Status::kOk);
  const RobotModelState state = model.State();
  EXPECT_EQ(state.form, Form::kFunctionSpace);
  ExpectBitIdentical(state.inputs, X, "stored inputs");
  const RobotModel restored = RobotModel::FromState(state);
  ExpectBitIdentical(model.kernel()->parameters(), h.shape, "kernel parameters in use");
  ExpectBitIdentical(restored.kernel()->parameters(), h.shape, "restored kernel parameters");
  ExpectSameModel(model, restored);
}

TEST(RobotModelState, InconsistentStatesAreRefused) {
  RobotModel model = FitModel("pol+fri", "", 300);
  EXPECT_THROW(RobotModel(ParseModelSpec("pol"), 2).State(), std::logic_error);
  RobotModelState state = model.State();
  state.form = Form::kAuto;
  EXPECT_THROW(RobotModel::FromState(state), std::invalid_argument);
  state = model.State();
  state.hyperparameters.log_block_scale.resize(1);
  EXPECT_THROW(RobotModel::FromState(state), std::invalid_argument);
  state = model.State();
  state.weight_space.covariance_factor(1, 0) = 1.0;  // not upper-triangular
  EXPECT_THROW(RobotModel::FromState(state), std::invalid_argument);
  state = model.State();
  state.spec = ParseModelSpec("rbf");  // no feature map: no weight-space form
  EXPECT_THROW(RobotModel::FromState(state), std::invalid_argument);
  state = model.State();
  state.form = Form::kFunctionSpace;
  state.inputs = Matrix::Zero(3, 2);  // 6 inputs expected
  state.targets = Matrix::Zero(3, 2);
  EXPECT_THROW(RobotModel::FromState(state), std::invalid_argument);
}

}  // namespace
}  // namespace structgp
