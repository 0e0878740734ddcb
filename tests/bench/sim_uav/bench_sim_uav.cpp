// Rendering one simulated UAV frame (1280 x 720 BGR, default world) and
// building the default orthomap. Budget: <= 20 ms per frame.
//   build-*/bench/bench_sim_uav --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <memory>
#include <opencv2/core/utility.hpp>

#include "vloc/sim/uav_world.h"

namespace {

const vloc::UavWorld& World() {
  static const auto world = std::make_unique<vloc::UavWorld>(vloc::UavWorldOptions());
  return *world;
}

// Frames spread over the whole default flight (20 m to 80 m, turns, marker).
void BM_RenderFrame(benchmark::State& state) {
  const vloc::UavWorld& world = World();
  int i = 0;
  for (auto _ : state) {
    const double t = world.FrameTime((i * 97) % world.NumFrames());
    cv::Mat frame = world.RenderFrame(t);
    benchmark::DoNotOptimize(frame.data);
    ++i;
  }
}
BENCHMARK(BM_RenderFrame)->Unit(benchmark::kMillisecond);

// The same on one thread: CPU time here is the whole work of a frame.
void BM_RenderFrameOneThread(benchmark::State& state) {
  const vloc::UavWorld& world = World();
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  int i = 0;
  for (auto _ : state) {
    cv::Mat frame = world.RenderFrame(world.FrameTime((i * 97) % world.NumFrames()));
    benchmark::DoNotOptimize(frame.data);
    ++i;
  }
  cv::setNumThreads(threads);
}
BENCHMARK(BM_RenderFrameOneThread)->Unit(benchmark::kMillisecond);

void BM_RenderFrameDistorted(benchmark::State& state) {
  static const auto world = [] {
    vloc::UavWorldOptions options;
    options.camera.k1 = -0.12;
    options.camera.k2 = 0.03;
    return std::make_unique<vloc::UavWorld>(options);
  }();
  int i = 0;
  for (auto _ : state) {
    cv::Mat frame = world->RenderFrame(world->FrameTime((i * 97) % world->NumFrames()));
    benchmark::DoNotOptimize(frame.data);
    ++i;
  }
}
BENCHMARK(BM_RenderFrameDistorted)->Unit(benchmark::kMillisecond);

void BM_BuildDefaultOrthomap(benchmark::State& state) {
  for (auto _ : state) {
    vloc::Orthomap map{vloc::OrthomapOptions()};
    benchmark::DoNotOptimize(map.Level(0).data);
  }
}
BENCHMARK(BM_BuildDefaultOrthomap)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
