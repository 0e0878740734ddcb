#pragma once
// MRPT graphs (CNetworkOfPoses2DInf / 3DInf, the graph's home) optimised by
// vloc's solver (sparse_solver.h, method "sparse", the default) or by MRPT's
// sparse Levenberg-Marquardt (mrpt::graphslam::optimize_graph_spa_levmarq)
// followed by vloc's weighted LM (method "mrpt", the former default); the
// conversions between MRPT graphs and the solver's problem, and between
// vloc's pose/covariance convention and MRPT's.
//
// MRPT conventions used by the optimiser (MRPT 2.5):
//  - a node pose P is perturbed on the right: P' = P (+) exp(d), d = [t r] with
//    the translation t in the node's own frame and the rotation vector r in
//    the node's frame (SE(3) pseudo-exponential: translation not coupled);
//  - an edge i->j holds Z = measured i_from_j; its residual is
//    e = pseudo-log(Z^-1 P_i^-1 P_j) = [t r] in the frame of Z's target;
//  - CPose3DPDFGaussianInf::cov_inv of an edge is used as the information
//    matrix of e, ordered [x y z rx ry rz] (the optimiser's tangent order,
//    not the yaw-pitch-roll order of CPose3DPDF's other methods). The text
//    format (saveToTextFile / writeAsText) stores that matrix unchanged
//    (it swaps indices 3 and 5 on write and back on read).
// vloc's convention (vloc/common/pose.h): covariance over [x y z rx ry rz] of
// a_from_b with the position error and a left rotation vector, both in frame
// a. For a relative pose with rotation R the two are related by
// J = blockdiag(R^T, R^T): cov_local = J cov_vloc J^T.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <map>
#include <mrpt/graphs/CNetworkOfPoses.h>
#include <mrpt/poses/CPose3D.h>
#include <string>
#include <vector>

#include "vloc/common/options.h"
#include "vloc/common/pose.h"
#include "vloc/posegraph/sparse_solver.h"

namespace vloc::posegraph {

// The solver's settings for an incremental update: no chordal step (warm
// start from the previous optimum), Eigen's simplicial factorisation (a
// traverse is nearly a chain: CHOLMOD's supernodes do not pay), and a cost
// tolerance of 1e-6.
inline SolverOptions WarmStartSolverOptions() {
  SolverOptions o;
  o.chordal_initialisation = false;
  o.linear_solver = "eigen";
  o.relative_cost_tolerance = 1e-6;
  return o;
}

// Which optimiser and its settings. method "sparse" is vloc's solver
// (sparse_solver.h); "mrpt" is MRPT's optimize_graph_spa_levmarq followed by
// vloc's weighted LM (the former default, kept to measure against).
struct OptimizerOptions {
  std::string method = "sparse";                  // "sparse" or "mrpt"
  SolverOptions solver = WarmStartSolverOptions();  // method "sparse"
  // method "mrpt":
  int mrpt_max_iterations = 1;       // iterations of MRPT's optimize_graph_spa_levmarq per update (see OptimizeGraph)
  int mrpt_window = 50;              // MRPT optimises only the newest this many nodes (by id); 0 = all
  int max_iterations = 100;          // iterations of the weighted Levenberg-Marquardt that follows
  double relative_chi2_tolerance = 1e-5;  // stop when an accepted step lowers chi2 by less than this fraction
  double gradient_tolerance = 1e-9;  // stop when |J^T W e|_inf <= this (MRPT "e1"), information-weighted
  double step_tolerance = 1e-12;     // stop when |step| < this * (|x| + this) (MRPT "e2"); MRPT's
                                     // default 1e-6 is loose on long traverses (|x| grows with the distance)
  double tau = 1e-3;                 // initial damping = tau * max diagonal of the Hessian (MRPT "tau")
  bool verbose = false;              // MRPT prints every iteration to stdout
  int num_threads = 1;               // OpenMP threads linearising the edges (LM and marginals); 1 is fastest on a busy 2-core machine

