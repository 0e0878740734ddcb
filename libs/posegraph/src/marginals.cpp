// Marginal covariances of a pose graph: diagonal blocks of the inverse of
// the Gauss-Newton Hessian by selected inversion (Takahashi et al. 1973).
//
// With P H P^T = L L^T (L lower, column-compressed) and Z = (P H P^T)^-1,
// L^T Z = L^-1 is lower triangular with diagonal 1/L_jj, so for every j
// (from the last column back) and every i > j in the pattern of column j:
//   Z_ij = -1/L_jj * sum_{k > j, k in col j} L_kj Z_ik
//   Z_jj = 1/L_jj^2 - 1/L_jj * sum_{k > j, k in col j} L_kj Z_kj
// Every Z_ik needed lies in the pattern of L (its columns are closed under
// this recurrence), so Z is only ever evaluated on that pattern.

#include <Eigen/SparseCholesky>
#include <algorithm>

#include "vloc/posegraph/sparse_solver.h"

namespace vloc::posegraph {

namespace {

using SpMat = Eigen::SparseMatrix<double>;

// The lower triangle of `matrix` with every diagonal block structurally
// dense (explicit zeros), so that the factor's pattern, on which Z is
// evaluated, covers the blocks we read.
SpMat LowerWithDenseBlocks(const SpMat& matrix, int block_size) {
  const int n = static_cast<int>(matrix.rows());
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<size_t>(matrix.nonZeros()) + static_cast<size_t>(n * block_size));
  for (int c = 0; c < matrix.outerSize(); ++c)
    for (SpMat::InnerIterator it(matrix, c); it; ++it)
      if (it.row() >= it.col()) triplets.emplace_back(it.row(), it.col(), it.value());
  for (int b = 0; b < n / block_size; ++b)
    for (int r = 0; r < block_size; ++r)
      for (int c = 0; c <= r; ++c) triplets.emplace_back(b * block_size + r, b * block_size + c, 0.0);
  SpMat lower(n, n);
  lower.setFromTriplets(triplets.begin(), triplets.end());
  return lower;
}

// Z on the pattern of L (z[t] for L's value t), by the recurrence above;
// false when a diagonal entry of L is missing or not positive. Column j
// needs Z(i, k) for every pair of rows i >= k > j of its pattern: Z(i, k)
// lies in column k. Column k's rows are scattered once (row -> position)
// and all its pairs read in O(1), each pair feeding both rows' sums.
bool SelectedInverse(const SpMat& L, std::vector<double>* z_out) {
  const int n = static_cast<int>(L.rows());
  const int* outer = L.outerIndexPtr();
  const int* inner = L.innerIndexPtr();
  const double* values = L.valuePtr();
  std::vector<double>& z = *z_out;
  z.assign(static_cast<size_t>(L.nonZeros()), 0.0);
  std::vector<int> position(static_cast<size_t>(n), -1);
  std::vector<double> acc;
  for (int j = n - 1; j >= 0; --j) {
    const int begin = outer[j];
    const int end = outer[j + 1];
    if (inner[begin] != j || !(values[begin] > 0.0)) return false;
    const double ljj = values[begin];
    const int m = end - begin - 1;  // rows below the diagonal
    acc.assign(static_cast<size_t>(m), 0.0);
    for (int a = 0; a < m; ++a) {
      const int k = inner[begin + 1 + a];
      for (int t = outer[k]; t < outer[k + 1]; ++t) position[static_cast<size_t>(inner[t])] = t;
      for (int b = a; b < m; ++b) {
        const int at = position[static_cast<size_t>(inner[begin + 1 + b])];
        if (at < 0) continue;  // outside the pattern: never needed
        const double z_ik = z[static_cast<size_t>(at)];
        acc[static_cast<size_t>(b)] += values[begin + 1 + a] * z_ik;
        if (b != a) acc[static_cast<size_t>(a)] += values[begin + 1 + b] * z_ik;
      }
      for (int t = outer[k]; t < outer[k + 1]; ++t) position[static_cast<size_t>(inner[t])] = -1;
    }
    double sum = 0.0;
    for (int b = 0; b < m; ++b) {
      z[static_cast<size_t>(begin + 1 + b)] = -acc[static_cast<size_t>(b)] / ljj;
      sum += values[begin + 1 + b] * z[static_cast<size_t>(begin + 1 + b)];
    }
    z[static_cast<size_t>(begin)] = 1.0 / (ljj * ljj) - sum / ljj;
  }
  return true;
}

template <class Ordering>
bool BlockDiagonalOfInverseImpl(const SpMat& matrix, int block_size, std::vector<Eigen::MatrixXd>* blocks) {
  const int n = static_cast<int>(matrix.rows());
  blocks->clear();
  if (n == 0) return true;
  if (matrix.cols() != n || block_size <= 0 || n % block_size != 0) return false;
  Eigen::SimplicialLLT<SpMat, Eigen::Lower, Ordering> llt(LowerWithDenseBlocks(matrix, block_size));
  if (llt.info() != Eigen::Success) return false;
  const SpMat& L = llt.matrixL().nestedExpression();
  std::vector<double> z;
  if (!SelectedInverse(L, &z)) return false;
  // Z(r, c) for r >= c, both in the pattern of L.
  auto z_at = [&](int r, int c) -> double {
    if (r < c) std::swap(r, c);
    const int* begin = L.innerIndexPtr() + L.outerIndexPtr()[c];
    const int* end = L.innerIndexPtr() + L.outerIndexPtr()[c + 1];
    const int* it = std::lower_bound(begin, end, r);
    if (it == end || *it != r) return 0.0;  // outside the pattern: never needed
    return z[static_cast<size_t>(it - L.innerIndexPtr())];
  };
  const int num_blocks = n / block_size;
  blocks->resize(static_cast<size_t>(num_blocks));
  const bool natural = llt.permutationP().size() == 0;
  const auto perm = [&](int i) { return natural ? i : llt.permutationP().indices()[i]; };
  for (int b = 0; b < num_blocks; ++b) {
    Eigen::MatrixXd& block = (*blocks)[static_cast<size_t>(b)];
    block.resize(block_size, block_size);
    for (int r = 0; r < block_size; ++r)
      for (int c = 0; c < block_size; ++c)
        block(r, c) = z_at(perm(b * block_size + r), perm(b * block_size + c));
  }
  return true;
}

}  // namespace

