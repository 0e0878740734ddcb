// Cross-site BA on one site pair: 200 tie points x 4 observations (7 + 7
// Navcam pairs, 0.3 px noise), intersection + resection + adjustment +
// covariance. Budget: <= 1 s per site pair on 2 cores.
//   bench_ba --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include "vloc/ba/crosssite_ba.h"
#include "vloc/ba/synthetic.h"
#include "vloc/common/options.h"

namespace {

void BM_CrossSiteBa(benchmark::State& state) {
  const vloc::NavcamModel navcam =
      vloc::LoadOptionsFile<vloc::NavcamModel>(std::string(VLOC_SOURCE_DIR) + "/config/navcam.yaml");
  const vloc::Pose3 previous = vloc::MakePose(3.0, -1.0, 0.2, 0.02, -0.01, 0.3);
  const vloc::Pose3 current = previous * vloc::MakePose(10.0, 0.5, 0.1, 0.01, 0.02, 0.05);
  const vloc::Pose3 current_dr = current * vloc::MakePose(0.6, -0.7, 0.1, 0.0, 0.01, 0.05);
  vloc::SyntheticTiePointOptions so;
  so.num_points = static_cast<int>(state.range(0));
  so.outlier_fraction = 0.05;
  const auto syn = vloc::MakeSyntheticTiePoints(navcam, previous, current, current_dr, so);
  vloc::CrossSiteBaOptions options;
  options.num_threads = 2;
  int usable = 0;
  for (auto _ : state) {
    const auto s = vloc::SolveCrossSiteBa(syn.set, navcam, options);
    usable += s.usable;
    benchmark::DoNotOptimize(s.world_from_current.pose);
  }
  state.counters["usable"] = static_cast<double>(usable) / state.iterations();
  state.counters["points"] = static_cast<double>(syn.set.points.size());
}
BENCHMARK(BM_CrossSiteBa)->Arg(200)->Arg(500)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
