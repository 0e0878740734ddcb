#include "vloc/sim/uav_geo.h"

#include <cmath>

namespace vloc {
namespace {
constexpr double kSemiMajor = 6378137.0;            // m, WGS84
constexpr double kEccentricity2 = 6.69437999014e-3; // WGS84 first eccentricity squared
constexpr double kDegToRad = M_PI / 180.0;
}  // namespace

LocalTangentPlane::LocalTangentPlane(double origin_latitude, double origin_longitude, double origin_altitude)
    : lat0_(origin_latitude), lon0_(origin_longitude), alt0_(origin_altitude) {
  const double s = std::sin(lat0_ * kDegToRad);
  const double w = std::sqrt(1.0 - kEccentricity2 * s * s);
  const double meridian = kSemiMajor * (1.0 - kEccentricity2) / (w * w * w);
  const double prime_vertical = kSemiMajor / w;
  metres_per_rad_lat_ = meridian + alt0_;
  metres_per_rad_lon_ = (prime_vertical + alt0_) * std::cos(lat0_ * kDegToRad);
}

void LocalTangentPlane::ToGeodetic(double east, double north, double up, double* latitude, double* longitude,
                                   double* altitude) const {
  *latitude = lat0_ + north / metres_per_rad_lat_ / kDegToRad;
  *longitude = lon0_ + east / metres_per_rad_lon_ / kDegToRad;
  *altitude = alt0_ + up;
}

void LocalTangentPlane::FromGeodetic(double latitude, double longitude, double altitude, double* east,
                                     double* north, double* up) const {
  *north = (latitude - lat0_) * kDegToRad * metres_per_rad_lat_;
  *east = (longitude - lon0_) * kDegToRad * metres_per_rad_lon_;
  *up = altitude - alt0_;
}

}  // namespace vloc
