#include "vloc/sim/uav_flight.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include "vloc/common/options.h"

namespace vloc {

namespace {

bool HeightTriples(const std::vector<double>& waypoints) {
  if (waypoints.empty() || waypoints.size() % 3 != 0) return false;
  for (size_t i = 2; i < waypoints.size(); i += 3)
    if (!(waypoints[i] > 0.5)) return false;
  return true;
}

}  // namespace

void UavFlightOptions::Visit(OptionsReader& r) {
  r.Optional("takeoff", &takeoff, "m, x east / y north of the take-off hover (marker below)");
  r.Optional("calibration_height", &calibration_height, "m above ground, hover height over the marker", Above(0.5));
  r.Optional("calibration_hover", &calibration_hover, "s, hover time before the route", NonNegative());
  r.Optional("waypoints", &waypoints, "m, x y height triples of the route",
             Rule<std::vector<double>>(HeightTriples, "x y height triples, at least one, each height > 0.5 m"));
  r.Optional("speed", &speed, "m/s, cruise speed", Positive());
  r.Optional("acceleration", &acceleration, "m/s^2, speed ramps", Positive());
  r.Optional("final_hover", &final_hover, "s, hover at the last waypoint", NonNegative());
  r.Optional("wobble_amplitude", &wobble_amplitude, "rad, roll/pitch wobble amplitude", InRange(0, 0.3));
  r.Optional("wobble_period", &wobble_period, "s, wobble period", Positive());
  r.Optional("seed", &seed, "wobble phase seed");
}

bool UavFlightOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

Eigen::Matrix3d UavBodyFromCameraRotation() {
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d(0, -1, 0);  // camera x (image right) = body -y
  R.col(1) = Eigen::Vector3d(-1, 0, 0);  // camera y (image down) = body -x
  R.col(2) = Eigen::Vector3d(0, 0, -1);  // camera z (optical axis) = body -z (down)
  return R;
}

Pose3 UavBodyFromCamera() { return MakePose(UavBodyFromCameraRotation(), Eigen::Vector3d::Zero()); }

UavFlight::UavFlight(const UavFlightOptions& options) : options_(options) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument(error);
  points_.push_back(Eigen::Vector3d(options_.takeoff.x(), options_.takeoff.y(), options_.calibration_height));
  for (size_t i = 0; i + 2 < options_.waypoints.size(); i += 3) {
    Eigen::Vector3d p(options_.waypoints[i], options_.waypoints[i + 1], options_.waypoints[i + 2]);
    if ((p - points_.back()).norm() > 1e-6) points_.push_back(p);
  }
  // Dense arc-length table of the curve.
  const int segments = static_cast<int>(points_.size()) - 1;
  const int per_segment = 400;
  Eigen::Vector3d previous = points_.front();
  table_u_.push_back(0.0);
  table_s_.push_back(0.0);
  for (int k = 1; k <= segments * per_segment; ++k) {
    const double u = static_cast<double>(k) / per_segment;
    const Eigen::Vector3d p = CurvePoint(u, nullptr);
    table_u_.push_back(u);
    table_s_.push_back(table_s_.back() + (p - previous).norm());
    previous = p;
  }
  length_ = table_s_.back();
  // Trapezoidal speed profile (triangular when the route is short).
  cruise_ = options_.speed;
  ramp_time_ = cruise_ / options_.acceleration;
  ramp_length_ = 0.5 * options_.acceleration * ramp_time_ * ramp_time_;
  if (2 * ramp_length_ > length_) {
    ramp_length_ = 0.5 * length_;
    ramp_time_ = std::sqrt(2 * ramp_length_ / options_.acceleration);
    cruise_ = options_.acceleration * ramp_time_;
  }
  route_time_ = segments == 0 ? 0.0 : 2 * ramp_time_ + (length_ - 2 * ramp_length_) / cruise_;
  duration_ = options_.calibration_hover + route_time_ + options_.final_hover;
  std::mt19937 rng(static_cast<uint32_t>(options_.seed));
  std::uniform_real_distribution<double> phase(0.0, 2 * M_PI);
  phase_roll_ = phase(rng);
  phase_pitch_ = phase(rng);
}

