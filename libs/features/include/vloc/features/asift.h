#pragma once
// ASIFT (Morel & Yu 2009): SIFT on affine-simulated views of an image. A
// view is (tilt t, longitude phi): rotate by phi, blur along x by
// 0.8 sqrt(t^2 - 1) and subsample x by 1/t. Keypoints are mapped back to
// the original image. The set of simulated (t, phi) is restricted by the
// caller from the predicted viewpoint change (Wan et al. 2.2), and views
// are processed in parallel with OpenMP. Matching gates candidates by a
// predicted position instead of comparing everything with everything.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <utility>
#include <vector>

namespace vloc {

class OptionsReader;

// One simulated view.
struct AffineView {
  double tilt = 1.0;       // t >= 1
  double longitude = 0.0;  // rad, phi
};

struct AsiftOptions {
  std::vector<double> tilts = {1.0, 1.4142135623730951, 2.0, 2.8284271247461903};  // transition tilts simulated (1 = the image itself)
  double longitude_step_deg = 72.0;   // deg, phi step at tilt t is this / t (Morel & Yu)
  double longitude_min_deg = 0.0;     // deg, simulated longitudes are in [min, max)
  double longitude_max_deg = 180.0;   // deg
  int max_features_per_view = 4000;   // SIFT nfeatures per view (0 = all)
  int sift_octave_layers = 3;         // SIFT nOctaveLayers
  double sift_contrast_threshold = 0.02;  // SIFT contrastThreshold (lower: more features)
  double sift_edge_threshold = 10.0;  // SIFT edgeThreshold
  double sift_sigma = 1.6;            // SIFT sigma
  int num_threads = 2;                // OpenMP threads over the simulated views

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;

  // The (t, phi) views these options simulate.
  std::vector<AffineView> Views() const;
};

struct FeatureSet {
  std::vector<cv::KeyPoint> keypoints;  // in the simulated view (size, angle as detected there)
  std::vector<Eigen::Vector2d> points;  // px, positions in the original image
  std::vector<int> view;                // index into `views`
  std::vector<AffineView> views;
  cv::Mat descriptors;                  // CV_32F, one row per keypoint

  size_t size() const { return points.size(); }
};

// SIFT on the views of `image` (CV_8UC1) listed in `views`; keypoints only
// where `mask` (CV_8UC1, same size, empty = everywhere) is non-zero.
FeatureSet DetectAsift(const cv::Mat& image, const cv::Mat& mask, const std::vector<AffineView>& views,
                       const AsiftOptions& options);
inline FeatureSet DetectAsift(const cv::Mat& image, const cv::Mat& mask, const AsiftOptions& options) {
  return DetectAsift(image, mask, options.Views(), options);
}

// The 2x3 transform from original pixels to the pixels of a simulated view
// of an image of `size`, and the size of that view.
cv::Matx23d AffineViewTransform(const cv::Size& size, const AffineView& view, cv::Size* view_size);

struct GatedMatchOptions {
  double gate_radius = 60.0;       // px, candidates within this distance of the predicted position
  double ratio = 0.8;              // Lowe ratio: best / second best (second from another location)
  double distinct_radius = 4.0;    // px, candidates closer than this to the best count as the same point
  double max_descriptor_distance = 0.0;  // L2 on SIFT descriptors; 0 = no limit
  int num_threads = 2;             // OpenMP threads over the query features

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// Lowe's ratio test against a rival at a distinct place. `sorted` holds
// one query's candidates as (squared descriptor distance, index into
// `points`), by increasing distance. The rival is the best candidate more
// than `distinct_radius` px from the best one: ASIFT repeats a point once
// per simulated view, and those copies are the same place, not rivals.
// True when best <= ratio * rival (or there is no rival).
inline bool DistinctRatioTest(const std::vector<std::pair<double, int>>& sorted,
                              const std::vector<Eigen::Vector2d>& points, double ratio, double distinct_radius) {
  if (sorted.empty()) return false;
  const Eigen::Vector2d& best = points[sorted[0].second];
  const double radius_sq = distinct_radius * distinct_radius;
  double rival = 1e300;
  for (size_t k = 1; k < sorted.size(); ++k) {
    if ((points[sorted[k].second] - best).squaredNorm() > radius_sq) {
      rival = sorted[k].first;
      break;
    }
  }
  return !(sorted[0].first > ratio * ratio * rival);
}

struct FeatureMatch {
  int query = 0;         // index in the query set
  int train = 0;         // index in the train set
  double distance = 0;   // descriptor distance
};

// For each query feature q, compares it with the train features whose
// points lie within gate_radius of predicted[q] (train image px; NaN =
// no prediction: skipped). One match per train location is kept (the best).
std::vector<FeatureMatch> GatedMatch(const FeatureSet& query, const std::vector<Eigen::Vector2d>& predicted,
                                     const FeatureSet& train, const GatedMatchOptions& options);

}  // namespace vloc
