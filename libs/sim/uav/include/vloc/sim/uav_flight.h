#pragma once
// The simulated UAV's flight: ground-truth pose as a function of time.
//
// Frames (see DESIGN.md): world x east, y north, z up, origin at the
// take-off marker's ground point by default; the ground is the plane z = 0,
// so the UAV's z is its height above ground. UAV body: x forward, y left,
// z up. The nadir camera sits at the body origin looking down, image top
// towards body x (forward), image right towards body -y (right):
//   body_from_camera = [camera x -> -body y, camera y -> -body x,
//                       camera z -> -body z]   (UavBodyFromCamera()).
//
// Flight plan: hover over the take-off point at `calibration_height` for
// `calibration_hover` s (the ArUco marker is below, for the calibration
// step), then fly a smooth Catmull-Rom curve through `waypoints` (x, y,
// height triples) at `speed` with `acceleration` ramps, yaw following the
// horizontal direction of travel, then hover at the last waypoint for
// `final_hover` s. Small roll/pitch wobble is optional.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "vloc/common/pose.h"

namespace vloc {

class OptionsReader;

struct UavFlightOptions {
  Eigen::Vector2d takeoff = Eigen::Vector2d(0.0, 0.0);  // m, x east / y north of the take-off hover
  double calibration_height = 15.0;  // m above ground, hover height over the marker
  double calibration_hover = 3.0;    // s, hover time at calibration_height before the route
  // m, x y height triples of the route after the hover (a loop back over the take-off point).
  std::vector<double> waypoints = {40, 10, 20,    100, 30, 40,   140, 90, 60,   110, 160, 80,
                                   30, 180, 80,   -50, 140, 60,  -80, 70, 40,   -50, 15, 30,
                                   -10, -5, 25,   30, 10, 20};
  double speed = 8.0;          // m/s, cruise speed along the route
  double acceleration = 2.0;   // m/s^2, speed ramp at the start and end of the route
  double final_hover = 2.0;    // s, hover at the last waypoint
  double wobble_amplitude = 0.008;  // rad, roll/pitch wobble amplitude (0 = perfectly nadir)
  double wobble_period = 3.0;       // s, wobble period
  int seed = 11;                    // wobble phases

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// Ground-truth state at a time.
struct UavState {
  double t = 0;                                       // s since flight start
  Eigen::Vector3d position = Eigen::Vector3d::Zero(); // m: x east, y north, z height above ground
  double yaw = 0;    // rad, heading of body x from east, counter-clockwise
  double roll = 0;   // rad
  double pitch = 0;  // rad
  double speed = 0;  // m/s along the route
};

// Fixed nadir mount (see the header comment).
Eigen::Matrix3d UavBodyFromCameraRotation();
Pose3 UavBodyFromCamera();

class UavFlight {
 public:
  // Throws std::invalid_argument when the options fail Check().
  explicit UavFlight(const UavFlightOptions& options);

  // Total time of the plan (hover + route + final hover), s.
  double Duration() const { return duration_; }
  // Time the route starts (end of the calibration hover), s.
  double RouteStart() const { return options_.calibration_hover; }
  double RouteLength() const { return length_; }  // m, 3-D length of the route

  // Ground truth at time t (clamped to [0, Duration()]).
  UavState StateAt(double t) const;
  Pose3 WorldFromBody(double t) const;
  Pose3 WorldFromCamera(double t) const;

  const UavFlightOptions& options() const { return options_; }

 private:
  Eigen::Vector3d CurvePoint(double u, Eigen::Vector3d* derivative) const;
  double ArcLengthAtTime(double route_t, double* speed) const;

  UavFlightOptions options_;
  std::vector<Eigen::Vector3d> points_;  // hover point, then the waypoints
  std::vector<double> table_u_, table_s_;  // dense arc-length table of the curve
  double length_ = 0, cruise_ = 0, ramp_time_ = 0, ramp_length_ = 0, route_time_ = 0, duration_ = 0;
  double phase_roll_ = 0, phase_pitch_ = 0;
};

}  // namespace vloc