  void Visit(OptionsReader& r);
  bool Check(std::string* error) const;
};

struct OptimizerResult {
  int iterations = 0;         // LM iterations
  double initial_chi2 = 0.0;  // sum of e^T W e before
  double final_chi2 = 0.0;    // and after
  double seconds = 0.0;       // wall time of the optimiser call
  int num_downweighted = 0;   // robust edges the kernel down-weighted (method sparse)
  bool marginals_valid = false;  // marginals asked for and computed (method sparse)
  double marginal_seconds = 0.0;
};

// A sparse solve's summary as an optimiser result; `seconds`: the wall time of the whole call.
OptimizerResult ToOptimizerResult(const SolverSummary& summary, double seconds);

// Optimises every node but graph.root. A graph with no free node or no edge
// is left unchanged. Throws std::runtime_error when MRPT fails.
// 3D: mrpt_max_iterations of MRPT's optimize_graph_spa_levmarq, then a
// Levenberg-Marquardt on the information-weighted chi2 with MRPT's residual,
// Jacobians and retraction (up to max_iterations). MRPT 2.5.8's LM accepts a
// step only when the UNWEIGHTED squared error drops and, after one rejected
// step, rebuilds its Hessian from an empty map so every later Cholesky fails:
// with edges of different precision (DR vs visual) it stops far from the
// optimum. 2D: MRPT alone with max_iterations.
// method "sparse": SolvePoseGraph on the graph's poses (root fixed); `robust`
// (graph.edges order): 0 = an ordinary edge, > 0 = the robust kernel with
// its width multiplied by this; throws std::runtime_error with the solver's
// message when it fails.
// `marginals` (method sparse only; 3D): the solver's marginal covariance of
// every free node in MRPT's local tangent (as LocalMarginals gives).
OptimizerResult OptimizeGraph(mrpt::graphs::CNetworkOfPoses3DInf& graph, const OptimizerOptions& options,
                              const std::vector<double>* robust = nullptr,
                              std::map<mrpt::graphs::TNodeID, Matrix6d>* marginals = nullptr);
OptimizerResult OptimizeGraph(mrpt::graphs::CNetworkOfPoses2DInf& graph, const OptimizerOptions& options,
                              const std::vector<double>* robust = nullptr);

// The solver's view of an MRPT graph: one pose per node in id order (the
// root fixed), one edge per MRPT edge in graph.edges order; ids[k] is pose
// k's node id. Throws std::runtime_error for an edge to a missing node.
PoseGraph3 ProblemFromGraph(const mrpt::graphs::CNetworkOfPoses3DInf& graph, std::vector<mrpt::graphs::TNodeID>* ids,
                            const std::vector<double>* robust = nullptr);
PoseGraph2 ProblemFromGraph(const mrpt::graphs::CNetworkOfPoses2DInf& graph, std::vector<mrpt::graphs::TNodeID>* ids,
                            const std::vector<double>* robust = nullptr);
// Writes the problem's poses back into the graph's nodes.
void PosesToGraph(const PoseGraph3& problem, const std::vector<mrpt::graphs::TNodeID>& ids,
                  mrpt::graphs::CNetworkOfPoses3DInf* graph);
void PosesToGraph(const PoseGraph2& problem, const std::vector<mrpt::graphs::TNodeID>& ids,
                  mrpt::graphs::CNetworkOfPoses2DInf* graph);

// Information-weighted squared error sum_e e^T W e with MRPT's residual.
double Chi2(const mrpt::graphs::CNetworkOfPoses3DInf& graph);
double Chi2(const mrpt::graphs::CNetworkOfPoses2DInf& graph);

mrpt::poses::CPose3D ToMrpt(const Pose3& pose);
Pose3 FromMrpt(const mrpt::poses::CPose3D& pose);

// Covariance of a_from_b in vloc's convention -> covariance of MRPT's local
// residual (and back). `a_from_b` gives the rotation R.
Matrix6d LocalFromVlocCovariance(const Pose3& a_from_b, const Matrix6d& covariance);
Matrix6d VlocFromLocalCovariance(const Pose3& a_from_b, const Matrix6d& covariance);

// Marginal covariance of every free node (all but graph.root), in MRPT's
// local tangent coordinates of the node, from the Gauss-Newton Hessian
// H = sum J^T W J at the current estimate: the 6x6 diagonal blocks of H^-1,
// by sparse Cholesky (Eigen SimplicialLLT, AMD ordering) and the Takahashi
// selected-inversion recurrence over the factor's pattern (exact, and about
// linear in the number of sites for a traverse with few loops). Returns
// false (with *error) when H is singular, e.g. a node not linked to the root.
// The edges are linearised on `num_threads` OpenMP threads.
bool LocalMarginals(const mrpt::graphs::CNetworkOfPoses3DInf& graph,
                    std::map<mrpt::graphs::TNodeID, Matrix6d>* marginals, std::string* error, int num_threads = 1);

// The residual of an edge i->j measuring z = i_from_j, e = pseudo-log(z^-1
// p1^-1 p2) = [t; Log R] (MRPT's), and its Jacobians with respect to
// right increments of p1 and p2 (MRPT's retraction p (+) exp(d)), in closed
// form (the inverse right Jacobian of SO(3) for the rotation): the same
// matrices as MRPT's SE<3>::jacob_dDinvP1invP2_de1e2(-z, p1, p2) at a
// fraction of its cost.
Vector6d EdgeResidualAndJacobians(const mrpt::poses::CPose3D& z, const mrpt::poses::CPose3D& p1,
                                  const mrpt::poses::CPose3D& p2, Matrix6d* J1, Matrix6d* J2);

// Gauss-Newton linearisation at the current estimate, with MRPT's residual
// and EdgeResidualAndJacobians: H = sum J^T W J (lower triangle only) and g = sum J^T W e
// over the free nodes, node id -> unknown block `index` (the root absent).
// Edges are linearised in parallel on `num_threads` threads, assembled
// serially. Throws std::runtime_error for an edge to a missing node.
void Linearise(const mrpt::graphs::CNetworkOfPoses3DInf& graph, const std::map<mrpt::graphs::TNodeID, int>& index,
               int num_threads, Eigen::SparseMatrix<double>* H, Eigen::VectorXd* g);



}  // namespace vloc::posegraph
