// The altitude tags fused with the vision heights (altitude_fusion.h), on a
// generated flight: a true height that climbs and oscillates, vision heights
// with a drifting bias and frame noise, altitude tags with GPS noise above
// an unknown ground level. Seeds fixed; thresholds from the noise.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "vloc/common/options.h"
#include "vloc/mosaic/altitude_fusion.h"

namespace vloc::mosaic {
namespace {

struct Flight {
  std::vector<double> seconds, truth, vision, altitude;
};

// 160 photos 2.5 s apart at 60-70 m; vision: 3 % frame noise and a bias
// drifting 0.4 %/sqrt(s) (6 % over the flight); tags: ground + truth + noise.
Flight MakeFlight(double ground_m, double altitude_sigma_m, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  Flight f;
  double bias = 0;
  for (int i = 0; i < 160; ++i) {
    const double t = 2.5 * i;
    const double h = 65 + 0.02 * t + 3 * std::sin(t / 15);
    bias += 0.004 * std::sqrt(2.5) * n01(rng);
    f.seconds.push_back(t);
    f.truth.push_back(h);
    f.vision.push_back(h * std::exp(bias + 0.03 * n01(rng)));
    f.altitude.push_back(ground_m + h + altitude_sigma_m * n01(rng));
  }
  // On the GPS track's scale, as the survey runner puts them: no mean bias left.
  double log_bias = 0;
  for (size_t i = 0; i < f.vision.size(); ++i) log_bias += std::log(f.vision[i] / f.truth[i]) / f.vision.size();
  for (double& v : f.vision) v *= std::exp(-log_bias);
  return f;
}

double RmsPercent(const std::vector<double>& h, const std::vector<double>& truth) {
  double sum = 0;
  int n = 0;
  for (size_t i = 0; i < h.size(); ++i)
    if (std::isfinite(h[i])) sum += std::pow(h[i] / truth[i] - 1, 2), ++n;
  return 100 * std::sqrt(sum / n);
}

AltitudeFusionOptions StillsOptions() {
  AltitudeFusionOptions o;  // as config/procs/uav_mosaic_files.yaml
  o.filter.vision_sigma = 0.03;
  o.filter.bias_drift = 0.004;
  return o;
}

TEST(AltitudeFusion, GpsAltitudeAboveUnknownGroundHoldsTheVisionDrift) {
  const Flight f = MakeFlight(/*ground_m=*/218, /*altitude_sigma_m=*/3, 7);
  const AltitudeFusion r = FuseAltitude(f.seconds, f.vision, f.altitude, /*relative=*/false, StillsOptions());
  ASSERT_TRUE(r.fused) << r.why;
  EXPECT_EQ(r.pairs, 160);
  // The ground is the median of altitude - vision: off by the vision bias (~6 % of 70 m) at most.
  EXPECT_NEAR(r.ground_m, 218, 0.1 * 70);
  const double vision = RmsPercent(f.vision, f.truth), fused = RmsPercent(r.height_m, f.truth);
  std::cout << "vision only " << vision << " %, fused " << fused << " % (" << r.why << ")\n";
  // Tags of 3 m (4.6 %) and vision of 3 % with drift: fused clearly below both.
  EXPECT_LT(fused, 0.75 * vision);
  EXPECT_LT(fused, 0.75 * 100 * 3.0 / 65);
  for (HeightSource s : r.source) EXPECT_EQ(s, HeightSource::kFused);
  EXPECT_NE(r.why.find("fused with the GPS altitude"), std::string::npos) << r.why;
}

TEST(AltitudeFusion, RelativeAltitudeIsHeightAboveTakeOff) {
  Flight f = MakeFlight(/*ground_m=*/0, /*altitude_sigma_m=*/0.5, 11);
  f.vision[40] = std::nan("");  // a frame not registered: its height from the tag alone
  const AltitudeFusion r = FuseAltitude(f.seconds, f.vision, f.altitude, /*relative=*/true, StillsOptions());
  ASSERT_TRUE(r.fused) << r.why;
  EXPECT_EQ(r.ground_m, 0);
  EXPECT_EQ(r.source[40], HeightSource::kAltitude);
  EXPECT_TRUE(std::isfinite(r.height_m[40]));
  // Barometric 0.5 m tags: the fused heights are within ~1 % (3 sigma of the tag).
  EXPECT_LT(RmsPercent(r.height_m, f.truth), 100 * 3 * 0.5 / 65);
}

TEST(AltitudeFusion, TagsThatDisagreeWithTheVisionAreNotFusedAndSaySo) {
  // A camera GPS whose altitude climbs 113 m while the photos keep their scale (uav_caliterra).
  Flight f = MakeFlight(317, 3, 13);
  for (size_t i = 0; i < f.altitude.size(); ++i) f.altitude[i] += 113.0 * i / f.altitude.size();
  const AltitudeFusion r = FuseAltitude(f.seconds, f.vision, f.altitude, false, StillsOptions());
  EXPECT_FALSE(r.fused);
  EXPECT_GT(r.normalised_rms, 3);
  EXPECT_NE(r.why.find("disagrees"), std::string::npos) << r.why;
  for (size_t i = 0; i < f.vision.size(); ++i) {
    EXPECT_EQ(r.height_m[i], f.vision[i]);  // the vision heights, untouched
    EXPECT_EQ(r.source[i], HeightSource::kVision);
  }
}

TEST(AltitudeFusion, NoTagsOrTooFewVisionOnly) {
  Flight f = MakeFlight(0, 0.5, 17);
  std::vector<double> none(f.altitude.size(), std::nan(""));
  const AltitudeFusion r = FuseAltitude(f.seconds, f.vision, none, true, StillsOptions());
  EXPECT_FALSE(r.fused);
  EXPECT_NE(r.why.find("0 frames carry both"), std::string::npos) << r.why;
  AltitudeFusionOptions off = StillsOptions();
  off.enabled = false;
  EXPECT_FALSE(FuseAltitude(f.seconds, f.vision, f.altitude, true, off).fused);
}

TEST(AltitudeFusion, OptionsChecked) {
  AltitudeFusionOptions o;
  std::string error;
  EXPECT_TRUE(o.Check(&error)) << error;
  o.gps_altitude_sigma = std::nan("");
  EXPECT_FALSE(o.Check(&error));
  EXPECT_NE(error.find("gps_altitude_sigma"), std::string::npos);
  o = AltitudeFusionOptions();
  o.filter.vision_sigma = -1;
  EXPECT_FALSE(o.Check(&error));
  EXPECT_EQ(error, "filter.vision_sigma = -1: must be > 0");
}

}  // namespace
}  // namespace vloc::mosaic
