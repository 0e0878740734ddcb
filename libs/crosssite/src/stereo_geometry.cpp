// Geometry the steps share: the epipolar segment of a left pixel and the
// intersection of two rays.
#include <algorithm>
#include <cmath>

#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

bool EpipolarSegment(const StereoRig& rig, const Eigen::Vector2d& left_px, double z0, double z1, Eigen::Vector2d* a,
                     Eigen::Vector2d* b) {
  const Pose3 right_from_left = rig.left_from_right.inverse();
  const Eigen::Vector3d ray = rig.left.Ray(left_px);
  const auto pa = rig.right.ProjectIdeal(right_from_left * (ray * z1));
  const auto pb = rig.right.ProjectIdeal(right_from_left * (ray * z0));
  if (!pa || !pb) return false;
  *a = *pa;
  *b = *pb;
  // Clip to the image (keep a small margin for the correlation window).
  const Eigen::Vector2d d = *b - *a;
  double t0 = 0, t1 = 1;
  const double lo[2] = {0, 0}, hi[2] = {static_cast<double>(rig.right.width - 1), static_cast<double>(rig.right.height - 1)};
  for (int k = 0; k < 2; ++k) {
    if (std::abs(d(k)) < 1e-12) {
      if ((*a)(k) < lo[k] || (*a)(k) > hi[k]) return false;
      continue;
    }
    double ta = (lo[k] - (*a)(k)) / d(k), tb = (hi[k] - (*a)(k)) / d(k);
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (t0 >= t1) return false;
  const Eigen::Vector2d a0 = *a;
  *a = a0 + t0 * d;
  *b = a0 + t1 * d;
  return true;
}

bool Triangulate(const Eigen::Vector3d& o1, const Eigen::Vector3d& d1, const Eigen::Vector3d& o2,
                 const Eigen::Vector3d& d2, Eigen::Vector3d* p) {
  const Eigen::Vector3d w = o1 - o2;
  const double a = d1.dot(d1), b = d1.dot(d2), c = d2.dot(d2), d = d1.dot(w), e = d2.dot(w);
  const double den = a * c - b * b;
  if (den < 1e-12) return false;
  const double s = (b * e - c * d) / den, t = (a * e - b * d) / den;
  if (s <= 0 || t <= 0) return false;
  *p = 0.5 * ((o1 + s * d1) + (o2 + t * d2));
  return true;
}

}  // namespace vloc::frontend_internal
