#pragma once
// Registration of two photos whose viewpoints differ too much for the
// frame-to-frame A-KAZE matcher: oblique aerial photos of one scene taken
// from different directions and distances (e.g. OpenCV's aero1.jpg and
// aero3.jpg). The views differ by strong foreshortening, so features are
// made affine invariant by simulating camera tilts (ASIFT: cv::AffineFeature
// around SIFT) on both images. Because ASIFT describes one scene point once
// per simulated view, the ratio test compares the best candidate with the
// best one at a DIFFERENT place (a duplicate of the same point is not a rival).
// A MAGSAC++ homography follows (the ground is far away: a plane), then a
// photometric check: the normalised cross-correlation of the two images
// detail (image minus a 3-px Gaussian blur) in their overlap, registered
// versus unregistered.
//
//   PairRegistration r = RegisterOblique(aero1, aero3, ObliqueOptions());
//   if (r.ok) cv::Mat mosaic = MosaicByHomographies({aero1, aero3}, {I, r.to_from_from.inv()}, ...);

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace vloc {
class OptionsReader;
}

namespace vloc::mosaic {

struct ObliqueOptions {
  double max_tilt = 5.0;           // ASIFT: largest simulated tilt (1/cos of the view angle); tilts 1, sqrt2, 2, ... up to this
  int sift_features = 0;           // SIFT keypoints kept per simulated view (0 = all)
  double max_side = 1000;          // px, images with a longer side are downscaled for matching (results in full px)
  double ratio = 0.8;              // ratio test: best distance < ratio * best distance at another place
  double distinct_radius = 5.0;    // px, candidates closer than this to the best one are the same point (not rivals)
  double ransac_threshold = 3.0;   // px, MAGSAC++ threshold on the homography
  int min_inliers = 20;            // fewer distinct inlier matches = not registered
  double min_ncc_gain = 0.1;       // the registered overlap's detail must correlate this much better than the unregistered images
  int num_threads = 2;             // OpenCV threads (simulated views, matching)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct PairRegistration {
  bool ok = false;
  std::string why;                      // when !ok
  cv::Matx33d to_from_from = cv::Matx33d::eye();  // homography: `from` px -> `to` px
  int keypoints_from = 0, keypoints_to = 0;       // ASIFT keypoints (all simulated views)
  int num_matches = 0;                  // after the ratio test
  int num_inliers = 0;                  // distinct inlier matches (duplicates from several views counted once)
  double ncc_registered = 0;            // NCC of `to` and warped `from` in their overlap
  double ncc_identity = 0;              // NCC of the two images laid on each other unregistered
  double overlap = 0;                   // fraction of `to` covered by warped `from`
  double median_residual = 0;           // px, median transfer error of the inliers
  double seconds = 0;
  std::vector<cv::Point2f> inliers_from, inliers_to;  // px, distinct inliers
  std::string BriefReport() const;
};

// Gray or BGR images. Never throws on bad input (empty image -> !ok).
PairRegistration RegisterOblique(const cv::Mat& from, const cv::Mat& to, const ObliqueOptions& options);

// NCC of the detail (image minus its 3-px Gaussian blur) of `to` and of
// `from` warped by to_from_from, over the pixels both cover (borders eroded
// by 3 px). *overlap = covered fraction of `to`. Returns 0
// when the overlap is under 1 % of `to`.
double RegisteredNcc(const cv::Mat& from, const cv::Mat& to, const cv::Matx33d& to_from_from, double* overlap = nullptr);

// Mosaic of images placed by homographies into the frame of a reference
// (ref_from_image[i]: image i px -> reference px), multi-band blended.
// Returns BGRA (alpha 255 where covered). Parts of an image that map beyond
// max_extent reference sizes from the reference (towards a horizon) are
// cut off. `bands` = multi-band levels.
cv::Mat MosaicByHomographies(const std::vector<cv::Mat>& images, const std::vector<cv::Matx33d>& ref_from_image,
                             cv::Size reference_size, double max_extent = 1.5, int bands = 5);

}  // namespace vloc::mosaic
