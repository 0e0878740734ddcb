#pragma once
// Reading recorded IMU and wheel-odometry CSV files (no LCM here).
//
// IMU CSV, header row with named columns (any order, extra columns ignored):
//   time (s) or utime (us), gx gy gz (rad/s, body frame), ax ay az (m/s^2, specific force)
// Wheel CSV:
//   time (s) or utime (us), distance (m, cumulative), speed (m/s)
// A row with a non-number, a value out of range or a time that goes back
// is skipped with one line in `problems`; the good rows are kept.

#include <string>
#include <vector>

#include "vloc/common/rover_data.h"

namespace vloc {

class OptionsReader;

struct SensorCsvLimits {
  double max_angular_velocity = 35.0;  // rad/s, |gx|, |gy|, |gz| above this are rejected
  double max_acceleration = 160.0;     // m/s^2, |ax|, |ay|, |az| above this are rejected
  double max_speed = 10.0;             // m/s, |speed| above this is rejected
};

struct ImuCsv {
  std::vector<ImuSample> samples;
  std::vector<std::string> problems;
  bool readable = false;  // false: the file or its header is unusable (see problems)
};

struct WheelCsv {
  std::vector<WheelOdometrySample> samples;
  std::vector<std::string> problems;
  bool readable = false;
};

ImuCsv ReadImuCsv(const std::string& path, const SensorCsvLimits& limits);
WheelCsv ReadWheelCsv(const std::string& path, const SensorCsvLimits& limits);

}  // namespace vloc
