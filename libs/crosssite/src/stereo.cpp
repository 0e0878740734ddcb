// Step 11: stereo at both sites (Wan et al. 2.2): ZNCC along the epipolar
// segment, a median filter of the disparities against the neighbours, and
// least-squares matching left -> right, then each site's point intersected
// with its covariance (eq. 7).
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

namespace {

void DropRejected(std::vector<Candidate>* cands) {
  cands->erase(std::remove_if(cands->begin(), cands->end(), [](const Candidate& c) { return !c.ok; }), cands->end());
}

}  // namespace

int CorrelateStereo(const NavcamModel& navcam, const StereoStepOptions& o, int num_threads, SitePairState* s) {
  std::vector<Candidate>& cands = s->candidates;
  const int n = static_cast<int>(cands.size());
#pragma omp parallel for schedule(dynamic, 16) num_threads(num_threads)
  for (int k = 0; k < n; ++k) {
    Candidate& c = cands[k];
    Eigen::Vector2d a, b;
    c.ok = false;
    if (!EpipolarSegment(navcam.rig, c.prev_left, o.stereo_min_depth, o.stereo_max_depth, &a, &b)) continue;
    const ZnccMatch zp = ZnccAlongSegment(s->previous_left[c.prev_pair].lsm.gray, s->previous_right[c.prev_pair].lsm.gray,
                                          c.prev_left, a, b, o.zncc);
    if (!zp.ok) continue;
    if (!EpipolarSegment(navcam.rig, c.cur_left, o.stereo_min_depth, o.stereo_max_depth, &a, &b)) continue;
    const ZnccMatch zc = ZnccAlongSegment(s->current_left[c.cur_pair].lsm.gray, s->current_right[c.cur_pair].lsm.gray,
                                          c.cur_left, a, b, o.zncc);
    if (!zc.ok) continue;
    c.prev_right = zp.right;
    c.cur_right = zc.right;
    c.ok = true;
  }
  DropRejected(&cands);
  return static_cast<int>(cands.size());
}

int MedianFilterDisparities(const StereoStepOptions& o, SitePairState* s) {
  std::vector<Candidate>& cands = s->candidates;
  for (int site = 0; site < 2; ++site) {
    std::map<int, std::vector<int>> by_image;
    for (int k = 0; k < static_cast<int>(cands.size()); ++k)
      by_image[site == 0 ? cands[k].prev_pair : cands[k].cur_pair].push_back(k);
    for (const auto& [image, idx] : by_image) {
      std::vector<Eigen::Vector2d> pts;
      std::vector<double> disp;
      for (int k : idx) {
        const Candidate& c = cands[k];
        pts.push_back(site == 0 ? c.prev_left : c.cur_left);
        disp.push_back(site == 0 ? (c.prev_left - c.prev_right).norm() : (c.cur_left - c.cur_right).norm());
      }
      const auto keep = MedianDisparityFilter(pts, disp, o.median);
      for (size_t q = 0; q < idx.size(); ++q)
        if (!keep[q]) cands[idx[q]].ok = false;
    }
  }
  DropRejected(&cands);
  return static_cast<int>(cands.size());
}

namespace {

// One site's point of candidate c (site 0: previous) in that site's body
// frame, with its covariance; false when the rays do not intersect.
bool Intersect(const NavcamModel& navcam, const MastPointing& mp, const Eigen::Vector2d& ul, const Eigen::Vector2d& ur,
               double sigma_parallax, double sigma_cross, const StereoStepOptions& o, Eigen::Vector3d* p,
               Eigen::Matrix3d* cov) {
  const double baseline = navcam.rig.Baseline(), focal = navcam.rig.left.fx;
  const Pose3 bl = navcam.mast.BodyFromLeft(mp.pan, mp.tilt, navcam.rig);
  const Pose3 br = bl * navcam.rig.left_from_right;
  const Eigen::Vector3d dl = bl.linear() * navcam.rig.left.Ray(ul);
  const Eigen::Vector3d dr = br.linear() * navcam.rig.right.Ray(ur);
  if (!Triangulate(bl.translation(), dl, br.translation(), dr, p)) return false;
  const double range = (*p - bl.translation()).norm();
  const double sp = std::max(o.min_sigma_parallax, sigma_parallax);
  const double sa = std::hypot(o.sigma_angle_px, sigma_cross) / focal;
  *cov = StereoPointCovariance(*p - bl.translation(), range, baseline, focal, sp, sa);
  return true;
}

}  // namespace

int RefineStereoAndIntersect(const NavcamModel& navcam, const TiePointSet& tps, const StereoStepOptions& o,
                             int num_threads, SitePairState* s) {
  std::vector<Candidate>& cands = s->candidates;
  const int n = static_cast<int>(cands.size());
#pragma omp parallel for schedule(dynamic, 16) num_threads(num_threads)
  for (int k = 0; k < n; ++k) {
    Candidate& c = cands[k];
    c.ok = false;
    const LsmResult lp = LeastSquaresMatch(s->previous_left[c.prev_pair].lsm, c.prev_left,
                                           s->previous_right[c.prev_pair].lsm, c.prev_right,
                                           Eigen::Matrix2d::Identity(), o.lsm);
    if (!lp.ok) continue;
    const LsmResult lc = LeastSquaresMatch(s->current_left[c.cur_pair].lsm, c.cur_left, s->current_right[c.cur_pair].lsm,
                                           c.cur_right, Eigen::Matrix2d::Identity(), o.lsm);
    if (!lc.ok) continue;
    c.prev_right = lp.target;
    c.cur_right = lc.target;
    c.sigma_prev_right = lp.sigma_px;
    c.sigma_cur_right = lc.sigma_px;
    c.ok = Intersect(navcam, tps.previous_pointing[c.prev_pair], c.prev_left, c.prev_right, lp.sigma_px, c.sigma_cross,
                     o, &c.p_prev, &c.cov_prev) &&
           Intersect(navcam, tps.current_pointing[c.cur_pair], c.cur_left, c.cur_right, lc.sigma_px, c.sigma_cross, o,
                     &c.p_cur, &c.cov_cur);
  }
  DropRejected(&cands);
  return static_cast<int>(cands.size());
}

}  // namespace vloc::frontend_internal
