#include "vloc/posegraph/mrpt_optimize.h"

#include <chrono>
#include <cstdio>
#include <set>
#include <cmath>
#include <Eigen/SparseCholesky>
#include <mrpt/graphslam/levmarq.h>
#include <mrpt/poses/Lie/SE.h>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include "vloc/common/stopwatch.h"

namespace vloc::posegraph {

void OptimizerOptions::Visit(OptionsReader& r) {
  r.Optional("method", &method, "sparse (vloc's solver) | mrpt (MRPT's LM + weighted LM, the former default)");
  r.Child("solver", [this](OptionsReader& c) { solver.Visit(c); });
  r.Optional("mrpt_max_iterations", &mrpt_max_iterations, "MRPT optimize_graph_spa_levmarq iterations per update");
  r.Optional("mrpt_window", &mrpt_window, "MRPT optimises only the newest this many nodes; 0 = all");
  r.Optional("max_iterations", &max_iterations, "weighted Levenberg-Marquardt iterations per update");
  r.Optional("relative_chi2_tolerance", &relative_chi2_tolerance, "stop when chi2 drops by less than this fraction");
  r.Optional("gradient_tolerance", &gradient_tolerance, "stop when the weighted gradient inf-norm is below");
  r.Optional("step_tolerance", &step_tolerance, "stop when |step| < tol * (|x| + tol)");
  r.Optional("tau", &tau, "initial damping factor relative to the Hessian diagonal");
  r.Optional("verbose", &verbose, "print MRPT's iterations");
  r.Optional("num_threads", &num_threads, "OpenMP threads of the weighted LM's linearisation");
}

bool OptimizerOptions::Check(std::string* error) const {
  if (method != "sparse" && method != "mrpt") return Fail(error, "method must be sparse or mrpt, got '" + method + "'");
  std::string sub;
  if (!solver.Check(&sub)) return Fail(error, "solver." + sub);
  if (max_iterations < 1 || mrpt_max_iterations < 1) return Fail(error, "max_iterations and mrpt_max_iterations must be >= 1");
  if (mrpt_window < 0) return Fail(error, "mrpt_window must be >= 0");
  if (!(relative_chi2_tolerance >= 0.0)) return Fail(error, "relative_chi2_tolerance must be >= 0");
  if (!(gradient_tolerance > 0.0)) return Fail(error, "gradient_tolerance must be > 0");
  if (!(step_tolerance > 0.0)) return Fail(error, "step_tolerance must be > 0");
  if (!(tau > 0.0)) return Fail(error, "tau must be > 0");
  if (num_threads < 1) return Fail(error, "num_threads must be >= 1");
  return true;
}

namespace {

template <class Graph>
double Chi2Impl(const Graph& graph) {
  using gst = mrpt::graphslam::graphslam_traits<Graph>;
  double chi2 = 0.0;
  for (const auto& [ids, edge] : graph.edges) {
    const auto it1 = graph.nodes.find(ids.first);
    const auto it2 = graph.nodes.find(ids.second);
    if (it1 == graph.nodes.end() || it2 == graph.nodes.end())
      throw std::runtime_error("pose graph edge " + std::to_string(ids.first) + "->" +
                               std::to_string(ids.second) + " refers to a missing node");
    const typename gst::edge_poses_type p1 = it1->second;
    const typename gst::edge_poses_type p2 = it2->second;
    const auto residual = gst::SE_TYPE::log((p2 - p1) - edge.getPoseMean());
    const auto e = residual.asEigen();
    chi2 += e.dot(edge.cov_inv.asEigen() * e);
  }
  return chi2;
}

template <class Graph>
OptimizerResult OptimizeImpl(Graph& graph, const OptimizerOptions& options, int mrpt_iterations, int window) {
  OptimizerResult result;
  const auto start = std::chrono::steady_clock::now();
  result.initial_chi2 = Chi2Impl(graph);
  bool has_free = false;
  for (const auto& n : graph.nodes) has_free |= n.first != graph.root;
  if (!has_free || graph.edges.empty()) {
    result.final_chi2 = result.initial_chi2;
    return result;
  }
  mrpt::containers::yaml params = mrpt::containers::yaml::Map();
  params["max_iterations"] = static_cast<uint64_t>(mrpt_iterations);
  params["e1"] = options.gradient_tolerance;
  params["e2"] = options.step_tolerance;
  params["tau"] = options.tau;
  params["verbose"] = options.verbose;
  mrpt::graphslam::TResultInfoSpaLevMarq info{};
  try {
    std::set<mrpt::graphs::TNodeID> newest;
    if (window > 0)
      for (auto it = graph.nodes.rbegin(); it != graph.nodes.rend() && static_cast<int>(newest.size()) < window; ++it)
        if (it->first != graph.root) newest.insert(it->first);
    mrpt::graphslam::optimize_graph_spa_levmarq(graph, info, window > 0 ? &newest : nullptr, params);
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("MRPT optimize_graph_spa_levmarq failed: ") + e.what());
  }
  result.iterations = static_cast<int>(info.num_iters);
  result.final_chi2 = Chi2Impl(graph);
  result.seconds = SecondsSince(start);
  return result;
}

Eigen::Matrix<double, 6, 6> RotationBlocks(const Eigen::Matrix3d& R) {
  Eigen::Matrix<double, 6, 6> J = Eigen::Matrix<double, 6, 6>::Zero();
  J.block<3, 3>(0, 0) = R;
  J.block<3, 3>(3, 3) = R;
  return J;
}

// Levenberg-Marquardt on the information-weighted chi2 with MRPT's residual,
// Jacobians and retraction (P <- P (+) exp(-delta)), continuing from where
// MRPT's optimize_graph_spa_levmarq stops. Needed with MRPT 2.5.8, whose LM
// accepts a step only when the *unweighted* squared error drops and, after one
// rejected step, rebuilds its Hessian from an empty map and cannot recover
// (every later Cholesky fails): with edges of different precision (DR vs
// visual) it stops far from the optimum.
int RefineWeighted(mrpt::graphs::CNetworkOfPoses3DInf& graph, const OptimizerOptions& options) {
  using SE3 = mrpt::poses::Lie::SE<3>;
  std::map<mrpt::graphs::TNodeID, int> index;
  for (const auto& n : graph.nodes)
    if (n.first != graph.root) index.emplace(n.first, static_cast<int>(index.size()));
  if (index.empty() || graph.edges.empty()) return 0;
  const int n = 6 * static_cast<int>(index.size());
  double chi2 = Chi2Impl(graph);
  double lambda = -1.0;
  int iterations = 0;
  bool rebuild = true;
  Eigen::SparseMatrix<double> H(n, n);
  Eigen::VectorXd g(n);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> solver;
  Eigen::VectorXd diagonal(n);
  bool analysed = false;
  for (int iter = 0; iter < options.max_iterations; ++iter) {
    if (rebuild) {
      Linearise(graph, index, options.num_threads, &H, &g);
      diagonal = H.diagonal().cwiseMax(1e-12);
      if (g.lpNorm<Eigen::Infinity>() <= options.gradient_tolerance) break;
      if (lambda < 0) lambda = 1e-5;  // Marquardt: relative to each diagonal entry
      rebuild = false;
    }
    ++iterations;
    Eigen::SparseMatrix<double> A = H;
    A.diagonal() += lambda * diagonal;
    if (!analysed) {
      solver.analyzePattern(A);
      analysed = true;
    }
    solver.factorize(A);
    if (solver.info() != Eigen::Success) {
      lambda *= 10.0;
      continue;
    }
    const Eigen::VectorXd delta = solver.solve(g);
    double x_norm = 0.0;
    for (const auto& [id, i] : index) {
      const auto& p = graph.nodes.at(id);
      x_norm += p.x() * p.x() + p.y() * p.y() + p.z() * p.z();
    }
    if (delta.norm() < options.step_tolerance * (std::sqrt(x_norm) + options.step_tolerance)) break;
    // Backup by value, restored in place: edge_list/node_ptr point into the maps.
    std::vector<typename std::decay_t<decltype(graph.nodes)>::mapped_type> backup;
    backup.reserve(index.size());
    for (const auto& [id, i] : index) backup.push_back(graph.nodes.at(id));
    for (const auto& [id, i] : index) {
      SE3::tangent_vector step;
      for (int k = 0; k < 6; ++k) step[k] = -delta[6 * i + k];
      auto& node = graph.nodes.at(id);
      node = mrpt::poses::CPose3D(node) + SE3::exp(step);
    }
    const double new_chi2 = Chi2Impl(graph);
    if (options.verbose)
      std::printf("[vloc refine] iter %d chi2 %.6f -> %.6f lambda %.3g |delta| %.3g\n", iter, chi2, new_chi2, lambda,
                  delta.norm());
    if (new_chi2 < chi2) {
      const bool converged = chi2 - new_chi2 < options.relative_chi2_tolerance * (1.0 + chi2);
      chi2 = new_chi2;
      lambda = std::max(lambda * 0.1, 1e-12);
      rebuild = true;
      if (converged) break;
    } else {
      size_t k = 0;
      for (const auto& [id, i] : index) graph.nodes.at(id) = backup[k++];
      lambda *= 10.0;
      if (lambda > 1e12) break;
    }
  }
  return iterations;
}

template <int D, class Graph>
PoseGraphProblem<D> ProblemFromGraphImpl(const Graph& graph, std::vector<mrpt::graphs::TNodeID>* ids,
                                         const std::vector<double>* robust) {
  PoseGraphProblem<D> problem;
  std::map<mrpt::graphs::TNodeID, int> index;
  ids->clear();
  problem.poses.reserve(graph.nodes.size());
  for (const auto& [id, node] : graph.nodes) {
    index.emplace(id, static_cast<int>(ids->size()));
    ids->push_back(id);
    typename PoseGraphProblem<D>::Pose p;
    if constexpr (D == 3) {
      p.R = node.getRotationMatrix().asEigen();
      p.t = Eigen::Vector3d(node.x(), node.y(), node.z());
    } else {
      p.R = Eigen::Rotation2Dd(node.phi()).toRotationMatrix();
      p.t = Eigen::Vector2d(node.x(), node.y());
    }
    problem.poses.push_back(p);
    problem.fixed.push_back(id == graph.root ? 1 : 0);
  }
  problem.edges.reserve(graph.edges.size());
  size_t k = 0;
  for (const auto& [key, edge] : graph.edges) {
    const auto a = index.find(key.first), b = index.find(key.second);
    if (a == index.end() || b == index.end())
      throw std::runtime_error("pose graph edge " + std::to_string(key.first) + "->" + std::to_string(key.second) +
                               " refers to a missing node");
    typename PoseGraphProblem<D>::Edge e;
    e.i = a->second;
    e.j = b->second;
    const auto& z = edge.getPoseMean();
    if constexpr (D == 3) {
      e.measurement.R = z.getRotationMatrix().asEigen();
      e.measurement.t = Eigen::Vector3d(z.x(), z.y(), z.z());
    } else {
      e.measurement.R = Eigen::Rotation2Dd(z.phi()).toRotationMatrix();
      e.measurement.t = Eigen::Vector2d(z.x(), z.y());
    }
    e.information = edge.cov_inv.asEigen();
    e.robust = robust && k < robust->size() && (*robust)[k] > 0;
    if (e.robust) e.robust_scale = (*robust)[k];
    problem.edges.push_back(e);
    ++k;
  }
  return problem;
}

template <int D, class Graph>
OptimizerResult OptimizeSparse(Graph& graph, const OptimizerOptions& options, const std::vector<double>* robust,
                               std::map<mrpt::graphs::TNodeID, Matrix6d>* marginals);

}  // namespace

