// Tests of online learning next to a control loop: the triple buffer, the OnlineLearner
// (exact agreement with a single-threaded WeightSpaceGP, rejection of bad samples, window
// policies, allocation-free control path, concurrent use), and forgetting under drifting
// friction on a simulated robot.
//
// The threaded tests are meant to be run under ThreadSanitizer too:
//   cmake -S . -B build-tsan -G Ninja -DSTRUCTGP_SANITIZER=thread
//   cmake --build build-tsan --target test_online && build-tsan/tests/test_online

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <iostream>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "alloc_counter.h"
#include "structgp/feature/friction_feature_map.h"
#include "structgp/feature/pol_feature_map.h"
#include "structgp/feature/random_feature_map.h"
#include "structgp/feature/sum_feature_map.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/model/weight_space_gp.h"
#include "structgp/online/online_learner.h"
#include "structgp/online/triple_buffer.h"
#include "structgp/sim/friction.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"

namespace structgp {
namespace {

#if defined(__SANITIZE_THREAD__)
constexpr bool kUnderTsan = true;
#else
constexpr bool kUnderTsan = false;
#endif

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// Seeds of the randomised tests, printed so that a failure can be replayed.
constexpr std::uint64_t kMapSeed = 11;
constexpr std::uint64_t kDataSeed = 12;

bool BitEqual(const Matrix& a, const Matrix& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() && (a.array() == b.array()).all();
}

// ---- TripleBuffer ---------------------------------------------------------------------------

TEST(TripleBuffer, ReaderSeesInitialThenNewestPublished) {
  TripleBuffer<int> buffer(7);
  EXPECT_FALSE(buffer.Acquire());
  EXPECT_EQ(buffer.read_buffer(), 7);
  buffer.write_buffer() = 1;
  buffer.Publish();
  buffer.write_buffer() = 2;
  buffer.Publish();
  EXPECT_EQ(buffer.read_buffer(), 7);  // not acquired yet
  EXPECT_TRUE(buffer.Acquire());
  EXPECT_EQ(buffer.read_buffer(), 2);  // 1 was superseded
  EXPECT_FALSE(buffer.Acquire());
  EXPECT_EQ(buffer.read_buffer(), 2);
  // The writer never gets the reader's slot back while the reader holds it.
  for (int v = 3; v < 20; ++v) {
    buffer.write_buffer() = v;
    buffer.Publish();
    EXPECT_EQ(buffer.read_buffer(), 2);
  }
  EXPECT_TRUE(buffer.Acquire());
  EXPECT_EQ(buffer.read_buffer(), 19);
}

// A writer publishes self-consistent records (every entry equals the sequence number) as fast
// as it can; the reader must never see a torn record or a sequence going backwards.
TEST(TripleBufferThreaded, NoTornOrStaleReads) {
  constexpr int kEntries = 64;
  const long kCount = kUnderTsan ? 20000 : 200000;
  struct Record {
    long sequence = 0;
    Vector values = Vector::Zero(kEntries);
  };
  TripleBuffer<Record> buffer(Record{});
  std::atomic<bool> done{false};
  std::thread writer([&]() {
    for (long s = 1; s <= kCount; ++s) {
      Record& r = buffer.write_buffer();
      r.sequence = s;
      r.values.setConstant(static_cast<double>(s));
      buffer.Publish();
    }
    done.store(true, std::memory_order_release);
  });
  long last = 0;
  long torn = 0;
  long backwards = 0;
  long reads = 0;
  while (true) {
    const bool finished = done.load(std::memory_order_acquire);
    buffer.Acquire();
    const Record& r = buffer.read_buffer();
    if ((r.values.array() != static_cast<double>(r.sequence)).any()) ++torn;
    if (r.sequence < last) ++backwards;
    last = r.sequence;
    ++reads;
    if (finished) {
      buffer.Acquire();
      last = buffer.read_buffer().sequence;
      break;
    }
  }
  writer.join();
  EXPECT_EQ(torn, 0);
  EXPECT_EQ(backwards, 0);
  EXPECT_EQ(last, kCount) << "the reader must end on the last value published";
  std::cout << "[ info     ] " << reads << " reads during " << kCount << " publishes\n";
}

// ---- OnlineLearner --------------------------------------------------------------------------

constexpr int kInputDim = 6;
constexpr int kFeatures = 40;
constexpr int kOutputs = 3;

std::shared_ptr<const FeatureMap> SmallMap() {
  return std::make_shared<RandomFeatureMap>(kInputDim, kFeatures, 2, kMapSeed);
}

struct Samples {
  Matrix X;  // m x input_dim
  Matrix Y;  // m x P
};

// y = a smooth function of x + noise, from a fixed seed.
Samples MakeSamples(int m, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(-1.5, 1.5);
  std::normal_distribution<double> noise(0.0, 0.05);
  Samples s;
  s.X = Matrix::NullaryExpr(m, kInputDim, [&]() { return uniform(rng); });
  s.Y.resize(m, kOutputs);
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < kOutputs; ++j) {
      s.Y(i, j) = std::sin(s.X(i, j) + 0.5 * s.X(i, j + 3)) +
                  0.3 * s.X(i, (j + 1) % kInputDim) * s.X(i, 5) + noise(rng);
    }
  }
  return s;
}

