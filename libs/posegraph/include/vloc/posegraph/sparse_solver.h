#pragma once
// vloc's pose-graph solver: chordal initialisation, then a sparse
// Levenberg-Marquardt on the information-weighted geodesic (or, as an
// option, chordal) error, with a robust kernel on the edges marked robust
// (loop closures, absolute fixes).
//
//   PoseGraph3 problem = ...;                         // or ProblemFromGraph(mrpt_graph, &ids)
//   SolverOptions options;                            // defaults pass Check()
//   SolverSummary s = SolvePoseGraph(&problem, options);
//   if (s.usable) ... problem.poses ...
//
// SolvePoseGraph reads as its steps:
//   1. InitialiseChordal (optional, chordal_initialisation.cpp): rotations by
//      linear least squares on R_j = R_i R_ij (rotation averaging, relaxed to
//      all 3x3 / 2x2 matrices), projected on SO(n) by SVD; then translations
//      by linear least squares given those rotations. Needs no initial guess,
//      so a graph whose odometry drifted far starts in the optimum's basin.
//   2. Minimise (sparse_solver.cpp): Levenberg-Marquardt, Gauss-Newton
//      first; each iteration linearises every edge into a block-sparse
//      Hessian (poses in approximate-minimum-degree order, pattern built
//      once) and solves H + lambda diag(H): the first by CHOLMOD's
//      supernodal Cholesky (SuiteSparse; large graphs) or Eigen's simplicial
//      LDL^T (traverses), the symbolic analysis done once; later ones by
//      conjugate gradients preconditioned with that factor (the Hessian
//      changes little after the chordal start: a 5,000-pose torus costs 2-4
//      CG iterations a step against a 380 MFlop factorisation), factorising
//      again only when CG does not converge (reuse_factorisation). A warm
//      start (no chordal step) from the previous optimum is what an
//      incremental update uses.
//
// Conventions (the same as MRPT's, so the information matrices of MRPT's
// CNetworkOfPoses2DInf / 3DInf edges are used unchanged): a pose is
// world_from_node (R, t); it is perturbed on the right, R <- R Exp(w),
// t <- t + R tau, with the tangent ordered [tau; w] (3D: x y z rx ry rz; 2D:
// x y phi). An edge i->j measures Z = i_from_j; its residual is
// e = [t_T; Log R_T] with T = Z^-1 P_i^-1 P_j (rotation_residual "chordal":
// [t_T; 2 sin(theta/2) axis]); the cost is sum rho(e^T W e) with rho the
// identity on ordinary edges and the robust kernel on robust ones.
// Global optimality for SE-Sync's objective is checked by
// CertifyGlobalOptimum (sesync_objective.h).

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <string>
#include <vector>

#include "vloc/common/options.h"

namespace vloc::posegraph {

// A pose graph in D = 2 or 3 dimensions, as the solver holds it.
template <int D>
struct PoseGraphProblem {
  static constexpr int kTangent = D == 3 ? 6 : 3;
  using Rotation = Eigen::Matrix<double, D, D>;
  using Translation = Eigen::Matrix<double, D, 1>;
  using Information = Eigen::Matrix<double, kTangent, kTangent>;
  using Tangent = Eigen::Matrix<double, kTangent, 1>;
  struct Pose {
    Rotation R = Rotation::Identity();
    Translation t = Translation::Zero();
  };
  struct Edge {
    int i = 0;                  // index into poses: the edge measures i_from_j
    int j = 0;
    Pose measurement;           // i_from_j
    Information information = Information::Identity();  // of the residual [t; rotation]
    bool robust = false;        // loop closure / absolute fix: the robust kernel applies
    double robust_scale = 1.0;  // multiplies options.robust_width for this edge (> 0)
  };
  std::vector<Pose> poses;      // world_from_node
  std::vector<char> fixed;      // per pose: held constant (at least one, normally the root)
  std::vector<Edge> edges;
};
using PoseGraph2 = PoseGraphProblem<2>;
using PoseGraph3 = PoseGraphProblem<3>;

struct SolverOptions {
  bool chordal_initialisation = true;     // rotation averaging + linear translations before the local solve
  int max_iterations = 100;               // Levenberg-Marquardt iterations
  double relative_cost_tolerance = 1e-8;  // stop when an accepted step lowers the cost by less than this fraction
  double gradient_tolerance = 1e-10;      // stop when |J^T W e|_inf <= this
  double initial_lambda = 1e-12;          // initial damping, relative to each diagonal entry of the Hessian (Gauss-Newton first)
  std::string robust_kernel = "dcs";      // on robust edges: "none", "cauchy" or "dcs" (dynamic covariance scaling)
  double robust_width = 10.0;             // kernel width in chi2 units (e^T W e): DCS Phi / Cauchy c^2
  std::string linear_solver = "cholmod";  // "cholmod" (SuiteSparse supernodal) or "eigen" (SimplicialLDLT)
  std::string rotation_residual = "geodesic";  // "geodesic" (rotation vector, MRPT's and g2o's) or "chordal"
                                          // (2 sin(theta/2) axis: with weights diag(tau, 2 kappa) the cost is
                                          // exactly SE-Sync's objective)
  int reuse_factorisation = 10;           // after the first factorisation, solve later iterations by conjugate gradients
                                          // preconditioned with it, up to this many CG iterations (else factorise
                                          // again); 0 = factorise every iteration (a traverse: cheap, and the
                                          // marginals read the last factor)
  double cg_relative_residual = 1e-2;     // CG stops when |A x + g| <= this * |g|
  int num_threads = 1;                    // OpenMP threads linearising the edges
  bool verbose = false;                   // one line per iteration on stdout

