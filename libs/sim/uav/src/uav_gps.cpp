#include "vloc/sim/uav_gps.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "vloc/common/options.h"
#include "vloc/sim/uav_flight.h"

namespace vloc {

namespace {

bool StartEndPairs(const std::vector<double>& dropouts) {
  if (dropouts.size() % 2 != 0) return false;
  for (size_t i = 0; i < dropouts.size(); i += 2)
    if (!(dropouts[i + 1] > dropouts[i])) return false;
  return true;
}

}  // namespace

void UavGpsOptions::Visit(OptionsReader& r) {
  r.Optional("rate", &rate, "Hz, fix rate", InLeftOpen(0, 100));
  r.Optional("origin_latitude", &origin_latitude, "deg, WGS84 latitude of the world origin", InOpen(-85, 85));
  r.Optional("origin_longitude", &origin_longitude, "deg, WGS84 longitude of the world origin", InRange(-180, 180));
  r.Optional("origin_altitude", &origin_altitude, "m above the ellipsoid, ground at the origin");
  r.Optional("horizontal_sigma", &horizontal_sigma, "m, 1-sigma horizontal error per axis", NonNegative());
  r.Optional("vertical_sigma", &vertical_sigma, "m, 1-sigma altitude error", NonNegative());
  r.Optional("correlation_time", &correlation_time, "s, GPS error time constant", Positive());
  r.Optional("baro_sigma", &baro_sigma, "m, 1-sigma height_above_ground error", NonNegative());
  r.Optional("baro_correlation_time", &baro_correlation_time, "s, baro error time constant", Positive());
  r.Optional("dropouts", &dropouts, "s, start/end pairs without a fix",
             Rule<std::vector<double>>(StartEndPairs, "start/end pairs, each end after its start"));
  r.Optional("seed", &seed, "noise seed");
}

bool UavGpsOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

namespace {
// One step of a first-order Gauss-Markov process with stationary sigma.
double MarkovStep(double x, double sigma, double tau, double dt, std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  const double phi = std::exp(-dt / tau);
  return phi * x + sigma * std::sqrt(1 - phi * phi) * n(rng);
}
}  // namespace

UavGps::UavGps(const UavGpsOptions& options, const UavFlight& flight)
    : options_(options), plane_(options.origin_latitude, options.origin_longitude, options.origin_altitude) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument(error);
  const int n = static_cast<int>(std::floor(flight.Duration() * options_.rate)) + 1;
  const double dt = 1.0 / options_.rate;
  std::mt19937 rng(static_cast<uint32_t>(options_.seed));
  std::normal_distribution<double> start(0.0, 1.0);
  double ex = options_.horizontal_sigma * start(rng), ey = options_.horizontal_sigma * start(rng);
  double ez = options_.vertical_sigma * start(rng), eb = options_.baro_sigma * start(rng);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  samples_.reserve(static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) {
    if (k > 0) {
      ex = MarkovStep(ex, options_.horizontal_sigma, options_.correlation_time, dt, rng);
      ey = MarkovStep(ey, options_.horizontal_sigma, options_.correlation_time, dt, rng);
      ez = MarkovStep(ez, options_.vertical_sigma, options_.correlation_time, dt, rng);
      eb = MarkovStep(eb, options_.baro_sigma, options_.baro_correlation_time, dt, rng);
    }
    const double t = k * dt;
    UavGpsSample s;
    s.utime = static_cast<int64_t>(std::llround(t * 1e6));
    s.true_position = flight.StateAt(t).position;
    s.has_fix = !InDropout(t);
    s.horizontal_sigma = options_.horizontal_sigma;
    s.vertical_sigma = options_.vertical_sigma;
    if (s.has_fix) {
      plane_.ToGeodetic(s.true_position.x() + ex, s.true_position.y() + ey, s.true_position.z() + ez, &s.latitude,
                        &s.longitude, &s.altitude);
      s.height_above_ground = s.true_position.z() + eb;
    } else {
      s.latitude = s.longitude = s.altitude = s.height_above_ground = nan;
    }
    samples_.push_back(s);
  }
}

bool UavGps::InDropout(double t) const {
  for (size_t i = 0; i + 1 < options_.dropouts.size(); i += 2)
    if (t >= options_.dropouts[i] && t < options_.dropouts[i + 1]) return true;
  return false;
}

const UavGpsSample& UavGps::At(double t) const {
  const int k = static_cast<int>(std::floor(t * options_.rate + 1e-9));
  return samples_[static_cast<size_t>(std::clamp(k, 0, NumSamples() - 1))];
}

}  // namespace vloc
