// Pose-graph update cost: a traverse of N sites (DR + visual edges, a revisit
// every 100 sites) already optimised; one update = the next site's DR pose
// and visual edge added, optimised and the marginal covariances of every
// site computed. The update at 1000 sites also carries a revisit edge
// (900 -> 1000): the worst case. Each case runs with vloc's sparse solver
// (mrpt:0: warm start, marginals from its factor) and, as the peer in the
// same run on the same graph, MRPT 2.5's optimize_graph_spa_levmarq (mrpt:1,
// 100 iterations at most, no marginals: the optimiser vloc no longer uses).
//   bench_posegraph --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
// And, not a benchmark: `bench_posegraph --reference` prints every site's pose
// and sigmas after every update of a deterministic traverse (300 sites 10 m
// apart, DR 5 %, a visual edge on most pairs, a revisit every 50 sites,
// three false loops, two absolute fixes, one waiting for its site), 17
// significant digits: two builds' outputs compared say whether a change to
// the optimiser changed what traverse_graph publishes.
#include <benchmark/benchmark.h>

#include <mrpt/graphslam/levmarq.h>
#include <cstdio>
#include <cstring>
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
  options.solver.verbose = getenv("VLOC_VERBOSE") != nullptr;
  options.solver.num_threads = static_cast<int>(state.range(1));
  const bool mrpt_peer = state.range(2) != 0;
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
    if (mrpt_peer) {
      state.PauseTiming();
      mrpt::graphs::CNetworkOfPoses3DInf graph = g.graph();
      mrpt::containers::yaml params = mrpt::containers::yaml::Map();
      params["max_iterations"] = static_cast<uint64_t>(100);
      mrpt::graphslam::TResultInfoSpaLevMarq info{};
      state.ResumeTiming();
      mrpt::graphslam::optimize_graph_spa_levmarq(graph, info, nullptr, params);
      last.iterations = static_cast<int>(info.num_iters);
      last.num_sites = static_cast<int>(graph.nodes.size());
      last.num_edges = static_cast<int>(graph.edges.size());
    } else {
      last = g.Optimize();
    }
    benchmark::DoNotOptimize(last);
  }
  state.counters["sites"] = last.num_sites;
  state.counters["edges"] = last.num_edges;
  state.counters["iterations"] = last.iterations;
  state.counters["optimize_s"] = last.optimize_seconds;
  state.counters["marginal_s"] = last.marginal_seconds;
}
// Arguments: sites, threads linearising the edges, optimiser (0 = vloc's
// sparse solver, 1 = MRPT's optimize_graph_spa_levmarq: the peer).
BENCHMARK(BM_GraphUpdate)
    ->Args({100, 1, 0})
    ->Args({100, 1, 1})
    ->Args({1000, 1, 0})
    ->Args({1000, 1, 1})
    ->Args({1000, 2, 0})
    ->ArgNames({"sites", "threads", "mrpt"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void Print(int update, const TraverseGraph& g, const PoseGraphSummary& s) {
  std::printf("update %d %s chi2 %.17g\n", update, s.usable ? "usable" : "NOT", s.final_chi2);
  for (const SiteEstimate& e : g.Sites()) {
    const Eigen::Vector3d t = e.world_from_body.pose.translation();
    const Eigen::Quaterniond q(e.world_from_body.pose.linear());
    std::printf("%d %d %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.9g %.9g\n", update, e.site_id, t.x(), t.y(), t.z(),
                q.w(), q.x(), q.y(), q.z(), std::sqrt(e.world_from_body.covariance(0, 0)),
                std::sqrt(e.world_from_body.covariance(5, 5)));
  }
}

int PrintReferenceTraverse() {
  const int n = 300;
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> turn(-0.3, 0.3);
  std::vector<Pose3> truth{Pose3::Identity()}, dr{Pose3::Identity()};
  for (int i = 1; i <= n; ++i) {
    const Pose3 motion = MakePose(10, 0, 0, 0, 0, turn(rng));
    truth.push_back(truth.back() * motion);
    dr.push_back(dr.back() * Noisy(motion, 0.5, 0.02, rng));
  }
  PoseGraphOptions options;
  options.dr_covariance = "per_metre";
  TraverseGraph g(options);
  int update = 0;
  PoseWithCovariance fix;
  fix.covariance = Diag(0.5, 3.0);
  fix.pose = truth[120];
  g.AddAbsoluteFix(120, fix);  // waits for its site
  for (int i = 0; i <= n; ++i) {
    PoseWithCovariance m;
    m.pose = dr[i];
    m.utime = i;
    g.AddDeadReckoning(i, m);
    Print(update++, g, g.Optimize());
    if (i == 0) continue;
    if (i % 7 != 3) {
      m.covariance = Diag(0.02, 0.001);
      m.pose = Noisy(truth[i - 1].inverse() * truth[i], 0.02, 0.001, rng);
      g.AddRelative(i - 1, i, m);
    }
    if (i % 50 == 0 && i >= 50) {
      m.covariance = Diag(0.05, 0.002);
      m.pose = Noisy(truth[i - 50].inverse() * truth[i], 0.05, 0.002, rng);
      g.AddRelative(i - 50, i, m);
    }
    if (i == 77 || i == 160 || i == 255) {  // false loops: the place 30 sites back, said to be 20 m off
      m.covariance = Diag(0.05, 0.002);
      m.pose = MakePose(20, 5, 0, 0, 0, 0.5);
      g.AddRelative(i - 30, i, m);
    }
    if (i == 200) {
      fix.pose = Noisy(truth[i], 0.3, 0.001, rng);
      g.AddAbsoluteFix(i, fix);
    }
    Print(update++, g, g.Optimize());
  }
  return 0;
}

}  // namespace
}  // namespace vloc::posegraph

int main(int argc, char** argv) {
  if (argc == 2 && std::strcmp(argv[1], "--reference") == 0) return vloc::posegraph::PrintReferenceTraverse();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
