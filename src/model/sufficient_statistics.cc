#include "structgp/model/sufficient_statistics.h"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <vector>

#include "structgp/core/validate.h"
#include "structgp/internal/workers.h"

namespace structgp {

SufficientStatistics::SufficientStatistics(int num_features, int num_outputs)
    : gram(Matrix::Zero(num_features, num_features)),
      cross(Matrix::Zero(num_features, num_outputs)),
      y_squared(Vector::Zero(num_outputs)) {}

void SufficientStatistics::Accumulate(const ConstMatrixRef& Phi, const ConstMatrixRef& Y) {
  RequireSize("SufficientStatistics::Accumulate Phi", Phi.cols(), num_features(), "columns");
  RequireSize("SufficientStatistics::Accumulate Y", Y.cols(), num_outputs(), "columns");
  RequireSize("SufficientStatistics::Accumulate Y", Y.rows(), Phi.rows(), "rows (as in Phi)");
  RequireFinite("SufficientStatistics::Accumulate Phi", Phi);
  RequireFinite("SufficientStatistics::Accumulate Y", Y);
  gram.selfadjointView<Eigen::Lower>().rankUpdate(Phi.transpose());
  cross.noalias() += Phi.transpose() * Y;
  y_squared += Y.colwise().squaredNorm().transpose();
  count += static_cast<double>(Phi.rows());
}

void SufficientStatistics::AccumulateTransposed(const ConstMatrixRef& PhiT,
                                                const ConstMatrixRef& Y) {
  RequireSize("SufficientStatistics::AccumulateTransposed PhiT", PhiT.rows(), num_features(),
              "rows");
  RequireSize("SufficientStatistics::AccumulateTransposed Y", Y.cols(), num_outputs(), "columns");
  RequireSize("SufficientStatistics::AccumulateTransposed Y", Y.rows(), PhiT.cols(),
              "rows (as columns of PhiT)");
  RequireFinite("SufficientStatistics::AccumulateTransposed PhiT", PhiT);
  RequireFinite("SufficientStatistics::AccumulateTransposed Y", Y);
  gram.selfadjointView<Eigen::Lower>().rankUpdate(PhiT);
  cross.noalias() += PhiT * Y;
  y_squared += Y.colwise().squaredNorm().transpose();
  count += static_cast<double>(PhiT.cols());
}

void SufficientStatistics::Merge(const SufficientStatistics& other) {
  RequireSize("SufficientStatistics::Merge", other.num_features(), num_features(), "features");
  RequireSize("SufficientStatistics::Merge", other.num_outputs(), num_outputs(), "outputs");
  gram.triangularView<Eigen::Lower>() += other.gram;
  cross += other.cross;
  y_squared += other.y_squared;
  count += other.count;
}

namespace {

// Rows [begin, end) into stats, chunk_rows samples at a time.
void AccumulateRange(const FeatureMap& map, const ConstMatrixRef& X, const ConstMatrixRef& Y,
                     Eigen::Index begin, Eigen::Index end, Eigen::Index chunk_rows,
                     SufficientStatistics* stats) {
  const int D = map.dim();
  Matrix PhiT(D, std::min(chunk_rows, std::max<Eigen::Index>(end - begin, 0)));
  Vector x(map.input_dim());
  for (Eigen::Index start = begin; start < end; start += chunk_rows) {
    const Eigen::Index rows = std::min(chunk_rows, end - start);
    for (Eigen::Index i = 0; i < rows; ++i) {
      x = X.row(start + i).transpose();
      map.Evaluate(x, PhiT.col(i));
    }
    const auto block = PhiT.leftCols(rows);
    if (!block.allFinite()) {
      for (Eigen::Index i = 0; i < rows; ++i) {
        if (!PhiT.col(i).allFinite()) {
          throw std::invalid_argument("AccumulateStatistics: the features of row " +
                                      std::to_string(start + i) + " are not finite");
        }
      }
    }
    stats->AccumulateTransposed(block, Y.middleRows(start, rows));
  }
}

}  // namespace

SufficientStatistics AccumulateStatistics(const FeatureMap& map, const ConstMatrixRef& X,
                                          const ConstMatrixRef& Y,
                                          const AccumulateOptions& options) {
  RequireSize("AccumulateStatistics X", X.cols(), map.input_dim(), "columns");
  RequireSize("AccumulateStatistics Y", Y.rows(), X.rows(), "rows (as in X)");
  if (options.chunk_rows < 1) {
    throw std::invalid_argument("AccumulateOptions::chunk_rows: expected >= 1, got " +
                                std::to_string(options.chunk_rows));
  }
  if (options.num_threads < 1) {
    throw std::invalid_argument("AccumulateOptions::num_threads: expected >= 1, got " +
                                std::to_string(options.num_threads));
  }
  RequireFinite("AccumulateStatistics X", X);
  RequireFinite("AccumulateStatistics Y", Y);
  const int D = map.dim();
  const int P = static_cast<int>(Y.cols());
  const Eigen::Index m = X.rows();
  // No more workers than chunks: a worker with less than one chunk costs a D^2 accumulator
  // for nothing.
  const Eigen::Index chunks = (m + options.chunk_rows - 1) / options.chunk_rows;
  const int workers = static_cast<int>(
      std::max<Eigen::Index>(1, std::min<Eigen::Index>(options.num_threads, chunks)));
  SufficientStatistics total(D, P);
  if (workers == 1) {
    AccumulateRange(map, X, Y, 0, m, options.chunk_rows, &total);
    return total;
  }
  // Contiguous ranges of whole chunks, as even as possible.
  std::vector<Eigen::Index> bounds(static_cast<size_t>(workers) + 1);
  for (int w = 0; w <= workers; ++w) {
    bounds[static_cast<size_t>(w)] = std::min(m, chunks * w / workers * options.chunk_rows);
  }
  std::vector<SufficientStatistics> parts;
  parts.reserve(static_cast<size_t>(workers));
  for (int w = 0; w < workers; ++w) parts.emplace_back(D, P);
  internal::RunWorkers(workers, [&](int w) {
    AccumulateRange(map, X, Y, bounds[static_cast<size_t>(w)], bounds[static_cast<size_t>(w) + 1],
                    options.chunk_rows, &parts[static_cast<size_t>(w)]);
  });
  for (const auto& part : parts) total.Merge(part);
  return total;
}

}  // namespace structgp
