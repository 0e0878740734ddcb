#include "vloc/features/stereo_pair_check.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "vloc/common/options.h"

namespace vloc {

void StereoPairCheckOptions::Visit(OptionsReader& r) {
  r.Optional("max_features", &max_features, "SIFT keypoints per image", AtLeast(10));
  r.Optional("ratio", &ratio, "Lowe's ratio test", InLeftOpen(0, 1));
  r.Optional("ransac_px", &ransac_px, "px, fundamental-matrix RANSAC threshold", Positive());
  r.Optional("min_matches", &min_matches, "fewer inliers: no verdict", AtLeast(8));
  r.Optional("max_median_dy_px", &max_median_dy_px, "px, largest median row difference of a rectified pair, offset removed",
             Positive());
  r.Optional("max_row_offset_px", &max_row_offset_px, "px, largest common row offset absorbed", NonNegative());
  r.Optional("range_percentile", &range_percentile, "%, disparity range from this percentile to 100 minus it",
             InRightOpen(0, 50));
  r.Optional("range_margin_px", &range_margin_px, "px, margin added to both ends of the range", NonNegative());
}

bool StereoPairCheckOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

namespace {

// The order statistic at rank round(pct / 100 (n - 1)), n > 0. Not
// vloc::Quantile (rank floor(q n)): at the tails of the disparities the two
// ranks are one apart, and on Aloe that one is a false match 61 px below
// zero (four such lie along the epipolar lines), which would widen the
// range and ask for a shift the pair does not need.
double Percentile(std::vector<double> v, double pct) {
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(pct / 100.0 * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

}  // namespace

StereoMatches MatchStereoPair(const cv::Mat& left, const cv::Mat& right, const StereoPairCheckOptions& o) {
  StereoMatches out;
  auto sift = cv::SIFT::create(o.max_features);
  std::vector<cv::KeyPoint> kl, kr;
  cv::Mat dl, dr;
  sift->detectAndCompute(left, cv::noArray(), kl, dl);
  sift->detectAndCompute(right, cv::noArray(), kr, dr);
  if (kl.size() < 2 || kr.size() < 2) return out;
  std::vector<std::vector<cv::DMatch>> knn;
  cv::BFMatcher().knnMatch(dl, dr, knn, 2);
  std::vector<cv::Point2f> pl, pr;
  for (const auto& m : knn)
    if (m.size() == 2 && m[0].distance < o.ratio * m[1].distance) {
      pl.push_back(kl[m[0].queryIdx].pt);
      pr.push_back(kr[m[0].trainIdx].pt);
    }
  if (static_cast<int>(pl.size()) < o.min_matches) return out;
  std::vector<uchar> inlier;
  out.fundamental = cv::findFundamentalMat(pl, pr, cv::FM_RANSAC, o.ransac_px, 0.999, inlier);
  for (size_t k = 0; !out.fundamental.empty() && k < inlier.size(); ++k)
    if (inlier[k]) out.left.push_back(pl[k]), out.right.push_back(pr[k]);
  return out;
}

StereoPairCheck CheckStereoPair(const cv::Mat& left, const cv::Mat& right, const StereoPairCheckOptions& o) {
  std::string error;
  if (!o.Check(&error)) throw std::invalid_argument(error);
  if (left.type() != CV_8UC1 || right.type() != CV_8UC1 || left.size() != right.size() || left.empty())
    throw std::invalid_argument("CheckStereoPair needs two 8-bit grey images of the same size");
  StereoPairCheck c;
  const StereoMatches m = MatchStereoPair(left, right, o);
  std::vector<double> dy, dx, signed_dy;
  for (size_t k = 0; k < m.left.size(); ++k) {
    dy.push_back(std::abs(m.left[k].y - m.right[k].y)), dx.push_back(m.left[k].x - m.right[k].x);
    signed_dy.push_back(m.right[k].y - m.left[k].y);
  }
  c.matches = static_cast<int>(dy.size());
  std::ostringstream msg;
  if (c.matches < o.min_matches) {
    msg << "only " << c.matches << " consistent feature matches (need " << o.min_matches
        << "): cannot tell whether the pair is rectified (texture? the same scene?)";
    c.message = msg.str();
    return c;
  }
  c.usable = true;
  c.median_abs_dy_px = Percentile(dy, 50);
  c.p90_abs_dy_px = Percentile(dy, 90);
  c.row_offset_px = Percentile(signed_dy, 50);
  std::vector<double> residual;
  for (double d : signed_dy) residual.push_back(std::abs(d - c.row_offset_px));
  c.median_residual_dy_px = Percentile(residual, 50);
  c.p90_residual_dy_px = Percentile(residual, 90);
  const bool on_rows = c.median_residual_dy_px <= o.max_median_dy_px;
  const bool small_offset = std::abs(c.row_offset_px) <= o.max_row_offset_px;
  c.rectified = on_rows && small_offset;
  const double low = Percentile(dx, o.range_percentile);
  c.min_disparity = std::max(0.0, std::floor(low - o.range_margin_px));
  c.max_disparity = std::max(c.min_disparity + 1, std::ceil(Percentile(dx, 100 - o.range_percentile) + o.range_margin_px));
  msg.precision(3);
  if (c.rectified) {
    msg << "rectified: " << c.matches << " feature matches on their rows (median |dy| " << c.median_abs_dy_px
        << " px";
    if (std::abs(c.row_offset_px) >= 0.01)
      msg << "; a common row offset of " << c.row_offset_px << " px, absorbed: median |dy| " << c.median_residual_dy_px
          << " px without it";
    msg << "), disparities " << c.min_disparity << ".." << c.max_disparity << " px with the margin";
    if (low < 0)
      msg << "; but " << o.range_percentile << " % of them are below " << low
          << " px, and the search starts at 0: shift the right image left by " << std::ceil(-low + o.range_margin_px)
          << " px";
  } else if (!on_rows) {
    msg << "not rectified: " << c.matches << " matched features are a median " << c.median_residual_dy_px
        << " px off their common row offset of " << c.row_offset_px << " px (90 % within " << c.p90_residual_dy_px
        << " px; rectified pairs are within " << o.max_median_dy_px
        << " px): rectify the pair with its camera models first";
  } else {
    msg << "not rectified: " << c.matches << " matched features agree on a row offset of " << c.row_offset_px
        << " px (median |dy| " << c.median_residual_dy_px << " px without it), more than the "
        << o.max_row_offset_px << " px a rectified pair keeps: rectify the pair with its camera models first";
  }
  c.message = msg.str();
  return c;
}

cv::Mat AlignRows(const cv::Mat& right, double row_offset_px) {
  if (std::abs(row_offset_px) < 0.01) return right;
  // dst(x, y) = src(x, y + offset).
  const cv::Matx23d shift(1, 0, 0, 0, 1, row_offset_px);
  cv::Mat out;
  cv::warpAffine(right, out, shift, right.size(), cv::INTER_CUBIC | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  return out;
}

}  // namespace vloc
