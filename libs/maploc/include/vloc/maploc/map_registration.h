#pragma once
// Absolute localization of a rover site against an aerial map: the rover's
// ground orthophoto (ground_ortho.h) registered to the map's orthoimage (and
// its height map when it has one) over (x, y, heading) within the prior's
// uncertainty.
//   1. Search window from the prior covariance (sigma_multiple sigmas, clamped).
//   2. Both rasters at the map's resolution, high-passed (difference of
//      Gaussians: sun, exposure and tilt leave little at the scale of rocks
//      and craters), a texture test on each.
//   3. For every heading step: the orthophoto rotated into the map's axes,
//      masked ZNCC over the window (grey and height, weighted mean).
//   4. The best heading refined at a finer step; the peak refined to
//      sub-pixel by a quadratic fit, heading by a parabola.
//   5. Tests: peak score, ambiguity (second peak outside an exclusion zone),
//      peak on the window's edge; any failure is "no fix" with the reason.
//   6. Height (when the map has one): the body's z = median of map height
//      minus orthophoto height over the placed orthophoto, sigma from their spread.
//   7. Covariance from the peak curvature: cov = k (1 - rho) H^-1 / N,
//      k calibrated in simulation (NEES), one k for position, one for heading.
//
//   MapFix fix = RegisterToMap(ortho, map, SitePriorFromPose(predicted), options);
//   if (fix.usable) PoseWithCovariance p = FixToPose(fix, predicted, options);

#include <Eigen/Core>
#include <string>

#include "vloc/common/pose.h"
#include "vloc/maploc/map_raster.h"

namespace vloc {
class OptionsReader;
}

namespace vloc::maploc {

struct RegistrationOptions {
  double sigma_multiple = 4.0;        // search window: this many prior sigmas ...
  double min_search_radius_m = 2.0;   // m, ... but at least this ...
  double max_search_radius_m = 30.0;  // m, ... and at most this
  double min_heading_range_deg = 4.0; // deg, heading searched +-max(this, sigma_multiple sigma) ...
  double max_heading_range_deg = 30.0;// deg, ... up to this
  double heading_step_deg = 1.0;      // deg, coarse heading step
  int fine_steps = 4;                 // the best coarse heading refined at heading_step_deg / this
  int heading_fit_half_width = 4;     // fine steps each side of the best in the heading parabola (least squares)
  double highpass_sigma_m = 1.5;      // m, Gaussian removed from both rasters (high pass)
  double lowpass_sigma_px = 0.7;      // px, Gaussian applied to both rasters (anti-alias)
  double gray_weight = 1.0;           // weight of the grey-level ZNCC
  double height_weight = 2.0;         // weight of the height ZNCC (when the map has heights; sun-independent)
  int min_valid_cells = 300;          // orthophoto cells with data, at the map's resolution
  double min_overlap = 0.9;           // fraction of the orthophoto that must fall on valid map cells
  double min_gray_texture = 0.5;      // grey levels, high-passed std below this = featureless (grey scale 0..255)
  double min_height_texture_m = 0.01; // m, high-passed height std below this = flat
  double min_peak_score = 0.35;       // combined ZNCC of the best placement
  double max_peak_ratio = 0.8;        // second peak / best peak above this = ambiguous
  double exclusion_radius_m = 2.0;    // m, the second peak: the best local maximum this far from the best, any heading
  double covariance_scale = 60.0;     // k in cov = k (1 - rho) H^-1 / N, position (calibrated: bench_maploc_sites)
  double heading_covariance_scale = 50.0;   // k of the heading variance (calibrated likewise)
  double min_position_sigma_m = 0.02; // m, floor of the reported position sigma
  double min_heading_sigma_deg = 0.05;// deg, floor of the reported heading sigma
  double map_position_sigma_m = 0.0;  // m, 1-sigma per axis of the map's own georeferencing error, added to the fix's
                                      // (a UAV mosaic tied to GPS: its tie error; an orthophoto: its stated accuracy)
  double map_heading_sigma_deg = 0.0; // deg, 1-sigma of the map's own orientation error, added likewise
  double tilt_sigma_rad = 0.5;        // rad, roll/pitch sigma of the published fix (the map does not see them)
  double vertical_sigma_m = 5.0;      // m, z sigma of the published fix without a map height (added to the prior's)
  double min_vertical_sigma_m = 0.05; // m, floor of the z sigma measured against the map's heights
  double vertical_correlation_cells = 100;  // cells per independent height difference (z sigma = spread / sqrt(N / this))

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// The predicted site pose, reduced to what the map constrains.
struct SitePrior {
  Eigen::Vector3d xyh = Eigen::Vector3d::Zero();       // x (m), y (m), heading (rad, ccw from east)
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero(); // of xyh
};
SitePrior SitePriorFromPose(const PoseWithCovariance& world_from_body);

struct MapFix {
  bool usable = false;
  std::string message;                                  // "ok" or the reason there is no fix
  Eigen::Vector3d xyh = Eigen::Vector3d::Zero();        // x (m), y (m), heading (rad), world frame
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero(); // of xyh
  double peak_score = 0;        // combined ZNCC at the peak
  double gray_score = 0;        // grey ZNCC at the peak
  double height_score = 0;      // height ZNCC at the peak (0 without heights)
  double second_score = 0;      // best score outside the exclusion zone
  bool has_z = false;           // the map's heights gave the body's height
  double z = 0;                 // m, world z of the body origin (when has_z)
  double z_sigma = 0;           // m
  int valid_cells = 0;          // orthophoto cells used (map resolution)
  double search_radius_m = 0;   // m
  double heading_range_deg = 0; // deg, +-
  int headings_tried = 0;
  double seconds = 0;
  std::string BriefReport() const;
};

MapFix RegisterToMap(const MapRaster& ground_ortho, const MapRaster& map, const SitePrior& prior,
                     const RegistrationOptions& options);

// The fix as a world_from_body pose: x, y, heading (and z when has_z) from
// the fix; roll, pitch (and z otherwise) from the prediction with the weak
// sigmas of `options`.
PoseWithCovariance FixToPose(const MapFix& fix, const PoseWithCovariance& predicted, const RegistrationOptions& options);

}  // namespace vloc::maploc
