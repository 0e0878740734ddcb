#pragma once
// Photogrammetric building blocks of the cross-site adjustment: the
// projection of a world point into a calibrated camera (undistorted pixels),
// space intersection of one point from several cameras, and space resection
// of a rigid multi-camera body (a rover site) from known points.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/pose.h"

namespace vloc {

// One calibrated image: where the camera is and its pinhole intrinsics.
// Observations are ideal (undistorted) pixels.
struct CameraView {
  Pose3 world_from_camera = Pose3::Identity();
  double fx = 1189.0, fy = 1189.0, cx = 511.5, cy = 511.5;  // px

  static CameraView Make(const Pose3& world_from_camera, const PinholeCamera& camera);
  // Ideal pixel of a world point; nullopt behind the camera.
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& p_world) const;
};

struct IntersectionResult {
  bool ok = false;
  std::string message;                               // why not, when !ok
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();  // m
  double rms_px = 0;                                  // reprojection RMS over the views
  double max_parallax_rad = 0;                        // largest angle between two rays
};

// Space intersection: linear (DLT) solution refined by Gauss-Newton on the
// reprojection error weighted by sigma_px (empty = 1 px each). Needs at
// least two views whose rays differ by min_parallax_rad and a point in
// front of every camera.
IntersectionResult IntersectPoint(const std::vector<CameraView>& views, const std::vector<Eigen::Vector2d>& uv,
                                  const std::vector<double>& sigma_px = {}, double min_parallax_rad = 1e-4);

// An observation of a known world point by one camera of a rigid body.
struct ResectionObservation {
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();  // m
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();       // px, ideal
  double sigma_px = 1.0;                              // px
  int camera = 0;                                     // index into the camera list
};

struct ResectionOptions {
  int max_iterations = 50;          // Gauss-Newton/LM iterations of the refinement
  double huber_px = 2.0;            // Huber loss threshold, in sigmas
  bool try_pnp = true;              // also start from cv::solvePnP of the best-covered camera
  int min_observations = 4;         // fewer observations: no solution
};

struct ResectionResult {
  bool ok = false;
  std::string message;
  Pose3 world_from_body = Pose3::Identity();
  double rms_px = 0;        // reprojection RMS over all observations
  int iterations = 0;
  bool used_pnp_start = false;  // the solvePnP start won over the given initial pose
};

// Space resection of a rigid camera set: finds world_from_body such that
// the cameras (body_from_camera[i], intrinsics[i]) see the points where
// observed. Starts from `initial_world_from_body` (e.g. dead reckoning) and,
// with try_pnp, from cv::solvePnP on the camera with most observations;
// keeps the start whose refined robust cost is lowest.
ResectionResult ResectBody(const std::vector<Pose3>& body_from_camera, const std::vector<PinholeCamera>& intrinsics,
                           const std::vector<ResectionObservation>& observations,
                           const Pose3& initial_world_from_body, const ResectionOptions& options = {});

}  // namespace vloc
