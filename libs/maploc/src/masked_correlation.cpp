#include "masked_correlation.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

namespace vloc::maploc::internal {

namespace {

cv::Mat NormalisedBlur(const cv::Mat& band, const cv::Mat& mask, double sigma) {
  cv::Mat num, den;
  cv::GaussianBlur(band.mul(mask), num, cv::Size(), sigma, sigma, cv::BORDER_CONSTANT);
  cv::GaussianBlur(mask, den, cv::Size(), sigma, sigma, cv::BORDER_CONSTANT);
  return num / cv::max(den, 1e-3);
}

cv::Mat Correlate(const cv::Mat& image, const cv::Mat& templ) {
  cv::Mat out;
  cv::matchTemplate(image, templ, out, cv::TM_CCORR);
  return out;
}

}  // namespace

cv::Mat MaskedHighPass(const cv::Mat& band, const cv::Mat& mask, double sigma_hp_px, double sigma_lp_px) {
  const cv::Mat low = sigma_lp_px > 0 ? NormalisedBlur(band, mask, sigma_lp_px) : band;
  const cv::Mat trend = NormalisedBlur(low, mask, sigma_hp_px);
  cv::Mat out = low - trend;
  return out.mul(mask);
}

double MaskedStd(const cv::Mat& band, const cv::Mat& mask) {
  const double n = cv::sum(mask)[0];
  if (n < 2) return 0;
  const double mean = cv::sum(band.mul(mask))[0] / n;
  const double second = cv::sum(band.mul(band).mul(mask))[0] / n;
  return std::sqrt(std::max(0.0, second - mean * mean));
}

cv::Mat MaskedZncc(const cv::Mat& image, const cv::Mat& image_valid, const cv::Mat& templ, const cv::Mat& templ_mask,
                   double min_overlap) {
  const double n = cv::sum(templ_mask)[0];
  const double templ_mean = cv::sum(templ.mul(templ_mask))[0] / std::max(n, 1.0);
  const cv::Mat centred = (templ - templ_mean).mul(templ_mask);
  const double templ_energy = cv::sum(centred.mul(centred))[0];
  const cv::Mat known = image.mul(image_valid);
  const cv::Mat num = Correlate(known, centred);
  const cv::Mat sum1 = Correlate(known, templ_mask);
  const cv::Mat sum2 = Correlate(known.mul(known), templ_mask);
  const cv::Mat overlap = Correlate(image_valid, templ_mask);
  cv::Mat score(num.size(), CV_32F, cv::Scalar(-1));
  for (int r = 0; r < num.rows; ++r)
    for (int c = 0; c < num.cols; ++c) {
      const double m = overlap.at<float>(r, c);
      if (n <= 0 || m < min_overlap * n) continue;
      const double s1 = sum1.at<float>(r, c);
      const double var = sum2.at<float>(r, c) - s1 * s1 / m;
      if (!(var > 1e-9 * m) || !(templ_energy > 0)) continue;
      score.at<float>(r, c) = static_cast<float>(num.at<float>(r, c) / std::sqrt(templ_energy * var));
    }
  return score;
}

cv::Mat RotateAbout(const cv::Mat& src, double angle, const cv::Point2d& centre, int interpolation) {
  // Destination pixel p maps to source centre + R(-angle) applied in (x, -row) axes:
  // src_u = c_u + cos a du - sin a dv, src_v = c_v + sin a du + cos a dv.
  const double ca = std::cos(angle), sa = std::sin(angle);
  cv::Matx23d m(ca, -sa, centre.x - ca * centre.x + sa * centre.y,  //
                sa, ca, centre.y - sa * centre.x - ca * centre.y);
  cv::Mat out;
  cv::warpAffine(src, out, m, src.size(), interpolation | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, 0);
  return out;
}

}  // namespace vloc::maploc::internal
