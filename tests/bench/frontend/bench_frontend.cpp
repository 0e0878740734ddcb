// The whole front end on one simulated site pair (7 + 7 Navcam stereo
// pairs), with 1 and 2 threads, beside it with SIFT on the zoomed grids (the
// default before session 21), and on the same images the plain approach:
// cv::AffineFeature (SIFT, default tilts) over whole left images +
// brute-force matching, measured on one image pair and added up to the site
// pair (14 images, 21 overlapping image pairs).
// BM_SiftStages: what OpenCV's SIFT spends on one zoomed region, per stage. BM_TemplateNcc: the correlation
// searches of the tile registration and the grid LSM, vloc's and OpenCV's. BM_WindowLsm: the grid LSM's
// window, vloc's LSM and OpenCV's ECC alignment.
//   VLOC_SIM_CACHE=/tmp/vloc-sim-cache build/bench/bench_frontend --benchmark_repetitions=5
//     (add --benchmark_report_aggregates_only=true for medians only)
// (run from the source root; the cache folder keeps the rendered images between runs)
// Time is wall; CPU is the whole process's (all threads), the work done whatever the machine's load. The
// counters give each stage's wall seconds under its FRONTEND_STATUS name. VLOC_TEST_FRONTEND_CONFIG=<yaml> overrides
// options, as in the pair tests (num_threads and the thread counts stay the benchmark's).
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdlib>
#include <map>
#include <string>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "../../unit/crosssite/sim_site_pair.h"
#include "vloc/common/allocator.h"
#include "vloc/features/lsm.h"
#include "vloc/features/template_ncc.h"

