// Pose-graph update cost: a traverse of N sites (DR + visual edges, a revisit
// every 100 sites) already optimised; one update = the next site's DR pose
// and visual edge added, optimised and the marginal covariances of every
// site computed. The update at 1000 sites also carries a revisit edge
// (900 -> 1000): the worst case. Each case runs with vloc's sparse solver
// (mrpt:0, the default: warm start, marginals from its factor) and, as the
// peer in the same run, the optimiser it replaced (mrpt:1: MRPT's LM + the
// weighted polish, marginals by a separate linearisation).
//   bench_posegraph --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <random>

#include "vloc/posegraph/traverse_graph.h"

namespace vloc::posegraph {
namespace {

Matrix6d Diag(double p, double r) {
  Vector6d d;
  d << p * p, p * p, p * p, r * r, r * r, r * r;
  return d.asDiagonal();
}

Pose3 Noisy(const Pose3& pose, double p, double r, std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  const Eigen::Vector3d dt(p * n(rng), p * n(rng), p * n(rng));
  const Eigen::Vector3d dr(r * n(rng), r * n(rng), r * n(rng));
  return MakePose(ExpSO3(dr) * pose.linear(), pose.translation() + dt);
}

struct Scene {
  std::vector<Pose3> truth, dr;
};

Scene MakeScene(int n) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> turn(-0.3, 0.3);
  Scene s;
  s.truth.push_back(Pose3::Identity());
  s.dr.push_back(Pose3::Identity());
  for (int i = 1; i <= n; ++i) {
    const Pose3 motion = MakePose(10, 0, 0, 0, 0, turn(rng));
    s.truth.push_back(s.truth.back() * motion);
    s.dr.push_back(s.dr.back() * Noisy(motion, 0.5, 0.02, rng));
  }
  return s;
}

void AddSite(TraverseGraph& g, const Scene& s, int i, std::mt19937& rng) {
  PoseWithCovariance dr;
  dr.pose = s.dr[i];
  dr.utime = i;
  g.AddDeadReckoning(i, dr);
  if (i == 0) return;
  PoseWithCovariance vis;
  vis.covariance = Diag(0.02, 0.001);
  vis.pose = Noisy(s.truth[i - 1].inverse() * s.truth[i], 0.02, 0.001, rng);
  g.AddRelative(i - 1, i, vis);
  if (i % 100 == 0 && i >= 100) {
    vis.pose = Noisy(s.truth[i - 100].inverse() * s.truth[i], 0.05, 0.002, rng);
    vis.covariance = Diag(0.05, 0.002);
    g.AddRelative(i - 100, i, vis);
  }
}

void BM_GraphUpdate(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const Scene scene = MakeScene(n);
  PoseGraphOptions options;
  options.dr_covariance = "per_metre";
  options.optimizer.verbose = getenv("VLOC_VERBOSE") != nullptr;
  options.optimizer.num_threads = static_cast<int>(state.range(1));
  options.optimizer.solver.num_threads = options.optimizer.num_threads;
  options.optimizer.method = state.range(2) == 0 ? "sparse" : "mrpt";
  TraverseGraph base(options);
  std::mt19937 rng(7);
  for (int i = 0; i < n; ++i) AddSite(base, scene, i, rng);
  for (int k = 0; k < 3; ++k) {
    const auto s0 = base.Optimize();
    if (getenv("VLOC_VERBOSE")) fprintf(stderr, "base: %s\n", s0.BriefReport().c_str());
  }
  PoseGraphSummary last;
  for (auto _ : state) {
    state.PauseTiming();
    TraverseGraph g = base;
    std::mt19937 r(8);
    state.ResumeTiming();
    AddSite(g, scene, n, r);
    last = g.Optimize();
    benchmark::DoNotOptimize(last);
  }
  state.counters["sites"] = last.num_sites;
  state.counters["edges"] = last.num_edges;
  state.counters["iterations"] = last.iterations;
  state.counters["optimize_s"] = last.optimize_seconds;
  state.counters["marginal_s"] = last.marginal_seconds;
}
// Arguments: sites, threads linearising the edges, method (0 = vloc's
// sparse solver, 1 = the former MRPT LM + weighted LM: the peer).
BENCHMARK(BM_GraphUpdate)
    ->Args({100, 1, 0})
    ->Args({100, 1, 1})
    ->Args({1000, 1, 0})
    ->Args({1000, 1, 1})
    ->Args({1000, 2, 0})
    ->ArgNames({"sites", "threads", "mrpt"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace vloc::posegraph

BENCHMARK_MAIN();