OnlineLearnerOptions SmallOptions() {
  OnlineLearnerOptions o;
  o.feature_map = SmallMap();
  o.num_outputs = kOutputs;
  o.noise_variance = 0.01;
  o.queue_capacity = 4096;
  o.covariance_publish_period = 7;
  o.idle_sleep = std::chrono::microseconds(20);
  // One Update per sample: bit-identical to the reference below (the batched learner is
  // compared to rounding in OnlineLearnerBatched).
  o.max_batch = 1;
  return o;
}

// The single-threaded model the learner must reproduce bit for bit: the same Update calls, and
// for a window the same downdates (weight forgetting^L) and rebuilds.
class ReferenceLearner {
 public:
  explicit ReferenceLearner(const OnlineLearnerOptions& o)
      : o_(o),
        model_(Prior(o), o.noise_variance, o.num_outputs, o.output_scales),
        prior_(model_),
        phi_(o.feature_map->dim()) {}

  void Add(const Vector& x, const Vector& y) {
    o_.feature_map->Evaluate(x, phi_);
    ASSERT_EQ(model_.Update(phi_, y, o_.forgetting), Status::kOk);
    if (o_.window_length == 0) return;
    window_phi_.push_back(phi_);
    window_y_.push_back(y);
    if (static_cast<int>(window_phi_.size()) <= o_.window_length) return;
    const double w = std::pow(o_.forgetting, o_.window_length);
    const Status s = model_.Downdate(window_phi_.front(), window_y_.front(), w);
    window_phi_.erase(window_phi_.begin());
    window_y_.erase(window_y_.begin());
    if (s != Status::kOk && o_.window_failure_policy == WindowFailurePolicy::kRebuild) {
      model_ = prior_;
      for (std::size_t k = 0; k < window_phi_.size(); ++k) {
        ASSERT_EQ(model_.Update(window_phi_[k], window_y_[k], o_.forgetting), Status::kOk);
      }
    }
  }
  const WeightSpaceGP& model() const { return model_; }

  static Vector Prior(const OnlineLearnerOptions& o) {
    if (o.prior_variance.size() != 0) return o.prior_variance;
    Vector lambda(o.feature_map->dim());
    o.feature_map->PriorVariance(o.feature_map->default_shape_parameters(), lambda);
    return lambda;
  }

 private:
  OnlineLearnerOptions o_;
  WeightSpaceGP model_;
  WeightSpaceGP prior_;
  Vector phi_;
  std::vector<Vector> window_phi_;
  std::vector<Vector> window_y_;
};

// Predict of the learner equals Predict / PredictWithVariance of the reference exactly.
void ExpectSamePredictions(OnlineLearner& learner, const WeightSpaceGP& reference,
                           const Matrix& X_test) {
  const FeatureMap& map = *learner.options().feature_map;
  Vector phi(map.dim()), mean(kOutputs), var(kOutputs), ref_mean(kOutputs), ref_latent(kOutputs),
      ref_noisy(kOutputs);
  WeightSpaceGP::Workspace workspace = reference.MakeWorkspace();
  for (int i = 0; i < X_test.rows(); ++i) {
    const Vector x = X_test.row(i).transpose();
    map.Evaluate(x, phi);
    ASSERT_EQ(reference.PredictWithVariance(phi, ref_mean, ref_latent, ref_noisy, workspace),
              Status::kOk);
    ASSERT_EQ(learner.Predict(x, mean), Status::kOk);
    EXPECT_TRUE(BitEqual(mean, ref_mean)) << "test state " << i << ": mean " << mean.transpose()
                                          << " vs reference " << ref_mean.transpose();
    if (learner.has_variance()) {
      ASSERT_EQ(learner.PredictWithVariance(x, mean, var), Status::kOk);
      EXPECT_TRUE(BitEqual(mean, ref_mean));
      EXPECT_TRUE(BitEqual(var, ref_latent))
          << "test state " << i << ": variance " << var.transpose() << " vs reference "
          << ref_latent.transpose();
    }
  }
}

struct LearnerCase {
  std::string name;
  double forgetting;
  int window;
  bool thread;
};
// The case's name in test listings (gtest would print the raw bytes of the struct, which
// change from run to run and so would the ctest names).
void PrintTo(const LearnerCase& c, std::ostream* os) { *os << c.name; }


class OnlineLearnerExact : public ::testing::TestWithParam<LearnerCase> {};

