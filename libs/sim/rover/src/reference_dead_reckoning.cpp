#include "vloc/sim/reference_dead_reckoning.h"

#include <algorithm>

namespace vloc::sim {
namespace {

// Cumulative wheel distance at `utime`, linear between samples (clamped).
double WheelDistanceAt(const std::vector<WheelOdometrySample>& wheel, int64_t utime, size_t* cursor) {
  if (wheel.empty()) return 0.0;
  if (utime <= wheel.front().utime) return wheel.front().distance;
  if (utime >= wheel.back().utime) return wheel.back().distance;
  while (*cursor + 1 < wheel.size() && wheel[*cursor + 1].utime < utime) ++*cursor;
  const WheelOdometrySample& a = wheel[*cursor];
  const WheelOdometrySample& b = wheel[*cursor + 1];
  const double f = static_cast<double>(utime - a.utime) / static_cast<double>(b.utime - a.utime);
  return a.distance + f * (b.distance - a.distance);
}

}  // namespace

std::vector<ReferencePoseSample> IntegrateReferenceDeadReckoning(const Pose3& initial,
                                                                 const std::vector<ImuSample>& imu,
                                                                 const std::vector<WheelOdometrySample>& wheel) {
  std::vector<ReferencePoseSample> out;
  if (imu.empty()) return out;
  out.reserve(imu.size());
  Eigen::Matrix3d R = initial.linear();
  Eigen::Vector3d p = initial.translation();
  size_t cursor = 0;
  double distance = WheelDistanceAt(wheel, imu.front().utime, &cursor);
  out.push_back({imu.front().utime, initial});
  for (size_t k = 1; k < imu.size(); ++k) {
    const double dt = (imu[k].utime - imu[k - 1].utime) * 1e-6;
    const Eigen::Matrix3d R_new = R * ExpSO3(imu[k].angular_velocity * dt);
    const double d = WheelDistanceAt(wheel, imu[k].utime, &cursor);
    p += (d - distance) * 0.5 * (R.col(0) + R_new.col(0));
    distance = d;
    R = R_new;
    out.push_back({imu[k].utime, MakePose(R, p)});
  }
  return out;
}

}  // namespace vloc::sim
