#pragma once
// Paces a replay of recorded data: message i is sent at
//   wall_start + (utime_i - utime_first) / speed,
// so the recorded timing is kept (speed 1), scaled (speed 2 = twice as
// fast), or ignored (speed 0 = as fast as possible). Used by the drivers
// (navcam_driver, imu_odometry_driver, uav_video_driver). Header-only.

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <thread>

#include "vloc/lcm_io/process.h"

namespace vloc {

class ReplayPacer {
 public:
  explicit ReplayPacer(double speed) : speed_(speed) {}

  // Sleeps until the wall time of `utime` (microseconds, recorded clock).
  // Returns false as soon as SIGINT/SIGTERM is pending (the caller stops).
  bool WaitFor(int64_t utime) {
    if (StopSignalPending()) return false;
    if (speed_ <= 0) return true;
    const auto now = std::chrono::steady_clock::now();
    if (!started_) {
      started_ = true;
      first_utime_ = utime;
      wall_start_ = now;
      return true;
    }
    const double offset_s = std::max<int64_t>(0, utime - first_utime_) * 1e-6 / speed_;
    const auto due = wall_start_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                       std::chrono::duration<double>(offset_s));
    while (std::chrono::steady_clock::now() < due) {
      std::this_thread::sleep_until(std::min(due, std::chrono::steady_clock::now() + std::chrono::milliseconds(50)));
      if (StopSignalPending()) return false;
    }
    return true;
  }

 private:
  double speed_;
  bool started_ = false;
  int64_t first_utime_ = 0;
  std::chrono::steady_clock::time_point wall_start_;
};

}  // namespace vloc
