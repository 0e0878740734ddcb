#include "vloc/mosaic/height_filter.h"

#include <algorithm>
#include <cmath>

#include "vloc/common/options.h"

namespace vloc::mosaic {

void HeightFilterOptions::Visit(OptionsReader& r) {
  r.Optional("gps_use", &gps_use, "calibration | fused", OneOf({"calibration", "fused"}));
  r.Optional("vision_sigma", &vision_sigma, "relative 1-sigma of one frame's vision height", Positive());
  r.Optional("rate_noise", &rate_noise, "1/s^1.5, random walk of the log climb rate", Positive());
  r.Optional("gps_height_sigma", &gps_height_sigma, "m, 1-sigma of GPS height above ground (fused)", Positive());
  r.Optional("bias_sigma", &bias_sigma, "relative, initial sigma of the vision height bias (fused)", NonNegative());
  r.Optional("bias_drift", &bias_drift, "1/s^0.5, random walk of the vision height bias (fused)", NonNegative());
  r.Optional("enabled", &enabled, "false = raw vision height");
}

bool HeightFilterOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

void HeightFilter::Reset(double height, int64_t utime) {
  initialized_ = true;
  utime_ = utime;
  x_ << std::log(height), 0.0, 0.0;
  P_.setZero();
  P_(0, 0) = options_.vision_sigma * options_.vision_sigma;
  P_(1, 1) = 0.1 * 0.1;
  if (options_.gps_use == "fused") P_(2, 2) = options_.bias_sigma * options_.bias_sigma;
}

void HeightFilter::Predict(int64_t utime) {
  const double dt = std::clamp((utime - utime_) * 1e-6, 0.0, 5.0);
  utime_ = std::max(utime_, utime);
  if (dt <= 0) return;
  Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
  F(0, 1) = dt;
  x_ = F * x_;
  const double q = options_.rate_noise * options_.rate_noise;
  Eigen::Matrix3d Q = Eigen::Matrix3d::Zero();
  Q(0, 0) = q * dt * dt * dt / 3.0;
  Q(0, 1) = Q(1, 0) = q * dt * dt / 2.0;
  Q(1, 1) = q * dt;
  if (options_.gps_use == "fused") Q(2, 2) = options_.bias_drift * options_.bias_drift * dt;
  P_ = F * P_ * F.transpose() + Q;
}

void HeightFilter::Update(double z, const Eigen::RowVector3d& H, double r) {
  const double s = (H * P_ * H.transpose())(0, 0) + r;
  const Eigen::Vector3d K = P_ * H.transpose() / s;
  x_ += K * (z - (H * x_)(0, 0));
  P_ = (Eigen::Matrix3d::Identity() - K * H) * P_;
  P_ = 0.5 * (P_ + P_.transpose());
}

double HeightFilter::UpdateVision(double height, int64_t utime) {
  if (!(height > 0)) return this->height();
  if (!initialized_ || !options_.enabled) {
    Reset(height, utime);
    return height;
  }
  Predict(utime);
  // The vision height measures log h + bias.
  Update(std::log(height), Eigen::RowVector3d(1, 0, 1), options_.vision_sigma * options_.vision_sigma);
  return this->height();
}

double HeightFilter::UpdateGps(double height, int64_t utime) {
  if (options_.gps_use != "fused" || !options_.enabled || !initialized_ || !(height > 0)) return this->height();
  Predict(utime);
  const double s = options_.gps_height_sigma / height;
  Update(std::log(height), Eigen::RowVector3d(1, 0, 0), s * s);
  return this->height();
}

double HeightFilter::height() const { return initialized_ ? std::exp(x_(0)) : 0.0; }

}  // namespace vloc::mosaic
