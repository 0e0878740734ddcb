#pragma once
// Camera models. Camera frame: x right, y down, z forward (OpenCV).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "vloc/common/pose.h"

namespace vloc {

class OptionsReader;

// Pinhole camera with OpenCV's radial/tangential distortion (k1 k2 p1 p2 k3).
struct PinholeCamera {
  int width = 1024;     // px
  int height = 1024;    // px
  double fx = 1189.0;   // px, focal length along x
  double fy = 1189.0;   // px, focal length along y
  double cx = 511.5;    // px, principal point column
  double cy = 511.5;    // px, principal point row
  double k1 = 0.0;      // radial distortion
  double k2 = 0.0;      // radial distortion
  double p1 = 0.0;      // tangential distortion
  double p2 = 0.0;      // tangential distortion
  double k3 = 0.0;      // radial distortion

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;

  bool HasDistortion() const;
  cv::Matx33d K() const;
  cv::Mat DistortionCoeffs() const;  // 1x5, CV_64F

  // Ideal (undistorted) pixel of a point in the camera frame; nullopt behind
  // the camera (z <= 1e-9).
  std::optional<Eigen::Vector2d> ProjectIdeal(const Eigen::Vector3d& p_camera) const;
  // Raw (distorted) pixel of a point in the camera frame.
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& p_camera) const;
  // Applies distortion to an ideal pixel, and removes it (iteratively).
  Eigen::Vector2d Distort(const Eigen::Vector2d& ideal_px) const;
  Eigen::Vector2d Undistort(const Eigen::Vector2d& raw_px) const;
  // Unit-z ray (x, y, 1) of an ideal pixel, in the camera frame.
  Eigen::Vector3d Ray(const Eigen::Vector2d& ideal_px) const;
  bool InImage(const Eigen::Vector2d& px, double margin = 0.0) const;
};

// A calibrated stereo pair: right camera located in the left camera frame.
struct StereoRig {
  PinholeCamera left;
  PinholeCamera right;
  Pose3 left_from_right = MakePose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.27, 0, 0));

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
  double Baseline() const { return left_from_right.translation().norm(); }
};

// The Navcam mast: a pan axis along body z at mast_base (body frame), a tilt
// axis at the mast head, and the stereo bar whose midpoint is the tilt
// centre. Pan is positive to the left (about +z), tilt positive downwards.
// At pan = tilt = 0 the cameras look along body x.
struct MastKinematics {
  Eigen::Vector3d mast_head = Eigen::Vector3d(0.0, 0.0, 1.5);  // m, tilt centre in body frame
  double camera_offset = 0.0;  // m, from the tilt axis to the stereo bar along the optical axis

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;

  // body_from_camera of the left camera of `rig` for a mast pan/tilt (rad).
  Pose3 BodyFromLeft(double pan, double tilt, const StereoRig& rig) const;
  Pose3 BodyFromRight(double pan, double tilt, const StereoRig& rig) const;
};

// Everything that defines the Navcam: the rig and the mast.
struct NavcamModel {
  StereoRig rig;
  MastKinematics mast;
  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// Rotation taking camera-frame vectors to body frame for a camera looking
// along body x (camera z = body x, camera x = -body y, camera y = -body z).
Eigen::Matrix3d BodyFromCameraAxes();

}  // namespace vloc
