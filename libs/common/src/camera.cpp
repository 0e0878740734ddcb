#include "vloc/common/camera.h"

#include <cmath>
#include <sstream>

#include "vloc/common/options.h"

namespace vloc {

void PinholeCamera::Visit(OptionsReader& r) {
  r.Optional("width", &width, "px", Positive());
  r.Optional("height", &height, "px", Positive());
  r.Optional("fx", &fx, "px, focal length along x", Positive());
  r.Optional("fy", &fy, "px, focal length along y", Positive());
  r.Optional("cx", &cx, "px, principal point column", InRange(0, width));
  r.Optional("cy", &cy, "px, principal point row", InRange(0, height));
  r.Optional("k1", &k1, "radial distortion");
  r.Optional("k2", &k2, "radial distortion");
  r.Optional("p1", &p1, "tangential distortion");
  r.Optional("p2", &p2, "tangential distortion");
  r.Optional("k3", &k3, "radial distortion");
}

bool PinholeCamera::Check(std::string* error) const { return CheckOptions(*this, error); }

bool PinholeCamera::HasDistortion() const {
  return k1 != 0.0 || k2 != 0.0 || p1 != 0.0 || p2 != 0.0 || k3 != 0.0;
}

cv::Matx33d PinholeCamera::K() const { return {fx, 0, cx, 0, fy, cy, 0, 0, 1}; }

cv::Mat PinholeCamera::DistortionCoeffs() const {
  return (cv::Mat_<double>(1, 5) << k1, k2, p1, p2, k3);
}

std::optional<Eigen::Vector2d> PinholeCamera::ProjectIdeal(const Eigen::Vector3d& p) const {
  if (p.z() <= 1e-9) return std::nullopt;
  return Eigen::Vector2d(fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy);
}

std::optional<Eigen::Vector2d> PinholeCamera::Project(const Eigen::Vector3d& p) const {
  auto ideal = ProjectIdeal(p);
  if (!ideal) return std::nullopt;
  return Distort(*ideal);
}

Eigen::Vector2d PinholeCamera::Distort(const Eigen::Vector2d& ideal) const {
  if (!HasDistortion()) return ideal;
  const double x = (ideal.x() - cx) / fx, y = (ideal.y() - cy) / fy;
  const double r2 = x * x + y * y;
  const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const double xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
  const double yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  return {fx * xd + cx, fy * yd + cy};
}

Eigen::Vector2d PinholeCamera::Undistort(const Eigen::Vector2d& raw) const {
  if (!HasDistortion()) return raw;
  // Fixed-point iteration as in cv::undistortPoints, enough for mild lenses.
  const double xd = (raw.x() - cx) / fx, yd = (raw.y() - cy) / fy;
  double x = xd, y = yd;
  for (int i = 0; i < 20; ++i) {
    const double r2 = x * x + y * y;
    const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
    const double dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
    x = (xd - dx) / radial;
    y = (yd - dy) / radial;
  }
  return {fx * x + cx, fy * y + cy};
}

Eigen::Vector3d PinholeCamera::Ray(const Eigen::Vector2d& ideal) const {
  return {(ideal.x() - cx) / fx, (ideal.y() - cy) / fy, 1.0};
}

bool PinholeCamera::InImage(const Eigen::Vector2d& px, double margin) const {
  return px.x() >= margin && px.y() >= margin && px.x() <= width - 1 - margin &&
         px.y() <= height - 1 - margin;
}

void StereoRig::Visit(OptionsReader& r) {
  r.Child("left", [&](OptionsReader& c) { left.Visit(c); });
  r.Child("right", [&](OptionsReader& c) { right.Visit(c); });
  Eigen::Vector3d t = left_from_right.translation();
  Eigen::Vector3d rpy = RollPitchYawFromRotation(left_from_right.linear());
  r.Optional("right_in_left_translation", &t, "m, right camera origin in the left camera frame");
  r.Optional("right_in_left_rpy", &rpy, "rad, roll/pitch/yaw of the right camera in the left frame");
  left_from_right = MakePose(RotationFromRollPitchYaw(rpy.x(), rpy.y(), rpy.z()), t);
  r.Relation("right_in_left_translation", Baseline() >= 1e-3, "must be at least 1 mm long (the stereo baseline)");
}

bool StereoRig::Check(std::string* error) const { return CheckOptions(*this, error); }

Eigen::Matrix3d BodyFromCameraAxes() {
  Eigen::Matrix3d R;
  // Columns: camera x, y, z axes expressed in body.
  R.col(0) = Eigen::Vector3d(0, -1, 0);
  R.col(1) = Eigen::Vector3d(0, 0, -1);
  R.col(2) = Eigen::Vector3d(1, 0, 0);
  return R;
}

void MastKinematics::Visit(OptionsReader& r) {
  r.Optional("mast_head", &mast_head, "m, tilt centre in the body frame");
  r.Optional("camera_offset", &camera_offset, "m, tilt axis to stereo bar along the optical axis");
  r.Relation("mast_head", mast_head.allFinite() && mast_head.z() >= 0.1 && mast_head.z() <= 5.0,
             "must be finite with z in [0.1, 5] m");
}

bool MastKinematics::Check(std::string* error) const { return CheckOptions(*this, error); }

Pose3 MastKinematics::BodyFromLeft(double pan, double tilt, const StereoRig& rig) const {
  const Eigen::Matrix3d R_mast =
      (Eigen::AngleAxisd(pan, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(tilt, Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  const Eigen::Matrix3d R = R_mast * BodyFromCameraAxes();
  // Stereo bar centred on the optical-axis line through the tilt centre; the
  // left camera sits half a baseline to the camera's -x.
  const Eigen::Vector3d bar_centre_cam(0, 0, camera_offset);
  const Eigen::Vector3d left_in_bar = bar_centre_cam - 0.5 * rig.left_from_right.translation();
  return MakePose(R, mast_head + R * left_in_bar);
}

Pose3 MastKinematics::BodyFromRight(double pan, double tilt, const StereoRig& rig) const {
  return BodyFromLeft(pan, tilt, rig) * rig.left_from_right;
}

void NavcamModel::Visit(OptionsReader& r) {
  r.Child("rig", [&](OptionsReader& c) { rig.Visit(c); });
  r.Child("mast", [&](OptionsReader& c) { mast.Visit(c); });
}

bool NavcamModel::Check(std::string* error) const { return CheckOptions(*this, error); }

}  // namespace vloc
