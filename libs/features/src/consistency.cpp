#include "vloc/features/consistency.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>

#include "vloc/common/options.h"

namespace vloc {

Eigen::Matrix3d StereoPointCovariance(const Eigen::Vector3d& ray, double range, double baseline, double focal,
                                      double sigma_parallax, double sigma_angle) {
  const Eigen::Vector3d u = ray.normalized();
  const double sr = RangeSigma(range, baseline, focal, sigma_parallax);
  const double sl = range * sigma_angle;
  const Eigen::Matrix3d uu = u * u.transpose();
  return sr * sr * uu + sl * sl * (Eigen::Matrix3d::Identity() - uu);
}

void ConsistencyOptions::Visit(OptionsReader& r) {
  r.Optional("k_sigma", &k_sigma, "threshold e_L in standard deviations of the distance residual", Positive());
  r.Optional("min_threshold", &min_threshold, "m, added to every pair's threshold", NonNegative());
  r.Optional("min_weight_fraction", &min_weight_fraction, "weight threshold as a fraction of the median weight",
             InLeftOpen(0, 1));
  r.Optional("min_weight", &min_weight, "votes, lowest weight threshold", AtLeast(1));
  r.Optional("max_passes", &max_passes, "voting passes among the survivors", AtLeast(1));
}

bool ConsistencyOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

ConsistencyResult DistanceConsistencyCheck(const std::vector<Eigen::Vector3d>& p1,
                                           const std::vector<Eigen::Matrix3d>& cov1,
                                           const std::vector<Eigen::Vector3d>& p2,
                                           const std::vector<Eigen::Matrix3d>& cov2,
                                           const ConsistencyOptions& o) {
  const int n = static_cast<int>(p1.size());
  const bool have_cov = cov1.size() == p1.size() && cov2.size() == p2.size();
  ConsistencyResult res;
  res.inlier.assign(n, true);
  res.weights.assign(n, 0);
  // consistent(i, j) does not change between passes: compute it once.
  std::vector<uint8_t> ok(static_cast<size_t>(n) * n, 0);
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      const Eigen::Vector3d d1 = p1[i] - p1[j], d2 = p2[i] - p2[j];
      const double l1 = d1.norm(), l2 = d2.norm();
      double var = 0;
      if (have_cov && l1 > 1e-9 && l2 > 1e-9) {
        const Eigen::Vector3d n1 = d1 / l1, n2 = d2 / l2;
        var = n1.dot((cov1[i] + cov1[j]) * n1) + n2.dot((cov2[i] + cov2[j]) * n2);
      }
      const double e_l = o.k_sigma * std::sqrt(var) + o.min_threshold;
      const uint8_t c = std::abs(l1 - l2) <= e_l ? 1 : 0;
      ok[static_cast<size_t>(i) * n + j] = ok[static_cast<size_t>(j) * n + i] = c;
    }
  }
  for (int pass = 0; pass < o.max_passes; ++pass) {
    res.passes = pass + 1;
    std::vector<int> w(n, 0);
    for (int i = 0; i < n; ++i) {
      const uint8_t* row = &ok[static_cast<size_t>(i) * n];
      for (int j = 0; j < n; ++j)
        if (j != i && res.inlier[j] && row[j]) ++w[i];
    }
    std::vector<int> inlier_w;
    for (int i = 0; i < n; ++i)
      if (res.inlier[i]) inlier_w.push_back(w[i]);
    int threshold = o.min_weight;
    if (!inlier_w.empty()) {
      std::nth_element(inlier_w.begin(), inlier_w.begin() + inlier_w.size() / 2, inlier_w.end());
      threshold = std::max(o.min_weight,
                           static_cast<int>(std::ceil(o.min_weight_fraction * inlier_w[inlier_w.size() / 2])));
    }
    bool changed = false;
    for (int i = 0; i < n; ++i) {
      const bool in = res.inlier[i] && w[i] >= threshold;
      changed |= in != res.inlier[i];
      res.inlier[i] = in;
    }
    res.weights = w;
    res.weight_threshold = threshold;
    if (!changed) break;
  }
  res.num_inliers = static_cast<int>(std::count(res.inlier.begin(), res.inlier.end(), true));
  return res;
}

