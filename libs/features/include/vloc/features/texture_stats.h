#pragma once
// Texture statistics of a grey image, to compare simulated Navcam images
// with real ones: feature density per image band (top / middle / bottom
// third: sky and horizon, far field, near field), the gradient magnitude
// distribution, local contrast, and the slope of the radially averaged power
// spectrum of the lower half (the ground; natural terrain is close to -2 to
// -3, white noise 0).
//
//   const TextureStats s = ComputeTextureStats(cv::imread(path, cv::IMREAD_GRAYSCALE));

#include <array>
#include <opencv2/core.hpp>
#include <string>

namespace vloc {

struct TextureStats {
  double mean_dn = 0, std_dn = 0;                 // whole image
  std::array<double, 3> features_per_10kpx{};     // SIFT keypoints per 10,000 px, top / middle / bottom third
  std::array<double, 3> gradient_percentiles{};   // Sobel magnitude (DN/px, 3x3 kernel / 8) at 50 / 90 / 99 %
  double local_contrast = 0;                      // median standard deviation in 15 x 15 px windows, DN
  double spectrum_slope = 0;                      // d log P / d log f, 0.02-0.25 cycles/px, lower half
};

// `gray`: CV_8UC1, at least 64 x 64. Throws std::invalid_argument otherwise.
TextureStats ComputeTextureStats(const cv::Mat& gray);

// One line: the fields in the order above.
std::string TextureStatsRow(const TextureStats& s);

}  // namespace vloc
