// The public pose-graph benchmarks of ../shared/data/posegraph (see its
// README), each solved from the file's vertices (manhattan: chained
// odometry) with SE-Sync's isotropic weights, SE-Sync's objective F reached
// beside its published certified optimum and SE-Sync's published time, and
// beside two peers on the same input in the same run:
//   - local:  vloc's Levenberg-Marquardt alone (no chordal initialisation);
//   - former: the optimiser this one replaced (MRPT's optimize_graph_spa_levmarq
//             + vloc's weighted LM for 3D, MRPT alone for 2D).
//   bench_posegraph_datasets [--reps N] [--peer-reps N] [--sets a,b,...]
// Times are medians over the repetitions (solve only: the file is read once).
// Skips with a message when the data is absent.

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "vloc/common/command_line.h"
#include "vloc/common/stopwatch.h"
#include "vloc/posegraph/graph_io.h"
#include "vloc/posegraph/mrpt_optimize.h"
#include "vloc/posegraph/sesync_objective.h"

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

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

// The MRPT graph's information replaced by SE-Sync's isotropic weights.
template <int D, class Graph>
void IsotropicGraph(Graph* graph) {
  std::vector<mrpt::graphs::TNodeID> ids;
  PoseGraphProblem<D> problem = ProblemFromGraph(*graph, &ids);
  UseSeSyncWeights(&problem);
  size_t k = 0;
  for (auto& [key, edge] : graph->edges) edge.cov_inv = decltype(edge.cov_inv)(problem.edges[k++].information);
}

struct Run {
  double objective = 0, seconds = 0;
  int iterations = 0;
  bool ok = true;
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
    }
    run.seconds = Median(times);
    return run;
  };
  const Run vloc = solve(true);
  const Run local = solve(false);
  Run former;
  std::vector<double> times;
  for (int r = 0; r < peer_reps; ++r) {
    Graph g = graph;
    IsotropicGraph<D>(&g);
    OptimizerOptions options;
    options.method = "mrpt";
    const Stopwatch watch;
    try {
      const OptimizerResult res = OptimizeGraph(g, options);
      former.iterations = res.iterations;
    } catch (const std::exception& e) {
      former.ok = false;
    }
    times.push_back(watch.Seconds());
    PoseGraphProblem<D> evaluated = original;
    std::vector<mrpt::graphs::TNodeID> unused;
    evaluated.poses = ProblemFromGraph(g, &unused).poses;
    former.objective = SeSyncObjective(evaluated);
  }
  former.seconds = Median(times);
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
  std::printf("%-15s %6zu %6zu | %12.6g %9s %8s | %8.3f s %3d it %6s | %9s | local %12.6g %7.3f s | former %12.6g %7.3f s%s\n",
              set.name, original.poses.size(), original.edges.size(), vloc.objective, published, vloc_gap,
              vloc.seconds, vloc.iterations, ratio, sesync_time, local.objective, local.seconds,
              peer_reps > 0 ? former.objective : 0.0, former.seconds, former.ok ? "" : " (failed)");
  std::fflush(stdout);
}

}  // namespace
}  // namespace vloc::posegraph

int main(int argc, char** argv) {
  using namespace vloc::posegraph;
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv, {"reps", "peer-reps", "sets", "data"}, &error)) {
    std::fprintf(stderr, "%s\nusage: bench_posegraph_datasets [--reps N] [--peer-reps N] [--sets a,b] [--data DIR]\n",
                 error.c_str());
    return 1;
  }
  const std::string dir = args.Get("data", std::string(VLOC_SOURCE_DIR) + "/../shared/data/posegraph");
  if (!std::filesystem::is_directory(dir)) {
    std::printf("bench_posegraph_datasets: %s absent (public pose-graph sets live beside the repo, see "
                "../shared/data/README.md): skipped\n", dir.c_str());
    return 0;
  }
  const int reps = args.GetInt("reps", 5), peer_reps = args.GetInt("peer-reps", 1);
  const std::string sets = args.Get("sets", "");
  std::printf("SE-Sync objective F (isotropic weights; from the file's vertices, manhattan from chained odometry); "
              "times: median of %d (vloc, local) and %d (former) runs, solve only\n", reps, peer_reps);
  std::printf("%-15s %6s %6s | %12s %9s %8s | %10s %5s %6s | %9s | %s\n", "set", "poses", "edges", "vloc F",
              "F*", "gap", "vloc time", "", "/SE-S", "SE-Sync", "peers on the same input: F, time");
  for (const auto& set : kSets) {
    if (!sets.empty() && ("," + sets + ",").find("," + std::string(set.name) + ",") == std::string::npos) continue;
    GraphFile file;
    const std::string path = dir + "/" + set.name + ".g2o";
    if (!ReadGraphFile(path, &file, &error)) {
      std::printf("%-15s %s\n", set.name, error.c_str());
      continue;
    }
    if (!file.repair_report.empty()) std::printf("%-15s note: %s\n", set.name, file.repair_report.c_str());
    if (file.dimension == 2) Bench<2>(set, file.graph2, reps, peer_reps);
    else Bench<3>(set, file.graph3, reps, peer_reps);
  }
  return 0;
}
