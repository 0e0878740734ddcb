#pragma once
// Dead reckoning of a rover: wheel-odometry distance along the body x axis,
// attitude from the integrated gyro with gravity-aided roll/pitch whenever
// the rover stands still, as a rover GNC does. An error-state covariance
// over [position (3), attitude (3), odometer scale, lateral slip, gyro bias
// (3)] grows with the distance driven (scale and slip errors: sigma
// proportional to distance) and with time (gyro bias: heading sigma linear
// in time; gyro noise: random walk).
//
// Frames: world is the level frame at site 0 (x east, y north, z up); body
// x forward, y left, z up. The output pose is world_from_body with the 6x6
// covariance of vloc/common/pose.h.
//
// Start: the first still_duration_s of standing still sets roll/pitch from
// the averaged accelerometer (coarse alignment); site arrivals wait for it.
// If the rover moves first, it starts from the first sample's tilt.
//
// Input may come from replayed logs: samples out of order, duplicated,
// missing, or jumping in time. Each is handled (dropped, bridged or reset)
// and counted in DeadReckoningStats, and logged.

#include <cstdint>
#include <deque>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "vloc/common/pose.h"
#include "vloc/common/rover_data.h"

namespace vloc {

class OptionsReader;

struct DeadReckoningOptions {
  double gravity_mps2 = 1.62;              // m/s^2, local gravity (lunar; must match the IMU's world)
  double publish_period_s = 0.1;           // s of message time between periodic poses (DR_POSE)
  Eigen::Vector3d initial_position = Eigen::Vector3d::Zero();  // m, body origin at start in world
  double initial_yaw_rad = 0.0;            // rad, heading at start (world is defined by site 0)
  double initial_position_sigma_m = 0.001; // m, 1-sigma of the start position
  double initial_yaw_sigma_rad = 0.001;    // rad, 1-sigma of the start heading
  double tilt_sigma_rad = 0.004;           // rad, 1-sigma of gravity-derived roll/pitch (accelerometer bias / g)
  double odometry_scale = 1.0;             // distance per odometer metre (e.g. 1 - nominal slip)
  double along_track_sigma_per_m = 0.12;   // 1-sigma odometer scale error (uncompensated slip): along-track sigma per metre
  double cross_track_sigma_per_m = 0.03;   // 1-sigma lateral slip: cross-track sigma per metre driven
  double distance_noise_m_per_sqrt_m = 0.005;  // m/sqrt(m), random position noise per distance
  double gyro_noise_density = 4.4e-5;      // rad/s/sqrt(Hz), angle random walk
  double gyro_bias_sigma = 1.5e-5;         // rad/s, 1-sigma constant gyro bias per axis (heading sigma grows linearly)
  double gyro_bias_walk = 1e-7;            // rad/s^2/sqrt(Hz), gyro bias random walk
  double still_gyro_threshold = 0.002;     // rad/s, |rate| below this may be still
  double still_accel_tolerance = 0.05;     // m/s^2, | |f| - g | below this may be still
  double still_speed_threshold = 1e-3;     // m/s, wheel speed below this may be still
  double still_settle_s = 0.5;             // s of stillness ignored first (the last of the braking)
  double still_duration_s = 1.0;           // s of stillness then averaged for one gravity update per stop
  double max_imu_gap_s = 0.5;              // s, a longer IMU gap is bridged without rotation and inflates attitude
  double gap_attitude_sigma_rate = 0.01;   // rad/s, attitude sigma added per second of a bridged gap
  double max_speed_mps = 1.0;              // m/s, faster odometer increments are dropped as implausible
  double wheel_wait_s = 0.5;               // s, hold wheel samples this long for the IMU to catch up
  double reset_backward_jump_s = 10.0;     // s, time going back more than this restarts dead reckoning (new log)
  double max_forward_jump_s = 60.0;        // s, a larger forward jump of a sample's time is held until the next sample confirms it
  double max_gyro_rate_rps = 10.0;         // rad/s, faster rates are not physical for a rover: sample rejected
  double max_accel_mps2 = 100.0;           // m/s^2, larger specific forces are rejected
  int site_window = 1000;                  // site arrivals remembered (the newest ids) to drop repeats; an arrival
                                           // older than all of them is dropped too, and at most this many wait
                                           // for alignment (a flood of site ids stays bounded)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// What the estimator did with its input.
struct DeadReckoningStats {
  int64_t imu_used = 0;
  int64_t imu_dropped = 0;          // duplicated or out of order
  int64_t imu_gaps = 0;             // gaps longer than max_imu_gap_s, bridged
  int64_t wheel_used = 0;
  int64_t wheel_dropped = 0;        // duplicated, out of order or implausible
  int64_t odometer_resets = 0;      // cumulative distance went down: rebased
  int64_t gravity_updates = 0;      // roll/pitch corrections from the accelerometer
  int64_t resets = 0;               // restarts after a large backward time jump
  int64_t site_events_dropped = 0;  // arrivals dropped: repeated, older than the site window, or waiting beyond it
  int64_t implausible = 0;          // samples rejected: time outside [0, 2^53] us or values beyond the sensor's range
  int64_t time_outliers = 0;        // samples whose time jumped and the next sample did not confirm the jump
  double distance_m = 0;            // m, distance integrated
};

class DeadReckoning {
 public:
  explicit DeadReckoning(const DeadReckoningOptions& options);

