// The Python module structgp: numpy arrays in and out, in the style of scikit-learn, over the
// library's own entry points (FitModel, RobotModel, Diagnose, ReadRobotCsv, SaveModel/LoadModel,
// OnlineLearner). Nothing of the workflow is done here: arrays are checked for shape and
// copied into Eigen matrices, the library is called (without the GIL for fits, predictions and
// diagnoses), and its results are handed back as numpy arrays and plain Python objects.
//
// Errors: std::invalid_argument -> ValueError, DataError -> structgp.DataError (a ValueError),
// a numerical failure (a Status, FitSummary::termination, Diagnosis::status) -> structgp.Error
// (a RuntimeError); the library's messages are kept as they are.

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <fstream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "structgp/core/version.h"
#include "structgp/diagnose/diagnosis.h"
#include "structgp/diagnose/diagnosis_loop.h"
#include "structgp/diagnose/diagnosis_report.h"
#include "structgp/feature/effects.h"
#include "structgp/fit/fit_model.h"
#include "structgp/hyper/hyperprior.h"
#include "structgp/io/atomic_file.h"
#include "structgp/io/csv.h"
#include "structgp/io/model_file.h"
#include "structgp/model/model_spec.h"
#include "structgp/model/robot_model.h"
#include "structgp/online/online_learner.h"
#include "structgp/report/report.h"
#include "structgp/report/report_data.h"
#include "structgp/fit/chain_identification.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/sim/hidden_effect.h"
#include "structgp/sim/robot.h"

namespace py = pybind11;