TEST_P(OnlineLearnerExact, MatchesSingleThreadedModelOnceDrained) {
  const LearnerCase& c = GetParam();
  std::cout << "[ seeds    ] map " << kMapSeed << ", data " << kDataSeed << "\n";
  OnlineLearnerOptions o = SmallOptions();
  o.forgetting = c.forgetting;
  o.window_length = c.window;
  o.start_thread = c.thread;
  const Samples data = MakeSamples(600, kDataSeed);
  const Samples test = MakeSamples(20, kDataSeed + 1);

  OnlineLearner learner(o);
  ReferenceLearner reference(o);
  // Three rounds: submit a burst, drain, compare; the learner keeps running in between.
  int next = 0;
  for (int round = 0; round < 3; ++round) {
    const int end = next + 200;
    for (; next < end; ++next) {
      const Vector x = data.X.row(next).transpose();
      const Vector y = data.Y.row(next).transpose();
      ASSERT_EQ(learner.Submit(x, y), SubmitResult::kAccepted);
      reference.Add(x, y);
    }
    ASSERT_TRUE(learner.WaitUntilIdle());
    EXPECT_TRUE(BitEqual(learner.model().weights(), reference.model().weights()));
    EXPECT_TRUE(
        BitEqual(learner.model().covariance_factor(), reference.model().covariance_factor()));
    ExpectSamePredictions(learner, reference.model(), test.X);
    EXPECT_EQ(learner.last_prediction_version(), next);
  }
  const OnlineLearnerSummary s = learner.summary();
  EXPECT_EQ(s.submitted, 600);
  EXPECT_EQ(s.accepted, 600);
  EXPECT_EQ(s.processed, 600);
  EXPECT_EQ(s.updates, 600);
  EXPECT_EQ(s.rejected(), 0);
  EXPECT_EQ(s.dropped_queue_full, 0);
  EXPECT_EQ(s.status_failures(), 0);
  EXPECT_EQ(s.samples_in_model, c.window > 0 ? c.window : 600);
  EXPECT_EQ(s.downdates, c.window > 0 ? 600 - c.window : 0);
  EXPECT_GE(s.covariance_publishes, 600 / 7);
  EXPECT_FALSE(s.learner_failed);
}

INSTANTIATE_TEST_SUITE_P(
    Cases, OnlineLearnerExact,
    ::testing::Values(LearnerCase{"plain_thread", 1.0, 0, true},
                      LearnerCase{"forgetting_thread", 0.995, 0, true},
                      LearnerCase{"window_thread", 1.0, 150, true},
                      LearnerCase{"window_forgetting_thread", 0.999, 150, true},
                      LearnerCase{"forgetting_manual", 0.995, 0, false},
                      LearnerCase{"window_manual", 1.0, 150, false}),
    [](const ::testing::TestParamInfo<LearnerCase>& p) { return p.param.name; });

// Bursts through UpdateBatch: the learner equals the single-call reference to rounding, with
// forgetting and windows, whatever grouping the learner thread happens to make.
double MaxRelDiff(const Matrix& a, const Matrix& b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(1e-300, b.cwiseAbs().maxCoeff());
}

class OnlineLearnerBatched : public ::testing::TestWithParam<LearnerCase> {};

TEST_P(OnlineLearnerBatched, MatchesSingleCallsToRounding) {
  const LearnerCase& c = GetParam();
  std::cout << "[ seeds    ] map " << kMapSeed << ", data " << kDataSeed << "\n";
  OnlineLearnerOptions o = SmallOptions();
  o.forgetting = c.forgetting;
  o.window_length = c.window;
  o.start_thread = c.thread;
  o.max_batch = 16;
  const Samples data = MakeSamples(600, kDataSeed);
  const Samples test = MakeSamples(20, kDataSeed + 1);
  OnlineLearner learner(o);
  ReferenceLearner reference(o);
  int next = 0;
  for (int round = 0; round < 3; ++round) {
    // Manual: bursts of 37 samples processed at once (batches of 16, 16, 5).
    for (const int end = next + 200; next < end; ++next) {
      const Vector x = data.X.row(next).transpose();
      const Vector y = data.Y.row(next).transpose();
      ASSERT_EQ(learner.Submit(x, y), SubmitResult::kAccepted);
      reference.Add(x, y);
      if (!c.thread && next % 37 == 36) learner.ProcessPending();
    }
    ASSERT_TRUE(learner.WaitUntilIdle());
    EXPECT_LT(MaxRelDiff(learner.model().weights(), reference.model().weights()), 1e-10);
    EXPECT_LT(
        MaxRelDiff(learner.model().covariance_factor(), reference.model().covariance_factor()),
        1e-10);
    Vector mean(kOutputs), var(kOutputs), ref_mean(kOutputs), ref_latent(kOutputs),
        ref_noisy(kOutputs), phi(kFeatures);
    for (int i = 0; i < test.X.rows(); ++i) {
      const Vector x = test.X.row(i).transpose();
      o.feature_map->Evaluate(x, phi);
      WeightSpaceGP::Workspace ws = reference.model().MakeWorkspace();
      ASSERT_EQ(reference.model().PredictWithVariance(phi, ref_mean, ref_latent, ref_noisy, ws),
                Status::kOk);
      ASSERT_EQ(learner.PredictWithVariance(x, mean, var), Status::kOk);
      // 600 updates and removals (a 5-sample window re-derives the posterior from few
      // samples after each): 1e-9 of the largest mean.
      EXPECT_LT((mean - ref_mean).cwiseAbs().maxCoeff(), 1e-9 * ref_mean.cwiseAbs().maxCoeff());
      EXPECT_LT((var - ref_latent).cwiseAbs().maxCoeff(), 1e-9 * ref_latent.maxCoeff());
    }
    EXPECT_EQ(learner.last_prediction_version(), next);
  }
  const OnlineLearnerSummary s = learner.summary();
  EXPECT_EQ(s.updates, 600);
  EXPECT_EQ(s.status_failures(), 0);
  EXPECT_EQ(s.samples_in_model, c.window > 0 ? c.window : 600);
  EXPECT_EQ(s.downdates, c.window > 0 ? 600 - c.window : 0);
  if (!c.thread) {
    EXPECT_LT(s.batches, s.processed) << "bursts should share passes";
  }
  EXPECT_FALSE(s.learner_failed);
}