bool BlockDiagonalOfInverse(const Eigen::SparseMatrix<double>& matrix, int block_size,
                            std::vector<Eigen::MatrixXd>* blocks, bool keep_order) {
  if (keep_order) return BlockDiagonalOfInverseImpl<Eigen::NaturalOrdering<int>>(matrix, block_size, blocks);
  return BlockDiagonalOfInverseImpl<Eigen::AMDOrdering<int>>(matrix, block_size, blocks);
}

bool BlockDiagonalOfInverseLDLT(const Eigen::SparseMatrix<double>& L, const Eigen::VectorXd& d, int block_size,
                                std::vector<Eigen::MatrixXd>* blocks) {
  // The recurrence above with a unit-diagonal L (strictly lower part stored,
  // rows sorted) and D: Z_ij = -sum_k L_kj Z_ik, Z_jj = 1/d_j - sum_k L_kj Z_kj.
  const int n = static_cast<int>(L.rows());
  blocks->clear();
  if (n == 0) return true;
  if (L.cols() != n || d.size() != n || block_size <= 0 || n % block_size != 0 || !L.isCompressed()) return false;
  const int* outer = L.outerIndexPtr();
  const int* inner = L.innerIndexPtr();
  const double* values = L.valuePtr();
  std::vector<double> z(static_cast<size_t>(L.nonZeros()), 0.0), z_diag(static_cast<size_t>(n), 0.0);
  std::vector<int> position(static_cast<size_t>(n), -1);
  std::vector<double> acc;
  for (int j = n - 1; j >= 0; --j) {
    if (!(d[j] > 0.0)) return false;
    const int begin = outer[j];
    const int m = outer[j + 1] - begin;
    acc.assign(static_cast<size_t>(m), 0.0);
    for (int a = 0; a < m; ++a) {
      const int k = inner[begin + a];
      for (int t = outer[k]; t < outer[k + 1]; ++t) position[static_cast<size_t>(inner[t])] = t;
      acc[static_cast<size_t>(a)] += values[begin + a] * z_diag[static_cast<size_t>(k)];
      for (int b = a + 1; b < m; ++b) {
        const int at = position[static_cast<size_t>(inner[begin + b])];
        if (at < 0) continue;  // outside the pattern: never needed
        const double z_ik = z[static_cast<size_t>(at)];
        acc[static_cast<size_t>(b)] += values[begin + a] * z_ik;
        acc[static_cast<size_t>(a)] += values[begin + b] * z_ik;
      }
      for (int t = outer[k]; t < outer[k + 1]; ++t) position[static_cast<size_t>(inner[t])] = -1;
    }
    double sum = 0.0;
    for (int b = 0; b < m; ++b) {
      z[static_cast<size_t>(begin + b)] = -acc[static_cast<size_t>(b)];
      sum += values[begin + b] * z[static_cast<size_t>(begin + b)];
    }
    z_diag[static_cast<size_t>(j)] = 1.0 / d[j] - sum;
  }
  auto z_at = [&](int r, int c) -> double {
    if (r == c) return z_diag[static_cast<size_t>(r)];
    if (r < c) std::swap(r, c);
    const int* begin = inner + outer[c];
    const int* end = inner + outer[c + 1];
    const int* it = std::lower_bound(begin, end, r);
    if (it == end || *it != r) return 0.0;
    return z[static_cast<size_t>(it - inner)];
  };
  const int num_blocks = n / block_size;
  blocks->resize(static_cast<size_t>(num_blocks));
  for (int b = 0; b < num_blocks; ++b) {
    Eigen::MatrixXd& block = (*blocks)[static_cast<size_t>(b)];
    block.resize(block_size, block_size);
    for (int r = 0; r < block_size; ++r)
      for (int c = 0; c <= r; ++c) block(r, c) = block(c, r) = z_at(b * block_size + r, b * block_size + c);
  }
  return true;
}

}  // namespace vloc::posegraph
