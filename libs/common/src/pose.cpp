#include "vloc/common/pose.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <istream>
#include <ostream>

namespace vloc {

Eigen::Matrix3d RotationFromRollPitchYaw(double roll, double pitch, double yaw) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Vector3d RollPitchYawFromRotation(const Eigen::Matrix3d& R) {
  const double pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  const double roll = std::atan2(R(2, 1), R(2, 2));
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  return {roll, pitch, yaw};
}

Pose3 MakePose(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
  Pose3 pose = Pose3::Identity();
  pose.linear() = R;
  pose.translation() = t;
  return pose;
}

Pose3 MakePose(double x, double y, double z, double roll, double pitch, double yaw) {
  return MakePose(RotationFromRollPitchYaw(roll, pitch, yaw), Eigen::Vector3d(x, y, z));
}

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& rotation_vector) {
  const double angle = rotation_vector.norm();
  if (angle < 1e-12) return Eigen::Matrix3d::Identity() + Skew(rotation_vector);
  return Eigen::AngleAxisd(angle, rotation_vector / angle).toRotationMatrix();
}

Eigen::Vector3d LogSO3(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

double Heading(const Pose3& world_from_body) {
  const Eigen::Vector3d x = world_from_body.linear().col(0);
  return std::atan2(x.y(), x.x());
}

double WrapAngle(double angle) {
  angle = std::fmod(angle + M_PI, 2.0 * M_PI);
  if (angle <= 0.0) angle += 2.0 * M_PI;
  return angle - M_PI;
}

// With T = (R, t) and perturbations t' = t + dt, R' = exp(dr) R:
//   inverse: R^T, -R^T t. d(R^T) = R^T exp(-dr) => rotation error of the
//   inverse in its parent frame (b) is -R^T dr; translation error
//   d(-R'^T t') = -R^T dt + R^T [dr]x t = -R^T dt - R^T [t]x dr.
Matrix6d InverseCovariance(const Pose3& a_from_b, const Matrix6d& covariance) {
  const Eigen::Matrix3d Rt = a_from_b.linear().transpose();
  const Eigen::Vector3d t = a_from_b.translation();
  Matrix6d J = Matrix6d::Zero();
  J.block<3, 3>(0, 0) = -Rt;
  J.block<3, 3>(0, 3) = -Rt * Skew(t);
  J.block<3, 3>(3, 3) = -Rt;
  return J * covariance * J.transpose();
}

// a_from_c = (R1 R2, R1 t2 + t1). Perturb the first: exp(dr1) R1 R2, t1 + dt1
// + [dr1]x R1 t2 => dt = dt1 - [R1 t2]x dr1, dr = dr1. Perturb the second in
// its parent frame (b): R1 exp(dr2) R2 = exp(R1 dr2) R1 R2; R1 (t2 + dt2) =>
// dt = R1 dt2, dr = R1 dr2.
Matrix6d ComposeCovariance(const Pose3& a_from_b, const Matrix6d& cov_a_from_b,
                           const Pose3& b_from_c, const Matrix6d& cov_b_from_c) {
  const Eigen::Matrix3d R1 = a_from_b.linear();
  Matrix6d J1 = Matrix6d::Identity();
  J1.block<3, 3>(0, 3) = -Skew(R1 * b_from_c.translation());
  Matrix6d J2 = Matrix6d::Zero();
  J2.block<3, 3>(0, 0) = R1;
  J2.block<3, 3>(3, 3) = R1;
  return J1 * cov_a_from_b * J1.transpose() + J2 * cov_b_from_c * J2.transpose();
}

bool IsPlausiblePose(const PoseWithCovariance& p, std::string* why) {
  auto fail = [why](const std::string& what) {
    if (why) *why = what;
    return false;
  };
  const Eigen::Vector3d t = p.pose.translation();
  const Eigen::Matrix3d R = p.pose.linear();
  if (!t.allFinite() || !R.allFinite()) return fail("pose is not finite");
  if (t.cwiseAbs().maxCoeff() > kMaxPositionMetres)
    return fail("position (" + std::to_string(t.x()) + ", " + std::to_string(t.y()) + ", " + std::to_string(t.z()) +
                ") m is beyond " + std::to_string(kMaxPositionMetres) + " m");
  if (!(((R.transpose() * R) - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-6) || !(R.determinant() > 0))
    return fail("rotation is not a proper rotation");
  const Matrix6d& C = p.covariance;
  if (!C.allFinite()) return fail("covariance is not finite");
  if (C.cwiseAbs().maxCoeff() > kMaxCovarianceEntry) return fail("covariance entry beyond 1e12");
  if (C.diagonal().minCoeff() < 0) return fail("covariance has a negative variance");
  if ((C - C.transpose()).cwiseAbs().maxCoeff() > 1e-9 * std::max(1.0, C.cwiseAbs().maxCoeff()))
    return fail("covariance is not symmetric");
  return true;
}

void WritePoseText(std::ostream& os, const PoseWithCovariance& p) {
  const Eigen::Quaterniond q(p.pose.linear());
  const Eigen::Vector3d t = p.pose.translation();
  const auto precision = os.precision(17);
  os << p.utime << ' ' << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << q.w() << ' ' << q.x() << ' ' << q.y()
     << ' ' << q.z();
  for (int i = 0; i < 36; ++i) os << ' ' << p.covariance(i / 6, i % 6);
  os.precision(precision);
}

bool ReadPoseText(std::istream& is, PoseWithCovariance* p) {
  double x, y, z, qw, qx, qy, qz;
  if (!(is >> p->utime >> x >> y >> z >> qw >> qx >> qy >> qz)) return false;
  for (int i = 0; i < 36; ++i)
    if (!(is >> p->covariance(i / 6, i % 6))) return false;
  const Eigen::Quaterniond q(qw, qx, qy, qz);
  if (!(std::abs(q.norm() - 1.0) < 1e-3)) return false;
  p->pose = MakePose(q.normalized().toRotationMatrix(), Eigen::Vector3d(x, y, z));
  return IsPlausiblePose(*p);
}

bool WriteFileAtomically(const std::string& path, const std::string& text, std::string* error) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp);
    if (!f) {
      if (error) *error = "cannot write " + tmp + " (check the directory exists and is writable)";
      return false;
    }
    f << text;
    f.flush();
    if (!f) {
      if (error) *error = "writing " + tmp + " failed (disk full?)";
      return false;
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    if (error) *error = "cannot rename " + tmp + " to " + path;
    return false;
  }
  return true;
}

}  // namespace vloc