Eigen::Matrix3d InverseRightJacobianSO3(const Eigen::Vector3d& theta) {
  const double phi = theta.norm();
  const Eigen::Matrix3d K = Skew(theta);
  // 1/phi^2 - (1 + cos phi) / (2 phi sin phi), series below 1e-4 rad.
  const double c = phi < 1e-4 ? 1.0 / 12.0 + phi * phi / 720.0
                              : 1.0 / (phi * phi) - (1.0 + std::cos(phi)) / (2.0 * phi * std::sin(phi));
  return Eigen::Matrix3d::Identity() + 0.5 * K + c * K * K;
}

Vector6d EdgeResidualAndJacobians(const mrpt::poses::CPose3D& z, const mrpt::poses::CPose3D& p1,
                                  const mrpt::poses::CPose3D& p2, Matrix6d* J1, Matrix6d* J2) {
  using SE3 = mrpt::poses::Lie::SE<3>;
  // T = Z^-1 P1^-1 P2 = D B, D = Z^-1, B = P1^-1 P2; e = [t_T; Log(R_T)].
  // With P_i <- P_i exp([tau_i; w_i]) (translation uncoupled, MRPT's
  // pseudo-exponential), at zero:
  //   de/d(tau1, w1) = [-R_D, R_D [t_B]x; 0, -Jr^-1(Log R_T) R_B^T]
  //   de/d(tau2, w2) = [R_T, 0; 0, Jr^-1(Log R_T)]
  const mrpt::poses::CPose3D B = p2 - p1;
  const Vector6d e = SE3::log(B - z).asEigen();
  const Eigen::Matrix3d R_B = B.getRotationMatrix().asEigen();
  const Eigen::Matrix3d R_D = z.getRotationMatrix().asEigen().transpose();
  const Eigen::Matrix3d R_T = R_D * R_B;
  const Eigen::Vector3d t_B(B.x(), B.y(), B.z());
  const Eigen::Matrix3d Jr_inv = InverseRightJacobianSO3(e.tail<3>());
  J1->setZero();
  J1->topLeftCorner<3, 3>() = -R_D;
  J1->topRightCorner<3, 3>() = R_D * Skew(t_B);
  J1->bottomRightCorner<3, 3>() = -Jr_inv * R_B.transpose();
  J2->setZero();
  J2->topLeftCorner<3, 3>() = R_T;
  J2->bottomRightCorner<3, 3>() = Jr_inv;
  return e;
}

