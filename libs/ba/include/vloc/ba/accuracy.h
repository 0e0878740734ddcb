#pragma once
// Theoretical accuracy of cross-site localization (Wan et al., section 3):
// stereo range error (eq. 7), 2-D point covariances (eq. 8), a similarity
// transform fitted to the tie points (eqs. 9-11) and the covariance of the
// new site's position it implies (eqs. 12-13). Plain 2-D geometry on the
// level plane; no LCM, no images.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace vloc {

class OptionsReader;

// Which tie-point covariances enter M_c^p (eq. 11).
enum class TiePointErrorModel {
  kPrevious,  // only the previous site's stereo measurement (x, y error-free)
  kCurrent,   // only the current site's stereo measurement
  kBoth,      // both sites' measurements (sum of the two covariances)
};

struct AccuracyOptions {
  double focal_px = 1189.0;              // px, Navcam focal length f
  double baseline_m = 0.27;              // m, stereo baseline B
  double sigma_parallax_px = 1.0 / 3.0;  // px, parallax (stereo matching) 1-sigma
  double sigma_azimuth_px = 3.0;         // px, cross-site matching 1-sigma; sigma_theta = atan(px / f)
  Eigen::Vector2d previous_site = Eigen::Vector2d(0, 0);  // m, previous site centre (x, y)
  Eigen::Vector2d current_site = Eigen::Vector2d(10, 0);  // m, current site centre (x, y)
  std::vector<double> landmarks_xy = {13, 1.5, 13, -1.5, 16, 1.5, 16, -1.5};  // m, x0 y0 x1 y1 ...
  std::string error_model = "previous";  // previous | current | both: covariances in M_c^p
  std::string current_frame = "world";   // world | site: frame of (x, y) and (x_p, y_p) in eqs. 9, 12
  bool paper_eq8_offdiagonal = false;    // true: eq. 8's off-diagonal as printed, sc sr^2 - r^2 (sc)^2 st^2 (reproduces the paper's figures)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
  double SigmaAzimuthRad() const;
  std::vector<Eigen::Vector2d> Landmarks() const;
  TiePointErrorModel ErrorModel() const;
};

// Range error of the normal-case stereo model, eq. 7: r^2 sigma_p / (B f).
double StereoRangeSigma(double range_m, double baseline_m, double focal_px, double sigma_parallax_px);

// 2-D covariance of a point measured at range r and azimuth theta with range
// and azimuth errors (eq. 8, polar -> cartesian): J diag(sr^2, st^2) J^T,
// off-diagonal sin(theta) cos(theta) (sr^2 - r^2 st^2).
Eigen::Matrix2d PolarPointCovariance(double range_m, double azimuth_rad, double sigma_range_m,
                                     double sigma_azimuth_rad);

// Covariance of a landmark as measured by stereo from `site` (eqs. 7-8).
// With options.paper_eq8_offdiagonal the off-diagonal is the paper's printed one.
Eigen::Matrix2d StereoPointCovariance(const Eigen::Vector2d& site, const Eigen::Vector2d& landmark,
                                      const AccuracyOptions& options);

struct AccuracyLandmark {
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // m
  double range_previous = 0;        // m, from the previous site
  double range_current = 0;         // m, from the current site
  double sigma_range_previous = 0;  // m, eq. 7
  double sigma_range_current = 0;   // m, eq. 7
  Eigen::Matrix2d cov_previous = Eigen::Matrix2d::Zero();  // m^2, eq. 8 from the previous site
  Eigen::Matrix2d cov_current = Eigen::Matrix2d::Zero();   // m^2, eq. 8 from the current site
};

struct AccuracyResult {
  bool usable = false;
  std::string message;
  std::vector<AccuracyLandmark> landmarks;
  Eigen::Matrix4d cov_transform = Eigen::Matrix4d::Zero();  // (a, b, c, d), eq. 11
  Eigen::Matrix2d cov_site = Eigen::Matrix2d::Zero();       // m^2, new site position, eq. 13
  double site_distance = 0;        // m, between the sites
  double sigma_x = 0, sigma_y = 0; // m, sqrt of the diagonal of cov_site
  double sigma_position = 0;       // m, sqrt(trace cov_site) (2-D position error)
  double accuracy_percent = 0;     // 100 * sigma_position / site_distance
};

// Analytic error propagation, eqs. 7-13.
AccuracyResult ComputeLocalizationAccuracy(const AccuracyOptions& options);

struct MonteCarloResult {
  int trials = 0;
  Eigen::Matrix2d cov_site = Eigen::Matrix2d::Zero();  // m^2, sample covariance of the new site position
  Eigen::Vector2d mean_error = Eigen::Vector2d::Zero(); // m
  double sigma_position = 0;    // m, sqrt(trace)
  double accuracy_percent = 0;  // 100 * sigma_position / site_distance
};

// Simulates the same estimate: draws stereo range/azimuth errors for every
// landmark as the error model says, fits the similarity transform by least
// squares weighted with the analytic M_c^p, maps the site and collects the
// error statistics.
MonteCarloResult MonteCarloLocalizationAccuracy(const AccuracyOptions& options, int trials, uint64_t seed);

// A printable report of the analytic result.
std::string FormatAccuracyReport(const AccuracyOptions& options, const AccuracyResult& result);

}  // namespace vloc
