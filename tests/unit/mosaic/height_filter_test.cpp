// The height filter: follows a climb without lag, and with GPS fused removes
// a vision-height bias (calibration error) that calibration-only mode keeps.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include <cmath>

#include "vloc/mosaic/height_filter.h"

namespace vloc::mosaic {
namespace {

// 30 s at 30 Hz: 20 m, climbing 2 m/s from t = 5 s to 20 s, then level at 50 m.
double TrueHeight(double t) { return 20.0 + 2.0 * std::clamp(t - 5.0, 0.0, 15.0); }

struct FilterRun {
  double worst_after_settle = 0;  // relative error vs truth for t > 25 s
  double worst_in_climb = 0;      // relative error vs biased truth during the climb
};

FilterRun Simulate(const std::string& gps_use, double bias) {
  HeightFilterOptions o;
  o.gps_use = gps_use;
  HeightFilter f(o);
  cv::RNG rng(7);
  FilterRun run;
  for (int i = 0; i <= 900; ++i) {
    const double t = i / 30.0;
    const int64_t utime = static_cast<int64_t>(t * 1e6);
    const double h = TrueHeight(t);
    if (i % 6 == 0) f.UpdateGps(h + rng.gaussian(0.4), utime);  // 5 Hz, 0.4 m baro noise
    const double vision = h * (1.0 + bias) * (1.0 + rng.gaussian(0.003));
    const double est = i == 0 ? (f.Reset(vision, utime), vision) : f.UpdateVision(vision, utime);
    if (t > 25.0) run.worst_after_settle = std::max(run.worst_after_settle, std::abs(est - h) / h);
    if (t > 8.0 && t < 20.0)
      run.worst_in_climb = std::max(run.worst_in_climb, std::abs(est - h * (1 + bias)) / (h * (1 + bias)));
  }
  return run;
}

TEST(MosaicHeightFilter, FollowsClimbWithoutLag) {
  const FilterRun r = Simulate("calibration", 0.0);
  // 0.3 % per-frame noise; a lagging filter would trail a 2 m/s climb by metres.
  EXPECT_LT(r.worst_in_climb, 0.006);
  EXPECT_LT(r.worst_after_settle, 0.004);
}

TEST(MosaicHeightFilter, FusedGpsRemovesVisionBiasCalibrationOnlyKeepsIt) {
  const FilterRun calibration_only = Simulate("calibration", 0.03);
  const FilterRun fused = Simulate("fused", 0.03);
  EXPECT_GT(calibration_only.worst_after_settle, 0.025);  // the 3 % calibration bias stays
  EXPECT_LT(fused.worst_after_settle, 0.01);              // GPS (0.4 m at 50 m) pulls it out
}

}  // namespace
}  // namespace vloc::mosaic
