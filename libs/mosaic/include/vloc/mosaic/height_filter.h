#pragma once
// A constant-velocity Kalman filter on log(height): smooths the per-frame
// height of equations 4-5 without lagging steady climbs and descents (the
// velocity state follows a ramp with no steady-state error). GPS height above
// ground can be fused as a second measurement (option).

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
  double gps_sigma_floor = 0.5;         // m, lower bound of the GPS vertical sigma when fused
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
  // GPS height above ground (m) with 1-sigma (m); ignored unless gps_use == "fused".
  double UpdateGps(double height, double sigma, int64_t utime);
  double height() const;
  double climb_rate() const;  // m/s

 private:
  void Predict(int64_t utime);
  void Update(double z_log, double var);
  HeightFilterOptions options_;
  bool initialized_ = false;
  int64_t utime_ = 0;
  double x_[2] = {0, 0};           // log h, d log h / dt
  double P_[2][2] = {{0, 0}, {0, 0}};
};

}  // namespace vloc::mosaic
