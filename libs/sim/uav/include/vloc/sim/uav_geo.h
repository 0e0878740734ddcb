#pragma once
// Local tangent plane <-> WGS84 geodetic coordinates for the simulated UAV
// (and for anything that must turn a GPS fix into metres).
// Local frame: x east, y north, z up, origin at (origin_latitude,
// origin_longitude, origin_altitude). The conversion uses the WGS84
// meridian and prime-vertical radii at the origin (first order): exact at
// the origin, < 1 cm error within 1 km of it.

namespace vloc {

class LocalTangentPlane {
 public:
  // Degrees, degrees, metres above the WGS84 ellipsoid.
  LocalTangentPlane(double origin_latitude, double origin_longitude, double origin_altitude);

  // Local east/north/up (m) -> latitude (deg), longitude (deg), altitude (m, ellipsoid).
  void ToGeodetic(double east, double north, double up, double* latitude, double* longitude,
                  double* altitude) const;
  // Latitude (deg), longitude (deg), altitude (m) -> local east/north/up (m).
  void FromGeodetic(double latitude, double longitude, double altitude, double* east, double* north,
                    double* up) const;

  double origin_latitude() const { return lat0_; }
  double origin_longitude() const { return lon0_; }
  double origin_altitude() const { return alt0_; }

 private:
  double lat0_, lon0_, alt0_;
  double metres_per_rad_lat_;  // meridian radius of curvature (+ altitude)
  double metres_per_rad_lon_;  // prime-vertical radius * cos(lat0) (+ altitude)
};

}  // namespace vloc
