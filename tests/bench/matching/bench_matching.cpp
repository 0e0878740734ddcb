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
// - Middlebury 2014 Motorcycle (741 x 500, python3-skimage, sub-pixel
//   truth): the same counters, without the offset.
// - A real Curiosity Navcam pair (../shared/data, no dense truth): terrain
//   and sky coverage, errors at SIFT check points.
// Each pair with the default options, the photograph settings
// (config/stereo_photo.yaml: depth edges) and the JPEG settings
// (config/stereo_jpeg.yaml: compressed images, weak texture); each stage's
// seconds and counts as counters.
//   build/bench/bench_matching --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
// (2 threads for both sides; skips with a message when opencv-doc or python3-skimage is absent)
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

// The stereo pairs: Aloe (integer truth, scored also against truth + 0.25
// px) and Motorcycle (sub-pixel truth).
struct StereoCase {
  vloc::testing::StereoPair pair;
  double truth_offset = 0;  // second scoring against truth + this (0 = none)
  cv::Mat sgbm, vloc;       // the maps of this run
};

StereoCase& Aloe() {
  static StereoCase c = [] {
    StereoCase s;
    s.pair = vloc::testing::LoadAloe();
    s.truth_offset = 0.25;
    return s;
  }();
  return c;
}

StereoCase& Motorcycle() {
  static StereoCase c = [] {
    StereoCase s;
    s.pair = vloc::testing::LoadMotorcycle();
    return s;
  }();
  return c;
}

// Scores `mine` on all its pixels and, with `other` (when computed), on
// the pixels both matched.
void SetStereoCounters(benchmark::State& state, const StereoCase& c, const cv::Mat& mine, const cv::Mat& other) {
  const vloc::testing::DisparityScore all = vloc::testing::ScoreDisparity(mine, c.pair.gt, 1);
  state.counters["coverage"] = all.coverage;
  state.counters["bad1_all"] = all.bad1;
  if (other.empty()) return;
  const cv::Mat both = vloc::testing::BothMatched(mine, other);
  const vloc::testing::DisparityScore s = vloc::testing::ScoreDisparity(mine, c.pair.gt, 1, both);
  state.counters["both_bad1"] = s.bad1;
  state.counters["both_median_px"] = s.median_abs;
  state.counters["both_mean_signed_px"] = s.mean_signed;
  if (c.truth_offset == 0) return;
  // Against the truth + 0.25 px (the centre of Aloe's integer steps, see real_pairs.h).
  const vloc::testing::DisparityScore o = vloc::testing::ScoreDisparity(mine, c.pair.gt, 1, both, c.truth_offset);
  state.counters["both_bad1_gt+0.25"] = o.bad1;
  state.counters["both_median_gt+0.25"] = o.median_abs;
}

// Each stage's seconds and what it kept: the points the ZNCC and median
// tests keep (after_median), those taken from the LSM lattice's planes
// (from_lattice), those dropped without LSM (lsm_dropped; the rest ran
// LSM) and the output (lsm_matches).
void SetStageCounters(benchmark::State& state, const vloc::DenseStereoSummary& s) {
  state.counters["zncc_s"] = s.zncc_seconds;
  state.counters["median_s"] = s.median_seconds;
  state.counters["lsm_s"] = s.lsm_seconds;
  state.counters["after_median"] = static_cast<double>(s.after_median);
  state.counters["from_lattice"] = static_cast<double>(s.lsm_from_lattice);
  state.counters["lsm_dropped"] = static_cast<double>(s.lsm_dropped);
  state.counters["lsm_matches"] = static_cast<double>(s.lsm_matches);
}

void StereoSgbm(benchmark::State& state, StereoCase& c) {
  if (!c.pair.ok) return state.SkipWithError(("missing " + c.pair.missing).c_str());
  cv::setNumThreads(kThreads);
  for (auto _ : state) c.sgbm = vloc::testing::SgbmDisparity(c.pair.left, c.pair.right, c.pair.min_disparity, c.pair.num_disparities);
  SetStereoCounters(state, c, c.sgbm, c.vloc);
}

// testing::StereoOptionsFor every pixel, kThreads threads.
template <typename Pair>
vloc::DenseStereoOptions StereoOptions(const Pair& pair, const char* options_file) {
  vloc::DenseStereoOptions o = vloc::testing::StereoOptionsFor(pair, options_file, 1);
  o.num_threads = kThreads;
  return o;
}