namespace structgp {
namespace python {
namespace {

// A numerical failure: structgp.Error.
class NumericalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// ---- arrays in ------------------------------------------------------------------------------

std::string Dimensions(const py::array& a) {
  std::string text;
  for (py::ssize_t d = 0; d < a.ndim(); ++d) {
    text += (d ? " x " : "") + std::to_string(a.shape(d));
  }
  return a.ndim() == 0 ? "a scalar" : "shape " + text;
}

py::array_t<double, py::array::c_style | py::array::forcecast> AsDoubles(const py::handle& obj,
                                                                          const char* name) {
  auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!a) {
    throw std::invalid_argument(std::string(name) + ": expected an array of numbers, got " +
                                std::string(py::str(py::type::handle_of(obj).attr("__name__"))));
  }
  return a;
}

// An m x n matrix from a 2-D array-like (copied, any dtype that converts to float64).
Matrix AsMatrix(const py::handle& obj, const char* name) {
  const auto a = AsDoubles(obj, name);
  if (a.ndim() != 2) {
    throw std::invalid_argument(std::string(name) + ": expected a 2-D array (one row per sample), got " +
                                Dimensions(a));
  }
  return Eigen::Map<const RowMatrix>(a.data(), a.shape(0), a.shape(1));
}

// A vector from a 1-D array-like; empty for None.
Vector AsVector(const py::handle& obj, const char* name) {
  if (obj.is_none()) return Vector();
  const auto a = AsDoubles(obj, name);
  if (a.ndim() != 1) {
    throw std::invalid_argument(std::string(name) + ": expected a 1-D array, got " + Dimensions(a));
  }
  return Eigen::Map<const Vector>(a.data(), a.shape(0));
}

py::object TimesOrNone(const Vector& t) {
  if (t.size() == 0) return py::none();
  return py::cast(t);
}

py::object Json(const std::string& text) { return py::module_::import("json").attr("loads")(text); }

// A model's training data given as train=(X, Y) or (X, Y, t).
// Effects given as one list text ("coulomb@2,viscous") or a list of them; None: none.
std::vector<EffectSpec> EffectList(const py::object& effects) {
  std::vector<EffectSpec> list;
  if (effects.is_none()) return list;
  std::vector<std::string> items;
  if (py::isinstance<py::str>(effects)) {
    items.push_back(effects.cast<std::string>());
  } else {
    items = effects.cast<std::vector<std::string>>();
  }
  for (const std::string& item : items) {
    for (EffectSpec& e : ParseEffectList(item)) list.push_back(std::move(e));
  }
  return list;
}

RobotData TrainingData(const py::object& train) {
  const py::tuple parts = train.cast<py::tuple>();
  if (parts.size() < 2 || parts.size() > 3) {
    throw std::invalid_argument("train: expected (X, Y) or (X, Y, t), got a tuple of " +
                                std::to_string(parts.size()));
  }
  RobotData data;
  data.X = AsMatrix(parts[0], "train X");
  data.Y = AsMatrix(parts[1], "train Y");
  if (parts.size() == 3) data.t = AsVector(parts[2], "train t");
  return data;
}

// ---- robot data ------------------------------------------------------------------------------

// read_robot_csv and the simulator give RobotData; Python sees arrays and metadata.
void BindRobotData(py::module_& m) {
  py::class_<RobotData>(m, "RobotData",
                        "Samples of a robot: X (m x 3N: q, qd, qdd), Y (m x N torques or "
                        "currents), t (m times in s, or None) and where they came from.")
      .def_property_readonly("X", [](const RobotData& d) { return d.X; })
      .def_property_readonly("Y", [](const RobotData& d) { return d.Y; })
      .def_property_readonly("t", [](const RobotData& d) { return TimesOrNone(d.t); })
      .def_readonly("joints", &RobotData::num_joints, "N, the number of joints")
      .def_property_readonly("size", &RobotData::size, "m, the number of samples")
      .def_property_readonly("segments", &RobotData::segments,
                             "First row of each trajectory (a time that starts again begins a "
                             "new one); [0] without times")
      .def_readonly("source", &RobotData::source, "The file the data came from")
      .def_property_readonly(
          "target", [](const RobotData& d) { return d.target == RobotData::Target::kCurrent ? "current" : "torque"; },
          "'torque' (tau1..tauN) or 'current' (cur1..curN)")
      .def("__len__", &RobotData::size)
      .def("__repr__", [](const RobotData& d) {
        return "RobotData(" + std::to_string(d.size()) + " samples, " + std::to_string(d.num_joints) +
               " joints" + (d.has_time() ? ", " + std::to_string(d.segments().size()) + " trajectories" : "") +
               (d.source.empty() ? "" : ", from '" + d.source + "'") + ")";
      });

  m.def(
      "read_robot_csv",
      [](const std::string& path, int joints) {
        CsvOptions options;
        options.expected_joints = joints;
        RobotData data = ReadRobotCsv(path, options);
        if (data.size() == 0) throw DataError(path, 0, 0, "no data rows after the header");
        return data;
      },
      py::arg("path"), py::arg("joints") = 0,
      "Reads a robot data file (CSV, plain or gzip; docs/csv-format.md) as `structgp fit` does. "
      "joints > 0 requires that many joints. Raises structgp.DataError naming the file, line "
      "and column.");

  m.def(
      "write_robot_csv",
      [](const std::string& path, const py::object& X, const py::object& Y, const py::object& t) {
        RobotData d;
        d.X = AsMatrix(X, "X");
        d.Y = AsMatrix(Y, "Y");
        d.t = AsVector(t, "t");
        d.num_joints = static_cast<int>(d.Y.cols());
        WriteRobotCsv(path, d);
      },
      py::arg("path"), py::arg("X"), py::arg("Y"), py::arg("t") = py::none(),
      "Writes X, Y (and t) as a robot data file that read_robot_csv and the structgp program "
      "read back exactly (17 significant digits), replacing the file atomically.");

  m.def(
      "simulate_hidden_effect",
      [](const std::string& robot, const std::string& effect, int joint, double magnitude,
         double noise, unsigned long seed) {
        sim::HiddenEffectOptions o;
        o.effect = sim::ParseHiddenEffect(effect);
        o.joint = joint;
        o.magnitude = magnitude;
        o.noise_std = noise;
        o.seed = seed;
        const sim::Robot r = sim::RobotByName(robot);
        sim::HiddenEffectScenario s;
        {
          py::gil_scoped_release release;
          s = sim::MakeHiddenEffectScenario(r, o);
        }
        return py::make_tuple(sim::ToRobotData(s.train, "train"), sim::ToRobotData(s.test, "test"));
      },
      py::arg("robot") = "two-link", py::arg("effect") = "coulomb", py::arg("joint") = 2,
      py::arg("magnitude") = 0.1, py::arg("noise") = 0.01, py::arg("seed") = 1,
      "The logs of `structgp demo` (Orocos KDL): a slow training log and the same path 2.5x "
      "faster, in N m, with a hidden effect (coulomb, viscous, stribeck, cogging, drift, spring "
      "or none) of `magnitude` times the joint's largest rigid-body torque on `joint` (1-based) "
      "and noise `noise` of each joint's. Returns (train, test) as RobotData.");
}

// ---- fit summary -----------------------------------------------------------------------------

// The library's FitSummary, with the JSON of `structgp fit --json` for to_dict().
struct FitResult {
  FitSummary summary;
  std::string json;  // ToJson(model, summary)
  std::string report;  // FitReport(model, summary)
};

// One entry of the summary's JSON, as a Python object.
py::object SummaryEntry(const FitResult& r, const char* key) {
  const py::object json = Json(r.json);
  const py::object summary = json["summary"];
  return summary[key];
}

void BindFitSummary(py::module_& m) {
  py::class_<FitResult>(m, "FitSummary",
                        "How a fit ended (the library's FitSummary): termination, message, the "
                        "hyper-parameter search, the held-out check, rows and times.")
      .def_property_readonly("termination", [](const FitResult& r) { return ToString(r.summary.termination); },
                             "'converged', 'max_iterations', 'line_search_failed', 'user_abort' or 'failure'")
      .def_property_readonly("usable", [](const FitResult& r) { return r.summary.IsUsable(); })
      .def_property_readonly("message", [](const FitResult& r) { return r.summary.message; })
      .def_property_readonly("method", [](const FitResult& r) { return ToString(r.summary.method); })
      .def_property_readonly("method_description", [](const FitResult& r) { return r.summary.method_description; })
      .def_property_readonly("notes", [](const FitResult& r) { return r.summary.notes; })
      .def_property_readonly("warnings", [](const FitResult& r) { return r.summary.warnings; })
      .def_property_readonly("iterations", [](const FitResult& r) { return r.summary.iterations; })
      .def_property_readonly("num_evaluations", [](const FitResult& r) { return r.summary.num_evaluations; })
      .def_property_readonly("initial_negative_log_evidence",
                             [](const FitResult& r) { return r.summary.initial_negative_log_evidence; })
      .def_property_readonly("final_negative_log_evidence",
                             [](const FitResult& r) { return r.summary.final_negative_log_evidence; })
      .def_property_readonly("final_negative_log_prior",
                             [](const FitResult& r) { return r.summary.final_negative_log_prior; })
      .def_property_readonly("at_bounds", [](const FitResult& r) { return r.summary.at_bounds; })
      .def_property_readonly("check", [](const FitResult& r) { return SummaryEntry(r, "check"); },
                             "The held-out check: ran, passed, rows, worst_joint, ..., message")
      .def_property_readonly("starts", [](const FitResult& r) { return SummaryEntry(r, "starts"); },
                             "Each LBFGS run of the evidence search (termination, iterations, objective)")
      .def_property_readonly("rows", [](const FitResult& r) { return r.summary.rows; })
      .def_property_readonly("hyperparameter_rows", [](const FitResult& r) { return r.summary.hyperparameter_rows; })
      .def_property_readonly("model_rows", [](const FitResult& r) { return r.summary.model_rows; })
      .def_property_readonly("hyperparameter_seconds", [](const FitResult& r) { return r.summary.hyperparameter_seconds; })
      .def_property_readonly("total_seconds", [](const FitResult& r) { return r.summary.total_seconds; })
      .def("to_dict", [](const FitResult& r) { return Json(r.json); },
           "The JSON of `structgp fit --json` (without its data file entries) as a dict")
      .def("__str__", [](const FitResult& r) { return r.report; })
      .def("__repr__", [](const FitResult& r) {
        return "FitSummary(" + std::string(ToString(r.summary.termination)) + ", " + r.summary.BriefReport() + ")";
      });
}

// ---- the model -------------------------------------------------------------------------------

// threads= of fit, predict and load: 1..kMaxThreads, as the CLI's --threads.
int CheckedThreads(int threads) {
  if (threads < 1 || threads > kMaxThreads) {
    throw std::invalid_argument("threads: expected 1 to " + std::to_string(kMaxThreads) +
                                ", got " + std::to_string(threads));
  }
  return threads;
}

class Model {
 public:
  Model(const py::object& spec, const py::object& base, const py::object& friction,
        const py::object& effects, const py::object& urdf, const std::string& root,
        const std::string& tip, const std::vector<double>& gravity, double friction_width,
        int threads, int max_kernel_rows, int inducing_states) {
    if (!spec.is_none()) {
      if (!base.is_none() || !friction.is_none()) {
        throw std::invalid_argument("Model: give the model either as a spec text ('" +
                                    std::string(py::str(spec)) + "') or as base=/friction=, not both");
      }
      spec_ = ParseModelLabel(spec.cast<std::string>());
    } else {
      spec_ = ParseModelSpec(base.is_none() ? std::string("pol") : base.cast<std::string>());
      spec_.friction = !friction.is_none() && friction.cast<bool>();
    }
    for (EffectSpec& e : EffectList(effects)) spec_.effects.push_back(std::move(e));
    if (gravity.size() != 3) {
      throw std::invalid_argument("gravity: expected three numbers (x, y, z in m/s^2), got " +
                                  std::to_string(gravity.size()));
    }
    if (!urdf.is_none()) {
      UrdfOptions u;
      u.root = root;
      u.tip = tip;
      u.gravity = Eigen::Vector3d(gravity[0], gravity[1], gravity[2]);
      options_.rigid_body = std::make_shared<const RigidBodyChain>(
          RigidBodyChain::FromUrdfFile(py::str(urdf).cast<std::string>(), u));
    } else if (!root.empty() || !tip.empty()) {
      throw std::invalid_argument("root/tip: they select a chain of urdf=, which is not given");
    }
    options_.friction_width = friction_width;
    options_.batch.num_threads = CheckedThreads(threads);
    options_.batch.max_kernel_rows = max_kernel_rows;
    if (inducing_states < 0) {
      throw std::invalid_argument("inducing_states: expected >= 0 (0: exact on every row), got " +
                                  std::to_string(inducing_states));
    }
    options_.batch.inducing_states = inducing_states;
  }

