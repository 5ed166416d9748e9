#include "structgp/feature/random_feature_map.h"

#include <cmath>
#include <random>
#include <string>

#include "structgp/core/validate.h"

namespace structgp {
namespace {

constexpr double kTwoPi = 6.283185307179586476925286766559;

// A uniform number in [0, 1) from the top 53 bits of one engine draw.
double Uniform01(std::mt19937_64* engine) {
  return static_cast<double>((*engine)() >> 11) * 0x1.0p-53;
}

// A standard normal number (Box-Muller, cosine branch); 1 - u keeps the logarithm finite.
double StandardNormal(std::mt19937_64* engine) {
  const double u1 = 1.0 - Uniform01(engine);
  const double u2 = Uniform01(engine);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(kTwoPi * u2);
}

}  // namespace

RandomFeatureMap::RandomFeatureMap(int input_dim, int num_features, int num_blocks,
                                   std::uint64_t seed)
    : seed_(seed) {
  RequireInRange("RandomFeatureMap input_dim", input_dim, 1, 1e9, true);
  RequireInRange("RandomFeatureMap num_features", num_features, 1, 1e9, true);
  RequireInRange("RandomFeatureMap num_blocks", num_blocks, 1, num_features, true, true);
  std::mt19937_64 engine(seed);
  frequencies_.resize(num_features, input_dim);
  phases_.resize(num_features);
  for (int k = 0; k < num_features; ++k) {
    for (int i = 0; i < input_dim; ++i) frequencies_(k, i) = StandardNormal(&engine);
    phases_[k] = kTwoPi * Uniform01(&engine);
  }
  for (int b = 0; b < num_blocks; ++b) {
    const int begin = static_cast<int>(static_cast<std::int64_t>(b) * num_features / num_blocks);
    const int end = static_cast<int>(static_cast<std::int64_t>(b + 1) * num_features / num_blocks);
    blocks_.push_back(FeatureBlock{"b" + std::to_string(b), begin, end - begin});
  }
}

void RandomFeatureMap::Evaluate(const ConstVectorRef& x, VectorRef phi) const {
  if (x.size() != input_dim()) {
    RequireSize("RandomFeatureMap::Evaluate x", x.size(), input_dim());
  }
  if (phi.size() != dim()) RequireSize("RandomFeatureMap::Evaluate phi", phi.size(), dim());
  for (Eigen::Index k = 0; k < frequencies_.rows(); ++k) {
    phi[k] = std::cos(frequencies_.row(k).dot(x) + phases_[k]);
  }
}

void RandomFeatureMap::PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                                     Matrix* jacobian) const {
  RequireSize("RandomFeatureMap::PriorVariance shape", shape.size(), 1);
  RequireSize("RandomFeatureMap::PriorVariance lambda", lambda.size(), dim());
  RequireFinite("RandomFeatureMap::PriorVariance shape (log_decay)", shape);
  const double rate = std::exp(shape[0]);
  const double d = dim();
  if (jacobian != nullptr) jacobian->resize(dim(), 1);
  for (int k = 0; k < dim(); ++k) {
    const double t = rate * k / d;
    lambda[k] = std::exp(-t);
    if (jacobian != nullptr) (*jacobian)(k, 0) = -t * lambda[k];
  }
}

}  // namespace structgp
