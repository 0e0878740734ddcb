#pragma once
// A simulated rover traverse over a Terrain: planned sites, terrain-following
// ground-truth motion, IMU, wheel odometry, site events and the Navcam
// exposures of each site's panorama. Deterministic from TraverseOptions::seed.
//
//   vloc::sim::SimulatedTraverse traverse = vloc::sim::SimulateTraverse(terrain, options);
//   traverse.ground_truth  // world_from_body at every IMU sample time
//   traverse.imu, .wheel   // sensor samples (with noise, bias and slip unless ideal_sensors)
//   traverse.sites         // per site: pose at arrival, event times, exposures
//   traverse.events        // ARRIVED / IMAGING_DONE / DEPARTED in time order
//   traverse.exposures     // every stereo exposure (site, pair, pan, tilt, time) in time order
//
// Motion: at each site the rover stops, images, departs, turns in place
// toward the next site and drives straight to it (smooth speed and turn-rate
// ramps). Roll and pitch come from a plane fitted to the six wheel contacts,
// smoothed by a critically damped filter; the body moves along its x axis
// (plus a downhill side-slip when sensors are not ideal).
//
// Sensor conventions:
//   ImuSample k: angular_velocity = mean body rate over (t_{k-1}, t_k] plus
//   bias and noise (so R_k = R_{k-1} Exp(w_k dt) without noise);
//   linear_acceleration = specific force R^T (a - g) in the body frame
//   (reads +gravity on z when level and still).
//   WheelOdometrySample: cumulative distance from wheel rotation (true 3-D
//   path length / (1 - slip)), speed = its rate.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "vloc/common/pose.h"
#include "vloc/common/rover_data.h"
#include "vloc/sim/terrain.h"

namespace vloc {
class OptionsReader;
}

namespace vloc::sim {

// The Navcam panorama taken at each site.
struct PanoramaOptions {
  int num_pairs = 7;              // pairs across the forward direction
  double pan_step_deg = 26.0;     // deg between adjacent pairs (46 deg FOV, ~20 deg overlap)
  double tilt_deg = 25.0;         // deg, mast tilt (positive down)
  bool backward_pair = false;     // add one pair looking backward (pan 180 deg)
  double backward_tilt_deg = 25.0;// deg, tilt of the backward pair
  double settle_s = 2.0;          // s the suspension settles after the stop, before the rover reports arrival and images
  double pair_interval_s = 4.0;   // s between exposures

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
  // Pointing of every pair: pair 0 is the leftmost (largest pan), then to
  // the right; the backward pair (if any) is last.
  std::vector<MastPointing> Pointings() const;
};

struct TraversePlanOptions {
  int num_sites = 20;                 // sites including the start (site 0 at the world origin)
  double spacing_min_m = 5.0;         // m, shortest leg
  double spacing_max_m = 10.0;        // m, longest leg
  double initial_heading_deg = 0.0;   // deg, heading at site 0, counter-clockwise from east
  double max_turn_deg = 25.0;         // deg, largest heading change between legs
  double margin_m = 30.0;             // m, sites stay this far inside the terrain
  int revisit_site = -1;              // >= 0: one extra site driving back to that site (loop closure)
  std::vector<double> sites_xy;       // optional explicit site positions x0,y0,x1,y1,... (m); overrides the random plan

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct MotionOptions {
  double speed_mps = 0.1;             // m/s, driving speed
  double ramp_s = 2.0;                // s, speed / turn-rate ramp up and down
  double turn_rate_deg_s = 5.0;       // deg/s, point-turn rate
  double attitude_time_constant_s = 0.5; // s, smoothing of roll/pitch following the terrain
  double wheel_base_m = 1.2;          // m, front to rear wheel contact distance
  double track_width_m = 1.0;         // m, left to right wheel contact distance
  double start_utime = 1000000;       // us, time of the first sample
  double stop_pause_s = 1.0;          // s, pause between events (stop -> arrived, done -> depart, turn -> drive)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct ImuOptions {
  double rate_hz = 100.0;               // Hz
  double gravity_mps2 = 1.62;           // m/s^2, lunar
  double gyro_noise_density = 4.4e-5;   // rad/s/sqrt(Hz) (0.15 deg/sqrt(h))
  double gyro_bias_sigma = 1.5e-5;      // rad/s, 1-sigma constant bias per axis (3 deg/h)
  double gyro_bias_walk = 1e-7;         // rad/s^2/sqrt(Hz), bias random walk
  double accel_noise_density = 1e-3;    // m/s^2/sqrt(Hz)
  double accel_bias_sigma = 5e-3;       // m/s^2, 1-sigma constant bias per axis

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct WheelOptions {
  double rate_hz = 20.0;                // Hz
  double slip_flat = 0.10;              // slip ratio on level ground in average soil
  double soil_variation = 0.5;          // relative spread of the soil factor (1 +- this)
  double soil_wavelength_m = 20.0;      // m, size of soil patches
  double slip_per_rad_uphill = 1.0;     // added slip per radian of uphill pitch
  double skid_per_rad_downhill = 0.4;   // removed slip per radian of downhill pitch
  double sideslip_per_rad_roll = 0.4;   // downhill side velocity / speed per radian of roll
  double distance_noise_m = 2e-4;       // m, 1-sigma noise per sample on the distance increment

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct TraverseOptions {
  uint64_t seed = 1;              // selects the plan's randomness and all sensor noise
  bool ideal_sensors = false;     // true: no IMU noise/bias, no slip: dead reckoning reproduces ground truth
  TraversePlanOptions plan;
  PanoramaOptions panorama;
  MotionOptions motion;
  ImuOptions imu;
  WheelOptions wheels;

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct GroundTruthSample {
  int64_t utime = 0;
  Pose3 world_from_body = Pose3::Identity();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  // m/s, world
};

// One stereo exposure of a site's panorama.
struct Exposure {
  int64_t utime = 0;
  int site_id = 0;
  int pair_index = 0;
  int num_pairs = 0;
  double mast_pan = 0;   // rad
  double mast_tilt = 0;  // rad
  Pose3 world_from_body = Pose3::Identity();
};

struct SiteVisit {
  int site_id = 0;
  int revisit_of = -1;                       // site this one returns to, or -1
  Eigen::Vector2d planned_xy = Eigen::Vector2d::Zero();
  int64_t arrived_utime = 0;
  int64_t imaging_done_utime = 0;
  int64_t departed_utime = 0;                // 0 for the last site
  Pose3 world_from_body = Pose3::Identity(); // ground truth while stopped
  double distance_from_start_m = 0;          // m, true 3-D path length driven to get here
  std::vector<Exposure> exposures;
};

struct SimulatedTraverse {
  std::vector<GroundTruthSample> ground_truth;  // at every IMU sample time
  std::vector<ImuSample> imu;
  std::vector<WheelOdometrySample> wheel;
  std::vector<SiteVisit> sites;
  std::vector<SiteEvent> events;     // time order
  std::vector<Exposure> exposures;   // time order
  double path_length_m = 0;          // m, true 3-D distance driven
  double duration_s = 0;
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();   // rad/s, initial bias drawn
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();  // m/s^2
};

// Plans and simulates the whole traverse. Throws std::invalid_argument on
// bad options (one line naming the option) or when a planned site falls off
// the terrain.
SimulatedTraverse SimulateTraverse(const Terrain& terrain, const TraverseOptions& options);

}  // namespace vloc::sim