void MotionConsistencyOptions::Visit(OptionsReader& r) {
  r.Optional("max_mahalanobis_sq", &max_mahalanobis_sq, "squared Mahalanobis residual of an inlier (chi-square, 3 DoF)",
             Positive());
  r.Optional("ransac_iterations", &ransac_iterations, "3-point RANSAC samples", AtLeast(1));
  r.Optional("seed", &seed, "sample generator seed");
}

bool MotionConsistencyOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

namespace {

// Inliers of p1 ~ T * p2 under the per-point covariances.
int CountMotionInliers(const Eigen::Matrix4d& T, const std::vector<Eigen::Vector3d>& p1,
                       const std::vector<Eigen::Matrix3d>& cov1, const std::vector<Eigen::Vector3d>& p2,
                       const std::vector<Eigen::Matrix3d>& cov2, double max_m2, std::vector<bool>* inlier) {
  const Eigen::Matrix3d R = T.block<3, 3>(0, 0);
  const Eigen::Vector3d t = T.block<3, 1>(0, 3);
  int n = 0;
  inlier->assign(p1.size(), false);
  for (size_t i = 0; i < p1.size(); ++i) {
    const Eigen::Vector3d r = p1[i] - (R * p2[i] + t);
    Eigen::Matrix3d C = Eigen::Matrix3d::Identity() * 1e-6;
    if (!cov1.empty()) C += cov1[i];
    if (!cov2.empty()) C += R * cov2[i] * R.transpose();
    const double m2 = r.dot(C.ldlt().solve(r));
    if (m2 <= max_m2) (*inlier)[i] = true, ++n;
  }
  return n;
}

Eigen::Matrix4d FitMotion(const std::vector<Eigen::Vector3d>& p1, const std::vector<Eigen::Vector3d>& p2,
                          const std::vector<int>& idx) {
  Eigen::Matrix3Xd a(3, idx.size()), b(3, idx.size());
  for (size_t k = 0; k < idx.size(); ++k) {
    a.col(k) = p2[idx[k]];
    b.col(k) = p1[idx[k]];
  }
  return Eigen::umeyama(a, b, false);
}

}  // namespace

MotionConsistencyResult MotionConsistencyCheck(const std::vector<Eigen::Vector3d>& p1,
                                               const std::vector<Eigen::Matrix3d>& cov1,
                                               const std::vector<Eigen::Vector3d>& p2,
                                               const std::vector<Eigen::Matrix3d>& cov2,
                                               const MotionConsistencyOptions& o) {
  MotionConsistencyResult res;
  const int n = static_cast<int>(p1.size());
  res.inlier.assign(n, false);
  if (n < 3 || p2.size() != p1.size()) return res;
  std::mt19937_64 rng(o.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<bool> in;
  int best = 0;
  Eigen::Matrix4d best_T = Eigen::Matrix4d::Identity();
  for (int it = 0; it < o.ransac_iterations; ++it) {
    const int a = pick(rng), b = pick(rng), c = pick(rng);
    if (a == b || b == c || a == c) continue;
    // Degenerate (nearly collinear) samples fix no rotation.
    const Eigen::Vector3d u = p2[b] - p2[a], v = p2[c] - p2[a];
    if (u.cross(v).norm() < 1e-3 * u.norm() * v.norm()) continue;
    const Eigen::Matrix4d T = FitMotion(p1, p2, {a, b, c});
    const int k = CountMotionInliers(T, p1, cov1, p2, cov2, o.max_mahalanobis_sq, &in);
    if (k > best) best = k, best_T = T;
  }
  if (best < 3) return res;
  // Refit on the inliers until the set settles.
  Eigen::Matrix4d T = best_T;
  int k = CountMotionInliers(T, p1, cov1, p2, cov2, o.max_mahalanobis_sq, &in);
  for (int pass = 0; pass < 5; ++pass) {
    std::vector<int> idx;
    for (int i = 0; i < n; ++i)
      if (in[i]) idx.push_back(i);
    if (idx.size() < 3) break;
    const Eigen::Matrix4d T2 = FitMotion(p1, p2, idx);
    std::vector<bool> in2;
    const int k2 = CountMotionInliers(T2, p1, cov1, p2, cov2, o.max_mahalanobis_sq, &in2);
    if (k2 < k) break;
    const bool same = in2 == in;
    T = T2, k = k2, in = in2;
    if (same) break;
  }
  res.ok = k >= 3;
  res.site1_from_site2 = T;
  res.inlier = in;
  res.num_inliers = k;
  return res;
}

}  // namespace vloc
