#pragma once
// A constant-velocity Kalman filter on log(height): smooths the per-frame
// height of equations 4-5 without lagging steady climbs and descents (the
// velocity state follows a ramp with no steady-state error). State: log h,
// d(log h)/dt and the log bias of the vision height (calibration error and
// drift of the scale chain). With gps_use "fused", GPS height above ground is
// an absolute measurement of log h and the vision height measures log h +
// bias, so GPS removes the bias slowly while vision keeps the detail; with
// "calibration" the bias is held at 0 and GPS is not used after calibration.

#include <Eigen/Core>
#include <cstdint>
#include <string>

namespace vloc {
class OptionsReader;
}

namespace vloc::mosaic {

struct HeightFilterOptions {
  std::string gps_use = "calibration";  // "calibration": GPS height only calibrates; "fused": also a filter measurement
  double vision_sigma = 0.004;          // relative (log) 1-sigma of one frame's vision height
  double rate_noise = 0.05;             // 1/s^1.5, random walk of d(log h)/dt (how fast climbs may change)
  double gps_height_sigma = 0.5;        // m, 1-sigma of GPS height_above_ground when fused (baro/rangefinder)
  double bias_sigma = 0.02;             // relative, initial 1-sigma of the vision height bias (fused)
  double bias_drift = 0.002;            // 1/s^0.5, random walk of the vision height bias (fused)
  bool enabled = true;                  // false = report the raw vision height

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

class HeightFilter {
 public:
  explicit HeightFilter(const HeightFilterOptions& options = {}) : options_(options) {}
  void Reset(double height, int64_t utime);
  bool initialized() const { return initialized_; }
  // Vision height (m) of a frame at utime (us). Returns the filtered height.
  double UpdateVision(double height, int64_t utime);
  // GPS height above ground (m); ignored unless gps_use == "fused".
  double UpdateGps(double height, int64_t utime);
  double height() const;

 private:
  void Predict(int64_t utime);
  void Update(double z_log, const Eigen::RowVector3d& H, double var);
  HeightFilterOptions options_;
  bool initialized_ = false;
  int64_t utime_ = 0;
  Eigen::Vector3d x_ = Eigen::Vector3d::Zero();   // log h, d log h / dt, log vision bias
  Eigen::Matrix3d P_ = Eigen::Matrix3d::Zero();
};

}  // namespace vloc::mosaic