  explicit Model(RobotModel model)
      : spec_(model.spec()),
        options_(model.options()),
        model_(std::make_shared<const RobotModel>(std::move(model))) {}

  Model& Fit(const py::object& X, const py::object& Y, const py::object& t,
             const std::string& hyper, const py::object& starts, const std::string& prior,
             bool check, bool verbose, const py::object& start_from, bool per_joint,
             bool calibrate_bands, double band_coverage) {
    const Matrix states = AsMatrix(X, "X");
    const Matrix torques = AsMatrix(Y, "Y");
    const Vector times = AsVector(t, "t");
    FitOptions o;
    if (!FromString(hyper, &o.method)) {
      throw std::invalid_argument("hyper: expected ml, cv or fixed, got '" + hyper + "'");
    }
    if (!FromString(prior, &o.evidence.prior.family)) {
      throw std::invalid_argument("prior: expected gaussian, student_t or none, got '" + prior + "'");
    }
    if (!starts.is_none()) o.evidence.num_starts = starts.cast<int>();
    o.check.enabled = check;
    o.evidence.verbose = verbose;
    o.per_joint = per_joint;
    o.calibrate_bands = calibrate_bands;
    if (!(band_coverage >= 0.5 && band_coverage <= 0.999)) {
      throw std::invalid_argument("band_coverage: expected a value in [0.5, 0.999], got " +
                                  std::to_string(band_coverage));
    }
    o.check.target_coverage = band_coverage;
    if (!start_from.is_none()) {
      const RobotModel& from = start_from.cast<const Model&>().fitted("start_from");
      if (spec_.base != BaseModel::kLagk || o.method != HyperparameterMethod::kEvidence ||
          !StartFromModel(from, &o)) {
        throw std::invalid_argument(
            "start_from: starts the evidence search (hyper='ml') of a lagk model from a lagk "
            "model; got " + ModelLabel(spec_) + " with hyper='" + hyper + "' and a " +
            ModelLabel(from.spec()) + " model");
      }
    }
    o.num_threads = options_.batch.num_threads;
    RobotModel model(spec_, static_cast<int>(torques.cols()), options_);
    FitSummary summary;
    {
      py::gil_scoped_release release;
      summary = FitModel(o, states, torques, times, &model);
    }
    if (!summary.IsUsable()) {
      throw NumericalError("fit failed (" + std::string(ToString(summary.termination)) + "): " +
                           summary.message);
    }
    summary_ = FitResult{summary, ToJson(model, summary), FitReport(model, summary)};
    model_ = std::make_shared<const RobotModel>(std::move(model));
    return *this;
  }

  // The fitted model, shared: a call that releases the GIL keeps it alive while another
  // thread refits this Model.
  std::shared_ptr<const RobotModel> shared(const char* what) const {
    if (!model_) {
      throw std::invalid_argument(std::string(what) + ": the model is not fitted (call fit, or "
                                  "Model.load a saved one)");
    }
    return model_;
  }
  const RobotModel& fitted(const char* what) const { return *shared(what); }

  py::object Predict(const py::object& X, const py::object& t, bool return_std,
                     int threads) const {
    const std::shared_ptr<const RobotModel> held = shared("predict");
    const RobotModel& model = *held;
    CheckedThreads(threads);
    const Matrix inputs = ModelInputs(model, AsMatrix(X, "X"), AsVector(t, "t"));
    Matrix mean, std_dev;
    {
      py::gil_scoped_release release;
      try {
        model.PredictRows(inputs, &mean, return_std ? &std_dev : nullptr, threads);
      } catch (const std::invalid_argument&) {
        throw;
      } catch (const std::runtime_error& e) {
        throw NumericalError(std::string("prediction failed: ") + e.what());
      }
    }
    if (return_std) return py::make_tuple(mean, std_dev);
    return py::cast(mean);
  }

  py::dict Components(const py::object& X, const py::object& t) const {
    const std::shared_ptr<const RobotModel> held = shared("components");
    const RobotModel& model = *held;
    const Matrix inputs = ModelInputs(model, AsMatrix(X, "X"), AsVector(t, "t"));
    std::vector<ComponentRows> parts;
    {
      py::gil_scoped_release release;
      try {
        parts = model.PredictComponentRows(inputs);
      } catch (const std::invalid_argument&) {
        throw;
      } catch (const std::runtime_error& e) {
        throw NumericalError(std::string("components failed: ") + e.what());
      }
    }
    py::dict out;
    for (const ComponentRows& c : parts) out[py::str(c.name)] = py::make_tuple(c.mean, c.latent_std);
    return out;
  }

  py::dict Coefficients() const {
    const std::vector<FeatureCoefficient> all = fitted("coefficients").Coefficients();
    // name -> (value, std); a feature of every joint in weight space ("offset") has one
    // coefficient per joint torque: arrays of N. A name the model holds twice (the friction
    // block's coulomb@2 and the effect coulomb@2) keeps both: the second as "coulomb@2#2".
    py::dict out;
    for (size_t i = 0; i < all.size();) {
      size_t end = i + 1;
      const bool per_joint_torque = all[i].name.find('@') == std::string::npos && all[i].joint > 0;
      if (per_joint_torque) {
        while (end < all.size() && all[end].name == all[i].name && all[end].joint == all[end - 1].joint + 1) ++end;
      }
      std::string key = all[i].name;
      for (int k = 2; out.contains(py::str(key)); ++k) key = all[i].name + "#" + std::to_string(k);
      if (per_joint_torque) {
        Vector value(static_cast<Eigen::Index>(end - i)), sd(value.size());
        for (size_t k = i; k < end; ++k) {
          value[static_cast<Eigen::Index>(k - i)] = all[k].value;
          sd[static_cast<Eigen::Index>(k - i)] = all[k].std;
        }
        out[py::str(key)] = py::make_tuple(value, sd);
      } else {
        out[py::str(key)] = py::make_tuple(all[i].value, all[i].std);
      }
      i = end;
    }
    return out;
  }

