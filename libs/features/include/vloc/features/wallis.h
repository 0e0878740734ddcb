#pragma once
// Wallis filter (Wan et al. eq. 1; Zhang et al. 1999): a local contrast and
// brightness normalisation that drives every window's mean and standard
// deviation towards target values, for texture enhancement and grey-level
// consistency between the two sites.

#include <opencv2/core.hpp>
#include <string>

namespace vloc {

class OptionsReader;

struct WallisOptions {
  int window = 31;             // px, side of the square window for the local mean/std (odd)
  double target_mean = 127.0;  // grey level, m_f: mean after filtering
  double target_std = 50.0;    // grey level, s_f: standard deviation after filtering
  double contrast = 0.95;      // c in (0, 1]: 1 = full contrast equalisation
  double brightness = 0.9;     // b in [0, 1]: 1 = local mean forced to target_mean
  double min_std = 2.0;        // grey level: local std floor (noise in flat areas is not amplified beyond s_f/min_std)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct ImageStats {
  double mean = 0;  // grey level
  double std = 0;   // grey level
};

// Mean and standard deviation of the pixels where mask != 0 (all pixels
// when mask is empty). `image` is CV_8UC1 or CV_32FC1.
ImageStats ComputeImageStats(const cv::Mat& image, const cv::Mat& mask = cv::Mat());

// Applies g_o = g * r1 + r0 with, per pixel, the window's mean m_g and
// standard deviation s_g:
//   r1 = c s_f / (c s_g + (1 - c) s_f),   r0 = b m_f + (1 - b - r1) m_g.
// (The paper prints r1 = c s_f / (c s_g + s_f / c) and r0 = b m_f +
// (1 + b + r1) m_g; those are typesetting slips of Zhang et al.'s form used
// here, which gives exactly m_f and s_f for c = b = 1.) Input CV_8UC1,
// output CV_8UC1 (saturated).
cv::Mat WallisFilter(const cv::Mat& gray, const WallisOptions& options);

}  // namespace vloc
