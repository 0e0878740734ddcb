#pragma once
// The simulated UAV's GPS: fixes at `rate` Hz with time-correlated
// (Gauss-Markov) horizontal and vertical errors, a barometer-like height
// above ground, and drop-out intervals without a fix. Samples are
// precomputed, so GpsAt(t) is a pure function of t (same seed, same data).

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "vloc/sim/uav_geo.h"

namespace vloc {

class OptionsReader;
class UavFlight;

struct UavGpsOptions {
  double rate = 5.0;                 // Hz, fix rate
  double origin_latitude = 45.4642;  // deg, WGS84 latitude of the world origin
  double origin_longitude = 9.19;    // deg, WGS84 longitude of the world origin
  double origin_altitude = 120.0;    // m above the WGS84 ellipsoid of the ground at the origin
  double horizontal_sigma = 1.5;     // m, 1-sigma horizontal error per axis
  double vertical_sigma = 3.0;       // m, 1-sigma altitude error
  double correlation_time = 10.0;    // s, time constant of the GPS errors (Gauss-Markov)
  double baro_sigma = 0.4;           // m, 1-sigma error of height_above_ground
  double baro_correlation_time = 5.0;  // s, time constant of the baro error
  // s, start/end pairs of drop-outs (no fix: lat/lon/altitude/height NaN).
  std::vector<double> dropouts = {45.0, 60.0};
  int seed = 3;                      // noise seed

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct UavGpsSample {
  int64_t utime = 0;           // microseconds since flight start
  bool has_fix = false;        // false inside a drop-out
  double latitude = 0;         // deg (NaN without fix)
  double longitude = 0;        // deg (NaN without fix)
  double altitude = 0;         // m above the ellipsoid (NaN without fix)
  double height_above_ground = 0;  // m, baro-like (NaN without fix)
  double horizontal_sigma = 0;     // m, 1-sigma (the configured value)
  double vertical_sigma = 0;       // m, 1-sigma
  Eigen::Vector3d true_position = Eigen::Vector3d::Zero();  // m, ground truth (x east, y north, z height)
};

class UavGps {
 public:
  UavGps(const UavGpsOptions& options, const UavFlight& flight);

  int NumSamples() const { return static_cast<int>(samples_.size()); }
  const UavGpsSample& Sample(int index) const { return samples_[index]; }
  // The latest sample at or before t (t clamped to the flight).
  const UavGpsSample& At(double t) const;
  double SampleTime(int index) const { return index / options_.rate; }
  bool InDropout(double t) const;
  const LocalTangentPlane& plane() const { return plane_; }

 private:
  UavGpsOptions options_;
  LocalTangentPlane plane_;
  std::vector<UavGpsSample> samples_;
};

}  // namespace vloc
