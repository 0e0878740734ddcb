// Step 2: the ground each current image sees, as a plane fitted to sparse
// stereo. The rover's own footprint (z = 0 in the body frame) is a poor
// model of ground 5-30 m away when it stands on a slope or a crater rim;
// region prediction projects onto these planes instead.
#include <omp.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <random>

#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

namespace {

// The stereo point (body frame) of a left pixel, its right match searched by
// ZNCC along the epipolar segment of depths [z0, z1]; nullopt without one.
std::optional<Eigen::Vector3d> StereoPoint(const StereoRig& rig, const Pose3& body_from_left, const cv::Mat& left,
                                           const cv::Mat& right, const Eigen::Vector2d& px, double z0, double z1,
                                           const ZnccOptions& zncc) {
  Eigen::Vector2d a, b;
  if (!EpipolarSegment(rig, px, z0, z1, &a, &b)) return std::nullopt;
  const ZnccMatch z = ZnccAlongSegment(left, right, px, a, b, zncc);
  if (!z.ok) return std::nullopt;
  const Pose3 body_from_right = body_from_left * rig.left_from_right;
  Eigen::Vector3d p;
  if (!Triangulate(body_from_left.translation(), body_from_left.linear() * rig.left.Ray(px),
                   body_from_right.translation(), body_from_right.linear() * rig.right.Ray(z.right), &p))
    return std::nullopt;
  return p;
}

}  // namespace

GroundPointSet GroundStereoPoints(const NavcamModel& navcam, const MastPointing& pointing, const cv::Mat& left,
                                  const cv::Mat& right, const GroundPlaneOptions& o, const RegionOptions& regions,
                                  const ZnccOptions& zncc) {
  const Pose3 bl = navcam.mast.BodyFromLeft(pointing.pan, pointing.tilt, navcam.rig);
  const PinholeCamera& cam = navcam.rig.left;
  GroundPointSet out;
  out.camera = bl.translation();
  const int step = std::max(kGroundMinGridPx, o.ground_grid_px);
  for (int v = step / 2; v < cam.height; v += step) {
    for (int u = step / 2; u < cam.width; u += step) {
      const std::optional<Eigen::Vector3d> sp = StereoPoint(navcam.rig, bl, left, right, Eigen::Vector2d(u, v),
                                                            0.5 * regions.min_range_current,
                                                            1.5 * regions.max_range_current, zncc);
      if (!sp) continue;
      const Eigen::Vector3d& p = *sp;
      const double range = (p - bl.translation()).norm();
      if (range < 0.5 * regions.min_range_current || range > regions.max_range_current) continue;
      out.points.push_back(p);
    }
  }
  return out;
}

namespace {

// RANSAC, then least squares on the inliers; zero when implausible.
Eigen::Vector4d FitPlaneToPoints(const GroundPointSet& set, const NavcamModel& navcam, const GroundPlaneOptions& o) {
  const std::vector<Eigen::Vector3d>& pts = set.points;
  const int n = static_cast<int>(pts.size());
  if (n < o.ground_min_points) return Eigen::Vector4d::Zero();
  // Inlier tolerance grows with range (stereo range error, eq. 7).
  auto tolerance = [&](const Eigen::Vector3d& p) {
    const double r = (p - set.camera).norm();
    return o.ground_tolerance_m + 3 * RangeSigma(r, navcam.rig.Baseline(), navcam.rig.left.fx, 0.5) * 0.2;
  };
  const double min_up = std::cos(o.ground_max_slope_deg * M_PI / 180);
  std::mt19937 rng(kGroundRansacSeed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  Eigen::Vector4d best = Eigen::Vector4d::Zero();
  int best_n = 0;
  for (int it = 0; it < kGroundRansacIterations; ++it) {
    const Eigen::Vector3d &a = pts[pick(rng)], &b = pts[pick(rng)], &c = pts[pick(rng)];
    Eigen::Vector3d nrm = (b - a).cross(c - a);
    if (nrm.norm() < 1e-6) continue;
    nrm.normalize();
    if (nrm.z() < 0) nrm = -nrm;
    if (nrm.z() < min_up) continue;
    const double e = -nrm.dot(a);
    int k = 0;
    for (const auto& p : pts) k += std::abs(nrm.dot(p) + e) <= tolerance(p) ? 1 : 0;
    if (k > best_n) best_n = k, best << nrm, e;
  }
  if (best_n < o.ground_min_points || best_n < kGroundMinInlierFraction * n) return Eigen::Vector4d::Zero();
  // Least squares on the inliers.
  std::vector<Eigen::Vector3d> in;
  for (const auto& p : pts)
    if (std::abs(best.head<3>().dot(p) + best(3)) <= tolerance(p)) in.push_back(p);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : in) mean += p;
  mean /= in.size();
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (const auto& p : in) C += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
  Eigen::Vector3d nrm = es.eigenvectors().col(0);
  if (nrm.z() < 0) nrm = -nrm;
  if (nrm.z() < min_up) return Eigen::Vector4d::Zero();
  Eigen::Vector4d plane;
  plane << nrm, -nrm.dot(mean);
  return plane;
}

}  // namespace