void Linearise(const mrpt::graphs::CNetworkOfPoses3DInf& graph, const std::map<mrpt::graphs::TNodeID, int>& index,
               int num_threads, Eigen::SparseMatrix<double>* H, Eigen::VectorXd* g) {
  struct Linearised {
    Matrix6d H11, H22, H21;
    Vector6d g1, g2;
    int i1 = -1, i2 = -1;  // unknown index of each node, -1 = fixed (root)
  };
  std::vector<const std::decay_t<decltype(graph.edges)>::value_type*> edges;
  edges.reserve(graph.edges.size());
  for (const auto& entry : graph.edges) {
    if (!graph.nodes.count(entry.first.first) || !graph.nodes.count(entry.first.second))
      throw std::runtime_error("pose graph edge " + std::to_string(entry.first.first) + "->" +
                               std::to_string(entry.first.second) + " refers to a missing node");
    edges.push_back(&entry);
  }
  const int m = static_cast<int>(edges.size());
  std::vector<Linearised> lin(edges.size());
  // Each edge on its own (in parallel), then one serial assembly.
#pragma omp parallel for schedule(static) num_threads(std::max(1, num_threads))
  for (int k = 0; k < m; ++k) {
    const auto& [key, edge] = *edges[static_cast<size_t>(k)];
    const mrpt::poses::CPose3D& p1 = graph.nodes.at(key.first);
    const mrpt::poses::CPose3D& p2 = graph.nodes.at(key.second);
    Matrix6d J1, J2;
    const Vector6d e = EdgeResidualAndJacobians(edge.mean, p1, p2, &J1, &J2);
    const Matrix6d W = edge.cov_inv.asEigen();
    Linearised& l = lin[static_cast<size_t>(k)];
    const Matrix6d WJ1 = W * J1, WJ2 = W * J2;
    l.g1 = WJ1.transpose() * e;
    l.g2 = WJ2.transpose() * e;
    l.H11 = J1.transpose() * WJ1;
    l.H22 = J2.transpose() * WJ2;
    l.H21 = J2.transpose() * WJ1;
    const auto f1 = index.find(key.first), f2 = index.find(key.second);
    l.i1 = f1 != index.end() ? f1->second : -1;
    l.i2 = f2 != index.end() ? f2->second : -1;
  }
  const int n = 6 * static_cast<int>(index.size());
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<size_t>(m) * 78);
  g->setZero(n);
  auto add_block = [&](int a, int b, const Matrix6d& block) {  // a >= b: lower triangle only
    for (int c = 0; c < 6; ++c)
      for (int r = (a == b ? c : 0); r < 6; ++r) triplets.emplace_back(6 * a + r, 6 * b + c, block(r, c));
  };
  for (const Linearised& l : lin) {
    if (l.i1 >= 0) {
      g->segment<6>(6 * l.i1) += l.g1;
      add_block(l.i1, l.i1, l.H11);
    }
    if (l.i2 >= 0) {
      g->segment<6>(6 * l.i2) += l.g2;
      add_block(l.i2, l.i2, l.H22);
    }
    if (l.i1 >= 0 && l.i2 >= 0) {
      if (l.i2 > l.i1) add_block(l.i2, l.i1, l.H21);
      else add_block(l.i1, l.i2, l.H21.transpose());
    }
  }
  H->resize(n, n);
  H->setFromTriplets(triplets.begin(), triplets.end());
}