  void Save(const std::string& path, bool posterior_file) const {
    SaveOptions options;
    options.posterior_file = posterior_file;
    SaveModel(path, fitted("save"), options);
  }

  // What Model.load did with the model's posterior file.
  bool posterior_file_read_ = false;
  std::string posterior_file_note_;

  std::string ModelFile() const { return ModelFileText(fitted("model_file")); }

  std::string Repr() const {
    return "Model('" + ModelLabel(spec_) + "'" +
           (model_ ? ", fitted, " + std::to_string(model_->num_joints()) + " joints" : std::string()) + ")";
  }

  const ModelSpec& spec() const { return spec_; }
  bool is_fitted() const { return model_ != nullptr; }
  const std::optional<FitResult>& summary() const { return summary_; }

 private:
  ModelSpec spec_;
  RobotModelOptions options_;
  std::shared_ptr<const RobotModel> model_;
  std::optional<FitResult> summary_;
};

void BindModel(py::module_& m) {
  py::class_<Model>(m, "Model", R"doc(
An inverse-dynamics model of an N-joint robot: X (m x 3N, columns q, qd, qdd) -> Y (m x N
joint torques).

    Model("pol+fri + coulomb@2")                  # the CLI's text: --model and --effects
    Model(base="pol", friction=True, effects=["coulomb@2", "cogging@3:period=0.3"])
    Model("rbd+fri", urdf="robot.urdf")           # the rigid-body regressor of a URDF chain

fit(X, Y, t=None, hyper="ml") chooses the hyper-parameters and fits (the library's FitModel, as
`structgp fit`), returns self; predict, components and coefficients read the fitted model;
save / Model.load use the CLI's model files.
)doc")
      .def(py::init<const py::object&, const py::object&, const py::object&, const py::object&,
                    const py::object&, const std::string&, const std::string&,
                    const std::vector<double>&, double, int, int, int>(),
           py::arg("spec") = py::none(), py::kw_only(), py::arg("base") = py::none(),
           py::arg("friction") = py::none(), py::arg("effects") = py::none(),
           py::arg("urdf") = py::none(), py::arg("root") = "", py::arg("tip") = "",
           py::arg("gravity") = std::vector<double>{0.0, 0.0, -9.81},
           py::arg("friction_width") = RobotModelOptions().friction_width,
           py::arg("threads") = 1, py::arg("max_kernel_rows") = kDefaultMaxKernelRows,
           py::arg("inducing_states") = BatchFitOptions().inducing_states)
      .def("fit", &Model::Fit, py::arg("X"), py::arg("Y"), py::arg("t") = py::none(),
           py::kw_only(), py::arg("hyper") = "ml", py::arg("starts") = py::none(),
           py::arg("prior") = "gaussian", py::arg("check") = true, py::arg("verbose") = false,
           py::arg("start_from") = py::none(), py::arg("per_joint") = false,
           py::arg("calibrate_bands") = true,
           py::arg("band_coverage") = FitCheckOptions().target_coverage,
           py::return_value_policy::reference_internal,
           "Fits the model to X (m x 3N), Y (m x N) and optional times t (m), rows in time "
           "order: hyper 'ml' (type-II maximum likelihood with a prior, `starts` runs), 'cv' "
           "(blocked cross-validation) or 'fixed' (the defaults). start_from: a fitted lagk "
           "Model whose hyper-parameters start a lagk model's evidence search, at its sigma "
           "(`structgp fit --start-from`). per_joint: each joint its own hyper-parameters "
           "(`structgp fit --per-joint`; pol, motor, rbf, rbfs). calibrate_bands: scale each joint's "
           "latent variance so that its 2 sigma band covers 95% of the held-out check's torques "
           "(False: `structgp fit --no-calibrate-bands`; band_coverage: that coverage, as "
           "--band-coverage). Returns self; the summary is in .summary. Raises ValueError for bad input, structgp.Error when the fit fails.")
      .def("predict", &Model::Predict, py::arg("X"), py::arg("t") = py::none(),
           py::arg("return_std") = false, py::arg("threads") = 1,
           "Predicted torques (m x N); with return_std=True also the posterior standard "
           "deviation of the mean torque (latent, without measurement noise), as (mean, std). "
           "threads: threads sharing the rows (the same result for any number).")
      .def("components", &Model::Components, py::arg("X"), py::arg("t") = py::none(),
           "The prediction split into physical parts: dict name -> (mean, std), each m x N "
           "('inertial', 'coriolis', 'gravity', 'friction', each effect); the means add up to "
           "predict(X). Weight-space pol/motor models, rbd and lag.")
      .def("coefficients", &Model::Coefficients,
           "Fitted friction and effect coefficients: dict name -> (value, std) on the torque of "
           "the feature's joint ('coulomb@2'); a feature of every joint ('offset') in weight "
           "space has one per joint torque (arrays of N).")
      .def("save", &Model::Save, py::arg("path"), py::arg("posterior_file") = true,
           "Writes the model file of `structgp fit --out` (atomically). A lagk model through "
           "inducing states also writes path + '.posterior', its posterior's factors, which "
           "load reads instead of computing them from the rows (posterior_file=False: not "
           "written).")
      .def_static(
          "load",
          [](const std::string& path, int threads, bool posterior_file) {
            LoadOptions options;
            options.num_threads = CheckedThreads(threads);
            options.posterior_file = posterior_file;
            LoadSummary summary;
            py::gil_scoped_release release;
            Model model(LoadModel(path, options, &summary));
            model.posterior_file_note_ = summary.posterior_file_note;
            model.posterior_file_read_ = summary.posterior_file_read;
            return model;
          },
          py::arg("path"), py::arg("threads") = 1, py::arg("posterior_file") = true,
          "Reads a model file written by save or by `structgp fit`, and its posterior file "
          "when it has one (posterior_file=False: computed from the rows). threads: workers "
          "factorising a lagk model's posterior again (the same result for any number).")
      .def_property_readonly(
          "posterior_file_read", [](const Model& s) { return s.posterior_file_read_; },
          "load read the model's posterior from its posterior file")
      .def_property_readonly(
          "posterior_file_note", [](const Model& s) { return s.posterior_file_note_; },
          "Why load did not use a posterior file that was there ('' otherwise)")
      .def("model_file", &Model::ModelFile, "The text save writes.")
      .def_property_readonly("spec", [](const Model& s) { return ModelLabel(s.spec()); },
                             "'pol+fri + coulomb@2': the model and its effects")
      .def_property_readonly("base", [](const Model& s) { return ToString(s.spec().base); })
      .def_property_readonly("friction", [](const Model& s) { return s.spec().friction; })
      .def_property_readonly("effects", [](const Model& s) {
        std::vector<std::string> out;
        for (const EffectSpec& e : s.spec().effects) out.push_back(ToString(e));
        return out;
      })
      .def_property_readonly("fitted", &Model::is_fitted)
      .def_property_readonly("num_joints", [](const Model& s) { return s.fitted("num_joints").num_joints(); })
      .def_property_readonly("uses_time", [](const Model& s) { return s.fitted("uses_time").uses_time(); },
                             "True when an effect needs t (then predict needs t too)")
      .def_property_readonly("component_names", [](const Model& s) { return s.fitted("component_names").ComponentNames(); })
      .def_property_readonly("form", [](const Model& s) { return ToString(s.fitted("form").gp().form()); })
      .def_property_readonly("per_joint", [](const Model& s) { return s.fitted("per_joint").per_joint(); },
                             "True when each joint has its own hyper-parameters (fit(per_joint=True)).")
      .def_property_readonly("latent_variance_scale",
                             [](const Model& s) -> Vector {
                               return s.fitted("latent_variance_scale").latent_variance_scale();
                             },
                             "Each joint's factor on the latent variance of predict(return_std="
                             "True) (N; all 1 unless fit calibrated the bands)")
      .def_property_readonly("noise_std",
                             [](const Model& s) -> Vector {
                               return s.fitted("noise_std").hyperparameters().noise_stds();
                             },
                             "Each joint's fitted noise standard deviation (N), in torque units: "
                             "the noisy band of a prediction is mean +- 2 sqrt(std^2 + "
                             "noise_std^2), std from predict(return_std=True)")
      .def_property_readonly("log_marginal_likelihood",
                             [](const Model& s) { return s.fitted("log_marginal_likelihood").gp().LogMarginalLikelihood(); })
      .def_property_readonly("summary", [](const Model& s) -> py::object {
        if (!s.summary()) return py::none();
        return py::cast(*s.summary());
      }, "The FitSummary of the last fit (None for a loaded model)")
      .def("__repr__", &Model::Repr);

  m.def("parse_model", [](const std::string& text) { return ModelLabel(ParseModelLabel(text)); },
        py::arg("text"), "The canonical text of a model with effects; ValueError naming the bad part.");
  m.def("base_models", [] {
    std::vector<std::pair<std::string, std::string>> out;
    for (BaseModel b : BaseModels()) out.emplace_back(ToString(b), Describe(b));
    return out;
  }, "Every base model as (name, one line on it).");
  m.def("effect_names", &EffectNames, "Every registered effect.");
}

// ---- diagnosis -------------------------------------------------------------------------------

struct DiagnosisResult {
  Diagnosis diagnosis;
  ModelSpec spec;
  DiagnosisOptions options;
};

void BindDiagnosis(py::module_& m) {
  py::class_<Concentration>(m, "Concentration", "A variable along which a joint's residual concentrates.")
      .def_readonly("variable", &Concentration::variable)
      .def_readonly("explained", &Concentration::explained)
      .def_readonly("bin_low", &Concentration::bin_low)
      .def_readonly("bin_high", &Concentration::bin_high)
      .def_readonly("bin_rms", &Concentration::bin_rms)
      .def("__repr__", [](const Concentration& c) {
        return "Concentration(" + c.variable + ", explained " + std::to_string(c.explained) + ")";
      });
  py::class_<JointFinding>(m, "JointFinding", "The residual of one joint.")
      .def_readonly("joint", &JointFinding::joint)
      .def_readonly("rms", &JointFinding::rms)
      .def_readonly("nmse", &JointFinding::nmse)
      .def_readonly("noise_std_estimate", &JointFinding::noise_std_estimate)
      .def_readonly("refit_rms", &JointFinding::refit_rms,
                    "residual RMS of the model refitted on the diagnosed data")
      .def_readonly("residual_rms_with_suggestions", &JointFinding::residual_rms_with_suggestions,
                    "residual RMS of the diagnosis's refit with this joint's suggestions (-1: not computed)")
      .def_readonly("outside_fraction", &JointFinding::outside_fraction)
      .def_readonly("max_distance", &JointFinding::max_distance)
      .def_readonly("concentrations", &JointFinding::concentrations)
      .def("__repr__", [](const JointFinding& f) {
        return "JointFinding(joint " + std::to_string(f.joint) + ", rms " + std::to_string(f.rms) + ")";
      });
  py::class_<AlternativeEffect>(m, "AlternativeEffect",
                                "An effect that explains what a suggestion explains.")
      .def_readonly("spec", &AlternativeEffect::spec)
      .def_readonly("scope", &AlternativeEffect::scope)
      .def_readonly("score", &AlternativeEffect::score, "its score in the suggestion's round, nats")
      .def("__repr__", [](const AlternativeEffect& a) {
        return "AlternativeEffect('" + a.spec + "', score " + std::to_string(a.score) + ")";
      });
  py::class_<Suggestion>(m, "Suggestion", "An effect the model misses, with its evidence.")
      .def_readonly("effect", &Suggestion::effect)
      .def_readonly("joint", &Suggestion::joint)
      .def_readonly("score", &Suggestion::score, "gain in log evidence of the joint's torque, nats")
      .def_readonly("rms_before", &Suggestion::rms_before)
      .def_readonly("rms_after", &Suggestion::rms_after)
      .def_readonly("residual_rms_before", &Suggestion::residual_rms_before)
      .def_readonly("residual_rms_after", &Suggestion::residual_rms_after)
      .def_readonly("score_uncorrected", &Suggestion::score_uncorrected)
      .def_readonly("inflation", &Suggestion::inflation)
      .def_readonly("effective_samples", &Suggestion::effective_samples)
      .def_readonly("p_value", &Suggestion::p_value)
      .def_readonly("adjusted_p_value", &Suggestion::adjusted_p_value)
      .def_readonly("effect_rms", &Suggestion::effect_rms)
      .def_readonly("effect_to_noise", &Suggestion::effect_to_noise)
      .def_readonly("z", &Suggestion::z)
      .def_readonly("confirmation", &Suggestion::confirmation)
      .def_readonly("folds_improved", &Suggestion::folds_improved)
      .def_readonly("fold_rms_ratio", &Suggestion::fold_rms_ratio)
      .def_readonly("selection", &Suggestion::selection)
      .def_readonly("passed_by", &Suggestion::passed_by,
                    "'evidence', or 'held_out' (refused by the evidence on the log, passed on "
                    "its held-out fall)")
      .def_readonly("scope", &Suggestion::scope)
      .def_readonly("params", &Suggestion::params)
      .def_readonly("spec", &Suggestion::spec, "the text to add to the effects, e.g. 'coulomb@2'")
      .def_readonly("alternatives", &Suggestion::alternatives,
                    "other effects of the joint that passed every bar in its round and that it "
                    "explains once added")
      .def_property_readonly("description", &DescribeEffect)
      .def("__repr__", [](const Suggestion& s) { return "Suggestion('" + s.spec + "', score " + std::to_string(s.score) + ")"; });
  py::class_<Refusal>(m, "Refusal", "A candidate effect that was not suggested, and why.")
      .def_readonly("candidate", &Refusal::candidate, "its numbers as far as the scoring went")
      .def_readonly("bar", &Refusal::bar, "the first bar it failed, e.g. 'held_out'")
      .def_readonly("reason", &Refusal::reason)
      .def_readonly("calibrated", &Refusal::calibrated)
      .def_readonly("after_suggestions", &Refusal::after_suggestions,
                    "scored with the suggestions chosen before it (they explain it)")
      .def("__repr__", [](const Refusal& r) { return "Refusal('" + r.candidate.spec + "', " + r.reason + ")"; });
  py::class_<DiagnosisResult>(m, "Diagnosis",
                              "Where a model fails on data and which effects it misses (the "
                              "content of the CLI's FINDINGS.json).")
      .def_property_readonly("status", [](const DiagnosisResult& d) { return ToString(d.diagnosis.status); })
      .def_property_readonly("message", [](const DiagnosisResult& d) { return d.diagnosis.message; })
      .def_property_readonly("joints", [](const DiagnosisResult& d) { return d.diagnosis.joints; })
      .def_property_readonly("suggestions", [](const DiagnosisResult& d) { return d.diagnosis.suggestions; })
      .def_property_readonly("refused", [](const DiagnosisResult& d) { return d.diagnosis.refused; },
                             "the closest candidates not suggested, with the bar each failed")
      .def_property_readonly("num_samples", [](const DiagnosisResult& d) { return d.diagnosis.num_samples; })
      .def_property_readonly("model", [](const DiagnosisResult& d) { return d.diagnosis.model; })
      .def_property_readonly("features", [](const DiagnosisResult& d) { return d.diagnosis.features; })
      .def_property_readonly("noise_std", [](const DiagnosisResult& d) { return d.diagnosis.noise_std; })
      .def_property_readonly("verdict", [](const DiagnosisResult& d) { return ToString(d.diagnosis.coverage.verdict); },
                             "'explained', 'coverage', 'missing_effect' or 'unexplained'")
      .def_property_readonly("verdict_message", [](const DiagnosisResult& d) { return d.diagnosis.coverage.message; })
      .def_property_readonly("coverage_joints", [](const DiagnosisResult& d) { return d.diagnosis.coverage.coverage_joints; })
      .def_property_readonly("unexplained_joints", [](const DiagnosisResult& d) { return d.diagnosis.coverage.unexplained_joints; },
                             "joints the model, refitted on the log with the suggestions, still does not predict to the noise")
      .def_property_readonly(
          "holding_torque_message", [](const DiagnosisResult& d) { return d.diagnosis.holding.message; },
          "Stops at one configuration that hold other torques (static friction), or ''")
      .def_property_readonly(
          "holding_torque_joints",
          [](const DiagnosisResult& d) {
            std::vector<int> joints;
            for (const HoldingTorqueJoint& h : d.diagnosis.holding.joints) joints.push_back(h.joint);
            return joints;
          },
          "joints (1-based) whose torque at rest differs between such stops")
      .def_property_readonly("suggested_model",
                             [](const DiagnosisResult& d) { return ModelLabel(WithSuggestions(d.spec, d.diagnosis)); },
                             "The diagnosed model with every suggestion added, as Model() reads it")
      .def("to_dict", [](const DiagnosisResult& d) { return Json(ToJson(d.diagnosis)); },
           "FINDINGS.json as a dict")
      .def("to_json", [](const DiagnosisResult& d) { return ToJson(d.diagnosis); },
           "FINDINGS.json as the CLI writes it")
      .def("__str__", [](const DiagnosisResult& d) { return DiagnosisReport(d.diagnosis, d.spec, d.options); })
      .def("__repr__", [](const DiagnosisResult& d) {
        return "Diagnosis(" + d.diagnosis.model + ": " + std::to_string(d.diagnosis.suggestions.size()) +
               " suggestions)";
      });

  m.def(
      "diagnose",
      [](const Model& model, const py::object& X, const py::object& Y, const py::object& t,
         const py::object& report, int folds, double min_evidence,
         const std::vector<std::string>& candidates, double significance, const py::object& train,
         const std::string& autocorrelation, bool reidentify, int threads) {
        if (threads < 1) throw std::invalid_argument("threads must be >= 1");
        const std::shared_ptr<const RobotModel> held = model.shared("diagnose");
        const RobotModel& fitted = *held;
        RobotData data;
        data.X = AsMatrix(X, "X");
        data.Y = AsMatrix(Y, "Y");
        data.t = AsVector(t, "t");
        data.num_joints = static_cast<int>(data.Y.cols());
        const Matrix inputs = ModelInputs(fitted, data.X, data.t);
        DiagnosisResult result;
        result.spec = fitted.spec();
        result.options.folds = folds;
        result.options.min_log_evidence_gain = min_evidence;
        result.options.candidates = candidates;
        result.options.significance = significance;
        result.options.reidentify_chain = reidentify;
        result.options.chain.num_threads = threads;
        if (!FromString(autocorrelation, &result.options.autocorrelation)) {
          throw py::value_error("autocorrelation: expected 'bartlett', 'prewhitening' or "
                                "'none', got '" + autocorrelation + "'");
        }
        if (!train.is_none()) {
          const RobotData train_data = TrainingData(train);
          result.options.training_inputs = ModelInputs(fitted, train_data.X, train_data.t);
          result.options.training_targets = train_data.Y;
          result.options.training_times = train_data.t;
        }
        std::string html;
        const std::string report_path = report.is_none() ? "" : py::str(report).cast<std::string>();
        {
          py::gil_scoped_release release;
          result.diagnosis = Diagnose(fitted, inputs, data.Y, data.t, result.options);
          if (result.diagnosis.status != DiagnosisStatus::kOk) {
            throw NumericalError("the diagnosis failed: " + result.diagnosis.message);
          }
          if (!report_path.empty()) {
            try {
              html = report::RenderHtml(report::DiagnosisReportData(fitted, data, result.diagnosis));
            } catch (const std::invalid_argument&) {
              throw;
            } catch (const std::runtime_error& e) {
              throw NumericalError(std::string("prediction failed: ") + e.what());
            }
          }
        }
        if (!report_path.empty()) WriteTextAtomically(report_path, html);
        return result;
      },
      py::arg("model"), py::arg("X"), py::arg("Y"), py::arg("t") = py::none(), py::kw_only(),
      py::arg("report") = py::none(), py::arg("folds") = DiagnosisOptions().folds,
      py::arg("min_evidence") = DiagnosisOptions().min_log_evidence_gain,
      py::arg("candidates") = std::vector<std::string>(),
      py::arg("significance") = DiagnosisOptions().significance, py::arg("train") = py::none(),
      py::arg("autocorrelation") = std::string(ToString(DiagnosisOptions().autocorrelation)),
      py::arg("reidentify") = DiagnosisOptions().reidentify_chain, py::arg("threads") = 1,
      "Diagnoses a fitted model on X, Y (and t, rows in time order), as `structgp diagnose`: "
      "per joint the residual and where it concentrates, the verdict (a missing effect, or "
      "motions the training data did not cover), and the effects the model misses, each scored "
      "by evidence corrected for autocorrelation, a Holm test at `significance`, its size and "
      "the error on unseen trajectories or blocks. train=(X, Y[, t]), the model's training data: "
      "candidates are scored on it and the data together, and the findings say how far the data "
      "are from the training states. report=PATH also writes the HTML report. "
      "autocorrelation: 'bartlett', 'prewhitening' or 'none' (DiagnosisOptions). "
      "An rbd model on a URDF that identify_chain wrote, with train: the chain is identified "
      "again on train and the data together (a local search on `threads` threads), and when it "
      "explains the data better the findings are against the model on it (to_json()['chain']; "
      "reidentify=False keeps the chain). "
      "Raises ValueError for bad input, structgp.Error when the diagnosis fails.");

  m.def(
      "identify_chain",
      [](const py::object& X, const py::object& Y, const py::object& t, bool friction,
         const py::object& effects, int starts, int rounds, int rows, int refine_rows,
         std::uint64_t seed, int threads, const std::string& name) {
        const Matrix states = AsMatrix(X, "X"), torques = AsMatrix(Y, "Y");
        const Vector times = AsVector(t, "t");  // for effects that use it
        ChainIdentificationOptions o;
        o.friction = friction;
        o.effects = EffectList(effects);
        o.starts = starts;
        o.max_rounds = rounds;
        o.search_rows = rows;
        o.refine_rows = refine_rows;
        o.seed = seed;
        o.num_threads = CheckedThreads(threads);
        o.robot_name = name;
        ChainIdentificationSummary s;
        {
          py::gil_scoped_release release;
          try {
            s = IdentifyChain(states, times, torques, o);
          } catch (const std::invalid_argument&) {
            throw;
          } catch (const std::runtime_error& e) {
            throw NumericalError(e.what());
          }
        }
        py::dict kinematics;
        const std::vector<std::string> names = ChainKinematicNames(static_cast<int>(torques.cols()));
        for (size_t k = 0; k < names.size(); ++k) {
          kinematics[py::str(names[k])] = s.kinematics[static_cast<Eigen::Index>(k)];
        }
        py::list undetermined;
        for (int k : s.undetermined) undetermined.append(names[static_cast<size_t>(k)]);
        py::dict out;
        out["urdf"] = s.urdf;
        out["kinematics"] = kinematics;
        out["undetermined"] = undetermined;
        out["cost_change"] = s.cost_change;
        out["faster_change"] = s.faster_change;
        out["starts"] = s.starts;
        out["start_costs"] = s.start_costs;
        out["moved_cost"] = s.moved_cost;
        out["moves_kept"] = s.moves_kept;
        out["best_start"] = s.best_start;
        out["starts_at_best"] = s.starts_at_best;
        out["rounds"] = s.rounds;
        out["refined_cost"] = s.refined_cost;
        out["torque_rms"] = s.torque_rms;  // numpy arrays, as the module's other per-joint values
        out["residual_rms"] = s.residual_rms;
        out["noise"] = s.noise;
        return out;
      },
      py::arg("X"), py::arg("Y"), py::arg("t") = py::none(), py::kw_only(),
      py::arg("friction") = true, py::arg("effects") = py::none(),
      py::arg("starts") = ChainIdentificationOptions().starts,
      py::arg("rounds") = ChainIdentificationOptions().max_rounds,
      py::arg("rows") = ChainIdentificationOptions().search_rows,
      py::arg("refine_rows") = ChainIdentificationOptions().refine_rows,
      py::arg("seed") = ChainIdentificationOptions().seed, py::arg("threads") = 1,
      py::arg("name") = ChainIdentificationOptions().robot_name,
      "The robot's kinematic chain found from its torques, as `structgp identify`: X (q, qd, qdd "
      "of N joints), Y (N torques), t (times, for effects that use them). effects: as Model's "
      "(e.g. 'cogging@1:period=0.3'), fitted beside the chain. rounds: rounds of `starts` "
      "starts at most, another while fewer than two reach the least cost. Returns a dict: "
      "'urdf' (the chain as a URDF document, "
      "placeholder inertias: write it to a file and fit Model('rbd+fri', urdf=PATH)), "
      "'kinematics' (name -> value, modified DH), 'starts' (the kept starts) with their "
      "'start_costs', 'best_start', 'starts_at_best', 'rounds', 'moved_cost', 'moves_kept', "
      "'undetermined' (names of the kinematic parameters the log does not determine although "
      "faster motion would show them), 'cost_change' and 'faster_change' per parameter, "
      "'refined_cost', 'torque_rms', 'residual_rms' and 'noise' (the residual's white noise) per joint (numpy arrays). Raises ValueError for bad "
      "input, structgp.Error when no start gives a chain.");

  m.def(
      "diagnose_loop",
      [](const py::object& model_object, const py::object& X, const py::object& Y,
         const py::object& t, const py::object& train, int rounds, bool reidentify, int threads) {
        const Model& model = model_object.cast<const Model&>();
        const std::shared_ptr<const RobotModel> held = model.shared("diagnose_loop");
        if (threads < 1) throw std::invalid_argument("threads must be >= 1");
        const Matrix states = AsMatrix(X, "X"), torques = AsMatrix(Y, "Y");
        const Vector times = AsVector(t, "t");
        const RobotData training = TrainingData(train);
        DiagnosisLoopOptions options;
        options.max_rounds = rounds;
        options.reidentify_chain = reidentify;
        options.diagnosis.reidentify_chain = reidentify;
        options.chain.num_threads = threads;
        options.diagnosis.chain.num_threads = threads;
        std::optional<RobotModel> improved;
        DiagnosisLoopSummary summary;
        {
          py::gil_scoped_release release;
          summary = RunDiagnosisLoop(options, *held, training.X, training.Y, training.t, states,
                                     torques, times, &improved);
        }
        if (summary.termination == DiagnosisLoopTermination::kDiagnosisFailed) {
          throw NumericalError("the diagnosis failed: " + summary.message);
        }
        py::object result = improved ? py::cast(Model(std::move(*improved))) : model_object;
        return py::make_tuple(result, Json(ToJson(summary)));
      },
      py::arg("model"), py::arg("X"), py::arg("Y"), py::arg("t") = py::none(), py::kw_only(),
      py::arg("train"), py::arg("rounds") = DiagnosisLoopOptions().max_rounds,
      py::arg("reidentify") = DiagnosisLoopOptions().reidentify_chain, py::arg("threads") = 1,
      "The diagnosis loop, as `structgp diagnose --rounds`: diagnoses the model on X, Y (and t) "
      "with its training data train=(X, Y[, t]), adds every suggestion, refits on the training "
      "data with the fit's defaults (a lagk model from its own hyper-parameters, at its sigma) "
      "and diagnoses again, up to `rounds` diagnoses or until one "
      "suggests nothing. An rbd model on a URDF that identify_chain wrote has its chain "
      "identified again before each refit, with the added effects beside it (from where it was, "
      "and identify_chain's default starts on `threads` threads; reidentify=False: refit on the "
      "chain as it is). Returns (model, loop): the last refitted Model (the given one when "
      "nothing was added) and the loop as a dict (termination, model, rounds with each one's "
      "added effects, identification or None, refit and findings). Raises ValueError for bad "
      "input, structgp.Error when a diagnosis fails.");
}

// ---- online learner --------------------------------------------------------------------------

class Online {
 public:
  Online(const Model& model, double forgetting, int window, bool variance, int queue_capacity) {
    OnlineLearnerOptions o = OnlineLearnerOptionsFor(model.fitted("OnlineLearner"));
    o.forgetting = forgetting;
    o.window_length = window;
    o.covariance_publish_period = variance ? 1 : 0;
    o.queue_capacity = queue_capacity;
    o.start_thread = false;  // scripted replay: update() runs the learner's work itself
    learner_ = std::make_unique<OnlineLearner>(o);
  }