namespace {

const vloc::testing::SimSitePair& Scene() {
  static const vloc::testing::SimSitePair scene = vloc::testing::MakeSimSitePair();
  return scene;
}

// The front end with `threads` threads on `s`, the options changed by `adjust` when given; counters: tie points
// and each stage's seconds (FRONTEND_STATUS's names).
void RunFrontend(benchmark::State& state, const vloc::testing::SimSitePair& s, int threads,
                 void (*adjust)(vloc::FrontendOptions*) = nullptr) {
  vloc::FrontendOptions o;
  if (const char* e = std::getenv("VLOC_TEST_FRONTEND_CONFIG")) o = vloc::LoadOptionsFile<vloc::FrontendOptions>(e);
  if (adjust) adjust(&o);
  o.num_threads = threads;
  o.features.asift.num_threads = threads;
  o.overlap_matching.matching.num_threads = threads;
  cv::setNumThreads(threads);
  const vloc::CrossSiteFrontend fe(s.navcam, o);
  int points = 0;
  std::map<std::string, double> stage_seconds;
  for (auto _ : state) {
    const auto r = fe.Run(s.previous, s.current);
    points = static_cast<int>(r.tie_points.points.size());
    benchmark::DoNotOptimize(points);
    stage_seconds.clear();
    for (const vloc::StageReport& st : r.summary.stages) stage_seconds[st.name] += st.seconds;
  }
  state.counters["tie_points"] = points;
  for (const auto& [name, seconds] : stage_seconds) state.counters[name] = seconds;
}

void BM_Frontend(benchmark::State& state) { RunFrontend(state, Scene(), static_cast<int>(state.range(0))); }
BENCHMARK(BM_Frontend)->Arg(1)->Arg(2)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime()->MeasureProcessCPUTime();

// Beside it, SIFT on the zoomed grids themselves (sift_max_zoom 0, 4000 features a view: the default before
// session 21), which cv::SIFT doubles again: 16x a region's pixels at zoom 2 in its first octave.
void SetSiftOnZoomedGrid(vloc::FrontendOptions* o) {
  o->features.sift_max_zoom = 0.0;
  o->features.asift.max_features_per_view = 4000;
}
void BM_FrontendSiftOnZoomedGrid(benchmark::State& state) {
  RunFrontend(state, Scene(), static_cast<int>(state.range(0)), SetSiftOnZoomedGrid);
}
BENCHMARK(BM_FrontendSiftOnZoomedGrid)->Arg(2)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime()
    ->MeasureProcessCPUTime();

// The same pair rendered in each simulator profile (config/procs/sim_rover_<profile>.yaml), 2 threads: the time
// per profile (a pair that fails stops early, at the stage that failed).
void BM_FrontendProfile(benchmark::State& state, const char* profile, void (*adjust)(vloc::FrontendOptions*)) {
  static std::map<std::string, vloc::testing::SimSitePair> scenes;  // rendered once per profile
  if (!scenes.count(profile)) {
    vloc::testing::SimSitePairOptions so;
    so.profile = profile;
    scenes.emplace(profile, vloc::testing::MakeSimSitePair(so));
  }
  RunFrontend(state, scenes.at(profile), 2, adjust);
}
BENCHMARK_CAPTURE(BM_FrontendProfile, hard, "config/procs/sim_rover_hard.yaml", nullptr)
    ->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime()->MeasureProcessCPUTime();
BENCHMARK_CAPTURE(BM_FrontendProfile, hard_sift_on_zoomed_grid, "config/procs/sim_rover_hard.yaml", SetSiftOnZoomedGrid)
    ->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime()->MeasureProcessCPUTime();
BENCHMARK_CAPTURE(BM_FrontendProfile, extreme, "config/procs/sim_rover_extreme.yaml", nullptr)
    ->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime()->MeasureProcessCPUTime();

// What a byte-identical SIFT cannot save (issue 36: the same tie points pin OpenCV's SIFT on the same pixels).
// One previous-site region as the front end saw it with sift_max_zoom 0 (the top 458 rows of pair 1's left image,
// zoomed 2x; the front end's SIFT settings then, one thread), timed as the front end called SIFT (0), without the
// descriptors (1), and with a contrast threshold no extremum passes (2: the Gaussian pyramid, the DoG and the
// extremum scan alone, the floor of any exact reimplementation). Counters: keypoints kept, candidates before the
// 4000 cap.
void BM_SiftStages(benchmark::State& state) {
  vloc::FrontendOptions zoomed_grid;
  SetSiftOnZoomedGrid(&zoomed_grid);
  const vloc::AsiftOptions a = zoomed_grid.features.asift;
  cv::Mat region;
  cv::resize(Scene().previous.pairs[1].left(cv::Rect(0, 0, 1024, 458)), region, cv::Size(), 2.0, 2.0,
             cv::INTER_LINEAR);
  cv::setNumThreads(1);
  const int variant = static_cast<int>(state.range(0));
  const double contrast = variant == 2 ? 1.0 : a.sift_contrast_threshold;
  auto sift = cv::SIFT::create(a.max_features_per_view, a.sift_octave_layers, contrast, a.sift_edge_threshold,
                               a.sift_sigma);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  for (auto _ : state) {
    if (variant == 0) sift->detectAndCompute(region, cv::noArray(), keypoints, descriptors);
    else sift->detect(region, keypoints);
    benchmark::DoNotOptimize(keypoints.data());
  }
  std::vector<cv::KeyPoint> all;
  cv::SIFT::create(0, a.sift_octave_layers, contrast, a.sift_edge_threshold, a.sift_sigma)->detect(region, all);
  state.counters["keypoints"] = static_cast<double>(keypoints.size());
  state.counters["candidates"] = static_cast<double>(all.size());
  state.counters["megapixels"] = region.total() / 1e6;
}
BENCHMARK(BM_SiftStages)->ArgName("detect_compute0_detect1_floor2")->DenseRange(0, 2)->Unit(benchmark::kMillisecond)
    ->Iterations(5)->UseRealTime();

// The front end's two correlation searches, by vloc::MatchTemplateNcc and by cv::matchTemplate (TM_CCOEFF_NORMED,
// its DFTs): a registration tile (48 x 4 reduced px, +-25 px: pass 1 over a DR gate) and an LSM start search on
// the grid (53 x 11 px, +-4 px), on pair 1's left image. Time per search.
void BM_TemplateNcc(benchmark::State& state, bool opencv, cv::Size templ, int radius) {
  cv::Mat image;
  Scene().previous.pairs[1].left(cv::Rect(300, 500, 400, 200)).convertTo(image, CV_32F);
  const cv::Rect search(100, 50, templ.width + 2 * radius, templ.height + 2 * radius);
  const cv::Rect tile(search.x + radius + 3, search.y + radius - 2, templ.width, templ.height);
  cv::setNumThreads(1);
  cv::Mat score;
  for (auto _ : state) {
    if (opencv) cv::matchTemplate(image(search), image(tile), score, cv::TM_CCOEFF_NORMED);
    else vloc::MatchTemplateNcc(image(search), image(tile), &score);
    benchmark::DoNotOptimize(score.data);
  }
  state.counters["positions"] = static_cast<double>(score.total());
}
BENCHMARK_CAPTURE(BM_TemplateNcc, tile_vloc, false, cv::Size(48, 4), 25)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_TemplateNcc, tile_opencv, true, cv::Size(48, 4), 25)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_TemplateNcc, tile_pass2_vloc, false, cv::Size(48, 4), 3)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_TemplateNcc, tile_pass2_opencv, true, cv::Size(48, 4), 3)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_TemplateNcc, grid_start_vloc, false, cv::Size(53, 11), 4)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_TemplateNcc, grid_start_opencv, true, cv::Size(53, 11), 4)->Unit(benchmark::kMicrosecond);