PoseGraph3 ProblemFromGraph(const mrpt::graphs::CNetworkOfPoses3DInf& graph, std::vector<mrpt::graphs::TNodeID>* ids,
                            const std::vector<double>* robust) {
  return ProblemFromGraphImpl<3>(graph, ids, robust);
}
PoseGraph2 ProblemFromGraph(const mrpt::graphs::CNetworkOfPoses2DInf& graph, std::vector<mrpt::graphs::TNodeID>* ids,
                            const std::vector<double>* robust) {
  return ProblemFromGraphImpl<2>(graph, ids, robust);
}

void PosesToGraph(const PoseGraph3& problem, const std::vector<mrpt::graphs::TNodeID>& ids,
                  mrpt::graphs::CNetworkOfPoses3DInf* graph) {
  for (size_t k = 0; k < ids.size(); ++k) {
    const auto& p = problem.poses[k];
    graph->nodes.at(ids[k]) = ToMrpt(MakePose(p.R, p.t));
  }
}
void PosesToGraph(const PoseGraph2& problem, const std::vector<mrpt::graphs::TNodeID>& ids,
                  mrpt::graphs::CNetworkOfPoses2DInf* graph) {
  for (size_t k = 0; k < ids.size(); ++k) {
    const auto& p = problem.poses[k];
    graph->nodes.at(ids[k]) = mrpt::poses::CPose2D(p.t.x(), p.t.y(), std::atan2(p.R(1, 0), p.R(0, 0)));
  }
}

