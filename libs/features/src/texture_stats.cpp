#include "vloc/features/texture_stats.h"

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "vloc/common/stats.h"

namespace vloc {

namespace {

std::array<double, 3> FeatureDensity(const cv::Mat& gray) {
  std::vector<cv::KeyPoint> keypoints;
  cv::SIFT::create()->detect(gray, keypoints);
  std::array<double, 3> count{};
  for (const auto& k : keypoints) count[std::min(2, static_cast<int>(3 * k.pt.y / gray.rows))] += 1;
  const double band_px = gray.cols * gray.rows / 3.0;
  for (double& c : count) c *= 1e4 / band_px;
  return count;
}

std::array<double, 3> GradientPercentiles(const cv::Mat& gray) {
  cv::Mat gx, gy, magnitude;
  cv::Sobel(gray, gx, CV_32F, 1, 0, 3, 1.0 / 8);
  cv::Sobel(gray, gy, CV_32F, 0, 1, 3, 1.0 / 8);
  cv::magnitude(gx, gy, magnitude);
  std::vector<float> v(magnitude.begin<float>(), magnitude.end<float>());
  return {Quantile(v, 0.5), Quantile(v, 0.9), Quantile(v, 0.99)};
}

double LocalContrast(const cv::Mat& gray) {
  cv::Mat f, mean, mean_sq;
  gray.convertTo(f, CV_32F);
  cv::blur(f, mean, cv::Size(15, 15));
  cv::blur(f.mul(f), mean_sq, cv::Size(15, 15));
  cv::Mat variance = cv::max(mean_sq - mean.mul(mean), 0.0f), sd;
  cv::sqrt(variance, sd);
  std::vector<float> v(sd.begin<float>(), sd.end<float>());
  return Quantile(v, 0.5);
}

// Radially averaged power spectrum of the largest centred square of the
// lower half (Hann window), fitted by a line in log-log between 0.02 and
// 0.25 cycles/px.
double SpectrumSlope(const cv::Mat& gray) {
  const cv::Mat lower = gray.rowRange(gray.rows / 2, gray.rows);
  const int n = std::min(lower.rows, lower.cols) & ~1;
  cv::Mat square;
  lower(cv::Rect((lower.cols - n) / 2, (lower.rows - n) / 2, n, n)).convertTo(square, CV_32F);
  square -= cv::mean(square)[0];
  cv::Mat window;
  cv::createHanningWindow(window, square.size(), CV_32F);
  cv::Mat spectrum;
  cv::dft(square.mul(window), spectrum, cv::DFT_COMPLEX_OUTPUT);
  std::vector<double> power(n / 2, 0.0);
  std::vector<int> count(n / 2, 0);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const int fy = y <= n / 2 ? y : y - n, fx = x <= n / 2 ? x : x - n;
      const int r = static_cast<int>(std::lround(std::hypot(fx, fy)));
      if (r <= 0 || r >= n / 2) continue;
      const cv::Vec2f c = spectrum.at<cv::Vec2f>(y, x);
      power[r] += c[0] * c[0] + c[1] * c[1];
      ++count[r];
    }
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int m = 0;
  for (int r = 1; r < n / 2; ++r) {
    const double f = static_cast<double>(r) / n;
    if (f < 0.02 || f > 0.25 || count[r] == 0 || power[r] <= 0) continue;
    const double lx = std::log(f), ly = std::log(power[r] / count[r]);
    sx += lx, sy += ly, sxx += lx * lx, sxy += lx * ly, ++m;
  }
  const double den = m * sxx - sx * sx;
  return m >= 2 && den > 0 ? (m * sxy - sx * sy) / den : 0.0;
}

}  // namespace

TextureStats ComputeTextureStats(const cv::Mat& gray) {
  if (gray.empty() || gray.type() != CV_8UC1 || gray.rows < 64 || gray.cols < 64)
    throw std::invalid_argument("texture statistics need an 8-bit grey image of at least 64 x 64 px");
  TextureStats s;
  cv::Scalar mean, sd;
  cv::meanStdDev(gray, mean, sd);
  s.mean_dn = mean[0], s.std_dn = sd[0];
  s.features_per_10kpx = FeatureDensity(gray);
  s.gradient_percentiles = GradientPercentiles(gray);
  s.local_contrast = LocalContrast(gray);
  s.spectrum_slope = SpectrumSlope(gray);
  return s;
}

std::string TextureStatsRow(const TextureStats& s) {
  char line[256];
  std::snprintf(line, sizeof line, "%6.1f %6.1f | %6.1f %6.1f %6.1f | %5.2f %5.2f %6.2f | %6.2f | %6.2f", s.mean_dn,
                s.std_dn, s.features_per_10kpx[0], s.features_per_10kpx[1], s.features_per_10kpx[2],
                s.gradient_percentiles[0], s.gradient_percentiles[1], s.gradient_percentiles[2], s.local_contrast,
                s.spectrum_slope);
  return line;
}

}  // namespace vloc
