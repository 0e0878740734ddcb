#pragma once
// Rigid poses and their covariances. A pose is named by what it maps:
// world_from_body maps body-frame points into the world frame.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <iosfwd>
#include <string>

namespace vloc {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;
using Pose3 = Eigen::Isometry3d;

// A pose with its covariance at a time. Covariance is over [x y z rx ry rz]:
// position error (m) in the parent frame and rotation error (rad) as a
// rotation vector in the parent frame (R = exp([r]x) * R_estimate).
// An all-zero covariance means "unknown".
struct PoseWithCovariance {
  int64_t utime = 0;             // microseconds
  Pose3 pose = Pose3::Identity();
  Matrix6d covariance = Matrix6d::Zero();
};

// Largest position magnitude any vloc frame holds (10,000 km): a local
// level frame on a planet. Beyond it a number is corrupt, not a position:
// 1e308 is finite but overflows the first product it enters.
inline constexpr double kMaxPositionMetres = 1e7;
// Largest covariance entry accepted (m^2 or rad^2): a 1,000 km sigma.
inline constexpr double kMaxCovarianceEntry = 1e12;

// True when the pose is finite, its position within kMaxPositionMetres, its
// rotation orthonormal, and its covariance finite, symmetric within
// rounding, with entries within kMaxCovarianceEntry and a non-negative
// diagonal. Otherwise false and *why (when not null) says what is wrong.
bool IsPlausiblePose(const PoseWithCovariance& p, std::string* why = nullptr);

// One line of text: utime x y z qw qx qy qz and the 36 covariance entries
// (row-major), at full precision; ReadPoseText reads it back (false when the
// numbers are missing or the pose is not plausible).
void WritePoseText(std::ostream& os, const PoseWithCovariance& p);
bool ReadPoseText(std::istream& is, PoseWithCovariance* p);

// Writes `text` to `path` through a temporary file and a rename, so a crash
// mid-write leaves the previous file whole. False with *error naming the file.
bool WriteFileAtomically(const std::string& path, const std::string& text, std::string* error);

// Rotation from roll (about x), pitch (about y), yaw (about z), applied as
// R = Rz(yaw) * Ry(pitch) * Rx(roll). Radians.
Eigen::Matrix3d RotationFromRollPitchYaw(double roll, double pitch, double yaw);
// Inverse of RotationFromRollPitchYaw; returns (roll, pitch, yaw), radians.
Eigen::Vector3d RollPitchYawFromRotation(const Eigen::Matrix3d& R);

Pose3 MakePose(const Eigen::Matrix3d& R, const Eigen::Vector3d& t);
Pose3 MakePose(double x, double y, double z, double roll, double pitch, double yaw);

// SO(3) exponential and logarithm (rotation vector <-> rotation matrix).
Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& rotation_vector);
Eigen::Vector3d LogSO3(const Eigen::Matrix3d& R);
Eigen::Matrix3d Skew(const Eigen::Vector3d& v);

// Heading (yaw) of a pose, radians, from the body x axis projected on the
// level plane.
double Heading(const Pose3& world_from_body);

// Wraps an angle to (-pi, pi].
double WrapAngle(double angle);

// Covariance of b_from_a (the inverse pose) from the covariance of
// a_from_b, both in the convention above (first order).
Matrix6d InverseCovariance(const Pose3& a_from_b, const Matrix6d& covariance);

// Covariance of a_from_c = a_from_b * b_from_c from independent covariances
// of a_from_b and b_from_c, both in the convention above (first order).
Matrix6d ComposeCovariance(const Pose3& a_from_b, const Matrix6d& cov_a_from_b,
                           const Pose3& b_from_c, const Matrix6d& cov_b_from_c);

}  // namespace vloc