INSTANTIATE_TEST_SUITE_P(
    Cases, OnlineLearnerBatched,
    ::testing::Values(LearnerCase{"plain_thread", 1.0, 0, true},
                      LearnerCase{"window_forgetting_thread", 0.999, 150, true},
                      LearnerCase{"forgetting_manual", 0.995, 0, false},
                      LearnerCase{"window_manual", 1.0, 150, false},
                      LearnerCase{"short_window_manual", 0.999, 5, false}),
    [](const ::testing::TestParamInfo<LearnerCase>& p) { return p.param.name; });

TEST(OnlineLearner, WindowModelIsThePosteriorOfTheWindow) {
  // Without forgetting, L downdates later the model holds exactly the last L samples: compare
  // with a batch fit of those (agreement to rounding of ~500 rank-one updates and downdates).
  OnlineLearnerOptions o = SmallOptions();
  o.window_length = 100;
  o.start_thread = false;
  const Samples data = MakeSamples(500, kDataSeed);
  OnlineLearner learner(o);
  for (int i = 0; i < 500; ++i) {
    ASSERT_EQ(learner.Submit(data.X.row(i).transpose(), data.Y.row(i).transpose()),
              SubmitResult::kAccepted);
  }
  ASSERT_TRUE(learner.WaitUntilIdle());
  Matrix Phi;
  o.feature_map->EvaluateRows(data.X.bottomRows(100), &Phi);
  WeightSpaceGP batch(ReferenceLearner::Prior(o), o.noise_variance, kOutputs);
  ASSERT_EQ(batch.Fit(Phi, data.Y.bottomRows(100)), Status::kOk);
  const Matrix& W = learner.model().weights();
  const double scale = batch.weights().cwiseAbs().maxCoeff();
  EXPECT_LT((W - batch.weights()).cwiseAbs().maxCoeff(), 1e-8 * scale);
  EXPECT_EQ(learner.model().num_samples(), 100);
}