Eigen::Vector4d FitGroundPlane(const NavcamModel& navcam, const MastPointing& pointing, const cv::Mat& left,
                               const cv::Mat& right, const GroundPlaneOptions& o, const RegionOptions& regions,
                               const ZnccOptions& zncc, GroundPointSet* points) {
  GroundPointSet set = GroundStereoPoints(navcam, pointing, left, right, o, regions, zncc);
  const Eigen::Vector4d plane = FitPlaneToPoints(set, navcam, o);
  if (points) *points = std::move(set);
  return plane;
}

int FitGroundPlanes(const NavcamModel& navcam, const TiePointSet& tps, const GroundPlaneOptions& o,
                    const RegionOptions& regions, const ZnccOptions& zncc, int num_threads, SitePairState* s) {
  const int nc = static_cast<int>(s->current.pairs.size());
  s->ground_planes.assign(nc, Eigen::Vector4d::Zero());
  s->current_ground.assign(nc, GroundPointSet());
  if (!o.fit_ground_planes) return 0;
  int num_planes = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(num_threads) reduction(+ : num_planes)
  for (int i = 0; i < nc; ++i) {
    s->ground_planes[i] =
        FitGroundPlane(navcam, tps.current_pointing[i], s->current_left[i].lsm.gray, s->current_right[i].lsm.gray, o, regions, zncc,
                       &s->current_ground[i]);
    num_planes += s->ground_planes[i].head<3>().norm() > kMinPlaneNormal ? 1 : 0;
  }
  return num_planes;
}

int MeasureFarTerrain(const NavcamModel& navcam, const TiePointSet& tps, const RegionOptions& regions,
                      const ZnccOptions& zncc, int num_threads, SitePairState* s) {
  const int nc = static_cast<int>(s->current.pairs.size());
  s->current_far.assign(nc, {});
  const RegionOptions& r = regions;
  const PinholeCamera& cam = navcam.rig.left;
  int total = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(num_threads) reduction(+ : total)
  for (int i = 0; i < nc; ++i) {
    const Pose3 bl = navcam.mast.BodyFromLeft(tps.current_pointing[i].pan, tps.current_pointing[i].tilt, navcam.rig);
    const cv::Mat& left = s->current_left[i].lsm.gray;
    const cv::Mat& right = s->current_right[i].lsm.gray;
    for (double v = r.image_margin; v < cam.height - r.image_margin; v += r.grid_step) {
      for (double u = r.image_margin; u < cam.width - r.image_margin; u += r.grid_step) {
        const Eigen::Vector2d px(u, v);
        const std::optional<Eigen::Vector3d> sp =
            StereoPoint(navcam.rig, bl, left, right, px, 0.5 * r.far_min_range, 2 * r.far_max_range, zncc);
        if (!sp) continue;
        const Eigen::Vector3d& p = *sp;
        const double range = (p - bl.translation()).norm();
        if (range < r.far_min_range || range > r.far_max_range) continue;
        s->current_far[i].push_back(
            {px, p, RangeSigma(range, navcam.rig.Baseline(), cam.fx, r.far_disparity_sigma_px)});
      }
    }
    total += static_cast<int>(s->current_far[i].size());
  }
  return total;
}

}  // namespace vloc::frontend_internal
