#include "vloc/posegraph/sesync_objective.h"

#include <Eigen/LU>

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

template void SeSyncWeights<2>(const PoseGraph2::Information&, double*, double*);
template void SeSyncWeights<3>(const PoseGraph3::Information&, double*, double*);
template double SeSyncObjective<2>(const PoseGraph2&);
template double SeSyncObjective<3>(const PoseGraph3&);
template void UseSeSyncWeights<2>(PoseGraph2*);
template void UseSeSyncWeights<3>(PoseGraph3*);

}  // namespace vloc::posegraph
