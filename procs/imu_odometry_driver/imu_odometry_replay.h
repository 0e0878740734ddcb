#pragma once
// LCM adapter of imu_odometry_driver: replays IMU and wheel CSV samples
// (sensor_csv.h) merged in time order on IMU (imu_t) and WHEEL_ODOM
// (wheel_odometry_t).

#include <string>

#include "sensor_csv.h"
#include "vloc/lcm_io/replay_pacer.h"
#include "vloc/lcm_io/transport.h"

namespace vloc {

class OptionsReader;

struct ImuOdometryDriverOptions {
  std::string imu_csv;                    // path of the IMU CSV (--imu overrides); empty = none
  std::string wheel_csv;                  // path of the wheel CSV (--wheel overrides); empty = none
  std::string imu_channel = "IMU";        // imu_t
  std::string wheel_channel = "WHEEL_ODOM";  // wheel_odometry_t
  double speed = 1.0;                     // real-time factor on the recorded times; 0 = as fast as possible
  SensorCsvLimits limits;                 // range checks of the CSV values

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct ImuOdometryReplaySummary {
  int imu_published = 0;
  int wheel_published = 0;
};

ImuOdometryReplaySummary ReplayImuOdometry(const ImuOdometryDriverOptions& options, const ImuCsv& imu,
                                           const WheelCsv& wheel, Transport& transport, ReplayPacer& pacer);

}  // namespace vloc
