#include "vloc/mosaic/height_filter.h"

#include <algorithm>
#include <cmath>

#include "vloc/common/options.h"

namespace vloc::mosaic {

void HeightFilterOptions::Visit(OptionsReader& r) {
  r.Optional("gps_use", &gps_use, "calibration | fused");
  r.Optional("vision_sigma", &vision_sigma, "relative 1-sigma of one frame's vision height");
  r.Optional("rate_noise", &rate_noise, "1/s^1.5, random walk of the log climb rate");
  r.Optional("gps_sigma_floor", &gps_sigma_floor, "m, lowest GPS vertical sigma used");
  r.Optional("enabled", &enabled, "false = raw vision height");
}

bool HeightFilterOptions::Check(std::string* error) const {
  if (gps_use != "calibration" && gps_use != "fused")
    return Fail(error, "height_filter.gps_use must be 'calibration' or 'fused'");
  if (!(vision_sigma > 0)) return Fail(error, "height_filter.vision_sigma must be > 0");
  if (!(rate_noise > 0)) return Fail(error, "height_filter.rate_noise must be > 0");
  if (!(gps_sigma_floor > 0)) return Fail(error, "height_filter.gps_sigma_floor must be > 0");
  return true;
}

void HeightFilter::Reset(double height, int64_t utime) {
  initialized_ = true;
  utime_ = utime;
  x_[0] = std::log(height);
  x_[1] = 0.0;
  P_[0][0] = options_.vision_sigma * options_.vision_sigma;
  P_[0][1] = P_[1][0] = 0.0;
  P_[1][1] = 0.1 * 0.1;
}

void HeightFilter::Predict(int64_t utime) {
  const double dt = std::clamp((utime - utime_) * 1e-6, 0.0, 5.0);
  utime_ = std::max(utime_, utime);
  if (dt <= 0) return;
  x_[0] += dt * x_[1];
  // P = F P F' + Q, F = [1 dt; 0 1], Q from a white-noise rate derivative.
  const double p00 = P_[0][0] + dt * (P_[0][1] + P_[1][0]) + dt * dt * P_[1][1];
  const double p01 = P_[0][1] + dt * P_[1][1];
  const double q = options_.rate_noise * options_.rate_noise;
  P_[0][0] = p00 + q * dt * dt * dt / 3.0;
  P_[0][1] = P_[1][0] = p01 + q * dt * dt / 2.0;
  P_[1][1] += q * dt;
}

void HeightFilter::Update(double z, double r) {
  const double s = P_[0][0] + r;
  const double k0 = P_[0][0] / s, k1 = P_[1][0] / s;
  const double y = z - x_[0];
  x_[0] += k0 * y;
  x_[1] += k1 * y;
  const double p00 = (1 - k0) * P_[0][0];
  const double p01 = (1 - k0) * P_[0][1];
  const double p11 = P_[1][1] - k1 * P_[0][1];
  P_[0][0] = p00;
  P_[0][1] = P_[1][0] = p01;
  P_[1][1] = p11;
}

double HeightFilter::UpdateVision(double height, int64_t utime) {
  if (!(height > 0)) return this->height();
  if (!initialized_ || !options_.enabled) {
    Reset(height, utime);
    return height;
  }
  Predict(utime);
  Update(std::log(height), options_.vision_sigma * options_.vision_sigma);
  return this->height();
}

double HeightFilter::UpdateGps(double height, double sigma, int64_t utime) {
  if (options_.gps_use != "fused" || !options_.enabled || !initialized_ || !(height > 0)) return this->height();
  Predict(utime);
  const double s = std::max(std::isfinite(sigma) ? sigma : 0.0, options_.gps_sigma_floor) / height;
  Update(std::log(height), s * s);
  return this->height();
}

double HeightFilter::height() const { return initialized_ ? std::exp(x_[0]) : 0.0; }
double HeightFilter::climb_rate() const { return height() * x_[1]; }

}  // namespace vloc::mosaic
