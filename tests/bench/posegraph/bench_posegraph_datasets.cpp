// Pose-graph benchmarks: the public sets of ../shared/data/posegraph (see
// its README) and the synthetic 3D sets of synthetic_sets.h (a 5,000-pose
// torus, with isotropic and with not-positive-definite 6 x 6 information, an
// 8,000-pose cube grid, a heavy-noise sphere), each read for SE-Sync's
// objective (its weights from the blocks) and solved from the file's
// vertices (manhattan: chained odometry). vloc's F beside the published
// certified optimum and SE-Sync's published time (for the torus: SE-Sync's
// torus3D of the same size, 0.28 s), and beside peers on the same input in
// the same run:
//   - local:  vloc's Levenberg-Marquardt alone (no chordal initialisation);
//   - ceres:  Ceres (Debian's 2.1) in its pose_graph_2d/3d examples'
//             formulation (quaternion + position with EigenQuaternionManifold,
//             or x y yaw), SPARSE_NORMAL_CHOLESKY on SuiteSparse, 1 thread;
//   - mrpt:   MRPT 2.5's optimize_graph_spa_levmarq (100 iterations), the
//             optimiser vloc no longer uses (see the README).
//   bench_posegraph_datasets [--reps N] [--peer-reps N] [--sets a,b,...] [--write DIR]
// Times are medians over the repetitions (solve only: the file is read once;
// vloc's includes the chordal initialisation), 1 thread. "cert":
// CertifyGlobalOptimum holds at vloc's poses (SE-Sync's verification, not
// timed in the solve; its own time is printed). --write DIR writes the
// synthetic sets as g2o files (for vloc_posegraph) and exits.
// Skips the public sets with a message when the data is absent.

#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <ceres/ceres.h>

#include <Eigen/Geometry>

#include "vloc/common/command_line.h"
#include "vloc/common/stats.h"
#include "vloc/common/stopwatch.h"
#include "vloc/posegraph/graph_io.h"
#include "vloc/posegraph/mrpt_graph.h"
#include "vloc/posegraph/sesync_objective.h"
#include "vloc/posegraph/synthetic_sets.h"

#include <mrpt/graphslam/levmarq.h>

