#pragma once
// What MRPT does for the pose graph, and only that: its pose types
// (CPose3D / CPose2D), its graph container (CNetworkOfPoses2DInf / 3DInf:
// nodes, edges with their information) and its text format (VERTEX3 /
// EDGE3, read and written by graph_io.h and TraverseGraph). The optimiser is
// vloc's own (sparse_solver.h): MRPT 2.5's optimize_graph_spa_levmarq stops
// in local minima and takes 10-100x the time on the public sets (see
// bench_posegraph_datasets, where it stays as a peer). This file converts
// between MRPT's graphs and the solver's problem, and between vloc's
// pose/covariance convention and MRPT's.
//
// MRPT conventions the solver shares (MRPT 2.5):
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
#include <mrpt/graphs/CNetworkOfPoses.h>
#include <mrpt/poses/CPose3D.h>
#include <vector>

#include "vloc/common/pose.h"
#include "vloc/posegraph/sparse_solver.h"

namespace vloc::posegraph {

// The solver's settings for an incremental update: no chordal step (warm
// start from the previous optimum), Eigen's simplicial factorisation every
// iteration (a traverse is nearly a chain: CHOLMOD's supernodes and the
// preconditioned CG do not pay, and the marginals read the last factor), and
// a cost tolerance of 1e-6.
inline SolverOptions WarmStartSolverOptions() {
  SolverOptions o;
  o.chordal_initialisation = false;
  o.linear_solver = "eigen";
  o.reuse_factorisation = 0;
  o.relative_cost_tolerance = 1e-6;
  return o;
}

// The solver's view of an MRPT graph: one pose per node in id order (the
// root fixed), one edge per MRPT edge in graph.edges order; ids[k] is pose
// k's node id. `robust` (graph.edges order): 0 = an ordinary edge, > 0 = the
// robust kernel with its width multiplied by this. Throws
// std::runtime_error for an edge to a missing node.
PoseGraph3 ProblemFromGraph(const mrpt::graphs::CNetworkOfPoses3DInf& graph, std::vector<mrpt::graphs::TNodeID>* ids,
                            const std::vector<double>* robust = nullptr);
PoseGraph2 ProblemFromGraph(const mrpt::graphs::CNetworkOfPoses2DInf& graph, std::vector<mrpt::graphs::TNodeID>* ids,
                            const std::vector<double>* robust = nullptr);
// Writes the problem's poses back into the graph's nodes.
void PosesToGraph(const PoseGraph3& problem, const std::vector<mrpt::graphs::TNodeID>& ids,
                  mrpt::graphs::CNetworkOfPoses3DInf* graph);
void PosesToGraph(const PoseGraph2& problem, const std::vector<mrpt::graphs::TNodeID>& ids,
                  mrpt::graphs::CNetworkOfPoses2DInf* graph);

mrpt::poses::CPose3D ToMrpt(const Pose3& pose);
Pose3 FromMrpt(const mrpt::poses::CPose3D& pose);
PoseGraph3::Pose ToSolver(const mrpt::poses::CPose3D& pose);

// Covariance of a_from_b in vloc's convention -> covariance of MRPT's local
// residual (and back). `a_from_b` gives the rotation R.
Matrix6d LocalFromVlocCovariance(const Pose3& a_from_b, const Matrix6d& covariance);
Matrix6d VlocFromLocalCovariance(const Pose3& a_from_b, const Matrix6d& covariance);

}  // namespace vloc::posegraph
