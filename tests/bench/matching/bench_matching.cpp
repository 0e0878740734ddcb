// The matching tools on real photographs with ground truth from Debian's
// opencv-doc, each beside the plain OpenCV approach in the same run:
// - Graffiti 1 -> 3 (a wall about 40 degrees apart, no prior):
//   vloc::MatchHomography against AffineFeature(SIFT) + FLANN + RANSAC;
//   counters: corner error (mean, max, px) against H1to3p.
// - Middlebury Aloe (1282 x 1110, every pixel): vloc::DenseStereo (ZNCC +
//   median + LSM) against cv::StereoSGBM; counters: coverage of the
//   ground-truth pixels, and on the pixels both matched, the fraction of
//   > 1 px errors, median |error|, mean signed error, and the first two
//   against the truth + 0.25 px (its integer steps sit 0.25 px low).
//   build/bench/bench_matching --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
// (2 threads for both sides; skips with a message when opencv-doc is absent)
#include <benchmark/benchmark.h>

#include <iostream>
#include <opencv2/core.hpp>

#include "../../unit/features/real_pairs.h"
#include "vloc/features/dense_stereo.h"
#include "vloc/features/homography_match.h"

namespace {

constexpr int kThreads = 2;

void SetCornerCounters(benchmark::State& state, const cv::Matx33d& h, const vloc::testing::GrafPair& g) {
  double mean, worst;
  vloc::testing::CornerErrors(h, g.b_from_a, g.a.size(), &mean, &worst);
  state.counters["corner_mean_px"] = mean;
  state.counters["corner_max_px"] = worst;
}

void BM_Homography_OpenCV_AffineFeatureFlannRansac(benchmark::State& state) {
  const vloc::testing::GrafPair g = vloc::testing::LoadGraf();
  if (!g.ok) return state.SkipWithError(("missing " + g.missing).c_str());
  cv::setNumThreads(kThreads);
  vloc::testing::PlainAsiftResult r;
  for (auto _ : state) r = vloc::testing::PlainAsiftHomography(g.a, g.b);
  SetCornerCounters(state, r.b_from_a, g);
  state.counters["inliers"] = r.inliers;
}
BENCHMARK(BM_Homography_OpenCV_AffineFeatureFlannRansac)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

void BM_Homography_Vloc(benchmark::State& state) {
  const vloc::testing::GrafPair g = vloc::testing::LoadGraf();
  if (!g.ok) return state.SkipWithError(("missing " + g.missing).c_str());
  cv::setNumThreads(kThreads);
  vloc::HomographyMatchOptions o;
  o.num_threads = kThreads;
  vloc::HomographyMatchResult r;
  for (auto _ : state) r = vloc::MatchHomography(g.a, g.b, o);
  SetCornerCounters(state, r.b_from_a, g);
  state.counters["inliers"] = r.summary.refine_inliers;
  state.counters["refined_rms_px"] = r.summary.rms_px;
}
BENCHMARK(BM_Homography_Vloc)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

const vloc::testing::AloePair& Aloe() {
  static const vloc::testing::AloePair aloe = vloc::testing::LoadAloe();
  return aloe;
}
constexpr int kMinDisparity = 16, kNumDisparities = 224;  // GT spans 40-215 px

cv::Mat& SgbmMap() {
  static cv::Mat map;
  return map;
}
cv::Mat& VlocMap() {
  static cv::Mat map;
  return map;
}

// Scores `mine` on all its pixels and, with `other` (when computed), on
// the pixels both matched.
void SetStereoCounters(benchmark::State& state, const cv::Mat& mine, const cv::Mat& other) {
  const auto& aloe = Aloe();
  const vloc::testing::DisparityScore all = vloc::testing::ScoreDisparity(mine, aloe.gt, 1);
  state.counters["coverage"] = all.coverage;
  state.counters["bad1_all"] = all.bad1;
  if (other.empty()) return;
  const cv::Mat both = vloc::testing::BothMatched(mine, other);
  const vloc::testing::DisparityScore s = vloc::testing::ScoreDisparity(mine, aloe.gt, 1, both);
  state.counters["both_bad1"] = s.bad1;
  state.counters["both_median_px"] = s.median_abs;
  state.counters["both_mean_signed_px"] = s.mean_signed;
  // Against the truth + 0.25 px (the centre of its integer steps, see real_pairs.h).
  const vloc::testing::DisparityScore c = vloc::testing::ScoreDisparity(mine, aloe.gt, 1, both, 0.25);
  state.counters["both_bad1_gt+0.25"] = c.bad1;
  state.counters["both_median_gt+0.25"] = c.median_abs;
}

void BM_Stereo_OpenCV_SGBM(benchmark::State& state) {
  if (!Aloe().ok) return state.SkipWithError(("missing " + Aloe().missing).c_str());
  cv::setNumThreads(kThreads);
  for (auto _ : state) SgbmMap() = vloc::testing::SgbmDisparity(Aloe().left, Aloe().right, kMinDisparity, kNumDisparities);
  SetStereoCounters(state, SgbmMap(), VlocMap());
}

void BM_Stereo_Vloc(benchmark::State& state) {
  if (!Aloe().ok) return state.SkipWithError(("missing " + Aloe().missing).c_str());
  vloc::DenseStereoOptions o;
  o.min_disparity = kMinDisparity;
  o.max_disparity = kMinDisparity + kNumDisparities - 1;
  o.step = 1;
  o.num_threads = kThreads;
  vloc::DenseStereoSummary s;
  for (auto _ : state) VlocMap() = vloc::DenseStereo(Aloe().left, Aloe().right, o, &s);
  SetStereoCounters(state, VlocMap(), SgbmMap());
  state.counters["zncc_s"] = s.zncc_seconds;
  state.counters["lsm_s"] = s.lsm_seconds;
}
// SGBM first, vloc (scored on both), SGBM again (scored on both).
BENCHMARK(BM_Stereo_OpenCV_SGBM)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK(BM_Stereo_Vloc)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK(BM_Stereo_OpenCV_SGBM)->Name("BM_Stereo_OpenCV_SGBM_scored_on_both")->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