// The grid LSM's window (53 x 11 px, affine, B-spline resampling) fitted from 0.6 px off on pair 1's left image
// and its copy sheared by 3 % and moved by (2.3, 1.7) px, by vloc::LeastSquaresMatch and by OpenCV's affine
// alignment of the same window (cv::findTransformECC, MOTION_AFFINE, 50 iterations or 1e-4): time per window.
void BM_WindowLsm(benchmark::State& state, bool opencv) {
  cv::Mat image;
  Scene().previous.pairs[1].left(cv::Rect(300, 500, 400, 200)).convertTo(image, CV_32F);
  const cv::Matx23d A(1.03, 0.03, 2.3, -0.02, 0.99, 1.7);
  cv::Mat warped;
  cv::warpAffine(image, warped, A, image.size(), cv::INTER_CUBIC);
  const vloc::LsmImage a = vloc::MakeLsmImage(image, true), b = vloc::MakeLsmImage(warped, true);
  vloc::LsmOptions o;
  o.half_window = 26, o.half_height = 5, o.estimate_affine = true, o.bspline = true;
  const Eigen::Vector2d p(200, 100);
  const Eigen::Vector2d q(A(0, 0) * p.x() + A(0, 1) * p.y() + A(0, 2) + 0.6,
                          A(1, 0) * p.x() + A(1, 1) * p.y() + A(1, 2) - 0.4);
  const cv::Rect templ(static_cast<int>(p.x()) - o.half_window, static_cast<int>(p.y()) - o.half_height,
                       2 * o.half_window + 1, 2 * o.half_height + 1);
  cv::setNumThreads(1);
  int iterations = 0;
  double correlation = 0;
  for (auto _ : state) {
    if (opencv) {
      // The warp maps template px to `warped` px, started as vloc is (identity shape at the start point).
      cv::Mat_<float> warp = (cv::Mat_<float>(2, 3) << 1, 0, q.x() - p.x(), 0, 1, q.y() - p.y());
      warp(0, 2) += templ.x, warp(1, 2) += templ.y;
      correlation = cv::findTransformECC(image(templ), warped, warp, cv::MOTION_AFFINE,
                                         cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-4),
                                         cv::noArray(), 1);
      benchmark::DoNotOptimize(warp.data);
    } else {
      const vloc::LsmResult r = vloc::LeastSquaresMatch(a, p, b, q, Eigen::Matrix2d::Identity(), o);
      iterations = r.iterations, correlation = r.correlation;
      benchmark::DoNotOptimize(r.target);
    }
  }
  state.counters["correlation"] = correlation;
  if (!opencv) state.counters["iterations"] = iterations;
}
BENCHMARK_CAPTURE(BM_WindowLsm, vloc, false)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_WindowLsm, opencv_ecc, true)->Unit(benchmark::kMicrosecond);

// The plain approach on one previous and one current image (the full pair
// has 14 images and 21 overlapping image pairs: at this machine's speed it
// runs for tens of minutes). The counters give the measured per-image
// detection and per-pair matching times and the whole-pair time they add
// up to (14 detections + 21 matchings).
void BM_PlainAffineFeature(benchmark::State& state) {
  const auto& s = Scene();
  const int threads = static_cast<int>(state.range(0));
  cv::setNumThreads(threads);
  int matches = 0;
  double detect_s = 0, match_s = 0;
  for (auto _ : state) {
    auto asift = cv::AffineFeature::create(cv::SIFT::create());
    std::vector<cv::KeyPoint> kp[2];
    cv::Mat desc[2];
    const auto t0 = std::chrono::steady_clock::now();
    asift->detectAndCompute(s.previous.pairs[3].left, cv::noArray(), kp[0], desc[0]);
    asift->detectAndCompute(s.current.pairs[3].left, cv::noArray(), kp[1], desc[1]);
    const auto t1 = std::chrono::steady_clock::now();
    cv::BFMatcher bf(cv::NORM_L2);
    std::vector<std::vector<cv::DMatch>> knn;
    bf.knnMatch(desc[1], desc[0], knn, 2);
    const auto t2 = std::chrono::steady_clock::now();
    matches = 0;
    for (const auto& m : knn)
      if (m.size() == 2 && m[0].distance < 0.8f * m[1].distance) ++matches;
    detect_s = std::chrono::duration<double>(t1 - t0).count() / 2;
    match_s = std::chrono::duration<double>(t2 - t1).count();
    benchmark::DoNotOptimize(matches);
  }
  state.counters["matches"] = matches;
  state.counters["detect_s_per_image"] = detect_s;
  state.counters["match_s_per_image_pair"] = match_s;
  state.counters["site_pair_s"] = 14 * detect_s + 21 * match_s;
}
BENCHMARK(BM_PlainAffineFeature)->Arg(2)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace

// The allocator set up as feature_frontend's main sets it.
int main(int argc, char** argv) {
  vloc::KeepLargeBlocksForReuse();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