OptimizerResult OptimizeGraph(mrpt::graphs::CNetworkOfPoses3DInf& graph, const OptimizerOptions& options,
                              const std::vector<double>* robust, std::map<mrpt::graphs::TNodeID, Matrix6d>* marginals) {
  if (options.method == "sparse") return OptimizeSparse<3>(graph, options, robust, marginals);
  OptimizerResult result = OptimizeImpl(graph, options, options.mrpt_max_iterations, options.mrpt_window);
  const auto start = std::chrono::steady_clock::now();
  if (options.verbose) std::printf("[vloc] MRPT stage %.3f s\n", result.seconds);
  result.iterations += RefineWeighted(graph, options);
  result.final_chi2 = Chi2Impl(graph);
  result.seconds += SecondsSince(start);
  return result;
}
OptimizerResult OptimizeGraph(mrpt::graphs::CNetworkOfPoses2DInf& graph, const OptimizerOptions& options,
                              const std::vector<double>* robust) {
  if (options.method == "sparse") return OptimizeSparse<2>(graph, options, robust, nullptr);
  // 2D: MRPT alone (no weighted polish), max_iterations iterations.
  return OptimizeImpl(graph, options, options.max_iterations, 0);
}
double Chi2(const mrpt::graphs::CNetworkOfPoses3DInf& graph) { return Chi2Impl(graph); }
double Chi2(const mrpt::graphs::CNetworkOfPoses2DInf& graph) { return Chi2Impl(graph); }