  void AddImu(const ImuSample& sample);
  void AddWheel(const WheelOdometrySample& sample);
  // Notes a site event; an ARRIVED event yields a site pose (PopSitePoses),
  // at once or, before the first IMU sample, as soon as there is attitude.
  // Other events and repeated arrivals at the same site are ignored.
  void AddSiteEvent(const SiteEvent& event);
  // Site poses ready since the last call: (site id, world_from_body at arrival).
  std::vector<std::pair<int, PoseWithCovariance>> PopSitePoses();
  // Sets the start position and heading (roll/pitch stay gravity's) while
  // the rover has not moved yet, e.g. from the lander or a ground-truth
  // site-0 pose; returns false (and logs) once it has moved.
  bool SetStartPose(const Pose3& world_from_body);
  // The next periodic pose once message time has passed it (call after every sample).
  std::optional<PoseWithCovariance> PopPeriodicPose();

  bool initialized() const { return initialized_; }
  PoseWithCovariance Current() const;
  const DeadReckoningStats& stats() const { return stats_; }
  const DeadReckoningOptions& options() const { return options_; }

 private:
  static constexpr int kN = 11;  // error state: p(3) r(3) scale slip bias(3)
  using StateMatrix = Eigen::Matrix<double, kN, kN>;

  void Reset(const char* why);
  void Initialize(const ImuSample& first);
  void ApplyImu(const ImuSample& s);  // after the plausibility and time gates
  // Attitude over dt (a gap longer than max_imu_gap_s held, its sigma
  // inflated) and the attitude history wheel samples interpolate in.
  void PropagateImu(const ImuSample& s, double dt);
  // Gravity-aided roll/pitch once per stop: the mean specific force of a
  // settled stop aligns (the first) or corrects roll and pitch.
  void UpdateStillness(const ImuSample& s, double dt);
  void PropagateAttitude(const Eigen::Vector3d& rate, double dt);
  void IntegrateWheel(const WheelOdometrySample& sample);
  void FlushWheel(bool force_all);
  void GravityUpdate(const Eigen::Vector3d& mean_specific_force);
  void Align(const Eigen::Vector3d& mean_specific_force);
  Eigen::Matrix3d AttitudeAt(int64_t utime) const;
  bool TimeWentBack(int64_t utime, int64_t last, const char* what);
  // How a sample's time relates to its stream's last time.
  enum class TimeStep { kContinues, kHeld, kConfirmedJump };
  // A sample whose time jumps (back more than reset_backward_jump_s or
  // forward more than max_forward_jump_s) is held in *held; the jump stands
  // when the next sample continues from it, else the held one is dropped.
  TimeStep GateTime(int64_t utime, int64_t last, std::optional<int64_t>* held, const char* what);
  bool Plausible(const ImuSample& s, std::string* why) const;

  DeadReckoningOptions options_;
  DeadReckoningStats stats_;
  bool initialized_ = false;
  bool aligned_ = false;  // roll/pitch set from gravity (or given up on: moved first)
  int64_t imu_utime_ = 0;
  int64_t state_utime_ = 0;
  Eigen::Matrix3d R_ = Eigen::Matrix3d::Identity();  // world_from_body rotation
  Eigen::Vector3d p_ = Eigen::Vector3d::Zero();      // m, world
  Eigen::Vector3d gyro_bias_ = Eigen::Vector3d::Zero();
  StateMatrix P_ = StateMatrix::Zero();
  std::deque<std::pair<int64_t, Eigen::Matrix3d>> attitude_history_;
  std::deque<WheelOdometrySample> wheel_queue_;
  bool have_wheel_ = false;
  WheelOdometrySample last_wheel_;
  double last_speed_ = 0;
  // Stillness: accumulated specific force while still, and whether this stop was used.
  double still_seconds_ = 0;
  Eigen::Vector3d still_force_sum_ = Eigen::Vector3d::Zero();
  int still_count_ = 0;
  bool stop_updated_ = false;
  int64_t next_publish_utime_ = 0;
  std::optional<int64_t> held_imu_utime_, held_wheel_utime_;  // times of samples held by GateTime
  std::optional<ImuSample> held_imu_;
  std::optional<WheelOdometrySample> held_wheel_;
  std::set<int> sites_seen_;               // the newest site_window arrivals
  bool site_reported_ = false;             // a site pose has been emitted
  std::deque<SiteEvent> pending_arrivals_; // at most site_window
  std::vector<std::pair<int, PoseWithCovariance>> ready_sites_;
  void EmitPendingArrivals();
};

}  // namespace vloc
