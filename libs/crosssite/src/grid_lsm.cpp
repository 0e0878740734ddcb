// Step 8: cross-site least-squares matching on the previous region's grid
// (Wan et al. 2.2). The previous window is matched against the warped
// current image, which the refined prediction has brought to the same
// scale, shape and (anti-aliased) resolution: the full-resolution current
// image holds detail the previous site never saw, and LSM from the coarse
// window into it rarely converges. Relief gates: a window on relief whose
// parallax is not affine matches differently forward and backward, and its
// x shift changes along the rows (shear); both flag matches that slid along
// the cross-site epipolar lines, where geometry cannot see them.
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include <glog/logging.h>

#include "vloc/common/homography.h"
#include "vloc/features/template_ncc.h"
#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

bool ZnccPeakNear(const cv::Mat& templ, const Eigen::Vector2d& templ_px, const cv::Mat& target, int radius, int half,
                  int half_y, double min_score, double min_margin, Eigen::Vector2d* target_px) {
  const int tx = static_cast<int>(std::lround(templ_px.x())), ty = static_cast<int>(std::lround(templ_px.y()));
  const int gx = static_cast<int>(std::lround(target_px->x())), gy = static_cast<int>(std::lround(target_px->y()));
  const cv::Rect tr(tx - half, ty - half_y, 2 * half + 1, 2 * half_y + 1);
  const cv::Rect sr(gx - half - radius, gy - half_y - radius, 2 * (half + radius) + 1, 2 * (half_y + radius) + 1);
  if ((tr & cv::Rect(0, 0, templ.cols, templ.rows)) != tr || (sr & cv::Rect(0, 0, target.cols, target.rows)) != sr)
    return false;
  cv::Mat score;
  MatchTemplateNcc(target(sr), templ(tr), &score);
  double best;
  cv::Point p;
  cv::minMaxLoc(score, nullptr, &best, nullptr, &p);
  if (!(best >= min_score) || p.x == 0 || p.y == 0 || p.x == score.cols - 1 || p.y == score.rows - 1) return false;
  // Unique: texture streaked along the view (a grazing look at the ground)
  // correlates almost as well a few px to the side.
  cv::Mat away = score.clone();
  cv::rectangle(away, cv::Rect(p.x - 2, p.y - 2, 5, 5), cv::Scalar(-2), cv::FILLED);
  double second;
  cv::minMaxLoc(away, nullptr, &second);
  if (best - second < min_margin) return false;
  auto peak = [](double a, double b, double c) {
    const double den = a - 2 * b + c;
    return std::abs(den) < 1e-12 ? 0.0 : std::clamp(0.5 * (a - c) / den, -0.5, 0.5);
  };
  const double sx = peak(score.at<float>(p.y, p.x - 1), best, score.at<float>(p.y, p.x + 1));
  const double sy = peak(score.at<float>(p.y - 1, p.x), best, score.at<float>(p.y + 1, p.x));
  // Offsets from the integer template centre carry over (templ_px sub-pixel).
  *target_px = Eigen::Vector2d(sr.x + half + p.x + sx + (templ_px.x() - tx), sr.y + half_y + p.y + sy + (templ_px.y() - ty));
  return true;
}

bool RefineOnGrid(const OverlapWork& work, const LsmImage& lt, const LsmImage& lw, const GridLsmStepOptions& o,
                  const LsmOptions& lsm, Candidate* c) {
  const Eigen::Vector2d pt = ApplyHomography(work.train_from_previous, c->prev_left);
  Eigen::Vector2d wt = ApplyHomography(work.current_from_train.inv(), c->cur_left);
  // The feature positions of the two sites differ by a few grid px
  // (different scales of detection): start LSM at the correlation peak near them.
  const int half_y = lsm.half_height > 0 ? lsm.half_height : lsm.half_window;
  if (!ZnccPeakNear(work.previous_crop, pt, work.warped, o.grid_search_px, lsm.half_window, half_y,
                    o.grid_min_zncc, o.grid_min_margin, &wt))
    return false;
  const LsmResult r = LeastSquaresMatch(lt, pt, lw, wt, Eigen::Matrix2d::Identity(), lsm);
  if (!r.ok) {
    VLOG(2) << "grid LSM: " << r.why << " corr " << r.correlation << " sigma " << r.sigma_px;
    return false;
  }
  if (o.grid_back_check_px > 0) {
    const LsmResult back = LeastSquaresMatch(lw, r.target, lt, pt, r.affine.inverse(), lsm);
    if (!back.ok || (back.target - pt).norm() > o.grid_back_check_px) {
      VLOG(2) << "grid LSM: back match " << (back.ok ? "misses" : back.why) << " by " << (back.target - pt).norm();
      return false;
    }
  }
  if (o.grid_max_shear > 0 && std::abs(r.affine(0, 1)) > o.grid_max_shear) {
    VLOG(2) << "grid LSM: shear " << r.affine(0, 1) << " beyond grid_max_shear";
    return false;
  }
  const Eigen::Matrix2d J = HomographyJacobian(work.current_from_train, r.target);  // current px per grid px
  c->cur_left = ApplyHomography(work.current_from_train, r.target);
  c->sigma_cross = r.sigma_px * std::sqrt(std::abs(J.determinant()));
  c->grid_refined = true;
  c->grid_correlation = r.correlation;
  c->grid_sigma_max = r.sigma_max_px;
  c->grid_affine = r.affine;
  VLOG(2) << "grid LSM ok at " << c->prev_left.transpose() << " sigma " << r.sigma_px << " max " << r.sigma_max_px
          << " corr " << r.correlation;
  return true;
}

int RefineOverlapOnGrid(const GridLsmStepOptions& o, bool warp_current, OverlapWork* work) {
  if (!warp_current || work->warped.empty() || work->previous_crop.empty() ||
      work->candidates.empty())
    return 0;
  const LsmImage lt = MakeLsmImage(work->previous_crop, o.grid_lsm.bspline),
                 lw = MakeLsmImage(work->warped, o.grid_lsm.bspline);
  int refined = 0;
  for (Candidate& c : work->candidates) refined += RefineOnGrid(*work, lt, lw, o, o.grid_lsm, &c) ? 1 : 0;
  VLOG(1) << "grid LSM refined " << refined << " of " << work->candidates.size();
  if (refined >= o.grid_retry_below) return refined;
  // Poor texture: the candidates left unrefined again, with the larger window.
  const LsmOptions& retry = o.grid_lsm_retry;
  const int first = refined;
  for (Candidate& c : work->candidates)
    if (!c.grid_refined) refined += RefineOnGrid(*work, lt, lw, o, retry, &c) ? 1 : 0;
  VLOG(1) << "grid LSM retry (" << 2 * retry.half_window + 1 << " x "
          << 2 * (retry.half_height > 0 ? retry.half_height : retry.half_window) + 1 << "): " << refined - first
          << " more";
  return refined;
}

}  // namespace vloc::frontend_internal
