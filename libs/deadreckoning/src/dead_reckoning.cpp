#include "vloc/deadreckoning/dead_reckoning.h"

#include <glog/logging.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "vloc/common/options.h"
#include "vloc/common/site_window.h"

namespace vloc {

namespace {
constexpr int kP = 0, kR = 3, kS = 6, kC = 7, kB = 8;
constexpr double kMicro = 1e-6;
// Samples the attitude history and the wheel queue hold at most, whatever
// their rate: their time spans (~6.5 s, wheel_wait_s) hold 650 and 10 at
// 100 Hz and 20 Hz; samples microseconds apart (a flood) stay within ~2 MB.
constexpr size_t kMaxBufferedSamples = 20'000;
}  // namespace

void DeadReckoningOptions::Visit(OptionsReader& r) {
  r.Optional("gravity_mps2", &gravity_mps2, "m/s^2, local gravity", Positive());
  r.Optional("publish_period_s", &publish_period_s, "s, message time between DR_POSE", Positive());
  r.Optional("initial_position", &initial_position, "m, start position in world", Each(Finite()));
  r.Optional("initial_yaw_rad", &initial_yaw_rad, "rad, start heading");
  r.Optional("initial_position_sigma_m", &initial_position_sigma_m, "m, start position 1-sigma", Positive());
  r.Optional("initial_yaw_sigma_rad", &initial_yaw_sigma_rad, "rad, start heading 1-sigma", Positive());
  r.Optional("tilt_sigma_rad", &tilt_sigma_rad, "rad, gravity roll/pitch 1-sigma", Positive());
  r.Optional("odometry_scale", &odometry_scale, "distance per odometer metre", Positive());
  r.Optional("along_track_sigma_per_m", &along_track_sigma_per_m, "along-track sigma per metre", NonNegative());
  r.Optional("cross_track_sigma_per_m", &cross_track_sigma_per_m, "cross-track sigma per metre", NonNegative());
  r.Optional("distance_noise_m_per_sqrt_m", &distance_noise_m_per_sqrt_m, "m/sqrt(m), random position noise",
             NonNegative());
  r.Optional("gyro_noise_density", &gyro_noise_density, "rad/s/sqrt(Hz)", NonNegative());
  r.Optional("gyro_bias_sigma", &gyro_bias_sigma, "rad/s, constant gyro bias 1-sigma", NonNegative());
  r.Optional("gyro_bias_walk", &gyro_bias_walk, "rad/s^2/sqrt(Hz)", NonNegative());
  r.Optional("still_gyro_threshold", &still_gyro_threshold, "rad/s", Positive());
  r.Optional("still_accel_tolerance", &still_accel_tolerance, "m/s^2", Positive());
  r.Optional("still_speed_threshold", &still_speed_threshold, "m/s", Positive());
  r.Optional("still_settle_s", &still_settle_s, "s of stillness ignored before averaging", NonNegative());
  r.Optional("still_duration_s", &still_duration_s, "s averaged per gravity update", Positive());
  r.Optional("max_imu_gap_s", &max_imu_gap_s, "s, longer IMU gaps are bridged", Positive());
  r.Optional("gap_attitude_sigma_rate", &gap_attitude_sigma_rate, "rad/s added over a bridged gap", NonNegative());
  r.Optional("max_speed_mps", &max_speed_mps, "m/s, faster odometer increments dropped", Positive());
  r.Optional("wheel_wait_s", &wheel_wait_s, "s, wheel samples wait this long for the IMU", NonNegative());
  r.Optional("reset_backward_jump_s", &reset_backward_jump_s, "s, larger backward jumps restart", Positive());
  r.Optional("max_forward_jump_s", &max_forward_jump_s, "s, larger forward jumps wait for the next sample to confirm",
             Below(1e9));
  r.Optional("max_gyro_rate_rps", &max_gyro_rate_rps, "rad/s, faster rates are rejected as not physical");
  r.Optional("max_accel_mps2", &max_accel_mps2, "m/s^2, larger specific forces are rejected");
  r.Optional("site_window", &site_window, "site arrivals remembered (newest ids) to drop repeats", AtLeast(1));
  r.Relation("max_forward_jump_s", max_forward_jump_s > max_imu_gap_s, "must be above max_imu_gap_s");
  r.Relation("max_gyro_rate_rps", max_gyro_rate_rps > still_gyro_threshold, "must exceed still_gyro_threshold");
  r.Relation("max_accel_mps2", max_accel_mps2 > gravity_mps2, "must exceed gravity_mps2");
}

bool DeadReckoningOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

DeadReckoning::DeadReckoning(const DeadReckoningOptions& options) : options_(options) {}

void DeadReckoning::Reset(const char* why) {
  LOG(WARNING) << "dead reckoning restarts: " << why;
  ++stats_.resets;
  const DeadReckoningStats keep = stats_;
  *this = DeadReckoning(options_);
  stats_ = keep;
}

bool DeadReckoning::TimeWentBack(int64_t utime, int64_t last, const char* what) {
  if (utime > last) return false;
  if ((last - utime) * kMicro > options_.reset_backward_jump_s) {
    Reset(("time of " + std::string(what) + " jumped back " + std::to_string((last - utime) * kMicro) +
           " s (a new log?)").c_str());
    return false;  // take the sample as the new start
  }
  return true;
}

void DeadReckoning::Initialize(const ImuSample& first) {
  // Roll/pitch from gravity when the first sample is consistent with standing still.
  double roll = 0, pitch = 0;
  const Eigen::Vector3d f = first.linear_acceleration;
  const bool gravity_like = std::abs(f.norm() - options_.gravity_mps2) < options_.still_accel_tolerance;
  if (gravity_like) {
    roll = std::atan2(f.y(), f.z());
    pitch = std::atan2(-f.x(), std::hypot(f.y(), f.z()));
  } else {
    LOG(WARNING) << "dead reckoning: first IMU sample is not at rest (|f| = " << f.norm() << " m/s^2, gravity "
                 << options_.gravity_mps2 << "); starting level until the first stop";
  }
  R_ = RotationFromRollPitchYaw(roll, pitch, options_.initial_yaw_rad);
  p_ = options_.initial_position;
  gyro_bias_.setZero();
  P_.setZero();
  P_.block<3, 3>(kP, kP) = Eigen::Matrix3d::Identity() * std::pow(options_.initial_position_sigma_m, 2);
  const double tilt = gravity_like ? 0.02 : 0.1;  // until the alignment
  P_.block<3, 3>(kR, kR) =
      Eigen::Vector3d(tilt * tilt, tilt * tilt, std::pow(options_.initial_yaw_sigma_rad, 2)).asDiagonal();
  P_(kS, kS) = std::pow(options_.along_track_sigma_per_m, 2);
  P_(kC, kC) = std::pow(options_.cross_track_sigma_per_m, 2);
  P_.block<3, 3>(kB, kB) = Eigen::Matrix3d::Identity() * std::pow(options_.gyro_bias_sigma, 2);
  imu_utime_ = state_utime_ = first.utime;
  next_publish_utime_ = first.utime;
  attitude_history_.clear();
  attitude_history_.emplace_back(first.utime, R_);
  initialized_ = true;
  aligned_ = false;
  stop_updated_ = false;
}

void DeadReckoning::Align(const Eigen::Vector3d& f) {
  const Eigen::Vector3d rpy = RollPitchYawFromRotation(R_);
  R_ = RotationFromRollPitchYaw(std::atan2(f.y(), f.z()), std::atan2(-f.x(), std::hypot(f.y(), f.z())), rpy.z());
  for (int i : {kR, kR + 1}) {
    P_.row(i).setZero();
    P_.col(i).setZero();
    P_(i, i) = options_.tilt_sigma_rad * options_.tilt_sigma_rad;
  }
  if (!attitude_history_.empty()) attitude_history_.back().second = R_;
  aligned_ = true;
  ++stats_.gravity_updates;
  EmitPendingArrivals();
}

void DeadReckoning::PropagateAttitude(const Eigen::Vector3d& rate, double dt) {
  R_ = R_ * ExpSO3(rate * dt);
  // Make R_ exactly orthonormal again now and then (cheap).
  const Eigen::Quaterniond q(R_);
  R_ = q.normalized().toRotationMatrix();
  StateMatrix F = StateMatrix::Identity();
  F.block<3, 3>(kR, kB) = -R_ * dt;  // true rate = measured - bias
  P_ = F * P_ * F.transpose();
  P_.block<3, 3>(kR, kR) += Eigen::Matrix3d::Identity() * options_.gyro_noise_density * options_.gyro_noise_density * dt;
  P_.block<3, 3>(kB, kB) += Eigen::Matrix3d::Identity() * options_.gyro_bias_walk * options_.gyro_bias_walk * dt;
}

bool DeadReckoning::Plausible(const ImuSample& s, std::string* why) const {
  if (s.utime < 0 || s.utime > kMaxPlausibleUtime) {
    *why = "its time " + std::to_string(s.utime) + " us is outside [0, 2^53]";
    return false;
  }
  if (!s.angular_velocity.allFinite() || !s.linear_acceleration.allFinite()) {
    *why = "it is not finite";
    return false;
  }
  if (s.angular_velocity.cwiseAbs().maxCoeff() > options_.max_gyro_rate_rps) {
    *why = "a rate of " + std::to_string(s.angular_velocity.cwiseAbs().maxCoeff()) +
           " rad/s exceeds max_gyro_rate_rps " + std::to_string(options_.max_gyro_rate_rps);
    return false;
  }
  if (s.linear_acceleration.cwiseAbs().maxCoeff() > options_.max_accel_mps2) {
    *why = "a specific force of " + std::to_string(s.linear_acceleration.cwiseAbs().maxCoeff()) +
           " m/s^2 exceeds max_accel_mps2 " + std::to_string(options_.max_accel_mps2);
    return false;
  }
  return true;
}

DeadReckoning::TimeStep DeadReckoning::GateTime(int64_t utime, int64_t last, std::optional<int64_t>* held,
                                                const char* what) {
  const double step_s = static_cast<double>(utime - last) * kMicro;  // both in [0, 2^53]: no overflow
  const bool jump = step_s > options_.max_forward_jump_s || -step_s > options_.reset_backward_jump_s;
  if (!jump) {
    if (*held) {
      ++stats_.time_outliers;
      LOG(WARNING) << "dead reckoning: " << what << " sample at " << **held << " us jumped from " << last
                   << " us and the stream did not follow; dropped as a time outlier";
      held->reset();
    }
    return TimeStep::kContinues;
  }
  if (*held && utime >= **held && static_cast<double>(utime - **held) * kMicro <= options_.max_imu_gap_s) {
    LOG(WARNING) << "dead reckoning: " << what << " time jumped " << static_cast<double>(**held - last) * kMicro
                 << " s and the next sample confirms it";
    held->reset();
    return TimeStep::kConfirmedJump;
  }
  if (*held) ++stats_.time_outliers;
  *held = utime;
  LOG(WARNING) << "dead reckoning: " << what << " sample at " << utime << " us jumps " << step_s
               << " s from the last; held until the next sample confirms the jump";
  return TimeStep::kHeld;
}

void DeadReckoning::AddImu(const ImuSample& s) {
  std::string why;
  if (!Plausible(s, &why)) {
    ++stats_.implausible;
    LOG_EVERY_N(WARNING, 100) << "dead reckoning: IMU sample rejected: " << why << " (" << google::COUNTER
                              << " so far)";
    return;
  }
  if (initialized_) {
    switch (GateTime(s.utime, imu_utime_, &held_imu_utime_, "IMU")) {
      case TimeStep::kHeld:
        held_imu_ = s;
        return;
      case TimeStep::kConfirmedJump: {
        const ImuSample first = *held_imu_;
        held_imu_.reset();
        if (first.utime < imu_utime_) Reset("IMU time jumped back (a new log?)");
        ApplyImu(first);
        break;
      }
      case TimeStep::kContinues:
        held_imu_.reset();
        break;
    }
  }
  ApplyImu(s);
}

void DeadReckoning::ApplyImu(const ImuSample& s) {
  if (!initialized_) {
    Initialize(s);
    ++stats_.imu_used;
    FlushWheel(false);
    return;
  }
  if (TimeWentBack(s.utime, imu_utime_, "IMU")) {
    ++stats_.imu_dropped;
    LOG_EVERY_N(WARNING, 100) << "dead reckoning: IMU sample at " << s.utime << " is not after " << imu_utime_
                              << " (duplicated or out of order); dropped (" << google::COUNTER << " so far)";
    return;
  }
  if (!initialized_) {  // Reset() above
    Initialize(s);
    ++stats_.imu_used;
    return;
  }
  const double dt = (s.utime - imu_utime_) * kMicro;
  PropagateImu(s, dt);
  ++stats_.imu_used;
  UpdateStillness(s, dt);
  FlushWheel(false);
}

void DeadReckoning::PropagateImu(const ImuSample& s, double dt) {
  const Eigen::Vector3d rate = s.angular_velocity - gyro_bias_;
  if (dt > options_.max_imu_gap_s) {
    ++stats_.imu_gaps;
    LOG(WARNING) << "dead reckoning: " << dt << " s without IMU before " << s.utime
                 << "; attitude held over the gap, its sigma inflated";
    P_.block<3, 3>(kR, kR) += Eigen::Matrix3d::Identity() * std::pow(options_.gap_attitude_sigma_rate * dt, 2);
    PropagateAttitude(rate, options_.max_imu_gap_s);
  } else {
    PropagateAttitude(rate, dt);
  }
  imu_utime_ = s.utime;
  state_utime_ = std::max(state_utime_, s.utime);
  attitude_history_.emplace_back(s.utime, R_);
  while (attitude_history_.size() > 2 &&
         ((attitude_history_.back().first - attitude_history_.front().first) * kMicro >
              options_.wheel_wait_s + options_.max_imu_gap_s + 5.0 ||
          attitude_history_.size() > kMaxBufferedSamples))
    attitude_history_.pop_front();
}

void DeadReckoning::UpdateStillness(const ImuSample& s, double dt) {
  const bool still = s.angular_velocity.norm() < options_.still_gyro_threshold &&
                     std::abs(s.linear_acceleration.norm() - options_.gravity_mps2) < options_.still_accel_tolerance &&
                     std::abs(last_speed_) < options_.still_speed_threshold;
  if (!still) {
    if (!aligned_) {
      LOG(WARNING) << "dead reckoning: moving before " << options_.still_duration_s
                   << " s of standing still; roll/pitch start from the first IMU sample";
      aligned_ = true;
      EmitPendingArrivals();
    }
    still_seconds_ = 0;
    still_force_sum_.setZero();
    still_count_ = 0;
    stop_updated_ = false;
    return;
  }
  if (stop_updated_) return;
  still_seconds_ += dt;
  if (still_seconds_ > options_.still_settle_s) {
    still_force_sum_ += R_ * s.linear_acceleration;  // world frame: gyro-compensated while settling
    ++still_count_;
  }
  if (still_seconds_ >= options_.still_settle_s + options_.still_duration_s && still_count_ > 0) {
    const Eigen::Vector3d mean_force_body = R_.transpose() * (still_force_sum_ / still_count_);
    if (aligned_) {
      GravityUpdate(mean_force_body);
    } else {
      Align(mean_force_body);
    }
    stop_updated_ = true;
  }
}

void DeadReckoning::GravityUpdate(const Eigen::Vector3d& f) {
  // With R_true = exp(dr) R, R f / |f| = exp(-dr) e_z ~ (-dr_y, dr_x, 1): the
  // accelerometer observes the world-frame tilt errors dr_x, dr_y.
  const Eigen::Vector3d v = R_ * f.normalized();
  const Eigen::Vector2d y(v.y(), -v.x());
  Eigen::Matrix<double, 2, kN> H = Eigen::Matrix<double, 2, kN>::Zero();
  H(0, kR) = 1;
  H(1, kR + 1) = 1;
  const Eigen::Matrix2d S = H * P_ * H.transpose() + Eigen::Matrix2d::Identity() * std::pow(options_.tilt_sigma_rad, 2);
  Eigen::Matrix<double, kN, 2> K = P_ * H.transpose() * S.inverse();
  // Attitude only: neither the position nor the gyro bias is corrected
  // through its correlation with the tilt (one gravity vector per stop,
  // with the accelerometer bias in it, does not pin them down reliably).
  // The Joseph form below keeps the covariance right for this gain.
  K.block<3, 2>(kP, 0).setZero();
  K.block<2, 2>(kS, 0).setZero();
  K.block<3, 2>(kB, 0).setZero();
  const Eigen::Matrix<double, kN, 1> dx = K * y;
  R_ = ExpSO3(dx.segment<3>(kR)) * R_;
  const StateMatrix IKH = StateMatrix::Identity() - K * H;
  P_ = IKH * P_ * IKH.transpose() + K * Eigen::Matrix2d::Identity() * std::pow(options_.tilt_sigma_rad, 2) * K.transpose();
  if (!attitude_history_.empty()) attitude_history_.back().second = R_;
  ++stats_.gravity_updates;
}

Eigen::Matrix3d DeadReckoning::AttitudeAt(int64_t utime) const {
  if (attitude_history_.empty()) return R_;
  if (utime <= attitude_history_.front().first) return attitude_history_.front().second;
  if (utime >= attitude_history_.back().first) return attitude_history_.back().second;
  auto it = std::lower_bound(attitude_history_.begin(), attitude_history_.end(), utime,
                             [](const auto& a, int64_t t) { return a.first < t; });
  const auto& b = *it;
  const auto& a = *(it - 1);
  const double w = static_cast<double>(utime - a.first) / static_cast<double>(b.first - a.first);
  const Eigen::Quaterniond qa(a.second), qb(b.second);
  return qa.slerp(w, qb).toRotationMatrix();
}

void DeadReckoning::AddWheel(const WheelOdometrySample& s) {
  if (s.utime < 0 || s.utime > kMaxPlausibleUtime || !std::isfinite(s.distance) || !std::isfinite(s.speed) ||
      std::abs(s.distance) > kMaxPositionMetres || std::abs(s.speed) > 100 * options_.max_speed_mps) {
    ++stats_.implausible;
    LOG_EVERY_N(WARNING, 100) << "dead reckoning: wheel sample at " << s.utime << " us (distance " << s.distance
                              << " m, speed " << s.speed << " m/s) is not plausible; rejected (" << google::COUNTER
                              << " so far)";
    return;
  }
  const int64_t last = !wheel_queue_.empty() ? wheel_queue_.back().utime : (have_wheel_ ? last_wheel_.utime : INT64_MIN);
  if (last != INT64_MIN) {
    switch (GateTime(s.utime, last, &held_wheel_utime_, "wheel odometry")) {
      case TimeStep::kHeld:
        held_wheel_ = s;
        return;
      case TimeStep::kConfirmedJump: {
        const WheelOdometrySample first = *held_wheel_;
        held_wheel_.reset();
        if (first.utime < last) {
          // The odometer's own restart: rebase on it, keep the IMU state.
          wheel_queue_.clear();
          have_wheel_ = false;
        }
        wheel_queue_.push_back(first);
        break;
      }
      case TimeStep::kContinues:
        held_wheel_.reset();
        break;
    }
  }
  const int64_t newest =
      !wheel_queue_.empty() ? wheel_queue_.back().utime : (have_wheel_ ? last_wheel_.utime : INT64_MIN);
  if (newest != INT64_MIN && TimeWentBack(s.utime, newest, "wheel odometry")) {
    ++stats_.wheel_dropped;
    LOG_EVERY_N(WARNING, 100) << "dead reckoning: wheel sample at " << s.utime << " is not after " << newest
                              << " (duplicated or out of order); dropped (" << google::COUNTER << " so far)";
    return;
  }
  wheel_queue_.push_back(s);
  FlushWheel(false);
  if (wheel_queue_.size() > kMaxBufferedSamples) {
    LOG_EVERY_N(WARNING, 1000) << "dead reckoning: more than " << kMaxBufferedSamples
                               << " wheel samples wait for the IMU (samples microseconds apart?); the oldest "
                               << "integrated now (" << google::COUNTER << " so far)";
    IntegrateWheel(wheel_queue_.front());
    wheel_queue_.pop_front();
  }
}

void DeadReckoning::FlushWheel(bool force_all) {
  if (!initialized_) {
    // Without attitude nothing can be integrated; keep only the newest sample as the odometer reference.
    while (wheel_queue_.size() > 1) wheel_queue_.pop_front();
    return;
  }
  while (!wheel_queue_.empty()) {
    const WheelOdometrySample& s = wheel_queue_.front();
    const bool imu_caught_up = s.utime <= imu_utime_;
    const bool waited_too_long = (s.utime - imu_utime_) * kMicro > options_.wheel_wait_s;
    if (!imu_caught_up && !waited_too_long && !force_all) break;
    IntegrateWheel(s);
    wheel_queue_.pop_front();
  }
}

void DeadReckoning::IntegrateWheel(const WheelOdometrySample& s) {
  last_speed_ = s.speed;
  if (!have_wheel_) {
    have_wheel_ = true;
    last_wheel_ = s;
    ++stats_.wheel_used;
    return;
  }
  const double dt = (s.utime - last_wheel_.utime) * kMicro;
  double ds = (s.distance - last_wheel_.distance) * options_.odometry_scale;
  if (ds < -1e-9) {
    ++stats_.odometer_resets;
    LOG(WARNING) << "dead reckoning: odometer went from " << last_wheel_.distance << " to " << s.distance
                 << " m at " << s.utime << " (reset?); rebased, no distance integrated";
    last_wheel_ = s;
    return;
  }
  if (ds > options_.max_speed_mps * dt + 0.05) {
    ++stats_.wheel_dropped;
    LOG(WARNING) << "dead reckoning: odometer increment " << ds << " m in " << dt << " s at " << s.utime
                 << " exceeds max_speed_mps " << options_.max_speed_mps << "; dropped and rebased";
    last_wheel_ = s;
    return;
  }
  ds = std::max(0.0, ds);
  if (ds > 0) {
    const Eigen::Matrix3d R_mid = AttitudeAt((last_wheel_.utime + s.utime) / 2);
    const Eigen::Vector3d u = R_mid.col(0) * ds;
    const Eigen::Vector3d v = R_mid.col(1) * ds;
    p_ += u;
    StateMatrix F = StateMatrix::Identity();
    F.block<3, 3>(kP, kR) = -Skew(u);
    F.block<3, 1>(kP, kS) = u;
    F.block<3, 1>(kP, kC) = v;
    P_ = F * P_ * F.transpose();
    P_.block<3, 3>(kP, kP) +=
        Eigen::Matrix3d::Identity() * options_.distance_noise_m_per_sqrt_m * options_.distance_noise_m_per_sqrt_m * ds;
    stats_.distance_m += ds;
  }
  last_wheel_ = s;
  state_utime_ = std::max(state_utime_, s.utime);
  ++stats_.wheel_used;
}

bool DeadReckoning::SetStartPose(const Pose3& world_from_body) {
  if (!world_from_body.matrix().allFinite()) return false;
  if (stats_.distance_m > 0) {
    LOG(WARNING) << "dead reckoning: start pose arrived after " << stats_.distance_m << " m of driving; ignored";
    return false;
  }
  options_.initial_position = world_from_body.translation();
  options_.initial_yaw_rad = Heading(world_from_body);
  if (initialized_) {
    const Eigen::Vector3d rpy = RollPitchYawFromRotation(R_);
    R_ = RotationFromRollPitchYaw(rpy.x(), rpy.y(), options_.initial_yaw_rad);
    p_ = options_.initial_position;
    for (auto& entry : attitude_history_) entry.second = R_;
    if (!ready_sites_.empty() || site_reported_)
      LOG(WARNING) << "dead reckoning: start pose set after a site pose was reported; that one used the old start";
  }
  LOG(INFO) << "dead reckoning: start position (" << p_.transpose() << ") m, heading " << options_.initial_yaw_rad
            << " rad";
  return true;
}

PoseWithCovariance DeadReckoning::Current() const {
  PoseWithCovariance out;
  out.utime = state_utime_;
  out.pose = MakePose(R_, p_);
  out.covariance = P_.topLeftCorner<6, 6>();
  return out;
}

void DeadReckoning::AddSiteEvent(const SiteEvent& event) {
  if (event.event != SiteEventType::kArrived) return;
  if (event.site_id < 0 || event.utime < 0 || event.utime > kMaxPlausibleUtime) {
    ++stats_.implausible;
    LOG(WARNING) << "dead reckoning: arrival at site " << event.site_id << " at " << event.utime
                 << " us: negative site id or time outside [0, 2^53] us; rejected";
    return;
  }
  if (!sites_seen_.empty() && static_cast<int64_t>(event.site_id) - *sites_seen_.rbegin() > kMaxSiteIdJump) {
    ++stats_.implausible;
    LOG(WARNING) << "dead reckoning: arrival at site " << event.site_id << " is more than " << kMaxSiteIdJump
                 << " beyond the newest site (a corrupt id?); rejected";
    return;
  }
  const bool repeat = sites_seen_.count(event.site_id) > 0;
  const bool full = static_cast<int>(sites_seen_.size()) >= options_.site_window;
  if (repeat || (full && event.site_id < *sites_seen_.begin())) {
    ++stats_.site_events_dropped;
    LOG_EVERY_N(WARNING, 100) << "dead reckoning: site " << event.site_id
                              << (repeat ? " arrival already reported"
                                         : " arrival is older than the newest site_window " +
                                               std::to_string(options_.site_window) + " arrivals")
                              << "; dropped as a repeat (" << google::COUNTER << " so far)";
    return;
  }
  sites_seen_.insert(event.site_id);
  KeepNewestSites(&sites_seen_, static_cast<size_t>(options_.site_window));
  pending_arrivals_.push_back(event);
  if (static_cast<int>(pending_arrivals_.size()) > options_.site_window) {
    ++stats_.site_events_dropped;
    LOG_EVERY_N(WARNING, 100) << "dead reckoning: more than site_window " << options_.site_window
                              << " arrivals wait for attitude (no IMU yet); the oldest, site "
                              << pending_arrivals_.front().site_id << ", dropped (" << google::COUNTER << " so far)";
    pending_arrivals_.pop_front();
  }
  EmitPendingArrivals();
}

void DeadReckoning::EmitPendingArrivals() {
  if (!initialized_ || !aligned_) return;
  for (const SiteEvent& event : pending_arrivals_) {
    // Integrate what the wheels reported up to the arrival.
    while (!wheel_queue_.empty() && wheel_queue_.front().utime <= event.utime) {
      IntegrateWheel(wheel_queue_.front());
      wheel_queue_.pop_front();
    }
    PoseWithCovariance pose = Current();
    pose.utime = event.utime;
    ready_sites_.emplace_back(event.site_id, pose);
    site_reported_ = true;
  }
  pending_arrivals_.clear();
}

std::vector<std::pair<int, PoseWithCovariance>> DeadReckoning::PopSitePoses() {
  std::vector<std::pair<int, PoseWithCovariance>> out;
  out.swap(ready_sites_);
  return out;
}

std::optional<PoseWithCovariance> DeadReckoning::PopPeriodicPose() {
  if (!initialized_ || imu_utime_ < next_publish_utime_) return std::nullopt;
  const int64_t period = static_cast<int64_t>(options_.publish_period_s * 1e6);
  next_publish_utime_ += period * (1 + (imu_utime_ - next_publish_utime_) / period);
  PoseWithCovariance pose = Current();
  pose.utime = imu_utime_;
  return pose;
}

}  // namespace vloc