// vloc::DenseStereo with the defaults or, when `options_file` is set, with
// that YAML (config/stereo_photo.yaml, config/stereo_jpeg.yaml).
void StereoVloc(benchmark::State& state, StereoCase& c, const char* options_file) {
  if (!c.pair.ok) return state.SkipWithError(("missing " + c.pair.missing).c_str());
  const vloc::DenseStereoOptions o = StereoOptions(c.pair, options_file);
  vloc::DenseStereoSummary s;
  for (auto _ : state) c.vloc = vloc::DenseStereo(c.pair.left, c.pair.right, o, &s);
  SetStereoCounters(state, c, c.vloc, c.sgbm);
  SetStageCounters(state, s);
}

// Per pair: SGBM first, vloc (scored on both), SGBM again (scored on both).
constexpr const char* kPhoto = "config/stereo_photo.yaml";
constexpr const char* kJpeg = "config/stereo_jpeg.yaml";
BENCHMARK_CAPTURE(StereoSgbm, Aloe_OpenCV_SGBM, Aloe())->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoVloc, Aloe_Vloc, Aloe(), nullptr)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoSgbm, Aloe_OpenCV_SGBM_scored_on_both, Aloe())->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoVloc, Aloe_Vloc_photo, Aloe(), kPhoto)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoSgbm, Aloe_OpenCV_SGBM_scored_on_both_photo, Aloe())->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoVloc, Aloe_Vloc_jpeg, Aloe(), kJpeg)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoSgbm, Aloe_OpenCV_SGBM_scored_on_both_jpeg, Aloe())->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoSgbm, Motorcycle_OpenCV_SGBM, Motorcycle())->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoVloc, Motorcycle_Vloc, Motorcycle(), nullptr)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoSgbm, Motorcycle_OpenCV_SGBM_scored_on_both, Motorcycle())->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoVloc, Motorcycle_Vloc_photo, Motorcycle(), kPhoto)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoSgbm, Motorcycle_OpenCV_SGBM_scored_on_both_photo, Motorcycle())->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoVloc, Motorcycle_Vloc_jpeg, Motorcycle(), kJpeg)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(StereoSgbm, Motorcycle_OpenCV_SGBM_scored_on_both_jpeg, Motorcycle())->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

// A real Curiosity Navcam pair (../shared/data/real/mars_navcam, sol 1431,
// rectified from its SIFT matches; no dense truth): coverage of the terrain,
// share of the sky matched (all wrong) and, on the SIFT check points both
// matched, > 1 px share and median |error| (real_pairs.h).
struct NavcamCase {
  vloc::testing::SparseStereoPair pair = vloc::testing::LoadNavcamPair();
  cv::Mat sgbm, vloc;
};

NavcamCase& Navcam() {
  static NavcamCase c;
  return c;
}

void SetSparseCounters(benchmark::State& state, const NavcamCase& c, const cv::Mat& mine, const cv::Mat& other) {
  const vloc::testing::SparseScore s = vloc::testing::ScoreSparse(mine, c.pair, other);
  state.counters["terrain_coverage"] = s.terrain_coverage;
  state.counters["sky_matched"] = s.sky_matched;
  state.counters["checked"] = static_cast<double>(s.checked);
  state.counters["check_bad1"] = s.bad1;
  state.counters["check_median_px"] = s.median_abs;
}

void NavcamSgbm(benchmark::State& state, NavcamCase& c) {
  if (!c.pair.ok) return state.SkipWithError(("missing " + c.pair.missing).c_str());
  cv::setNumThreads(kThreads);
  for (auto _ : state)
    c.sgbm = vloc::testing::SgbmDisparity(c.pair.left, c.pair.right, c.pair.min_disparity, c.pair.num_disparities);
  SetSparseCounters(state, c, c.sgbm, c.vloc);
}

void NavcamVloc(benchmark::State& state, NavcamCase& c, const char* options_file) {
  if (!c.pair.ok) return state.SkipWithError(("missing " + c.pair.missing).c_str());
  const vloc::DenseStereoOptions o = StereoOptions(c.pair, options_file);
  vloc::DenseStereoSummary summary;
  for (auto _ : state) c.vloc = vloc::DenseStereo(c.pair.left, c.pair.right, o, &summary);
  SetSparseCounters(state, c, c.vloc, c.sgbm);
  SetStageCounters(state, summary);
}

BENCHMARK_CAPTURE(NavcamSgbm, Navcam_OpenCV_SGBM, Navcam())->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(NavcamVloc, Navcam_Vloc, Navcam(), nullptr)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(NavcamSgbm, Navcam_OpenCV_SGBM_checked_on_both, Navcam())->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(NavcamVloc, Navcam_Vloc_photo, Navcam(), kPhoto)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(NavcamSgbm, Navcam_OpenCV_SGBM_checked_on_both_photo, Navcam())->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(NavcamVloc, Navcam_Vloc_jpeg, Navcam(), kJpeg)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK_CAPTURE(NavcamSgbm, Navcam_OpenCV_SGBM_checked_on_both_jpeg, Navcam())->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