namespace vloc::posegraph {
namespace {

struct Published {
  const char* name;
  double optimum;        // F* (0 = none published in the data README)
  double sesync_seconds; // SE-Sync's time in its paper (0 = none)
};
const Published kSets[] = {{"tinyGrid3D", 0, 0},        {"smallGrid3D", 0, 0},         {"parking-garage", 1.263, 0.47},
                           {"sphere2500", 1.687e3, 0.58}, {"intel", 52.35, 0.07},        {"manhattan", 6.432e3, 0.08},
                           {"city10000", 638.6, 1.58}};
// The synthetic sets: no published optimum; SE-Sync's time on its set of the same size where there is one.
const Published kSynthetic[] = {{"torus", 0, 0.28}, {"torus_indefinite", 0, 0.28}, {"cube", 0, 0}, {"sphere_heavy", 0, 0}};

// The MRPT graph's information replaced by SE-Sync's isotropic weights.
template <int D, class Graph>
void IsotropicGraph(Graph* graph) {
  std::vector<mrpt::graphs::TNodeID> ids;
  PoseGraphProblem<D> problem = ProblemFromGraph(*graph, &ids);
  UseSeSyncWeights(&problem);
  size_t k = 0;
  for (auto& [key, edge] : graph->edges) edge.cov_inv = decltype(edge.cov_inv)(problem.edges[k++].information);
}

// Ceres' pose_graph_3d example residual: [p_ab - p_ab_measured; 2 vec(q_ab_measured q_ab^-1)].
struct Error3d {
  Eigen::Vector3d p;
  Eigen::Quaterniond q;
  Eigen::Matrix<double, 6, 6> sqrt_information;
  template <typename T>
  bool operator()(const T* p_a_ptr, const T* q_a_ptr, const T* p_b_ptr, const T* q_b_ptr, T* residuals_ptr) const {
    Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(p_a_ptr), p_b(p_b_ptr);
    Eigen::Map<const Eigen::Quaternion<T>> q_a(q_a_ptr), q_b(q_b_ptr);
    const Eigen::Quaternion<T> q_a_inverse = q_a.conjugate();
    const Eigen::Quaternion<T> q_ab = q_a_inverse * q_b;
    const Eigen::Matrix<T, 3, 1> p_ab = q_a_inverse * (p_b - p_a);
    const Eigen::Quaternion<T> delta_q = q.template cast<T>() * q_ab.conjugate();
    Eigen::Map<Eigen::Matrix<T, 6, 1>> residuals(residuals_ptr);
    residuals.template head<3>() = p_ab - p.template cast<T>();
    residuals.template tail<3>() = T(2.0) * delta_q.vec();
    residuals.applyOnTheLeft(sqrt_information.template cast<T>());
    return true;
  }
};

// Ceres' pose_graph_2d example residual: [R_a^T (p_b - p_a) - p_ab; wrap(yaw_b - yaw_a - yaw_ab)].
struct Error2d {
  Eigen::Vector2d p;
  double yaw;
  Eigen::Matrix3d sqrt_information;
  template <typename T>
  bool operator()(const T* x_a, const T* y_a, const T* yaw_a, const T* x_b, const T* y_b, const T* yaw_b,
                  T* residuals_ptr) const {
    const T c = ceres::cos(*yaw_a), s = ceres::sin(*yaw_a);
    const T dx = *x_b - *x_a, dy = *y_b - *y_a;
    Eigen::Map<Eigen::Matrix<T, 3, 1>> residuals(residuals_ptr);
    residuals(0) = c * dx + s * dy - T(p.x());
    residuals(1) = -s * dx + c * dy - T(p.y());
    T angle = *yaw_b - *yaw_a - T(yaw);
    const T two_pi(2.0 * M_PI);
    angle = angle - two_pi * ceres::floor((angle + T(M_PI)) / two_pi);
    residuals(2) = angle;
    residuals.applyOnTheLeft(sqrt_information.template cast<T>());
    return true;
  }
};

// Solves `problem` (its weights, poses as the start) with Ceres; returns the
// poses reached and the solve time.
template <int D>
PoseGraphProblem<D> SolveWithCeres(const PoseGraphProblem<D>& problem, double* seconds, bool* ok) {
  ceres::Problem ceres_problem;
  const size_t n = problem.poses.size();
  std::vector<double> parameters(n * 7, 0.0);
  PoseGraphProblem<D> out = problem;
  for (size_t i = 0; i < n; ++i) {
    double* x = &parameters[7 * i];
    if constexpr (D == 3) {
      Eigen::Map<Eigen::Vector3d> position(x);
      Eigen::Map<Eigen::Quaterniond> rotation(x + 3);
      position = problem.poses[i].t;
      rotation = Eigen::Quaterniond(problem.poses[i].R);
    } else {
      x[0] = problem.poses[i].t.x();
      x[1] = problem.poses[i].t.y();
      x[2] = std::atan2(problem.poses[i].R(1, 0), problem.poses[i].R(0, 0));
    }
  }
  for (const auto& edge : problem.edges) {
    double* a = &parameters[7 * static_cast<size_t>(edge.i)];
    double* b = &parameters[7 * static_cast<size_t>(edge.j)];
    // The information of our residual [t; theta]: Ceres' residual has the
    // same first-order meaning (2 vec(dq) ~ theta), so its square root serves.
    const auto sqrt_information = Eigen::LLT<typename PoseGraphProblem<D>::Information>(edge.information)
                                      .matrixL()
                                      .transpose()
                                      .toDenseMatrix();
    if constexpr (D == 3) {
      auto* cost = new ceres::AutoDiffCostFunction<Error3d, 6, 3, 4, 3, 4>(
          new Error3d{edge.measurement.t, Eigen::Quaterniond(edge.measurement.R), sqrt_information});
      ceres_problem.AddResidualBlock(cost, nullptr, a, a + 3, b, b + 3);
    } else {
      auto* cost = new ceres::AutoDiffCostFunction<Error2d, 3, 1, 1, 1, 1, 1, 1>(new Error2d{
          edge.measurement.t, std::atan2(edge.measurement.R(1, 0), edge.measurement.R(0, 0)), sqrt_information});
      ceres_problem.AddResidualBlock(cost, nullptr, a, a + 1, a + 2, b, b + 1, b + 2);
    }
  }
  for (size_t i = 0; i < n; ++i) {
    double* x = &parameters[7 * i];
    if constexpr (D == 3) {
      if (ceres_problem.HasParameterBlock(x + 3)) ceres_problem.SetManifold(x + 3, new ceres::EigenQuaternionManifold);
      if (problem.fixed[i] && ceres_problem.HasParameterBlock(x)) {
        ceres_problem.SetParameterBlockConstant(x);
        ceres_problem.SetParameterBlockConstant(x + 3);
      }
    } else if (problem.fixed[i] && ceres_problem.HasParameterBlock(x)) {
      for (int k = 0; k < 3; ++k) ceres_problem.SetParameterBlockConstant(x + k);
    }
  }
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  options.max_num_iterations = 200;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &ceres_problem, &summary);
  *seconds = summary.total_time_in_seconds;
  *ok = summary.IsSolutionUsable();
  for (size_t i = 0; i < n; ++i) {
    const double* x = &parameters[7 * i];
    if constexpr (D == 3) {
      out.poses[i].t = Eigen::Map<const Eigen::Vector3d>(x);
      out.poses[i].R = Eigen::Map<const Eigen::Quaterniond>(x + 3).normalized().toRotationMatrix();
    } else {
      out.poses[i].t = Eigen::Vector2d(x[0], x[1]);
      out.poses[i].R = Eigen::Rotation2Dd(x[2]).toRotationMatrix();
    }
  }
  return out;
}

struct Run {
  double objective = 0, seconds = 0;
  int iterations = 0;
  bool ok = true;
  bool certified = false;  // CertifyGlobalOptimum at the poses reached (not timed in `seconds`)
  double certificate_seconds = 0;
};

template <int D, class Graph>
void Bench(const Published& set, const Graph& graph, int reps, int peer_reps) {
  std::vector<mrpt::graphs::TNodeID> ids;
  const PoseGraphProblem<D> original = ProblemFromGraph(graph, &ids);
  PoseGraphProblem<D> weighted = original;
  UseSeSyncWeights(&weighted);
  auto solve = [&](bool chordal) {
    SolverOptions options;
    options.chordal_initialisation = chordal;
    options.rotation_residual = "chordal";  // with SE-Sync's weights: exactly its objective
    std::vector<double> times;
    Run run;
    for (int r = 0; r < reps; ++r) {
      PoseGraphProblem<D> p = weighted;
      const SolverSummary s = SolvePoseGraph(&p, options);
      times.push_back(s.total_seconds);
      PoseGraphProblem<D> evaluated = original;
      evaluated.poses = p.poses;
      run.objective = SeSyncObjective(evaluated);
      run.iterations = s.iterations;
      run.ok = s.usable;
      if (r == 0) {
        const OptimalityCertificate c = CertifyGlobalOptimum(evaluated);
        run.certified = c.certified;
        run.certificate_seconds = c.seconds;
      }
    }
    run.seconds = Median(times);
    return run;
  };
  const Run vloc = solve(true);
  const Run local = solve(false);
  Run ceres_run;
  {
    std::vector<double> ceres_times;
    for (int r = 0; r < peer_reps; ++r) {
      double seconds = 0;
      PoseGraphProblem<D> evaluated = original;
      evaluated.poses = SolveWithCeres(weighted, &seconds, &ceres_run.ok).poses;
      ceres_run.objective = SeSyncObjective(evaluated);
      ceres_times.push_back(seconds);
    }
    ceres_run.seconds = Median(ceres_times);
  }
  Run mrpt_run;
  std::vector<double> times;
  for (int r = 0; r < peer_reps; ++r) {
    Graph g = graph;
    IsotropicGraph<D>(&g);
    mrpt::containers::yaml params = mrpt::containers::yaml::Map();
    params["max_iterations"] = static_cast<uint64_t>(100);
    mrpt::graphslam::TResultInfoSpaLevMarq info{};
    const Stopwatch watch;
    try {
      mrpt::graphslam::optimize_graph_spa_levmarq(g, info, nullptr, params);
      mrpt_run.iterations = static_cast<int>(info.num_iters);
    } catch (const std::exception& e) {
      mrpt_run.ok = false;
    }
    times.push_back(watch.Seconds());
    PoseGraphProblem<D> evaluated = original;
    std::vector<mrpt::graphs::TNodeID> unused;
    evaluated.poses = ProblemFromGraph(g, &unused).poses;
    mrpt_run.objective = SeSyncObjective(evaluated);
  }
  mrpt_run.seconds = Median(times);
  auto gap = [&](double f) { return set.optimum > 0 ? 100.0 * (f - set.optimum) / set.optimum : 0.0; };
  char published[64] = "-", sesync_time[64] = "-", vloc_gap[32] = "-", ratio[32] = "-";
  if (set.optimum > 0) {
    std::snprintf(published, sizeof published, "%.4g", set.optimum);
    std::snprintf(vloc_gap, sizeof vloc_gap, "%+.3f%%", gap(vloc.objective));
  }
  if (set.sesync_seconds > 0) {
    std::snprintf(sesync_time, sizeof sesync_time, "%.2f s", set.sesync_seconds);
    std::snprintf(ratio, sizeof ratio, "%.2fx", vloc.seconds / set.sesync_seconds);
  }
  std::printf("%-16s %6zu %6zu | %12.6g %4s (%.2f s) %9s %8s | %8.3f s %3d it %6s | %9s | local %12.6g %7.3f s | ceres %12.6g "
              "%7.3f s%s | mrpt %12.6g %7.3f s%s\n",
              set.name, original.poses.size(), original.edges.size(), vloc.objective, vloc.certified ? "cert" : "NO",
              vloc.certificate_seconds, published, vloc_gap,
              vloc.seconds, vloc.iterations, ratio, sesync_time, local.objective, local.seconds, ceres_run.objective,
              ceres_run.seconds, ceres_run.ok ? "" : " (failed)", mrpt_run.objective, mrpt_run.seconds,
              mrpt_run.ok ? "" : " (failed)");
  std::fflush(stdout);
}

}  // namespace
}  // namespace vloc::posegraph