Eigen::Vector3d UavFlight::CurvePoint(double u, Eigen::Vector3d* derivative) const {
  const int segments = static_cast<int>(points_.size()) - 1;
  if (segments <= 0) {
    if (derivative) derivative->setZero();
    return points_.front();
  }
  u = std::clamp(u, 0.0, static_cast<double>(segments));
  int i = std::min(static_cast<int>(std::floor(u)), segments - 1);
  const double s = u - i;
  auto P = [&](int k) -> Eigen::Vector3d {
    if (k < 0) return 2 * points_[0] - points_[1];
    if (k > segments) return 2 * points_[segments] - points_[segments - 1];
    return points_[k];
  };
  const Eigen::Vector3d p0 = P(i - 1), p1 = P(i), p2 = P(i + 1), p3 = P(i + 2);
  // Uniform Catmull-Rom.
  const Eigen::Vector3d a = 2 * p1;
  const Eigen::Vector3d b = p2 - p0;
  const Eigen::Vector3d c = 2 * p0 - 5 * p1 + 4 * p2 - p3;
  const Eigen::Vector3d d = -p0 + 3 * p1 - 3 * p2 + p3;
  Eigen::Vector3d point = 0.5 * (a + b * s + c * s * s + d * s * s * s);
  if (derivative) *derivative = 0.5 * (b + 2 * c * s + 3 * d * s * s);
  // Height: monotone cubic Hermite (no overshoot above or below the waypoints).
  auto slope = [&](int k) {
    if (k <= 0 || k >= segments) return 0.0;
    const double d0 = points_[k].z() - points_[k - 1].z(), d1 = points_[k + 1].z() - points_[k].z();
    if (d0 * d1 <= 0) return 0.0;
    const double m = 0.5 * (d0 + d1);
    const double limit = 3.0 * std::min(std::abs(d0), std::abs(d1));
    return std::copysign(std::min(std::abs(m), limit), m);
  };
  const double z0 = p1.z(), z1 = p2.z(), m0 = slope(i), m1 = slope(i + 1);
  const double s2 = s * s, s3 = s2 * s;
  point.z() = (2 * s3 - 3 * s2 + 1) * z0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * z1 + (s3 - s2) * m1;
  if (derivative)
    derivative->z() = (6 * s2 - 6 * s) * z0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * z1 + (3 * s2 - 2 * s) * m1;
  return point;
}

double UavFlight::ArcLengthAtTime(double rt, double* speed) const {
  const double a = options_.acceleration;
  if (rt <= 0) {
    *speed = 0;
    return 0;
  }
  if (rt >= route_time_) {
    *speed = 0;
    return length_;
  }
  if (rt < ramp_time_) {
    *speed = a * rt;
    return 0.5 * a * rt * rt;
  }
  const double cruise_end = route_time_ - ramp_time_;
  if (rt <= cruise_end) {
    *speed = cruise_;
    return ramp_length_ + cruise_ * (rt - ramp_time_);
  }
  const double left = route_time_ - rt;
  *speed = a * left;
  return length_ - 0.5 * a * left * left;
}

UavState UavFlight::StateAt(double t) const {
  t = std::clamp(t, 0.0, duration_);
  UavState state;
  state.t = t;
  double speed = 0;
  const double s = ArcLengthAtTime(t - options_.calibration_hover, &speed);
  // Arc length -> curve parameter.
  const auto it = std::lower_bound(table_s_.begin(), table_s_.end(), s);
  double u = 0;
  if (it == table_s_.begin()) {
    u = 0;
  } else if (it == table_s_.end()) {
    u = table_u_.back();
  } else {
    const size_t k = static_cast<size_t>(it - table_s_.begin());
    const double ds = table_s_[k] - table_s_[k - 1];
    const double f = ds > 0 ? (s - table_s_[k - 1]) / ds : 0.0;
    u = table_u_[k - 1] + f * (table_u_[k] - table_u_[k - 1]);
  }
  Eigen::Vector3d tangent;
  state.position = CurvePoint(u, &tangent);
  // Yaw follows the horizontal tangent; at the hovers it holds the route's
  // first/last direction.
  if (tangent.head<2>().norm() < 1e-9) CurvePoint(std::min(u + 1e-3, table_u_.back()), &tangent);
  state.yaw = std::atan2(tangent.y(), tangent.x());
  state.speed = speed;
  const double w = 2 * M_PI / options_.wobble_period;
  state.roll = options_.wobble_amplitude * std::sin(w * t + phase_roll_);
  state.pitch = options_.wobble_amplitude * std::sin(0.77 * w * t + phase_pitch_);
  return state;
}

Pose3 UavFlight::WorldFromBody(double t) const {
  const UavState s = StateAt(t);
  return MakePose(RotationFromRollPitchYaw(s.roll, s.pitch, s.yaw), s.position);
}

Pose3 UavFlight::WorldFromCamera(double t) const { return WorldFromBody(t) * UavBodyFromCamera(); }

}  // namespace vloc