TEST(OnlineLearner, BadSamplesAreCountedAndNeverAbsorbed) {
  OnlineLearnerOptions o = SmallOptions();
  o.input_lower = Vector::Constant(kInputDim, -2.0);
  o.input_upper = Vector::Constant(kInputDim, 2.0);
  o.target_limit = Vector::Constant(kOutputs, 5.0);
  const Samples data = MakeSamples(300, kDataSeed);
  OnlineLearner learner(o);
  ReferenceLearner reference(o);

  long expect_size = 0, expect_nonfinite = 0, expect_range = 0;
  for (int i = 0; i < 300; ++i) {
    Vector x = data.X.row(i).transpose();
    Vector y = data.Y.row(i).transpose();
    switch (i % 10) {
      case 1:
        x[i % kInputDim] = kNaN;
        break;
      case 2:
        y[i % kOutputs] = kInf;
        break;
      case 3:
        x[0] = -kInf;
        break;
      case 4:
        x[i % kInputDim] = 2.5;
        break;  // outside [-2, 2]
      case 5:
        y[1] = -6.0;
        break;  // |tau| > 5
      default:
        break;
    }
    SubmitResult expected = SubmitResult::kAccepted;
    if (i % 10 >= 1 && i % 10 <= 3) expected = SubmitResult::kRejectedNonFinite;
    if (i % 10 == 4 || i % 10 == 5) expected = SubmitResult::kRejectedOutOfRange;
    if (i % 10 == 6) {
      const Vector short_x = x.head(kInputDim - 1);
      ASSERT_EQ(learner.Submit(short_x, y), SubmitResult::kRejectedSize);
      const Vector long_y = Vector::Zero(kOutputs + 1);
      ASSERT_EQ(learner.Submit(x, long_y), SubmitResult::kRejectedSize);
      expect_size += 2;
    }
    const SubmitResult got = learner.Submit(x, y);
    ASSERT_EQ(got, expected) << "sample " << i << ": " << ToString(got);
    if (expected == SubmitResult::kAccepted) reference.Add(x, y);
    if (expected == SubmitResult::kRejectedNonFinite) ++expect_nonfinite;
    if (expected == SubmitResult::kRejectedOutOfRange) ++expect_range;
  }
  ASSERT_TRUE(learner.WaitUntilIdle());
  // Bit-identical to a model that never saw the bad samples.
  EXPECT_TRUE(BitEqual(learner.model().weights(), reference.model().weights()));
  EXPECT_TRUE(BitEqual(learner.model().covariance_factor(), reference.model().covariance_factor()));
  const OnlineLearnerSummary s = learner.summary();
  EXPECT_EQ(s.rejected_size, expect_size);
  EXPECT_EQ(s.rejected_non_finite, expect_nonfinite);
  EXPECT_EQ(s.rejected_out_of_range, expect_range);
  EXPECT_EQ(s.accepted, 300 - expect_nonfinite - expect_range);
  EXPECT_EQ(s.updates, s.accepted);
  EXPECT_EQ(s.submitted, 300 + expect_size);
  EXPECT_EQ(s.status_failures(), 0);
  std::cout << s.Report();

  // Bad queries are refused without touching the outputs.
  Vector mean = Vector::Constant(kOutputs, 42.0), var(kOutputs);
  Vector bad_x = data.X.row(0).transpose();
  bad_x[2] = kNaN;
  EXPECT_EQ(learner.Predict(bad_x, mean), Status::kInvalidInput);
  EXPECT_TRUE((mean.array() == 42.0).all());
  EXPECT_EQ(learner.Predict(bad_x.head(3), mean), Status::kInvalidInput);
  EXPECT_EQ(learner.PredictWithVariance(data.X.row(0).transpose(), mean, var.head(2)),
            Status::kInvalidInput);
  EXPECT_EQ(learner.summary().prediction_failures, 3);
}

TEST(OnlineLearner, FullQueueDropsAndCounts) {
  OnlineLearnerOptions o = SmallOptions();
  o.queue_capacity = 8;
  o.start_thread = false;  // nothing drains the queue until ProcessPending
  OnlineLearner learner(o);
  const Samples data = MakeSamples(20, kDataSeed);
  int accepted = 0, dropped = 0;
  for (int i = 0; i < 20; ++i) {
    const SubmitResult r = learner.Submit(data.X.row(i).transpose(), data.Y.row(i).transpose());
    accepted += r == SubmitResult::kAccepted;
    dropped += r == SubmitResult::kDroppedQueueFull;
  }
  EXPECT_EQ(accepted, 8);
  EXPECT_EQ(dropped, 12);
  EXPECT_EQ(learner.ProcessPending(), 8);
  EXPECT_EQ(learner.summary().dropped_queue_full, 12);
  EXPECT_EQ(learner.summary().updates, 8);
  // Room again after draining.
  EXPECT_EQ(learner.Submit(data.X.row(0).transpose(), data.Y.row(0).transpose()),
            SubmitResult::kAccepted);
}

// A removal is refused when the rest of the window leaves the leaving sample's direction to
// a negligible prior: huge prior variance, fewer samples than features.
TEST(OnlineLearner, WindowFailurePolicies) {
  for (const int max_batch : {1, 16}) {
  for (const WindowFailurePolicy policy :
       {WindowFailurePolicy::kRebuild, WindowFailurePolicy::kKeepSample}) {
    SCOPED_TRACE(policy == WindowFailurePolicy::kRebuild ? "kRebuild" : "kKeepSample");
    SCOPED_TRACE("max_batch " + std::to_string(max_batch));
    OnlineLearnerOptions o = SmallOptions();
    o.max_batch = max_batch;
    o.prior_variance = Vector::Constant(kFeatures, 1e12);
    o.window_length = 5;
    o.window_failure_policy = policy;
    o.start_thread = false;
    const Samples data = MakeSamples(30, kDataSeed);
    OnlineLearner learner(o);
    ReferenceLearner reference(o);
    for (int i = 0; i < 30; ++i) {
      const Vector x = data.X.row(i).transpose();
      const Vector y = data.Y.row(i).transpose();
      ASSERT_EQ(learner.Submit(x, y), SubmitResult::kAccepted);
      if (policy == WindowFailurePolicy::kRebuild) reference.Add(x, y);
    }
    ASSERT_TRUE(learner.WaitUntilIdle());
    const OnlineLearnerSummary s = learner.summary();
    EXPECT_EQ(s.downdate_failures, 25) << "every removal should be refused here";
    EXPECT_EQ(s.downdates, 0);
    if (policy == WindowFailurePolicy::kRebuild) {
      EXPECT_EQ(s.rebuilds, 25);
      EXPECT_EQ(s.samples_in_model, 5);
      if (max_batch == 1) {
        EXPECT_TRUE(BitEqual(learner.model().weights(), reference.model().weights()));
      } else {
        EXPECT_LT(MaxRelDiff(learner.model().weights(), reference.model().weights()), 1e-8);
      }
    } else {
      EXPECT_EQ(s.rebuilds, 0);
      EXPECT_EQ(s.samples_in_model, 30);
    }
    EXPECT_TRUE(learner.model().weights().allFinite());
  }
  }
}