mrpt::poses::CPose3D ToMrpt(const Pose3& pose) {
  mrpt::math::CMatrixDouble44 m(pose.matrix());
  return mrpt::poses::CPose3D(m);
}

Pose3 FromMrpt(const mrpt::poses::CPose3D& pose) {
  Pose3 out = Pose3::Identity();
  out.linear() = pose.getRotationMatrix().asEigen();
  out.translation() = Eigen::Vector3d(pose.x(), pose.y(), pose.z());
  return out;
}

Matrix6d LocalFromVlocCovariance(const Pose3& a_from_b, const Matrix6d& covariance) {
  const Matrix6d J = RotationBlocks(a_from_b.linear().transpose());
  return J * covariance * J.transpose();
}

Matrix6d VlocFromLocalCovariance(const Pose3& a_from_b, const Matrix6d& covariance) {
  const Matrix6d J = RotationBlocks(a_from_b.linear());
  return J * covariance * J.transpose();
}

OptimizerResult ToOptimizerResult(const SolverSummary& s, double seconds) {
  OptimizerResult r;
  r.iterations = s.iterations;
  r.initial_chi2 = s.initial_cost;
  r.final_chi2 = s.final_cost;
  r.num_downweighted = s.num_downweighted;
  r.marginals_valid = s.marginals_valid;
  r.marginal_seconds = s.marginal_seconds;
  r.seconds = seconds;
  return r;
}

namespace {

template <int D, class Graph>
OptimizerResult OptimizeSparse(Graph& graph, const OptimizerOptions& options, const std::vector<double>* robust,
                               std::map<mrpt::graphs::TNodeID, Matrix6d>* marginals) {
  const Stopwatch watch;
  OptimizerResult result;
  std::vector<mrpt::graphs::TNodeID> ids;
  PoseGraphProblem<D> problem = ProblemFromGraph(graph, &ids, robust);
  if (problem.edges.empty() || problem.poses.size() < 2) {
    result.initial_chi2 = result.final_chi2 = Cost(problem, nullptr);
    if (marginals) marginals->clear();
    result.marginals_valid = problem.poses.size() < 2;
    return result;
  }
  SolverOptions solver = options.solver;
  solver.verbose |= options.verbose;
  std::vector<typename PoseGraphProblem<D>::Information> blocks;
  const SolverSummary s = SolvePoseGraph(&problem, solver, marginals ? &blocks : nullptr);
  if (!s.usable) throw std::runtime_error("pose graph solver: " + s.message);
  PosesToGraph(problem, ids, &graph);
  if constexpr (D == 3) {
    if (marginals) {
      marginals->clear();
      if (s.marginals_valid)
        for (size_t k = 0; k < ids.size(); ++k)
          if (!problem.fixed[k]) (*marginals)[ids[k]] = blocks[k];
    }
  }
  return ToOptimizerResult(s, watch.Seconds());
}

}  // namespace

}  // namespace vloc::posegraph
