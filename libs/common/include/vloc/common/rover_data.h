#pragma once
// The rover's data model shared by the libraries (no message types here;
// libs/lcm_io converts these to and from vloc's LCM messages).

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "vloc/common/pose.h"

namespace vloc {

// Latest plausible message time, microseconds (2^53 us: year 2255).
// Later times are corrupt; every product of them overflows.
inline constexpr int64_t kMaxPlausibleUtime = int64_t{1} << 53;

// Most stereo pairs one site's panorama may hold (a full 360 x 3-tier
// panorama is about 30); more is a corrupt count.
inline constexpr int kMaxPairsPerSite = 64;

// Site ids count up along a traverse; one this far beyond the newest site
// is a corrupt id, not a drive.
inline constexpr int kMaxSiteIdJump = 1000;

// One Navcam stereo pair at a site.
struct StereoPair {
  int64_t utime = 0;     // microseconds, time of exposure
  int site_id = 0;
  int pair_index = 0;    // 0..num_pairs-1 in the site's panorama
  int num_pairs = 0;
  double mast_pan = 0;   // rad, positive left
  double mast_tilt = 0;  // rad, positive down
  cv::Mat left;          // CV_8UC1 (raw, possibly distorted)
  cv::Mat right;         // CV_8UC1
};

struct ImuSample {
  int64_t utime = 0;                                     // microseconds
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();    // rad/s, body
  Eigen::Vector3d linear_acceleration = Eigen::Vector3d::Zero(); // m/s^2, body, specific force
};

struct WheelOdometrySample {
  int64_t utime = 0;     // microseconds
  double distance = 0;   // m, cumulative
  double speed = 0;      // m/s
};

enum class SiteEventType { kArrived = 0, kImagingDone = 1, kDeparted = 2 };

struct SiteEvent {
  int64_t utime = 0;
  int site_id = 0;
  SiteEventType event = SiteEventType::kArrived;
  int num_pairs = 0;
};

// Mast pointing of one stereo pair.
struct MastPointing {
  double pan = 0;   // rad
  double tilt = 0;  // rad
};

enum class SiteRole { kPrevious = 0, kCurrent = 1 };
enum class CameraSide { kLeft = 0, kRight = 1 };

struct TieObservation {
  SiteRole site = SiteRole::kPrevious;
  int pair_index = 0;
  CameraSide camera = CameraSide::kLeft;
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();  // px, undistorted (ideal pinhole) image
  double sigma = 0.3;                            // px, 1-sigma
};

struct TiePoint {
  int id = 0;
  Eigen::Vector3d p_previous = Eigen::Vector3d::Zero();  // m, previous site's body frame
  Eigen::Vector3d p_current = Eigen::Vector3d::Zero();   // m, current site's body frame
  int weight = 0;                                        // consistency votes
  std::vector<TieObservation> observations;
};

// Everything the bundle adjustment needs about one site pair.
struct TiePointSet {
  int64_t utime = 0;
  int previous_site_id = 0;
  int current_site_id = 0;
  PoseWithCovariance previous_site_pose;    // world_from_body, held fixed
  PoseWithCovariance current_site_pose_dr;  // world_from_body, initial value
  std::vector<MastPointing> previous_pointing;  // per pair of the previous site
  std::vector<MastPointing> current_pointing;   // per pair of the current site
  std::vector<TiePoint> points;
};

}  // namespace vloc