int main(int argc, char** argv) {
  using namespace vloc::posegraph;
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv, {"reps", "peer-reps", "sets", "data", "write"}, &error)) {
    std::fprintf(stderr, "%s\nusage: bench_posegraph_datasets [--reps N] [--peer-reps N] [--sets a,b] [--data DIR] "
                 "[--write DIR]\n", error.c_str());
    return 1;
  }
  if (args.Has("write")) {
    for (const SyntheticSet& set : StandardSyntheticSets()) {
      const std::string path = args.Get("write") + "/" + set.name + ".g2o";
      if (!vloc::WriteFileAtomically(path, SyntheticG2o(set), &error)) {
        std::fprintf(stderr, "%s\n", error.c_str());
        return 1;
      }
      std::printf("wrote %s\n", path.c_str());
    }
    return 0;
  }
  omp_set_num_threads(1);  // 1 thread: CHOLMOD's and METIS' OpenMP too
  const std::string dir = args.Get("data", std::string(VLOC_SOURCE_DIR) + "/../shared/data/posegraph");
  const int reps = args.GetInt("reps", 5), peer_reps = args.GetInt("peer-reps", 5);
  const std::string sets = args.Get("sets", "");
  auto wanted = [&](const char* name) {
    return sets.empty() || ("," + sets + ",").find("," + std::string(name) + ",") != std::string::npos;
  };
  std::printf("SE-Sync objective F (its weights from the blocks; from the file's vertices, manhattan from chained "
              "odometry); times: median of %d (vloc, local) and %d (ceres, mrpt) runs, solve only, 1 thread\n",
              reps, peer_reps);
  std::printf("%-16s %6s %6s | %12s %4s %8s %9s %8s | %10s %5s %6s | %9s | %s\n", "set", "poses", "edges", "vloc F", "",
              "(cert)", "F*", "gap", "vloc time", "", "/SE-S", "SE-Sync", "peers on the same input: F, time");
  auto run = [&](const Published& set, GraphFile& file) {
    if (!file.repair_report.empty()) std::printf("%-16s note: %s\n", set.name, file.repair_report.c_str());
    if (file.dimension == 2) Bench<2>(set, file.graph2, reps, peer_reps);
    else Bench<3>(set, file.graph3, reps, peer_reps);
  };
  if (!std::filesystem::is_directory(dir)) {
    std::printf("bench_posegraph_datasets: %s absent (public pose-graph sets live beside the repo, see "
                "../shared/data/README.md): public sets skipped\n", dir.c_str());
  } else {
    for (const auto& set : kSets) {
      if (!wanted(set.name)) continue;
      GraphFile file;
      if (!ReadGraphFile(dir + "/" + set.name + ".g2o", &file, &error, InformationUse::kSeSyncBlocks)) {
        std::printf("%-16s %s\n", set.name, error.c_str());
        continue;
      }
      run(set, file);
    }
  }
  for (const Published& set : kSynthetic) {
    if (!wanted(set.name)) continue;
    for (const SyntheticSet& spec : StandardSyntheticSets()) {
      if (spec.name != set.name) continue;
      GraphFile file;
      if (!ParseGraphText(SyntheticG2o(spec), &file, &error, InformationUse::kSeSyncBlocks)) {
        std::printf("%-16s %s\n", set.name, error.c_str());
        continue;
      }
      run(set, file);
    }
  }
  return 0;
}
