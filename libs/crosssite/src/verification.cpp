// Step 12: verification (Wan et al. 2.2). Distance consistency (eq. 2)
// with thresholds from the points' covariances (eq. 7), then one rigid
// motion within each point's anisotropic covariance, then the tie points
// with their sigmas; finally the motion they imply against dead reckoning
// (the distance check is blind to a set of matches that is wrong by one
// rigid motion, e.g. on repeated texture).
#include <Eigen/Geometry>
#include <cmath>
#include <sstream>

#include <glog/logging.h>

#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

Verification CheckConsistency(const std::vector<Candidate>& cands, const VerificationOptions& o) {
  std::vector<Eigen::Vector3d> p1, p2;
  std::vector<Eigen::Matrix3d> c1, c2;
  for (const auto& c : cands) {
    p1.push_back(c.p_prev);
    p2.push_back(c.p_cur);
    c1.push_back(c.cov_prev);
    c2.push_back(c.cov_cur);
  }
  const ConsistencyResult cons = DistanceConsistencyCheck(p1, c1, p2, c2, o.consistency);
  // Until the motion check: kept = consistent.
  return Verification{cons.inlier, cons.weights, cons.num_inliers, cons.inlier, cons.num_inliers};
}

void CheckMotion(const std::vector<Candidate>& cands, const VerificationOptions& o, Verification* v) {
  if (!o.motion_consistency) return;
  std::vector<Eigen::Vector3d> q1, q2;
  std::vector<Eigen::Matrix3d> d1, d2;
  std::vector<size_t> where;
  for (size_t k = 0; k < cands.size(); ++k) {
    if (!v->consistent[k]) continue;
    q1.push_back(cands[k].p_prev), q2.push_back(cands[k].p_cur), d1.push_back(cands[k].cov_prev),
        d2.push_back(cands[k].cov_cur);
    where.push_back(k);
  }
  const MotionConsistencyResult mc = MotionConsistencyCheck(q1, d1, q2, d2, o.motion);
  for (size_t q = 0; q < where.size(); ++q) v->keep[where[q]] = mc.ok && mc.inlier[q];
  v->num_kept = 0;
  for (bool k : v->keep) v->num_kept += k ? 1 : 0;
}

void MakeTiePoints(const std::vector<Candidate>& cands, const Verification& v, const RegionPrediction& pred,
                   const VerificationOptions& o, TiePointSet* tps) {
  int id = 0;
  for (size_t k = 0; k < cands.size(); ++k) {
    if (!v.keep[k]) continue;
    const Candidate& c = cands[k];
    TiePoint tp;
    tp.id = id++;
    tp.p_previous = c.p_prev;
    tp.p_current = c.p_cur;
    tp.weight = v.weights[k];
    // The cross-site error is split between the two left observations: the
    // floor in previous px, scaled to current px by the overlap's scale.
    const double cur_per_prev = 1.0 / std::max(pred.overlaps[c.overlap].scale, 1e-3);
    const double s_prev = std::max(c.sigma_cross / cur_per_prev, o.cross_sigma_floor_px) / std::sqrt(2.0);
    const double s_cur = std::max(c.sigma_cross, o.cross_sigma_floor_px * cur_per_prev) / std::sqrt(2.0);
    tp.observations.push_back({SiteRole::kPrevious, c.prev_pair, CameraSide::kLeft, c.prev_left, s_prev});
    tp.observations.push_back({SiteRole::kPrevious, c.prev_pair, CameraSide::kRight, c.prev_right,
                               std::hypot(std::max(c.sigma_prev_right, o.stereo_sigma_floor_px), s_prev)});
    tp.observations.push_back({SiteRole::kCurrent, c.cur_pair, CameraSide::kLeft, c.cur_left, s_cur});
    tp.observations.push_back({SiteRole::kCurrent, c.cur_pair, CameraSide::kRight, c.cur_right,
                               std::hypot(std::max(c.sigma_cur_right, o.stereo_sigma_floor_px), s_cur)});
    VLOG(2) << "tie point at previous " << c.prev_left.transpose() << " range " << c.p_prev.norm() << " corr "
            << c.grid_correlation << " sigma_max " << c.grid_sigma_max << " affine " << c.grid_affine(0, 0) << " "
            << c.grid_affine(0, 1) << " " << c.grid_affine(1, 0) << " " << c.grid_affine(1, 1) << " weight "
            << v.weights[k];
    tps->points.push_back(std::move(tp));
  }
}

std::optional<std::string> CheckAgainstDeadReckoning(const RegionPrediction& pred, const VerificationOptions& o,
                                                     TiePointSet* tps) {
  if (tps->points.size() < 3 || o.max_motion_sigmas <= 0) return std::nullopt;
  Eigen::Matrix3Xd a(3, tps->points.size()), b(3, tps->points.size());
  for (size_t k = 0; k < tps->points.size(); ++k) {
    a.col(k) = tps->points[k].p_current;
    b.col(k) = tps->points[k].p_previous;
  }
  const Eigen::Matrix4d T = Eigen::umeyama(a, b, false);  // previous_from_current
  const Eigen::Vector3d dt = T.block<3, 1>(0, 3) - pred.previous_from_current.translation();
  const double dyaw = std::abs(WrapAngle(std::atan2(T(1, 0), T(0, 0)) -
                                         std::atan2(pred.previous_from_current.linear()(1, 0),
                                                    pred.previous_from_current.linear()(0, 0))));
  const double sp = std::max(std::hypot(pred.relative_sigma(0), pred.relative_sigma(1)), 0.05);
  const double sy = std::max(pred.relative_sigma(5), 1e-3);
  const bool translation_off = o.dr_check_translation && dt.head<2>().norm() > o.max_motion_sigmas * sp;
  if (!(translation_off || dyaw > o.max_motion_sigmas * sy)) return std::nullopt;
  std::ostringstream os;
  os << "the " << tps->points.size() << " consistent tie points imply a motion " << dt.head<2>().norm() << " m / "
     << dyaw * 180 / M_PI << " deg from dead reckoning (beyond " << o.max_motion_sigmas
     << " sigma): likely repeated texture; not used";
  tps->points.clear();
  return os.str();
}

}  // namespace vloc::frontend_internal
