// Step 1 of SolvePoseGraph: chordal initialisation (Carlone et al., "Initialization
// techniques for 3D SLAM", ICRA 2015; Martinec & Pajdla's rotation averaging).
//
// Rotations: with Y_i = R_i^T, every edge gives Y_j - R_ij^T Y_i = 0 (linear,
// D right-hand sides: the rows of R decouple), weighted by the edge's
// isotropic rotation precision. The normal equations are one sparse
// (D n) x (D n) system; each block Y_i^T is then projected on SO(D) by SVD.
// Translations: with the rotations fixed, t_j - t_i = R_i t_ij is linear
// (a weighted graph Laplacian, D right-hand sides). Fixed poses give the
// right-hand sides and anchor the gauge. Both systems are factorised by
// CHOLMOD's supernodal Cholesky.

#include <Eigen/CholmodSupport>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "vloc/posegraph/sparse_solver.h"

namespace vloc::posegraph {

template <int D>
Eigen::Matrix<double, D, D> ProjectToRotation(const Eigen::Matrix<double, D, D>& m) {
  Eigen::JacobiSVD<Eigen::Matrix<double, D, D>> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix<double, D, D> S = Eigen::Matrix<double, D, D>::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) S(D - 1, D - 1) = -1.0;
  return svd.matrixU() * S * svd.matrixV().transpose();
}

namespace {

// Isotropic precision of a block: its dimension / trace of its inverse.
template <int N>
double IsotropicPrecision(const Eigen::Matrix<double, N, N>& information) {
  const double trace = information.inverse().trace();
  return trace > 0 && std::isfinite(trace) ? N / trace : 0.0;
}

// Solves the block system assembled from per-edge terms r = Y_j - M Y_i - c
// (B x B blocks M, right-hand side width D) for the free poses. `terms`
// gives for each edge (M, c, weight). Fixed poses' values come from `known`.
template <int B, int D>
bool SolveLinear(const std::vector<int>& free_index, const std::vector<std::pair<int, int>>& ends,
                 const std::vector<Eigen::Matrix<double, B, B>>& M, const std::vector<Eigen::Matrix<double, B, D>>& c,
                 const std::vector<double>& weight, const std::vector<Eigen::Matrix<double, B, D>>& known,
                 int num_free, std::vector<Eigen::Matrix<double, B, D>>* solution) {
  using Block = Eigen::Matrix<double, B, B>;
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(ends.size() * 4 * B * B);
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(B * num_free, D);
  auto add = [&](int a, int b, const Block& block) {
    for (int r = 0; r < B; ++r)
      for (int col = 0; col < B; ++col)
        if (block(r, col) != 0.0) triplets.emplace_back(B * a + r, B * b + col, block(r, col));
  };
  for (size_t e = 0; e < ends.size(); ++e) {
    const double w = weight[e];
    if (!(w > 0)) continue;
    const int i = ends[e].first, j = ends[e].second;
    const int fi = free_index[static_cast<size_t>(i)], fj = free_index[static_cast<size_t>(j)];
    const Block& m = M[e];
    // Row block j: w (Y_j - M Y_i - c) = 0.
    if (fj >= 0) {
      add(fj, fj, w * Block::Identity());
      if (fi >= 0) add(fj, fi, -w * m);
      else rhs.block<B, D>(B * fj, 0) += w * m * known[static_cast<size_t>(i)];
      rhs.block<B, D>(B * fj, 0) += w * c[e];
    }
    // Row block i: -w M^T (Y_j - M Y_i - c) = 0.
    if (fi >= 0) {
      add(fi, fi, w * m.transpose() * m);
      if (fj >= 0) add(fi, fj, -w * m.transpose());
      else rhs.block<B, D>(B * fi, 0) += w * m.transpose() * known[static_cast<size_t>(j)];
      rhs.block<B, D>(B * fi, 0) -= w * m.transpose() * c[e];
    }
  }
  Eigen::SparseMatrix<double> L(B * num_free, B * num_free);
  L.setFromTriplets(triplets.begin(), triplets.end());
  // CHOLMOD's supernodal Cholesky: a 3D grid's rotation system (24,000
  // unknowns) takes 17.8 s in Eigen's simplicial one.
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> llt(L);
  if (llt.info() != Eigen::Success) return false;
  const Eigen::MatrixXd x = llt.solve(rhs);
  if (llt.info() != Eigen::Success || !x.allFinite()) return false;
  solution->assign(known.begin(), known.end());
  for (size_t p = 0; p < free_index.size(); ++p)
    if (free_index[p] >= 0) (*solution)[p] = x.block<B, D>(B * free_index[p], 0);
  return true;
}

}  // namespace

