// Texture statistics on images whose answer is known: a flat image, white
// noise (flat spectrum), 1/f noise (power spectrum slope -2), a ramp
// (constant gradient) and texture in one band only. The simulator against
// real Navcam images: tests/procs/sim_rover (ProfilesTextureAgainstReal...).
#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <filesystem>
#include <random>
#include <stdexcept>

#include "vloc/features/texture_stats.h"

namespace vloc {
namespace {

cv::Mat WhiteNoise(int n, double sd, unsigned seed) {
  cv::Mat f(n, n, CV_32F);
  cv::RNG rng(seed);
  rng.fill(f, cv::RNG::NORMAL, 128.0, sd);
  cv::Mat out;
  f.convertTo(out, CV_8U);
  return out;
}

// Noise whose amplitude falls as 1/f: power spectrum slope -2.
cv::Mat PinkNoise(int n, unsigned seed) {
  cv::Mat f(n, n, CV_32F);
  cv::RNG rng(seed);
  rng.fill(f, cv::RNG::NORMAL, 0.0, 1.0);
  cv::Mat spectrum;
  cv::dft(f, spectrum, cv::DFT_COMPLEX_OUTPUT);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const int fy = y <= n / 2 ? y : y - n, fx = x <= n / 2 ? x : x - n;
      const double r = std::hypot(fx, fy);
      spectrum.at<cv::Vec2f>(y, x) *= r > 0 ? static_cast<float>(1.0 / r) : 0.0f;
    }
  cv::Mat back;
  cv::idft(spectrum, back, cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  cv::normalize(back, back, 30, 220, cv::NORM_MINMAX);
  cv::Mat out;
  back.convertTo(out, CV_8U);
  return out;
}

TEST(TextureStats, FlatImageHasNoFeaturesNoGradientNoContrast) {
  const TextureStats s = ComputeTextureStats(cv::Mat(256, 256, CV_8U, cv::Scalar(90)));
  EXPECT_DOUBLE_EQ(s.mean_dn, 90);
  EXPECT_DOUBLE_EQ(s.std_dn, 0);
  for (double d : s.features_per_10kpx) EXPECT_EQ(d, 0);
  EXPECT_EQ(s.gradient_percentiles[2], 0);
  EXPECT_NEAR(s.local_contrast, 0, 1e-3);
}

TEST(TextureStats, SpectrumSlopeOfWhiteAndPinkNoise) {
  const TextureStats white = ComputeTextureStats(WhiteNoise(512, 20, 1));
  EXPECT_NEAR(white.spectrum_slope, 0.0, 0.25) << "white noise: a flat spectrum";
  const TextureStats pink = ComputeTextureStats(PinkNoise(512, 2));
  EXPECT_NEAR(pink.spectrum_slope, -2.0, 0.3) << "1/f amplitude: power slope -2";
}

TEST(TextureStats, RampGradientAndBandedFeatures) {
  cv::Mat ramp(192, 192, CV_8U);
  for (int y = 0; y < ramp.rows; ++y)
    for (int x = 0; x < ramp.cols; ++x) ramp.at<uint8_t>(y, x) = static_cast<uint8_t>(x);  // 1 DN per px
  const TextureStats r = ComputeTextureStats(ramp);
  EXPECT_NEAR(r.gradient_percentiles[0], 1.0, 1e-4);
  // Texture in the bottom third only: features there and nowhere else.
  cv::Mat banded(300, 300, CV_8U, cv::Scalar(128));
  WhiteNoise(300, 40, 3).rowRange(200, 300).copyTo(banded.rowRange(200, 300));
  const TextureStats b = ComputeTextureStats(banded);
  EXPECT_EQ(b.features_per_10kpx[0], 0);
  EXPECT_GT(b.features_per_10kpx[2], 10);
}

TEST(TextureStats, RejectsWhatIsNotAGreyImage) {
  EXPECT_THROW(ComputeTextureStats(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(ComputeTextureStats(cv::Mat(32, 32, CV_8U)), std::invalid_argument);
  EXPECT_THROW(ComputeTextureStats(cv::Mat(128, 128, CV_8UC3)), std::invalid_argument);
}

}  // namespace
}  // namespace vloc
