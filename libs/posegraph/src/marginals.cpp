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
#include <mrpt/poses/Lie/SE.h>

#include "vloc/posegraph/mrpt_optimize.h"

namespace vloc::posegraph {

bool BlockDiagonalOfInverse(const Eigen::SparseMatrix<double>& matrix, int block_size,
                            std::vector<Eigen::MatrixXd>* blocks) {
  using SpMat = Eigen::SparseMatrix<double>;
  const int n = static_cast<int>(matrix.rows());
  blocks->clear();
  if (n == 0) return true;
  if (matrix.cols() != n || block_size <= 0 || n % block_size != 0) return false;
  // Make every diagonal block structurally dense (explicit zeros), so that
  // the factor's pattern, on which Z is evaluated, covers the blocks we read.
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
  Eigen::SimplicialLLT<SpMat, Eigen::Lower, Eigen::AMDOrdering<int>> llt(lower);
  if (llt.info() != Eigen::Success) return false;
  const SpMat& L = llt.matrixL().nestedExpression();
  const int* outer = L.outerIndexPtr();
  const int* inner = L.innerIndexPtr();
  const double* values = L.valuePtr();
  std::vector<double> z(static_cast<size_t>(L.nonZeros()), 0.0);

  // Z(r, c) for r >= c, both in the pattern of L.
  auto z_at = [&](int r, int c) -> double {
    if (r < c) std::swap(r, c);
    const int* begin = inner + outer[c];
    const int* end = inner + outer[c + 1];
    const int* it = std::lower_bound(begin, end, r);
    if (it == end || *it != r) return 0.0;  // outside the pattern: never needed
    return z[static_cast<size_t>(it - inner)];
  };

  for (int j = n - 1; j >= 0; --j) {
    const int begin = outer[j];
    const int end = outer[j + 1];
    if (inner[begin] != j || !(values[begin] > 0.0)) return false;
    const double ljj = values[begin];
    for (int p = end - 1; p > begin; --p) {
      const int i = inner[p];
      double sum = 0.0;
      for (int q = begin + 1; q < end; ++q) sum += values[q] * z_at(i, inner[q]);
      z[static_cast<size_t>(p)] = -sum / ljj;
    }
    double sum = 0.0;
    for (int q = begin + 1; q < end; ++q) sum += values[q] * z[static_cast<size_t>(q)];
    z[static_cast<size_t>(begin)] = 1.0 / (ljj * ljj) - sum / ljj;
  }

  const auto& perm = llt.permutationP().indices();
  const int num_blocks = n / block_size;
  blocks->resize(static_cast<size_t>(num_blocks));
  for (int b = 0; b < num_blocks; ++b) {
    Eigen::MatrixXd& block = (*blocks)[static_cast<size_t>(b)];
    block.resize(block_size, block_size);
    for (int r = 0; r < block_size; ++r)
      for (int c = 0; c < block_size; ++c)
        block(r, c) = z_at(perm[b * block_size + r], perm[b * block_size + c]);
  }
  return true;
}

bool LocalMarginals(const mrpt::graphs::CNetworkOfPoses3DInf& graph,
                    std::map<mrpt::graphs::TNodeID, Matrix6d>* marginals, std::string* error) {
  using SE3 = mrpt::poses::Lie::SE<3>;
  marginals->clear();
  std::map<mrpt::graphs::TNodeID, int> index;
  std::vector<mrpt::graphs::TNodeID> ids;
  for (const auto& n : graph.nodes) {
    if (n.first == graph.root) continue;
    index[n.first] = static_cast<int>(ids.size());
    ids.push_back(n.first);
  }
  if (ids.empty()) return true;
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(graph.edges.size() * 3 * 36);
  auto add_block = [&](int bi, int bj, const Matrix6d& block) {
    // Lower triangle only (row block >= column block).
    if (bi < bj) return;
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c)
        if (bi > bj || r >= c) triplets.emplace_back(6 * bi + r, 6 * bj + c, block(r, c));
  };
  for (const auto& [key, edge] : graph.edges) {
    const auto it1 = graph.nodes.find(key.first);
    const auto it2 = graph.nodes.find(key.second);
    if (it1 == graph.nodes.end() || it2 == graph.nodes.end()) {
      if (error) *error = "edge to a missing node";
      return false;
    }
    SE3::matrix_TxT J1, J2;
    const mrpt::poses::CPose3D p1 = it1->second;
    const mrpt::poses::CPose3D p2 = it2->second;
    SE3::jacob_dDinvP1invP2_de1e2(-edge.mean, p1, p2, J1, J2);
    const Matrix6d W = edge.cov_inv.asEigen();
    const Matrix6d A = J1.asEigen();
    const Matrix6d B = J2.asEigen();
    const auto f1 = index.find(key.first);
    const auto f2 = index.find(key.second);
    const bool free1 = f1 != index.end();
    const bool free2 = f2 != index.end();
    if (free1) add_block(f1->second, f1->second, A.transpose() * W * A);
    if (free2) add_block(f2->second, f2->second, B.transpose() * W * B);
    if (free1 && free2) {
      const Matrix6d AB = A.transpose() * W * B;  // block (1, 2)
      if (f1->second > f2->second) add_block(f1->second, f2->second, AB);
      else add_block(f2->second, f1->second, AB.transpose());
    }
  }
  const int n = static_cast<int>(ids.size()) * 6;
  Eigen::SparseMatrix<double> H(n, n);
  H.setFromTriplets(triplets.begin(), triplets.end());
  std::vector<Eigen::MatrixXd> blocks;
  if (!BlockDiagonalOfInverse(H, 6, &blocks)) {
    if (error)
      *error = "the pose graph's Hessian is singular (a site not linked to site " + std::to_string(graph.root) +
               " by edges?); marginal covariances not computed";
    return false;
  }
  for (size_t i = 0; i < ids.size(); ++i) (*marginals)[ids[i]] = blocks[i];
  return true;
}

}  // namespace vloc::posegraph
