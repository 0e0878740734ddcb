// Rendering one 1024 x 1024 Navcam image of the default terrain (budget:
// <= 1 s on 2 cores). Run:
//   build/bench/bench_sim_render --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cmath>
#include <ctime>
#include <memory>

#include "vloc/common/options.h"
#include "vloc/sim/navcam_renderer.h"
#include "vloc/sim/terrain.h"

namespace {

const vloc::sim::Terrain& DefaultTerrain() {
  static const auto terrain = std::make_unique<vloc::sim::Terrain>(vloc::sim::TerrainOptions{});
  return *terrain;
}

void BM_RenderNavcamImage(benchmark::State& state) {
  const auto model = vloc::LoadOptionsFile<vloc::NavcamModel>(VLOC_SOURCE_DIR "/config/navcam.yaml");
  vloc::sim::NavcamRenderOptions options;
  options.num_threads = 2;
  const vloc::sim::Terrain& terrain = DefaultTerrain();
  const vloc::sim::NavcamRenderer renderer(terrain, model, options);
  const double tilt = static_cast<double>(state.range(0)) * M_PI / 180.0;
  const vloc::Pose3 world_from_body = vloc::MakePose(0, 0, 0, 0, 0, 0);
  const vloc::Pose3 world_from_left = world_from_body * model.mast.BodyFromLeft(0.0, tilt, model.rig);
  uint64_t seed = 1;
  // Process CPU time (all threads): on a busy machine wall time overstates
  // the cost; cpu_s_per_image / 2 is the wall time on 2 idle cores.
  const std::clock_t cpu_start = std::clock();
  for (auto _ : state) {
    auto image = renderer.Render(model.rig.left, world_from_left, seed++);
    benchmark::DoNotOptimize(image.image.data);
  }
  state.counters["cpu_s_per_image"] =
      static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC / static_cast<double>(state.iterations());
  state.counters["pixels_per_s"] = benchmark::Counter(
      static_cast<double>(model.rig.left.width) * model.rig.left.height, benchmark::Counter::kIsIterationInvariantRate);
}
// Argument: mast tilt in degrees (25 = the default panorama tilt).
BENCHMARK(BM_RenderNavcamImage)->Arg(25)->Arg(15)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
