#include "vloc/posegraph/sesync_objective.h"

#include <Eigen/LU>
#include <Eigen/CholmodSupport>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <sstream>

#include "vloc/common/stopwatch.h"

namespace vloc::posegraph {

template <int D>
void SeSyncWeights(const typename PoseGraphProblem<D>::Information& information, double* kappa, double* tau) {
  constexpr int kRot = PoseGraphProblem<D>::kTangent - D;
  *tau = D / information.template topLeftCorner<D, D>().inverse().trace();
  const Eigen::Matrix<double, kRot, kRot> rot = information.template bottomRightCorner<kRot, kRot>();
  if constexpr (D == 3) {
    // I_q = 4 I_theta: kappa = 3 / (2 tr(inv(I_q))) = 6 / tr(inv(I_theta)).
    *kappa = 6.0 / rot.inverse().trace();
  } else {
    *kappa = rot(0, 0);
  }
}

template <int D>
double SeSyncObjective(const PoseGraphProblem<D>& problem) {
  double f = 0.0;
  for (const auto& edge : problem.edges) {
    double kappa, tau;
    SeSyncWeights<D>(edge.information, &kappa, &tau);
    const auto& pi = problem.poses[static_cast<size_t>(edge.i)];
    const auto& pj = problem.poses[static_cast<size_t>(edge.j)];
    f += kappa * (pj.R - pi.R * edge.measurement.R).squaredNorm() +
         tau * (pj.t - pi.t - pi.R * edge.measurement.t).squaredNorm();
  }
  return f;
}

template <int D>
void UseSeSyncWeights(PoseGraphProblem<D>* problem) {
  constexpr int K = PoseGraphProblem<D>::kTangent;
  for (auto& edge : problem->edges) {
    double kappa, tau;
    SeSyncWeights<D>(edge.information, &kappa, &tau);
    Eigen::Matrix<double, K, 1> d;
    d.template head<D>().setConstant(tau);
    d.template tail<K - D>().setConstant(2.0 * kappa);
    edge.information = d.asDiagonal();
  }
}

namespace {

// Columns of the SE-Sync variable X = [t_1 .. t_n | R_1 .. R_n] (D x n(D + 1)).
template <int D>
struct Columns {
  int n;
  int T(int i) const { return i; }
  int R(int i) const { return n + D * i; }
};

// M = sum kappa B B^T + tau b b^T (see the header), as triplets.
template <int D>
std::vector<Eigen::Triplet<double>> ConnectionTriplets(const PoseGraphProblem<D>& problem, Columns<D> col) {
  std::vector<Eigen::Triplet<double>> m;
  m.reserve(problem.edges.size() * (4 * D * D + 4 * D + 4));
  for (const auto& e : problem.edges) {
    double kappa, tau;
    SeSyncWeights<D>(e.information, &kappa, &tau);
    const Eigen::Matrix<double, D, D>& Rij = e.measurement.R;
    const Eigen::Matrix<double, D, 1>& tij = e.measurement.t;
    const int ri = col.R(e.i), rj = col.R(e.j), ti = col.T(e.i), tj = col.T(e.j);
    for (int a = 0; a < D; ++a) {
      m.emplace_back(rj + a, rj + a, kappa);
      m.emplace_back(ri + a, ri + a, kappa);
      for (int b = 0; b < D; ++b) {
        m.emplace_back(rj + a, ri + b, -kappa * Rij(b, a));  // -R_ij^T
        m.emplace_back(ri + a, rj + b, -kappa * Rij(a, b));  // -R_ij
        m.emplace_back(ri + a, ri + b, tau * tij(a) * tij(b));
      }
      m.emplace_back(tj, ri + a, -tau * tij(a));
      m.emplace_back(ri + a, tj, -tau * tij(a));
      m.emplace_back(ti, ri + a, tau * tij(a));
      m.emplace_back(ri + a, ti, tau * tij(a));
    }
    m.emplace_back(tj, tj, tau);
    m.emplace_back(ti, ti, tau);
    m.emplace_back(tj, ti, -tau);
    m.emplace_back(ti, tj, -tau);
  }
  return m;
}

// The Lagrange multipliers' block diagonal -Lambda (as triplets) at the
// poses, and the relative norm of the gradient C X left there
// (stationarity).
template <int D>
std::vector<Eigen::Triplet<double>> NegativeMultipliers(const PoseGraphProblem<D>& problem, Columns<D> col,
                                                        const std::vector<Eigen::Triplet<double>>& m,
                                                        double* stationarity) {
  const int size = col.n * (D + 1);
  Eigen::SparseMatrix<double> M(size, size);
  M.setFromTriplets(m.begin(), m.end());
  Eigen::MatrixXd X = Eigen::MatrixXd::Zero(D, size);
  for (int i = 0; i < col.n; ++i) {
    X.col(col.T(i)) = problem.poses[static_cast<size_t>(i)].t;
    X.block(0, col.R(i), D, D) = problem.poses[static_cast<size_t>(i)].R;
  }
  const Eigen::MatrixXd XM = (M * X.transpose()).transpose();  // D x size (M symmetric)
  std::vector<Eigen::Triplet<double>> lambda;
  Eigen::MatrixXd CX = XM;
  for (int i = 0; i < col.n; ++i) {
    const Eigen::Matrix<double, D, D> R = problem.poses[static_cast<size_t>(i)].R;
    const Eigen::Matrix<double, D, D> G = XM.block(0, col.R(i), D, D);
    const Eigen::Matrix<double, D, D> L = 0.5 * (R.transpose() * G + G.transpose() * R);
    CX.block(0, col.R(i), D, D) -= R * L;
    for (int a = 0; a < D; ++a)
      for (int b = 0; b < D; ++b) lambda.emplace_back(col.R(i) + a, col.R(i) + b, -L(a, b));
  }
  *stationarity = CX.norm() / std::max(XM.norm(), 1e-300);
  return lambda;
}

// As SE-Sync's fast_verification: whether a supernodal Cholesky of
// C + eta I = M - Lambda + eta I succeeds (it stops at the first pivot that
// is not positive).
bool CholeskyCertifies(const std::vector<Eigen::Triplet<double>>& m, const std::vector<Eigen::Triplet<double>>& lambda,
                       int size, double eta) {
  std::vector<Eigen::Triplet<double>> all = m;
  all.insert(all.end(), lambda.begin(), lambda.end());
  for (int k = 0; k < size; ++k) all.emplace_back(k, k, eta);
  Eigen::SparseMatrix<double> C(size, size);
  C.setFromTriplets(all.begin(), all.end());
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> llt;
  llt.cholmod().quick_return_if_not_posdef = 1;
  llt.cholmod().print = 0;
  llt.compute(C);
  return llt.info() == Eigen::Success;
}

}  // namespace

template <int D>
OptimalityCertificate CertifyGlobalOptimum(const PoseGraphProblem<D>& problem, const CertificateOptions& options) {
  const Stopwatch watch;
  OptimalityCertificate c;
  c.objective = SeSyncObjective(problem);
  const Columns<D> col{static_cast<int>(problem.poses.size())};
  const std::vector<Eigen::Triplet<double>> m = ConnectionTriplets(problem, col);
  const std::vector<Eigen::Triplet<double>> lambda = NegativeMultipliers(problem, col, m, &c.stationarity);
  c.eta = options.min_eig_num_tol;
  std::ostringstream os;
  os.precision(10);
  os << "F = " << c.objective;
  const std::string f = os.str();
  os.str("");
  os.precision(3);
  if (c.stationarity > options.stationarity_tolerance) {
    os << "NOT certified: " << f << " is not at a critical point of F (stationarity " << c.stationarity << " > "
       << options.stationarity_tolerance << ")";
  } else {
    c.certified = CholeskyCertifies(m, lambda, col.n * (D + 1), c.eta);
    c.negative_pivots = c.certified ? 0 : 1;
    os << (c.certified ? "certified global optimum: " : "NOT certified: ") << f << ", lambda_min(C) "
       << (c.certified ? "> -" : "< -") << c.eta << " (SE-Sync's min_eig_num_tol)" << ", stationarity "
       << c.stationarity;
  }
  c.message = os.str();
  c.seconds = watch.Seconds();
  return c;
}

template OptimalityCertificate CertifyGlobalOptimum<2>(const PoseGraph2&, const CertificateOptions&);
template OptimalityCertificate CertifyGlobalOptimum<3>(const PoseGraph3&, const CertificateOptions&);
template void SeSyncWeights<2>(const PoseGraph2::Information&, double*, double*);
template void SeSyncWeights<3>(const PoseGraph3::Information&, double*, double*);
template double SeSyncObjective<2>(const PoseGraph2&);
template double SeSyncObjective<3>(const PoseGraph3&);
template void UseSeSyncWeights<2>(PoseGraph2*);
template void UseSeSyncWeights<3>(PoseGraph3*);

}  // namespace vloc::posegraph
