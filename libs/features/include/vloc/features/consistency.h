#pragma once
// Outlier detection by distance consistency (Wan et al. eq. 2): a rigid
// motion keeps every distance between two ground points, so the distance of
// points a and b intersected at site 1 must equal the one at site 2 up to
// the measurement error. The threshold e_L of each pair comes from the
// range error model (eq. 7, sigma_r = r^2 / (b f) sigma_p) and a lateral
// (angular) error, projected on the line between the two points. Each
// consistent pair adds a vote to both points; points with fewer votes
// than the weight threshold are outliers.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace vloc {

class OptionsReader;

// Position covariance of a stereo-intersected point (eq. 7 along the ray,
// r * sigma_angle across it). `ray` is the viewing direction (camera to
// point), `range` its length (m), baseline (m), focal (px), sigma_parallax
// (px), sigma_angle (rad).
Eigen::Matrix3d StereoPointCovariance(const Eigen::Vector3d& ray, double range, double baseline, double focal,
                                      double sigma_parallax, double sigma_angle);

// eq. 7: sigma_r = r^2 / (b f) sigma_p.
inline double RangeSigma(double range, double baseline, double focal, double sigma_parallax) {
  return range * range / (baseline * focal) * sigma_parallax;
}

struct ConsistencyOptions {
  double k_sigma = 3.0;               // e_L = k_sigma * sigma(e) + min_threshold
  double min_threshold = 0.02;        // m, added to every pair's threshold
  double min_weight_fraction = 0.8;   // weight threshold = this * median weight of the current inliers
  int min_weight = 3;                 // and at least this many votes
  int max_passes = 5;                 // re-vote among the survivors until nothing changes

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct ConsistencyResult {
  std::vector<int> weights;    // votes of each point (last pass)
  std::vector<bool> inlier;    // weight >= threshold
  int num_inliers = 0;
  int weight_threshold = 0;    // of the last pass
  int passes = 0;
};

// p1[i], p2[i]: point i in the frames of site 1 and 2; cov1/cov2 their
// covariances (same size; empty = use min_threshold only).
ConsistencyResult DistanceConsistencyCheck(const std::vector<Eigen::Vector3d>& p1,
                                           const std::vector<Eigen::Matrix3d>& cov1,
                                           const std::vector<Eigen::Vector3d>& p2,
                                           const std::vector<Eigen::Matrix3d>& cov2,
                                           const ConsistencyOptions& options);

// Motion consistency, the per-point complement of eq. 2: the points of
// both sites must agree under ONE rigid motion, each within its own
// anisotropic covariance (long along the ray at far range, narrow across
// it). Pairwise distances cannot see a point shifted across the line of
// sight by many angular sigmas when its distances to the others run along
// the rays, where the range error hides it; the Mahalanobis residual does.
// RANSAC over 3-point samples (Umeyama), refit on the inliers.
struct MotionConsistencyOptions {
  double max_mahalanobis_sq = 16.27;  // chi-square, 3 DoF, 99.9 %
  int ransac_iterations = 300;        // 3-point samples
  uint64_t seed = 1;                  // sample generator (results are reproducible)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct MotionConsistencyResult {
  bool ok = false;                         // a motion with at least 3 inliers was found
  Eigen::Matrix4d site1_from_site2 = Eigen::Matrix4d::Identity();
  std::vector<bool> inlier;
  int num_inliers = 0;
};

MotionConsistencyResult MotionConsistencyCheck(const std::vector<Eigen::Vector3d>& p1,
                                               const std::vector<Eigen::Matrix3d>& cov1,
                                               const std::vector<Eigen::Vector3d>& p2,
                                               const std::vector<Eigen::Matrix3d>& cov2,
                                               const MotionConsistencyOptions& options);

}  // namespace vloc
