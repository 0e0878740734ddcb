// imu_odometry_driver: replays recorded IMU and wheel-odometry CSV files
// (columns: sensor_csv.h) on IMU and WHEEL_ODOM, at the recorded pace
// (x speed) or as fast as possible (--speed 0).
//   imu_odometry_driver --config config/procs/imu_odometry_driver.yaml --imu imu.csv --wheel wheel.csv [--speed 0]
#include <iostream>

#include "imu_odometry_replay.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(
      argc, argv,
      {"imu_odometry_driver", {"imu", "wheel", "speed"}, false,
       "[--config config/procs/imu_odometry_driver.yaml] [--imu imu.csv] [--wheel wheel.csv] [--speed X] "
       "[--lcm-url URL]"});
  if (!setup) return 1;
  const auto loaded = vloc::LoadProcessOptions<vloc::ImuOdometryDriverOptions>(*setup, [&](vloc::ImuOdometryDriverOptions& o) {
    if (setup->args.Has("imu")) o.imu_csv = setup->args.Get("imu");
    if (setup->args.Has("wheel")) o.wheel_csv = setup->args.Get("wheel");
    if (setup->args.Has("speed")) o.speed = setup->args.GetDouble("speed", o.speed);
  });
  if (!loaded) return 1;
  const vloc::ImuOdometryDriverOptions& options = *loaded;
  if (options.imu_csv.empty() && options.wheel_csv.empty()) {
    std::cerr << "imu_odometry_driver: nothing to replay (give --imu FILE.csv and/or --wheel FILE.csv)\n";
    return 1;
  }
  vloc::ImuCsv imu;
  vloc::WheelCsv wheel;
  if (!options.imu_csv.empty()) imu = vloc::ReadImuCsv(options.imu_csv, options.limits);
  if (!options.wheel_csv.empty()) wheel = vloc::ReadWheelCsv(options.wheel_csv, options.limits);
  for (const auto& p : imu.problems) LOG(ERROR) << p;
  for (const auto& p : wheel.problems) LOG(ERROR) << p;
  if (!imu.readable && !wheel.readable) return 1;
  vloc::ReplayPacer pacer(options.speed);
  const auto summary = vloc::ReplayImuOdometry(options, imu, wheel, *setup->transport, pacer);
  LOG(INFO) << "imu_odometry_driver: published " << summary.imu_published << " IMU and " << summary.wheel_published
            << " wheel samples; skipped " << imu.problems.size() + wheel.problems.size() << " rows/files";
  return 0;
}
