#include "structgp/core/row_subset.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <string>

namespace structgp {
namespace {

void CheckIndex(int row, size_t position, Eigen::Index size) {
  if (row < 0 || row >= size) {
    throw std::invalid_argument("SelectRows: expected row indices in [0, " +
                                std::to_string(size) + "), got " + std::to_string(row) +
                                " at position " + std::to_string(position));
  }
}

}  // namespace

std::vector<int> EvenlySpacedRows(Eigen::Index m, Eigen::Index count) {
  if (m < 0) {
    throw std::invalid_argument("EvenlySpacedRows: expected m >= 0 rows, got " +
                                std::to_string(m));
  }
  std::vector<int> rows;
  if (count <= 0 || count >= m) {
    rows.reserve(static_cast<size_t>(m));
    for (Eigen::Index i = 0; i < m; ++i) rows.push_back(static_cast<int>(i));
    return rows;
  }
  rows.reserve(static_cast<size_t>(count));
  for (Eigen::Index k = 0; k < count; ++k) rows.push_back(static_cast<int>(k * m / count));
  return rows;
}

std::vector<int> FarthestStateRows(const ConstMatrixRef& X, Eigen::Index count) {
  const Eigen::Index m = X.rows();
  if (count <= 0 || count >= m) return EvenlySpacedRows(m, m);
  // Standardised columns; a constant column gets scale 0 (it cannot separate states).
  const Eigen::RowVectorXd mean = X.colwise().mean();
  Eigen::RowVectorXd scale(X.cols());
  for (Eigen::Index c = 0; c < X.cols(); ++c) {
    const double sd = std::sqrt((X.col(c).array() - mean[c]).square().sum() / static_cast<double>(m));
    scale[c] = sd > 0.0 ? 1.0 / sd : 0.0;
  }
  auto distance2 = [&](Eigen::Index r, const Eigen::RowVectorXd& y) {
    return ((X.row(r) - y).cwiseProduct(scale)).squaredNorm();
  };
  // nearest[r]: squared distance to the chosen rows; before the first, to the mean (which is
  // then forgotten).
  std::vector<double> nearest(static_cast<size_t>(m));
  for (Eigen::Index r = 0; r < m; ++r) nearest[static_cast<size_t>(r)] = distance2(r, mean);
  std::vector<int> rows;
  rows.reserve(static_cast<size_t>(count));
  for (Eigen::Index k = 0; k < count; ++k) {
    const auto far = std::max_element(nearest.begin(), nearest.end());
    const Eigen::Index chosen = far - nearest.begin();
    if (k == 0) std::fill(nearest.begin(), nearest.end(), std::numeric_limits<double>::infinity());
    rows.push_back(static_cast<int>(chosen));
    const Eigen::RowVectorXd y = X.row(chosen);
    for (Eigen::Index r = 0; r < m; ++r) {
      nearest[static_cast<size_t>(r)] = std::min(nearest[static_cast<size_t>(r)], distance2(r, y));
    }
    nearest[static_cast<size_t>(chosen)] = -1.0;  // never again, even among duplicates
  }
  std::sort(rows.begin(), rows.end());
  return rows;
}

Matrix SelectRows(const ConstMatrixRef& X, const std::vector<int>& rows) {
  Matrix out(static_cast<Eigen::Index>(rows.size()), X.cols());
  for (size_t i = 0; i < rows.size(); ++i) {
    CheckIndex(rows[i], i, X.rows());
    out.row(static_cast<Eigen::Index>(i)) = X.row(rows[i]);
  }
  return out;
}

}  // namespace structgp
