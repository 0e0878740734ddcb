#pragma once
// Is a stereo pair rectified, and which disparities does it span? From
// sparse SIFT matches (Lowe's ratio test, then a fundamental matrix by
// RANSAC to drop wrong matches): on a rectified pair the inliers lie on the
// same row to the features' own localisation noise (a tenth of a pixel);
// their horizontal offsets give the disparity range. Dense stereo matches
// along rows only, so an unrectified pair (a raw Navcam EDR pair, say: rows
// 1-4 px apart) gives a disparity map that is wrong everywhere without a
// sign; this check names the problem instead. Real rectified pairs keep a
// residual vertical offset (the UTIAS Devon Island XB3 pairs: 0.55-0.63
// px): the median signed row difference is measured and absorbed
// (AlignRows shifts the right image by it) when the matches agree on it;
// only a pair whose rows disagree once it is removed (a rotation, a raw
// pair) or whose offset exceeds max_row_offset_px is refused.
//
//   const StereoPairCheck c = CheckStereoPair(left, right, StereoPairCheckOptions());
//   if (!c.rectified) std::cerr << c.message << "\n";

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace vloc {

class OptionsReader;

struct StereoPairCheckOptions {
  int max_features = 4000;          // SIFT keypoints per image
  double ratio = 0.75;              // Lowe's ratio test
  double ransac_px = 1.0;           // px, fundamental-matrix RANSAC threshold
  int min_matches = 30;             // fewer inliers: no verdict (texture?)
  double max_median_dy_px = 0.5;    // px, median |row difference| of a rectified pair's matches, the offset removed
  double max_row_offset_px = 4.0;   // px, largest common row offset absorbed (larger: not rectified)
  double range_percentile = 0.5;    // %, the disparity range spans this percentile to 100 minus it ...
  double range_margin_px = 8.0;     // px, ... widened by this on both sides (and never below 0)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct StereoPairCheck {
  bool usable = false;              // enough matches for a verdict
  bool rectified = false;           // usable and the matches lie on their rows (after row_offset_px)
  std::string message;              // the verdict in one line
  int matches = 0;                  // fundamental-matrix inliers
  double median_abs_dy_px = 0;      // px, median |left y - right y| of the inliers
  double p90_abs_dy_px = 0;         // px, 90th percentile
  double row_offset_px = 0;         // px, median (right y - left y): shift the right image up by it
  double median_residual_dy_px = 0; // px, median |right y - left y - row_offset_px|
  double p90_residual_dy_px = 0;    // px, 90th percentile of the same
  double min_disparity = 0;         // px, suggested search range (left x - right x) ...
  double max_disparity = 0;         // ... with the margin
};

// The check's matches: SIFT (max_features) with Lowe's ratio test, kept
// when consistent with a fundamental matrix fitted by RANSAC (ransac_px);
// none when fewer than min_matches pass the ratio test.
struct StereoMatches {
  std::vector<cv::Point2f> left, right;  // px, inlier pairs
  cv::Mat fundamental;                   // 3 x 3, right^T F left = 0; empty without a fit
};
StereoMatches MatchStereoPair(const cv::Mat& left, const cv::Mat& right, const StereoPairCheckOptions& options);

// `left`, `right`: CV_8UC1 of the same size. Throws std::invalid_argument
// on bad images or options.
StereoPairCheck CheckStereoPair(const cv::Mat& left, const cv::Mat& right, const StereoPairCheckOptions& options);

// The right image resampled (bicubic) so that its row y + row_offset_px
// lands on row y: after it, a pair whose check found row_offset_px has its
// matches on the same rows. Returns `right` itself for |offset| < 0.01 px.
cv::Mat AlignRows(const cv::Mat& right, double row_offset_px);

}  // namespace vloc
