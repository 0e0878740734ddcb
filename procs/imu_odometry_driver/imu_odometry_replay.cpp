#include "imu_odometry_replay.h"

#include "vloc/common/options.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/typed.h"

namespace vloc {

void ImuOdometryDriverOptions::Visit(OptionsReader& r) {
  r.Optional("imu_csv", &imu_csv, "path of the IMU CSV; empty = none");
  r.Optional("wheel_csv", &wheel_csv, "path of the wheel CSV; empty = none");
  r.Optional("imu_channel", &imu_channel, "imu_t channel");
  r.Optional("wheel_channel", &wheel_channel, "wheel_odometry_t channel");
  r.Optional("speed", &speed, "real-time factor, 0 = as fast as possible", NonNegative());
  r.Optional("max_angular_velocity", &limits.max_angular_velocity, "rad/s, larger gyro values are rejected",
             Positive());
  r.Optional("max_acceleration", &limits.max_acceleration, "m/s^2, larger accelerometer values are rejected",
             Positive());
  r.Optional("max_speed", &limits.max_speed, "m/s, larger wheel speeds are rejected", Positive());
}

bool ImuOdometryDriverOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

ImuOdometryReplaySummary ReplayImuOdometry(const ImuOdometryDriverOptions& options, const ImuCsv& imu,
                                           const WheelCsv& wheel, Transport& transport, ReplayPacer& pacer) {
  ImuOdometryReplaySummary summary;
  size_t i = 0, w = 0;
  while (i < imu.samples.size() || w < wheel.samples.size()) {
    const bool take_imu =
        w >= wheel.samples.size() || (i < imu.samples.size() && imu.samples[i].utime <= wheel.samples[w].utime);
    const int64_t utime = take_imu ? imu.samples[i].utime : wheel.samples[w].utime;
    if (!pacer.WaitFor(utime)) break;
    if (take_imu) {
      Publish(transport, options.imu_channel, ImuToMessage(imu.samples[i++]));
      ++summary.imu_published;
    } else {
      Publish(transport, options.wheel_channel, WheelOdometryToMessage(wheel.samples[w++]));
      ++summary.wheel_published;
    }
  }
  return summary;
}

}  // namespace vloc
