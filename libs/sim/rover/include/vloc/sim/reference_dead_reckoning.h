#pragma once
// A minimal dead reckoning used ONLY to test the simulator's sensor data
// (the real one is libs/deadreckoning): attitude from integrating the gyro,
// position from wheel-odometry distance along the body x axis. With ideal
// sensors it reproduces the ground truth; with noise and slip it drifts.

#include <cstdint>
#include <vector>

#include "vloc/common/pose.h"
#include "vloc/common/rover_data.h"

namespace vloc::sim {

struct ReferencePoseSample {
  int64_t utime = 0;
  Pose3 world_from_body = Pose3::Identity();
};

// Integrates from `initial` at imu.front().utime over every later IMU
// sample; wheel distance is interpolated linearly in time between wheel
// samples. Returns one pose per IMU sample.
std::vector<ReferencePoseSample> IntegrateReferenceDeadReckoning(const Pose3& initial,
                                                                 const std::vector<ImuSample>& imu,
                                                                 const std::vector<WheelOdometrySample>& wheel);

}  // namespace vloc::sim