  void Update(const py::object& x, const py::object& y) {
    const Vector state = AsVector(x, "x");
    const Vector tau = AsVector(y, "y");
    const SubmitResult r = learner_->Submit(state, tau);
    if (r == SubmitResult::kRejectedSize) {
      throw std::invalid_argument("update: expected x of " + std::to_string(learner_->input_dim()) +
                                  " and y of " + std::to_string(learner_->num_outputs()) +
                                  " entries, got " + std::to_string(state.size()) + " and " +
                                  std::to_string(tau.size()));
    }
    if (r != SubmitResult::kAccepted) {
      throw std::invalid_argument(std::string("update: sample refused: ") + ToString(r));
    }
    learner_->ProcessPending();
    const OnlineLearnerSummary s = learner_->summary();
    if (s.status_failures() > failures_) {
      failures_ = s.status_failures();
      throw NumericalError("update: the sample could not be absorbed (not positive definite)");
    }
  }

  py::object Predict(const py::object& x, bool return_std) {
    const Vector state = AsVector(x, "x");
    Vector mean(learner_->num_outputs()), variance(learner_->num_outputs());
    if (state.size() != learner_->input_dim()) {
      throw std::invalid_argument("predict: expected x of " + std::to_string(learner_->input_dim()) +
                                  " entries, got " + std::to_string(state.size()));
    }
    if (return_std && !learner_->has_variance()) {
      throw std::invalid_argument("predict: return_std needs OnlineLearner(..., variance=True)");
    }
    const Status s = return_std ? learner_->PredictWithVariance(state, mean, variance)
                                : learner_->Predict(state, mean);
    if (s == Status::kInvalidInput) throw std::invalid_argument("predict: x holds NaN or Inf");
    if (s != Status::kOk) throw NumericalError(std::string("predict: ") + ToString(s));
    if (return_std) return py::make_tuple(mean, Vector(variance.cwiseMax(0.0).cwiseSqrt()));
    return py::cast(mean);
  }

