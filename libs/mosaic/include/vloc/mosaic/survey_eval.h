#pragma once
// Route and height of a flight against its GPS (real surveys): the route
// (mosaic px of the frame centres) is fitted to the GPS track by a 2-D
// similarity (the mosaic has no absolute position, heading or scale of its
// own) and the horizontal residual is reported per frame, as RMS and as a
// percentage of the path length. Heights are compared with a GPS height
// (relative altitude, or altitude minus a fitted ground level), or with
// another tool's heights above the ground (ReadReferenceHeights).

#include <opencv2/core.hpp>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "vloc/mosaic/geometry.h"

namespace vloc::mosaic {

struct RouteComparison {
  bool ok = false;
  std::string why;                      // when !ok
  int pairs = 0;                        // frames in the fit
  Similarity2 enu_from_flipped;         // (x, -y) mosaic px -> east/north m
  std::vector<double> residual_m;       // per input frame, m (NaN when not usable)
  double rms_m = 0;                     // over the frames in the fit
  double held_out_rms_m = 0;            // over usable frames not in the fit (e.g. a GPS drop-out), 0 if none
  int held_out = 0;
  double path_m = 0;                    // GPS path length through the usable frames, m
  // Robust fit: fixes whose residual exceeds max(outlier_sigmas x 1.4826 x median residual, min_outlier_m) are
  // GPS outliers (consumer receivers jump tens of metres for a fix or two); the fit is repeated without them.
  int gps_outliers = 0;                 // fixes left out of the final fit
  std::vector<int> outlier_frames;      // their input indices
  double inlier_rms_m = 0;              // over the frames in the final fit
  double rms_percent() const { return path_m > 0 ? 100.0 * rms_m / path_m : 0.0; }
  double inlier_rms_percent() const { return path_m > 0 ? 100.0 * inlier_rms_m / path_m : 0.0; }
};

struct RouteFitOptions {
  bool robust = true;                   // reject GPS outliers (else one least-squares fit over every pair)
  double outlier_sigmas = 3.0;          // threshold in robust sigmas (1.4826 x median residual)
  double min_outlier_m = 10.0;          // m, a residual below this is never an outlier (GPS noise of a few metres)
  double max_outlier_fraction = 0.1;    // at most this fraction of the fixes is rejected (the worst first)
};

// route_px[i] mosaic px of frame i, gps_enu[i] its GPS east/north (m);
// usable[i] false = no registration or no GPS; in_fit[i] false = compared
// but not used in the fit (held out).
// rms_m is over every frame in the fit, under the (robust) final similarity.
RouteComparison CompareRouteToGps(const std::vector<cv::Point2d>& route_px, const std::vector<cv::Point2d>& gps_enu,
                                  const std::vector<bool>& usable, const std::vector<bool>& in_fit,
                                  const RouteFitOptions& options = RouteFitOptions());

struct HeightComparison {
  bool ok = false;
  int pairs = 0;
  double offset_m = 0;                  // fitted ground level (reference = gps - offset); 0 when not fitted
  double rms_m = 0;
  double rms_percent = 0;               // RMS of the error / mean reference height, % (NaN when that is <= 0)
  std::vector<double> error_m;          // per input frame (NaN when not usable)
};

// height[i] estimate, gps[i] reference (NaN = none). fit_offset: the
// reference is gps - ground with the ground level fitted (mean difference),
// for GPS altitudes above sea level over unknown ground.
HeightComparison CompareHeights(const std::vector<double>& height, const std::vector<double>& gps, bool fit_offset);

// Heights above the ground per photo from another tool's reconstruction of
// the same flight (scripts/survey_reference.py: COLMAP's bundle adjustment,
// aligned to the GPS): a tab-separated file (LF or CRLF) with a header
// naming the columns "name" (the photo's file name) and "height_m" (others
// ignored); lines starting with '#' skipped. False with one line in *error
// naming the file and the problem (unreadable, no such header, a line with
// another number of fields than the header, without a name or a height in
// (0, 100 km), a photo twice, no photo).
bool ReadReferenceHeights(const std::string& path, std::map<std::string, double>* heights, std::string* error);

// Where the photos lie in a reference orthomosaic made by another tool
// (e.g. OpenDroneMap's): an independent check of the route where the
// camera's GPS is poor. Each photo is matched to the reference with SIFT,
// Lowe's ratio test and a RANSAC homography; its centre is mapped into the
// reference. The reference's own scale and orientation are unknown: compare
// with CompareRouteToGps(reference px, route or GPS metres, ...).
struct ReferenceFix {
  bool ok = false;
  cv::Point2d px;                       // the photo's centre in reference px
  int inliers = 0;                      // RANSAC inliers of the photo -> reference homography
};

struct ReferenceLocatorOptions {
  int reference_features = 20000;       // SIFT features of the reference
  double photo_scale = 0.5;             // photos reduced by this first (a reference is coarser than the photos)
  double ratio = 0.8;                   // Lowe's ratio test
  double ransac_px = 4.0;               // px in the reference
  int min_inliers = 25;                 // fewer: no fix (a weak registration would add its own error)
};

class ReferenceLocator {
 public:
  // `reference`: the orthomosaic, any 8-bit image. Throws std::invalid_argument when it is empty.
  explicit ReferenceLocator(const cv::Mat& reference, const ReferenceLocatorOptions& options = ReferenceLocatorOptions());
  ReferenceLocator(const ReferenceLocator&) = delete;
  ReferenceLocator& operator=(const ReferenceLocator&) = delete;
  ~ReferenceLocator();
  int reference_features() const;
  ReferenceFix Locate(const cv::Mat& photo) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The route (m, after its GPS fit) and the GPS (m) each fitted to the photos'
// places in the reference (fixes[i] for frame i; frames not located are left
// out) by a 2-D similarity: RMS in the route's and the GPS's metres.
struct ReferenceComparison {
  int located = 0;
  RouteComparison route, gps;           // .ok false with .why when too few photos are located
};
ReferenceComparison CompareWithReference(const std::vector<ReferenceFix>& fixes, const std::vector<cv::Point2d>& route_m,
                                         const std::vector<cv::Point2d>& gps_m, const std::vector<bool>& has_gps);

}  // namespace vloc::mosaic
