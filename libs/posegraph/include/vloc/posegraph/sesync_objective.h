#pragma once
// SE-Sync's objective (Rosen et al., IJRR 2019), the measure its published
// certified optima are given in:
//   F = sum kappa |R_j - R_i R_ij|_F^2 + tau |t_j - t_i - R_i t_ij|^2
// with, per edge, from the file's information matrices: 3D (g2o quaternion
// units I_q) tau = 3 / tr(inv(I_tt)), kappa = 3 / (2 tr(inv(I_rr))); 2D
// tau = 2 / tr(inv(I_tt)), kappa = I_thetatheta. The problems here hold the
// information over the rotation vector (I_theta = I_q / 4 in 3D), which the
// functions account for.

#include "vloc/posegraph/sparse_solver.h"

namespace vloc::posegraph {

// SE-Sync's weights of one edge from its information (rotation-vector units).
template <int D>
void SeSyncWeights(const typename PoseGraphProblem<D>::Information& information, double* kappa, double* tau);

// F at the problem's poses.
template <int D>
double SeSyncObjective(const PoseGraphProblem<D>& problem);

// Replaces every edge's information by the isotropic one whose geodesic
// cost matches F to second order: diag(tau I, 2 kappa I) (|R - I|_F^2 =
// 4 (1 - cos theta) ~ 2 theta^2). Optimising it reaches F's optimum.
template <int D>
void UseSeSyncWeights(PoseGraphProblem<D>* problem);

// A certificate of global optimality for F (SE-Sync's verification, by
// inertia instead of an eigensolver). With X = [t_1..t_n R_1..R_n] (d rows),
// F = tr(X M X^T) for a sparse M of size n(d+1); at a critical point the
// rotations' Lagrange multipliers are Lambda_i = sym(R_i^T (X M)_{R_i}), and
// the poses are a global minimum of F (and of its semidefinite relaxation)
// when C = M - blockdiag(0, Lambda) is positive semidefinite (Rosen et al.,
// IJRR 2019, thm. 7). C is built from the file's weights. As SE-Sync does (SESyncProblem::verify_solution,
// fast_verification), C + eta I is factorised: all pivots positive <=>
// lambda_min(C) > -eta, with eta = SE-Sync's min_eig_num_tol (1e-3, absolute:
// in the objective's units, not scaled by C). Certified only at a critical
// point: the theorem needs one, so the relative stationarity
// |C X^T|_F / |M X^T|_F must also be below stationarity_tolerance (a
// perturbed optimum is refused by it before the eigenvalues are looked at).
struct CertificateOptions {
  double min_eig_num_tol = 1e-3;          // eta: SE-Sync's tolerance on lambda_min(C)
  double stationarity_tolerance = 1e-4;   // |C X^T|_F / |M X^T|_F at most this
};
struct OptimalityCertificate {
  bool certified = false;     // a critical point and lambda_min(C) > -eta
  double objective = 0.0;     // F at the poses certified (or not)
  double eta = 0.0;           // the tolerance used
  int negative_pivots = 0;    // 1 when C + eta I is not positive definite (the factorisation stops at the first)
  double stationarity = 0.0;  // |C X^T|_F / |M X^T|_F: how far from a critical point of F the poses are
  double seconds = 0.0;       // wall time of the check
  std::string message;        // one line: "certified global optimum: F = ..." or "NOT certified: F = ..., why"
};
template <int D>
OptimalityCertificate CertifyGlobalOptimum(const PoseGraphProblem<D>& problem, const CertificateOptions& options = {});

}  // namespace vloc::posegraph
