// The whole front end on one simulated site pair (7 + 7 Navcam stereo
// pairs), with 1 and 2 threads, and on the same images the plain approach:
// cv::AffineFeature (SIFT, default tilts) over the whole left images +
// brute-force matching of the overlapping left pairs.
//   VLOC_SIM_CACHE=/tmp/vloc-sim-cache build/bench/bench_frontend --benchmark_repetitions=5 \
//     --benchmark_report_aggregates_only=true
// (run from the source root; the cache folder keeps the rendered images between runs)
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include "../../unit/crosssite/sim_site_pair.h"

namespace {

const vloc::testing::SimSitePair& Scene() {
  static const vloc::testing::SimSitePair scene = vloc::testing::MakeSimSitePair();
  return scene;
}

void BM_Frontend(benchmark::State& state) {
  const auto& s = Scene();
  vloc::FrontendOptions o;
  const int threads = static_cast<int>(state.range(0));
  o.num_threads = threads;
  o.asift.num_threads = threads;
  o.matching.num_threads = threads;
  cv::setNumThreads(threads);
  const vloc::CrossSiteFrontend fe(s.navcam, o);
  int points = 0;
  for (auto _ : state) {
    const auto r = fe.Run(s.previous, s.current);
    points = static_cast<int>(r.tie_points.points.size());
    benchmark::DoNotOptimize(points);
  }
  state.counters["tie_points"] = points;
}
BENCHMARK(BM_Frontend)->Arg(1)->Arg(2)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

void BM_PlainAffineFeature(benchmark::State& state) {
  const auto& s = Scene();
  const int threads = static_cast<int>(state.range(0));
  cv::setNumThreads(threads);
  int matches = 0;
  for (auto _ : state) {
    auto asift = cv::AffineFeature::create(cv::SIFT::create());
    std::vector<std::vector<cv::KeyPoint>> kp(14);
    std::vector<cv::Mat> desc(14);
    for (int k = 0; k < 14; ++k) {
      const cv::Mat& img = k < 7 ? s.previous.pairs[k].left : s.current.pairs[k - 7].left;
      asift->detectAndCompute(img, cv::noArray(), kp[k], desc[k]);
    }
    cv::BFMatcher bf(cv::NORM_L2);
    matches = 0;
    // Overlapping pairs: each current image with the previous images of the same and adjacent pointing.
    for (int i = 0; i < 7; ++i) {
      for (int j = std::max(0, i - 1); j <= std::min(6, i + 1); ++j) {
        std::vector<std::vector<cv::DMatch>> knn;
        bf.knnMatch(desc[7 + i], desc[j], knn, 2);
        for (const auto& m : knn)
          if (m.size() == 2 && m[0].distance < 0.8f * m[1].distance) ++matches;
      }
    }
    benchmark::DoNotOptimize(matches);
  }
  state.counters["matches"] = matches;
}
BENCHMARK(BM_PlainAffineFeature)->Arg(2)->Unit(benchmark::kSecond)->Iterations(1)->Repetitions(1)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