  const OnlineLearner& learner() const { return *learner_; }

 private:
  std::unique_ptr<OnlineLearner> learner_;
  long failures_ = 0;
};

void BindOnline(py::module_& m) {
  py::class_<Online>(m, "OnlineLearner", R"doc(
The library's OnlineLearner for scripted replay (no learner thread: each update is absorbed
before it returns). It starts from the prior of a fitted feature-map Model (pol up to 3 joints,
motor) at that model's hyper-parameters and learns from no data; forgetting in (0, 1], window
> 0 keeps only the newest samples.
)doc")
      .def(py::init<const Model&, double, int, bool, int>(), py::arg("model"), py::kw_only(),
           py::arg("forgetting") = 1.0, py::arg("window") = 0, py::arg("variance") = false,
           py::arg("queue_capacity") = 1024)
      .def("update", &Online::Update, py::arg("x"), py::arg("y"),
           "Adds one sample: x (3N: q, qd, qdd), y (N torques). ValueError when it is refused.")
      .def("predict", &Online::Predict, py::arg("x"), py::arg("return_std") = false,
           "Mean torques (N) at x, and with return_std the latent std (variance=True).")
      .def_property_readonly("num_samples", [](const Online& o) { return o.learner().model().num_samples(); })
      .def_property_readonly("summary", [](const Online& o) {
        const OnlineLearnerSummary s = o.learner().summary();
        py::dict d;
        d["submitted"] = s.submitted;
        d["accepted"] = s.accepted;
        d["rejected"] = s.rejected();
        d["updates"] = s.updates;
        d["update_failures"] = s.update_failures;
        d["downdates"] = s.downdates;
        d["downdate_failures"] = s.downdate_failures;
        d["rebuilds"] = s.rebuilds;
        d["predictions"] = s.predictions;
        d["samples_in_model"] = s.samples_in_model;
        return d;
      });
}

}  // namespace
}  // namespace python
}  // namespace structgp

PYBIND11_MODULE(structgp, m) {
  using namespace structgp::python;
  m.doc() = "structgp: Gaussian processes with structured kernels for robot inverse dynamics "
            "(numpy in and out; the library of the structgp program).";
  m.attr("__version__") = structgp::Version();
  static py::exception<NumericalError> error(m, "Error", PyExc_RuntimeError);
  static py::exception<structgp::DataError> data_error(m, "DataError", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const NumericalError& e) {
      PyErr_SetString(error.ptr(), e.what());
    } catch (const structgp::DataError& e) {
      PyErr_SetString(data_error.ptr(), e.what());
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
  BindRobotData(m);
  BindFitSummary(m);
  BindModel(m);
  BindDiagnosis(m);
  BindOnline(m);
}
