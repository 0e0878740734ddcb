#pragma once
// Initial matching regions (Wan et al. 2.1). The current site's left image
// footprints are projected onto the local ground plane with the
// dead-reckoning poses and the mast/camera geometry, and back-projected into
// the previous site's left images; the regions are grown by re-projecting
// with the relative pose perturbed by k sigma along each of its 6 axes.
// Pairs looking in opposite directions are flagged "backward": they are
// matched on the ground plane (GroundOrthoImage) instead.
// Far terrain (regions.far_max_range > 0): where sites are tens of metres
// apart the shared scene is not the ground in front of the rover but hills
// beyond it. The current pair's stereo points between far_min_range and
// far_max_range (ScenePoint) are projected like the ground samples, each
// grown by its stereo range uncertainty as well as the pose's, into one more
// overlap per previous image (PairOverlap::far) whose homography is fitted
// to them (its fit residual widens the gate).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/pose.h"
#include "vloc/common/rover_data.h"

namespace vloc {

class OptionsReader;

struct RegionOptions {
  double ground_height = 0.0;          // m, local ground plane z in each site's body frame
  double max_range_previous = 30.0;    // m, ground points farther from the previous site's camera are not used
  double max_range_current = 30.0;     // m, ... from the current site's camera
  double min_range_current = 5.0;      // m, nearer ground (seen at a very different scale from the previous site) is not used
  int grid_step = 24;                  // px, sampling of the current image footprint
  double sigma_scale = 1.5;            // regions grow to cover the pose perturbed by this many sigma
  double max_growth_px = 250.0;        // px, cap of a sample's growth (grazing points near the horizon)
  double default_position_sigma_fraction = 0.15;  // relative position sigma, fraction of the distance, when no covariance
  double default_yaw_sigma_deg = 3.0;      // deg, relative yaw sigma when no covariance
  double default_tilt_sigma_deg = 1.0;     // deg, relative roll/pitch sigma when no covariance
  double max_position_sigma_fraction = 0.3;  // relative position sigma is capped at this fraction of the distance
  int min_samples = 8;                 // ground samples an overlap needs
  double backward_angle_deg = 100.0;   // viewing directions further apart than this: backward pair
  double image_margin = 8.0;           // px, samples this close to an image border are dropped
  double far_min_range = 0.0;          // m, nearest far-terrain stereo point from the current camera
  double far_max_range = 0.0;          // m, farthest one; 0 = no far-terrain overlaps
  double far_disparity_sigma_px = 0.5; // px, stereo disparity sigma of a far point (its range sigma)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// What region prediction says about one (current pair, previous pair).
struct PairOverlap {
  bool far = false;           // from far-terrain stereo points (else the ground plane)
  int current_pair = 0;
  int previous_pair = 0;
  bool backward = false;
  cv::Rect current_region;    // px (ideal) in the current left image
  cv::Rect previous_region;   // px (ideal) in the previous left image, grown by the pose uncertainty
  cv::Matx33d previous_from_current = cv::Matx33d::eye();  // ground-plane homography, current-left px -> previous-left px
  double scale = 1.0;         // previous px per current px (sqrt |det| of the homography's Jacobian at the region centre)
  double tilt = 1.0;          // transition tilt (ratio of the Jacobian's singular values)
  double tilt_longitude = 0;  // rad, direction in the current image along which the previous view is compressed
  double growth_px = 0;       // px, largest displacement of a sample under the perturbed poses (gate radius)
  int num_samples = 0;        // ground samples in this overlap
  Eigen::Vector2d median_current_px = Eigen::Vector2d::Zero();  // px, median member sample (where scale/tilt are taken)
  Eigen::Vector2d ground_min = Eigen::Vector2d::Zero();  // m, previous body frame x/y box of the common
  Eigen::Vector2d ground_max = Eigen::Vector2d::Zero();  // ground (grown by the position sigma), for backward pairs
};

struct RegionPrediction {
  Pose3 previous_from_current = Pose3::Identity();  // body frames, from the DR poses
  Vector6d relative_sigma = Vector6d::Zero();       // sigma [x y z rx ry rz] used for growing
  std::vector<PairOverlap> overlaps;
};

// Relative pose sigma of the current site w.r.t. the previous one: the
// growth of the DR covariance between the sites, or the defaults when the
// covariances are unknown (all zero).
Vector6d RelativePoseSigma(const PoseWithCovariance& world_from_previous, const PoseWithCovariance& world_from_current,
                           const RegionOptions& options);

// A far-terrain point the current pair's stereo measured.
struct ScenePoint {
  Eigen::Vector2d px = Eigen::Vector2d::Zero();      // px, current left ideal image
  Eigen::Vector3d p_body = Eigen::Vector3d::Zero();  // m, current body frame
  double range_sigma = 0;                            // m, along the left camera's ray
};

// `current_ground_planes` (optional, one per current pair): the ground seen
// by that pair as a plane n . p + e = 0 (n up, unit) in the current body
// frame, e.g. fitted to the pair's stereo points; an empty vector or a zero
// plane uses z = ground_height. `current_far_points` (optional, one list per
// current pair): far-terrain stereo points, each list making one far
// overlap per previous pair (with at least min_samples members).
RegionPrediction PredictRegions(const NavcamModel& navcam, const PoseWithCovariance& world_from_previous,
                                const PoseWithCovariance& world_from_current,
                                const std::vector<MastPointing>& previous_pointing,
                                const std::vector<MastPointing>& current_pointing, const RegionOptions& options,
                                const std::vector<Eigen::Vector4d>& current_ground_planes = {},
                                const std::vector<std::vector<ScenePoint>>& current_far_points = {});

// Ground-plane projection: the homography from an ortho image to the ideal
// pixels of a camera. The ortho pixel (u, v) is the ground point
// (origin.x + u * resolution, origin.y - v * resolution, ground_height) in
// the body frame `body_from_camera` refers to.
cv::Matx33d ImageFromOrtho(const PinholeCamera& camera, const Pose3& body_from_camera, const Eigen::Vector2d& origin,
                           double resolution, double ground_height);

// Warps `image` (ideal pixels) onto the ortho grid of `size` pixels.
cv::Mat GroundOrthoImage(const cv::Mat& image, const cv::Matx33d& image_from_ortho, const cv::Size& size);

}  // namespace vloc
