#pragma once
// Section 2.2: A-KAZE features of a frame, matching two frames, the RANSAC
// homography refined by Levenberg-Marquardt, the foreground filter of
// equation 2 and the least-squares scale fit of equation 3.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vloc/mosaic/geometry.h"

namespace vloc {
class OptionsReader;
}

namespace vloc::mosaic {

struct MatcherOptions {
  std::string detector = "akaze";    // "akaze" (the paper's: binary MLDB descriptors, fast on video) or "sift" (float
                                     // descriptors; finds 1.3-2x the consistent matches on low-texture fields)
  double downscale = 0.5;            // the detector runs on the frame resized by this factor (0.1..1)
  int detect_width = 0;              // px: the detector's frame is at most this wide (large photos: the factor shrinks
                                     // with the frame, the cost stays that of this width); 0 = downscale alone
  double akaze_threshold = 0.0005;   // A-KAZE detector response threshold
  int akaze_octaves = 3;             // A-KAZE octaves
  int akaze_sublevels = 2;           // A-KAZE sublevels per octave (OpenCV default 4; 2 halves the scale-space cost)
  int max_features = 1200;           // strongest keypoints kept per frame (spread over a grid)
  int min_features = 0;              // fewer keypoints than this: A-KAZE again at a quarter of the threshold (down to
                                     // 1/64 of akaze_threshold; low-texture fields); 0 = off
  double sift_contrast = 0.01;       // SIFT contrast threshold (OpenCV default 0.04; low texture needs less)
  int grid_cells = 8;                // grid cells per image side for spreading the kept keypoints
  double ratio = 0.8;                // Lowe ratio test on Hamming distances
  double ransac_threshold = 3.0;     // px (full resolution), RANSAC reprojection threshold
  double foreground_rho = 2.0;       // px (full resolution), rho of equation 2
  std::string foreground_rule = "reprojection";  // "eq2": |(|k-k^|-|k-Hk|)| >= rho; "reprojection": |k^-Hk| >= rho (stricter, implies eq2)
  std::string scale_model = "similarity";        // eq. 3 model: "similarity" (handles yaw), "axis_scale" (eq. 3 as printed), "affine"
  int min_inliers = 25;              // fewer background matches than this = matching failed
  double max_scale_change = 1.6;     // a scale change beyond [1/x, x] between two frames = failure
  double loose_ratio = 0.0;          // when the homography has too few inliers: again with this looser ratio test and
                                     // MAGSAC++ (low-texture fields); 0 = off
  double guided_ratio = 0.9;         // ratio test among the candidates inside the gate (guided matching, MotionPrior)
  int num_threads = 2;               // OpenCV threads for A-KAZE and matching

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// Keypoints (full-resolution pixel coordinates) and their descriptors.
struct FrameFeatures {
  std::vector<cv::Point2f> points;   // px, full resolution
  cv::Mat descriptors;               // one row per point: A-KAZE MLDB (CV_8U, Hamming) or SIFT (CV_32F, L2)
  cv::Size size;                     // full-resolution frame size
  double seconds = 0.0;              // time spent extracting
  bool empty() const { return points.empty(); }
};

// Gray (CV_8UC1) or BGR frame.
FrameFeatures ExtractFeatures(const cv::Mat& image, const MatcherOptions& options);

// Frame-to-frame motion: `from` px -> `to` px.
struct MotionEstimate {
  bool ok = false;
  std::string why;                   // when !ok
  cv::Matx33d homography = cv::Matx33d::eye();
  Similarity2 similarity;            // least-squares fit to the background matches
  double lambda = 1.0;               // scale change (eq. 3); > 1 = zoom in = descending
  double lambda_x = 1.0, lambda_y = 1.0;  // eq. 3 as printed (axis scales)
  int num_matches = 0;               // after the ratio test
  int num_inliers = 0;               // RANSAC homography inliers
  int num_foreground = 0;            // matches removed by equation 2
  int num_background = 0;            // matches used for the scale fit
  double fit_rms = 0.0;              // px, residual of the scale fit
  double spread = 0.0;               // area of the background matches' convex hull / area of `to` (0..1)
  bool guided = false;               // matched inside a MotionPrior's gate
  bool loose = false;                // found by the second try (loose_ratio, MAGSAC++)
  double seconds = 0.0;              // matching + estimation
  std::vector<cv::Point2f> from_background, to_background;
};

// Guided matching: where `to` should see `from`'s points (e.g. predicted
// from the GPS motion). Only candidates within gate_px of the predicted
// place compete, and the ratio test runs among them (guided_ratio).
struct MotionPrior {
  Similarity2 to_from_from;          // predicted `from` px -> `to` px
  double gate_px = 100.0;            // px, search radius around the prediction
};

// `prior` null = unguided (every feature against every feature).
MotionEstimate EstimateMotion(const FrameFeatures& from, const FrameFeatures& to, const MatcherOptions& options,
                              const MotionPrior* prior = nullptr);

// Equation 2 for each match (from[i] -> to[i]) under homography H (from -> to):
// true = foreground (moving object). Rule as in MatcherOptions::foreground_rule.
std::vector<bool> ForegroundFilter(const std::vector<cv::Point2f>& from, const std::vector<cv::Point2f>& to,
                                   const cv::Matx33d& H, double rho, const std::string& rule);

}  // namespace vloc::mosaic