template <int D>
bool InitialiseChordal(PoseGraphProblem<D>* problem, std::string* error) {
  using Problem = PoseGraphProblem<D>;
  constexpr int kRot = Problem::kTangent - D;
  const size_t n = problem->poses.size();
  std::vector<int> free_index(n, -1);
  int num_free = 0;
  for (size_t p = 0; p < n; ++p)
    if (!problem->fixed[p]) free_index[p] = num_free++;
  if (num_free == 0) return true;
  const size_t m = problem->edges.size();
  std::vector<std::pair<int, int>> ends(m);
  std::vector<double> w_rot(m), w_trans(m);
  for (size_t e = 0; e < m; ++e) {
    const auto& edge = problem->edges[e];
    ends[e] = {edge.i, edge.j};
    w_rot[e] = IsotropicPrecision<kRot>(edge.information.template bottomRightCorner<kRot, kRot>());
    w_trans[e] = IsotropicPrecision<D>(edge.information.template topLeftCorner<D, D>());
  }
  // Rotations: Y_j - R_ij^T Y_i = 0, Y = R^T.
  using Mat = Eigen::Matrix<double, D, D>;
  std::vector<Mat> M(m), c(m, Mat::Zero()), known(n);
  for (size_t e = 0; e < m; ++e) M[e] = problem->edges[e].measurement.R.transpose();
  for (size_t p = 0; p < n; ++p) known[p] = problem->poses[p].R.transpose();
  std::vector<Mat> Y;
  if (!SolveLinear<D, D>(free_index, ends, M, c, w_rot, known, num_free, &Y))
    return Fail(error, "chordal initialisation: the rotation system is singular (a pose not linked to a fixed one?)");
  std::vector<Mat> rotations(n);
  for (size_t p = 0; p < n; ++p) rotations[p] = problem->fixed[p] ? problem->poses[p].R : ProjectToRotation<D>(Y[p].transpose());
  // Translations: t_j^T - t_i^T = (R_i t_ij)^T (1 x 1 blocks, D columns).
  using One = Eigen::Matrix<double, 1, 1>;
  using Row = Eigen::Matrix<double, 1, D>;
  std::vector<One> identity(m, One::Identity());
  std::vector<Row> d(m), t_known(n);
  for (size_t e = 0; e < m; ++e) {
    const auto& edge = problem->edges[e];
    d[e] = (rotations[static_cast<size_t>(edge.i)] * edge.measurement.t).transpose();
  }
  for (size_t p = 0; p < n; ++p) t_known[p] = problem->poses[p].t.transpose();
  std::vector<Row> T;
  if (!SolveLinear<1, D>(free_index, ends, identity, d, w_trans, t_known, num_free, &T))
    return Fail(error, "chordal initialisation: the translation system is singular (a pose not linked to a fixed one?)");
  for (size_t p = 0; p < n; ++p) {
    if (problem->fixed[p]) continue;
    problem->poses[p].R = rotations[p];
    problem->poses[p].t = T[p].transpose();
  }
  return true;
}

template Eigen::Matrix<double, 2, 2> ProjectToRotation<2>(const Eigen::Matrix<double, 2, 2>&);
template Eigen::Matrix<double, 3, 3> ProjectToRotation<3>(const Eigen::Matrix<double, 3, 3>&);
template bool InitialiseChordal<2>(PoseGraph2*, std::string*);
template bool InitialiseChordal<3>(PoseGraph3*, std::string*);

}  // namespace vloc::posegraph
