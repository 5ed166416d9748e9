#include "structgp/core/row_subset.h"

#include <stdexcept>
#include <cstddef>
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

Matrix SelectRows(const ConstMatrixRef& X, const std::vector<int>& rows) {
  Matrix out(static_cast<Eigen::Index>(rows.size()), X.cols());
  for (size_t i = 0; i < rows.size(); ++i) {
    CheckIndex(rows[i], i, X.rows());
    out.row(static_cast<Eigen::Index>(i)) = X.row(rows[i]);
  }
  return out;
}

}  // namespace structgp