  void Visit(OptionsReader& r);
  bool Check(std::string* error) const;
};

struct SolverSummary {
  bool usable = false;              // the poses may be used
  std::string message;              // why not, or what happened
  int num_poses = 0;
  int num_edges = 0;
  int num_robust_edges = 0;
  int num_downweighted = 0;         // robust edges whose kernel weight ended below 0.5
  double initial_cost = 0.0;        // sum rho(e^T W e) before (after the initialisation: initialised_cost)
  double initialised_cost = 0.0;    // after the chordal step (= initial_cost without it)
  double final_cost = 0.0;
  int iterations = 0;               // Levenberg-Marquardt iterations (accepted and rejected)
  int factorisations = 0;           // sparse Cholesky factorisations (the other iterations: preconditioned CG)
  int cg_iterations = 0;            // conjugate-gradient iterations over all the preconditioned steps
  bool marginals_valid = false;     // marginals asked for and computed
  double initialisation_seconds = 0.0;  // chordal step
  double minimise_seconds = 0.0;        // Levenberg-Marquardt
  double marginal_seconds = 0.0;        // marginal covariances
  double total_seconds = 0.0;

  std::string BriefReport() const;
};

// Steps 1 + 2 above. Throws nothing: a problem the solver cannot handle (an
// edge to a missing pose, no fixed pose, a pose not linked to a fixed one,
// non-finite information) gives usable = false with the reason, and the
// poses as they came in.
// With `marginals`: then the marginal covariance of every pose in its
// tangent (zero for fixed poses), the diagonal blocks of the inverse of the
// Gauss-Newton Hessian at the optimum (robust weights included), by the
// selected inversion of BlockDiagonalOfInverse in the solver's ordering.
template <int D>
SolverSummary SolvePoseGraph(PoseGraphProblem<D>* problem, const SolverOptions& options,
                             std::vector<typename PoseGraphProblem<D>::Information>* marginals = nullptr);

// The same marginal covariances at the problem's poses as they are (no
// optimisation): the diagonal blocks of the inverse of the Gauss-Newton
// Hessian (robust weights included). False with *error when it is singular
// (a pose not linked to a fixed one) or the problem is refused.
template <int D>
bool MarginalCovariances(const PoseGraphProblem<D>& problem, const SolverOptions& options,
                         std::vector<typename PoseGraphProblem<D>::Information>* marginals, std::string* error);

// Step 1 alone. False with *error (poses unchanged) when a free pose is not
// linked to a fixed one.
template <int D>
bool InitialiseChordal(PoseGraphProblem<D>* problem, std::string* error);

// sum rho(e^T W e) over the edges (rho per `options`' kernel on robust edges;
// pass nullptr for the plain chi2).
template <int D>
double Cost(const PoseGraphProblem<D>& problem, const SolverOptions* options);

// An edge's residual e and its Jacobians with respect to right increments of
// P_i and P_j (exposed for tests).
template <int D>
typename PoseGraphProblem<D>::Tangent EdgeResidual(
    const typename PoseGraphProblem<D>::Pose& z, const typename PoseGraphProblem<D>::Pose& p_i,
    const typename PoseGraphProblem<D>::Pose& p_j,
    Eigen::Matrix<double, PoseGraphProblem<D>::kTangent, PoseGraphProblem<D>::kTangent>* J_i,
    Eigen::Matrix<double, PoseGraphProblem<D>::kTangent, PoseGraphProblem<D>::kTangent>* J_j);

// Rotation part of a residual (and of its Jacobians' rows) from the
// rotation vector phi to the chordal 2 sin(|phi|/2) phi / |phi|, whose
// squared norm is |R_T - I|_F^2 / 2 (exposed for tests).
template <int D>
void ToChordalRotation(typename PoseGraphProblem<D>::Tangent* e,
                       Eigen::Matrix<double, PoseGraphProblem<D>::kTangent, PoseGraphProblem<D>::kTangent>* J_i,
                       Eigen::Matrix<double, PoseGraphProblem<D>::kTangent, PoseGraphProblem<D>::kTangent>* J_j);

// P <- P (+) delta (R Exp(w), t + R tau).
template <int D>
void Retract(typename PoseGraphProblem<D>::Pose* pose, const typename PoseGraphProblem<D>::Tangent& delta);

// The robust kernel of width options.robust_width * scale: rho(s) and its
// derivative rho'(s) (the IRLS weight).
double RobustCost(const SolverOptions& options, double s, double* weight, double scale = 1.0);

// Diagonal blocks (block_size x block_size) of the inverse of a symmetric
// positive-definite sparse matrix (the lower triangle is read). Exposed for
// tests. Returns false when the matrix is not positive definite.
// `keep_order`: the matrix is already in a fill-reducing order (no AMD).
bool BlockDiagonalOfInverse(const Eigen::SparseMatrix<double>& matrix, int block_size,
                            std::vector<Eigen::MatrixXd>* blocks, bool keep_order = false);

// The same from an LDL^T factorisation (natural order) of the matrix: L
// unit lower triangular with only its strictly lower part stored (row indices
// sorted, compressed; Eigen's SimplicialLDLT layout), d the diagonal of D.
// The factor's pattern must cover the diagonal blocks.
bool BlockDiagonalOfInverseLDLT(const Eigen::SparseMatrix<double>& L, const Eigen::VectorXd& d, int block_size,
                                std::vector<Eigen::MatrixXd>* blocks);

// Nearest rotation (SVD, det +1) to a D x D matrix.
template <int D>
Eigen::Matrix<double, D, D> ProjectToRotation(const Eigen::Matrix<double, D, D>& m);

}  // namespace vloc::posegraph