TEST(OnlineLearner, OptionsAreValidated) {
  std::string error;
  OnlineLearnerOptions o = SmallOptions();
  EXPECT_TRUE(o.IsValid(&error)) << error;
  const auto expect_invalid = [&](OnlineLearnerOptions bad, const std::string& fragment) {
    std::string message;
    EXPECT_FALSE(bad.IsValid(&message));
    EXPECT_NE(message.find(fragment), std::string::npos) << message;
    EXPECT_THROW(OnlineLearner learner(bad), std::invalid_argument);
  };
  OnlineLearnerOptions bad = o;
  bad.feature_map = nullptr;
  expect_invalid(bad, "feature_map");
  bad = o;
  bad.num_outputs = 0;
  expect_invalid(bad, "num_outputs");
  bad = o;
  bad.prior_variance = Vector::Ones(kFeatures - 1);
  expect_invalid(bad, "expected 40 entries, got 39");
  bad = o;
  bad.noise_variance = 0.0;
  expect_invalid(bad, "noise_variance");
  bad = o;
  bad.forgetting = 1.5;
  expect_invalid(bad, "forgetting");
  bad = o;
  bad.window_length = 10000;
  bad.forgetting = 0.99;
  expect_invalid(bad, "window");
  bad = o;
  bad.input_lower = Vector::Zero(kInputDim);
  bad.input_upper = Vector::Constant(kInputDim, -1.0);
  expect_invalid(bad, "input_lower exceeds input_upper");
  bad = o;
  bad.target_limit = Vector::Zero(kOutputs);
  expect_invalid(bad, "target_limit");
  bad = o;
  bad.queue_capacity = 0;
  expect_invalid(bad, "queue_capacity");
  bad = o;
  bad.publish_period = 0;
  expect_invalid(bad, "publish_period");
  // Without variance PredictWithVariance is refused.
  o.covariance_publish_period = 0;
  o.start_thread = false;
  OnlineLearner learner(o);
  Vector mean(kOutputs), var(kOutputs);
  EXPECT_FALSE(learner.has_variance());
  EXPECT_EQ(learner.PredictWithVariance(Vector::Zero(kInputDim), mean, var), Status::kInvalidInput);
  EXPECT_EQ(learner.Predict(Vector::Zero(kInputDim), mean), Status::kOk);
  EXPECT_TRUE((mean.array() == 0.0).all()) << "the prior mean is zero";
}

