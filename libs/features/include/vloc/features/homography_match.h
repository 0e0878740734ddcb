#pragma once
// Homography between two photographs of a planar scene, no prior, to
// sub-pixel accuracy:
//   1. coarse: ASIFT on both images reduced by `coarse_scale`, FLANN
//      matching with Lowe's ratio, RANSAC homography;
//   2. refine (rounds): the second image warped into the first by the
//      current homography; at Shi-Tomasi corners of the first image, a ZNCC
//      peak search near the prediction, then least-squares matching (affine +
//      radiometry) of the full-resolution windows; RANSAC with a sub-pixel
//      threshold, then Levenberg-Marquardt refinement of the homography over
//      all inliers.
// The coarse stage only has to bring the prediction within the ZNCC search
// radius; accuracy comes from LSM at full resolution.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vloc/features/asift.h"
#include "vloc/features/lsm.h"

namespace vloc {

class OptionsReader;

struct HomographyMatchOptions {
  AsiftOptions asift = DefaultAsift();  // coarse stage (views and SIFT on the reduced images)
  double coarse_scale = 0.5;          // images reduced by this for the coarse stage (1 = full size)
  double ratio = 0.8;                 // Lowe ratio for the coarse matches
  double coarse_ransac_px = 3.0;      // px (full size), RANSAC threshold of the coarse homography
  int refine_rounds = 2;              // LSM rounds (0 = coarse homography only)
  int refine_points = 5000;           // at most this many Shi-Tomasi corners of the first image matched by LSM ...
  int refine_cell_px = 8;             // px, ... the strongest in each cell of this size
  double refine_corner_quality = 0.001;  // goodFeaturesToTrack qualityLevel
  int refine_min_distance = 5;        // px, between corners
  int refine_search_px = 4;           // px, ZNCC search radius around the prediction (first round)
  double refine_min_zncc = 0.7;       // ZNCC of the peak
  double refine_ransac_px = 3.0;      // px, RANSAC threshold on the LSM correspondences (real planes
                                      // depart from a homography by tenths of a px: keep them all)
  LsmOptions lsm = DefaultLsm();      // window and acceptance of the refinement's LSM
  int num_threads = 2;                // OpenMP threads (views, corners)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;

  static AsiftOptions DefaultAsift();
  static LsmOptions DefaultLsm();
};

struct HomographyMatchSummary {
  bool usable = false;
  std::string message;                 // why not usable, or "ok"
  int features_a = 0, features_b = 0;  // coarse ASIFT keypoints
  int coarse_matches = 0, coarse_inliers = 0;
  int refine_points = 0;               // corners tried in the last round
  int refine_matches = 0;              // LSM correspondences in the last round
  int refine_inliers = 0;              // ... within refine_ransac_px of the final homography
  double rms_px = 0;                   // px, RMS transfer residual of the inliers
  double detect_seconds = 0, match_seconds = 0, refine_seconds = 0, total_seconds = 0;

  std::string BriefReport() const;
};

struct HomographyMatchResult {
  cv::Matx33d b_from_a = cv::Matx33d::eye();  // px of image a -> px of image b
  std::vector<Eigen::Vector2d> inliers_a, inliers_b;  // the final inlier correspondences
  HomographyMatchSummary summary;
};

// `a`, `b`: CV_8UC1. Throws std::invalid_argument on bad input or options.
HomographyMatchResult MatchHomography(const cv::Mat& a, const cv::Mat& b, const HomographyMatchOptions& options);

// The refinement stage alone, from a homography known to a few px.
HomographyMatchResult RefineHomography(const cv::Mat& a, const cv::Mat& b, const cv::Matx33d& b_from_a,
                                       const HomographyMatchOptions& options);

}  // namespace vloc