// Submit, Predict and PredictWithVariance allocate nothing after construction, while the
// learner thread updates concurrently (the counter sees every thread, so the learner's work is
// proved allocation-free too).
TEST(OnlineLearnerRealTime, ControlPathAllocatesNothing) {
  OnlineLearnerOptions o = SmallOptions();
  o.forgetting = 0.999;
  o.window_length = 50;
  o.queue_capacity = 64;
  o.covariance_publish_period = 5;
  o.input_lower = Vector::Constant(kInputDim, -2.0);
  o.input_upper = Vector::Constant(kInputDim, 2.0);
  const Samples data = MakeSamples(400, kDataSeed);
  OnlineLearner learner(o);
  Vector mean(kOutputs), var(kOutputs);
  Vector bad = data.X.row(0).transpose();
  bad[1] = kNaN;
  Vector out_of_range = data.X.row(0).transpose();
  out_of_range[1] = 3.0;
  // Warm up (first touches of every path).
  for (int i = 0; i < 60; ++i) {
    learner.Submit(data.X.row(i).transpose(), data.Y.row(i).transpose());
    learner.PredictWithVariance(data.X.row(i).transpose(), mean, var);
  }
  ASSERT_TRUE(learner.WaitUntilIdle());
  // Pre-built views, so the loop itself creates no temporaries.
  std::vector<Vector> xs, ys;
  for (int i = 0; i < 400; ++i) {
    xs.emplace_back(data.X.row(i).transpose());
    ys.emplace_back(data.Y.row(i).transpose());
  }
  const OnlineLearnerSummary before = learner.summary();
  std::size_t count = 0;
  {
    testing::AllocationCounter guard;
    for (int i = 60; i < 400; ++i) {
      learner.Submit(xs[i], ys[i]);
      learner.Submit(bad, ys[i]);
      learner.Submit(out_of_range, ys[i]);
      learner.Predict(xs[i - 1], mean);
      learner.PredictWithVariance(xs[i - 1], mean, var);
      learner.Predict(bad, mean);
    }
    // Let the learner finish its work inside the guard.
    while (learner.summary().processed < learner.summary().accepted) {
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
    count = guard.count();
  }
  if (testing::CountsEveryAllocation()) {
    EXPECT_EQ(count, 0u) << "allocations on the control path or the learner";
  }
  const OnlineLearnerSummary s = learner.summary();
  EXPECT_GT(s.updates, before.updates);
  EXPECT_GT(s.downdates, 0);
  EXPECT_EQ(s.rejected_non_finite - before.rejected_non_finite, 340);
  EXPECT_EQ(s.rejected_out_of_range - before.rejected_out_of_range, 340);
  std::cout << s.Report();
  if (!testing::CountsEveryAllocation()) GTEST_SKIP() << testing::kIncompleteCountReason;
}

// The control thread runs a fast loop (submit + predict, with and without variance) while the
// learner updates: no failures, finite outputs, versions never going backwards, all counters
// consistent. Run it under ThreadSanitizer to check the synchronisation.
TEST(OnlineLearnerThreaded, ConcurrentSubmitPredictAndUpdate) {
  OnlineLearnerOptions o = SmallOptions();
  o.forgetting = 0.998;
  o.window_length = 200;
  o.queue_capacity = 32;  // small: some samples will be dropped
  o.covariance_publish_period = 3;
  o.publish_period = 2;
  o.idle_sleep = std::chrono::microseconds(0);
  const int steps = kUnderTsan ? 3000 : 20000;
  const Samples data = MakeSamples(1000, kDataSeed);
  OnlineLearner learner(o);
  Vector mean(kOutputs), var(kOutputs);
  long last_version = 0;
  long backwards = 0;
  long non_finite = 0;
  long failures = 0;
  long results[5] = {0, 0, 0, 0, 0};
  std::atomic<bool> watching{true};
  // A supervisor reads the counters concurrently.
  std::thread supervisor([&]() {
    while (watching.load(std::memory_order_acquire)) {
      const OnlineLearnerSummary s = learner.summary();
      EXPECT_LE(s.updates, s.submitted);
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  });
  for (int i = 0; i < steps; ++i) {
    const int k = i % 1000;
    ++results[static_cast<int>(
        learner.Submit(data.X.row(k).transpose(), data.Y.row(k).transpose()))];
    const int q = (k * 7) % 1000;
    const Status st = (i % 2 == 0)
                          ? learner.Predict(data.X.row(q).transpose(), mean)
                          : learner.PredictWithVariance(data.X.row(q).transpose(), mean, var);
    failures += st != Status::kOk;
    non_finite += !mean.allFinite() || (i % 2 == 1 && (!var.allFinite() || var.minCoeff() < 0));
    if (learner.last_prediction_version() < last_version) ++backwards;
    last_version = learner.last_prediction_version();
  }
  ASSERT_TRUE(learner.WaitUntilIdle());
  watching.store(false, std::memory_order_release);
  supervisor.join();
  EXPECT_EQ(failures, 0);
  EXPECT_EQ(non_finite, 0);
  EXPECT_EQ(backwards, 0);
  const OnlineLearnerSummary s = learner.summary();
  EXPECT_EQ(s.accepted, results[static_cast<int>(SubmitResult::kAccepted)]);
  EXPECT_EQ(s.dropped_queue_full, results[static_cast<int>(SubmitResult::kDroppedQueueFull)]);
  EXPECT_EQ(s.accepted + s.dropped_queue_full, steps);
  EXPECT_EQ(s.processed, s.accepted);
  EXPECT_EQ(s.updates, s.accepted);
  EXPECT_EQ(s.predictions, steps);
  EXPECT_FALSE(s.learner_failed);
  // After idling, Predict uses the newest model.
  learner.Predict(data.X.row(0).transpose(), mean);
  EXPECT_EQ(learner.last_prediction_version(), s.updates);
  std::cout << s.Report();
  learner.Stop();
  learner.Stop();  // idempotent
}

// ---- Forgetting and windows under drifting friction ------------------------------------------

// Two-link arm (KDL dynamics), joint friction whose Coulomb coefficient rises linearly from
// 0.5 to 3 N m over a 120 s run at 100 Hz. Three online models of pol + friction features
// predict each torque before learning it (one-step-ahead, i.e. prequential, error): without
// forgetting the model averages the friction over the whole past and its error grows with the
// drift; with forgetting (memory ~10 s) or a 10 s sliding window it tracks the friction and the
// error stays bounded.
TEST(OnlineDrift, ForgettingKeepsErrorBoundedWhileNoForgettingGrows) {
  if (kUnderTsan) {
    GTEST_SKIP() << "single-threaded numerical test (no learner thread); too slow under TSan";
  }
  constexpr std::uint64_t kTrajectorySeed = 5;
  constexpr std::uint64_t kNoiseSeed = 6;
  std::cout << "[ seeds    ] trajectory " << kTrajectorySeed << ", noise " << kNoiseSeed << "\n";
  const double duration = 120.0;
  const double dt = 0.01;
  const sim::Robot robot = sim::TwoLinkArm();
  const sim::Trajectory traj = sim::SumOfSines(2, duration, dt, 3, 0.2, 1.2, kTrajectorySeed);
  const int m = static_cast<int>(traj.num_samples());
  const double coulomb_start = 0.5, coulomb_end = 3.0;
  std::mt19937_64 rng(kNoiseSeed);
  std::normal_distribution<double> noise(0.0, 0.02);  // N m
  Matrix X(m, 6), Y(m, 2);
  for (int i = 0; i < m; ++i) {
    const Eigen::VectorXd q = traj.q.row(i).transpose();
    const Eigen::VectorXd qd = traj.qd.row(i).transpose();
    const Eigen::VectorXd qdd = traj.qdd.row(i).transpose();
    sim::JointFriction jf;
    jf.coulomb = coulomb_start + (coulomb_end - coulomb_start) * traj.t[i] / duration;
    jf.viscous = 0.3;
    jf.smoothing_velocity = 0.02;
    const sim::FrictionModel friction = sim::FrictionModel::Uniform(2, jf);
    const Eigen::VectorXd tau = robot.InverseDynamics(q, qd, qdd) + friction.Torque(qd);
    X.row(i) << q.transpose(), qd.transpose(), qdd.transpose();
    Y.row(i) = tau.transpose();
    for (int j = 0; j < 2; ++j) Y(i, j) += noise(rng);
  }

  auto map = std::make_shared<SumFeatureMap>(std::vector<std::shared_ptr<const FeatureMap>>{
      std::make_shared<PolFeatureMap>(2), std::make_shared<FrictionFeatureMap>(2, 0.02)});
  Hyperparameters hyper = DefaultHyperparameters(*map, 2);
  hyper.log_block_scale[hyper.log_block_scale.size() - 1] = std::log(10.0);  // broad friction
  const Vector lambda = PriorVariance(*map, hyper);
  const Vector scales = (Y.array().square().colwise().mean().sqrt()).transpose();
  const double noise_variance = 1e-4;  // (0.01 of the torque scale)^2

  struct Variant {
    const char* name;
    double forgetting;
    int window;
  };
  const std::vector<Variant> variants = {
      {"no forgetting", 1.0, 0}, {"forgetting 0.999", 0.999, 0}, {"window 1000", 1.0, 1000}};
  constexpr int kSegments = 6;
  const int per_segment = m / kSegments;
  std::vector<std::vector<double>> rms(variants.size(), std::vector<double>(kSegments, 0.0));
  for (std::size_t v = 0; v < variants.size(); ++v) {
    OnlineLearnerOptions o;
    o.feature_map = map;
    o.num_outputs = 2;
    o.prior_variance = lambda;
    o.noise_variance = noise_variance;
    o.output_scales = scales;
    o.forgetting = variants[v].forgetting;
    o.window_length = variants[v].window;
    o.queue_capacity = 4;
    o.start_thread = false;  // deterministic: learn each sample right after predicting it
    OnlineLearner learner(o);
    Vector mean(2);
    for (int i = 0; i < m; ++i) {
      const Vector x = X.row(i).transpose();
      ASSERT_EQ(learner.Predict(x, mean), Status::kOk);
      const int seg = std::min(i / per_segment, kSegments - 1);
      rms[v][seg] += (mean - Y.row(i).transpose()).squaredNorm() / 2.0;
      ASSERT_EQ(learner.Submit(x, Y.row(i).transpose()), SubmitResult::kAccepted);
      learner.ProcessPending();
    }
    for (double& r : rms[v]) r = std::sqrt(r / per_segment);
    EXPECT_EQ(learner.summary().status_failures(), 0) << variants[v].name;
  }
  std::cout << "[ figures  ] one-step-ahead torque RMS (N m) per " << duration / kSegments
            << " s segment; Coulomb friction " << coulomb_start << " -> " << coulomb_end
            << " N m over " << duration << " s\n";
  for (std::size_t v = 0; v < variants.size(); ++v) {
    std::cout << "[ figures  ]   " << std::setw(17) << std::left << variants[v].name << std::right;
    for (double r : rms[v]) std::cout << std::setw(9) << std::fixed << std::setprecision(4) << r;
    std::cout << "\n";
  }
  // Bounded: over the last three segments (after the memory has filled) the error of the
  // forgetting and window models grows by less than 10%, while without forgetting it keeps
  // growing with the drift (by more than 30%), and ends more than twice theirs.
  const int late = kSegments - 1, earlier = kSegments - 3;
  EXPECT_GT(rms[0][late], 1.3 * rms[0][earlier]) << "without forgetting the error should grow";
  EXPECT_GT(rms[0][late], 2.0 * rms[0][1]);
  for (int v = 1; v <= 2; ++v) {
    SCOPED_TRACE(variants[v].name);
    EXPECT_LT(rms[v][late], 1.1 * rms[v][earlier]) << "the error should stay bounded";
    EXPECT_LT(rms[v][late], 0.5 * rms[0][late]) << "should beat no forgetting at the end";
  }
}

}  // namespace
}  // namespace structgp
