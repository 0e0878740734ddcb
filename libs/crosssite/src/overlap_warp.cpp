// Step 6: each forward overlap's current image warped onto the previous
// region's (zoomed) grid by the predicted ground-plane homography, so that
// what distortion remains is what the DR error leaves; then registered by
// tile correlation (a pose error maps the ground plane by a homography) and
// warped again, so that features are detected on an image aligned with the
// previous region. Then ASIFT on it (the warp leaves tilt ~1).
#include <cmath>
#include <cstdlib>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <glog/logging.h>

#include "vloc/common/homography.h"
#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

namespace {

// The current image, anti-aliased by the warp's local reduction (train px
// per current px at the overlap's median sample). A copy when blurred:
// several overlaps (threads) share the current image.
cv::Mat AntiAliased(const cv::Mat& filtered, const PairOverlap& ov, double z) {
  const Eigen::Matrix2d Jc = z * HomographyJacobian(ov.previous_from_current, ov.median_current_px);
  const double sx = Jc.col(0).norm(), sy = Jc.col(1).norm();
  const double bx = sx < 1 ? 0.8 * std::sqrt(1 / (sx * sx) - 1) : 0.0;
  const double by = sy < 1 ? 0.8 * std::sqrt(1 / (sy * sy) - 1) : 0.0;
  if (!(bx > 0.3 || by > 0.3)) return filtered;
  cv::Mat blurred;
  cv::GaussianBlur(filtered, blurred, cv::Size(0, 0), std::max(bx, 0.01), std::max(by, 0.01));
  return blurred;
}

// Warps `source` onto the grid of `size` by work->current_from_train, and its coverage.
void Warp(const cv::Mat& source, const cv::Size& current_size, const cv::Size& size, double z,
          const WarpOptions& o, OverlapWork* work) {
  cv::warpPerspective(source, work->warped, cv::Mat(work->current_from_train), size,
                      cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, 0);
  cv::warpPerspective(cv::Mat(current_size, CV_8UC1, cv::Scalar(255)), work->coverage,
                      cv::Mat(work->current_from_train), size, cv::INTER_NEAREST | cv::WARP_INVERSE_MAP,
                      cv::BORDER_CONSTANT, 0);
  // The previous region was zoomed up by z: its finest detail is z grid px,
  // while the warped current image still holds detail down to one grid px
  // (the previous site saw this ground from farther away). Blur the warped
  // image to the previous region's resolution, or SIFT describes different
  // texture at the two sites.
  if (z > 1.05 && o.match_previous_resolution) {
    const double bz = 0.8 * std::sqrt(z * z - 1);
    cv::GaussianBlur(work->warped, work->warped, cv::Size(0, 0), bz, bz);
  }
  cv::erode(work->coverage, work->coverage,
            cv::getStructuringElement(cv::MORPH_RECT, cv::Size(kCoverageErodePx, kCoverageErodePx)));
}

// One registration pass: the similarity/homography the tiles agree on
// (true grid -> predicted grid), empty when fewer than min_tile_inliers agree.
cv::Mat RegisterPass(const PairOverlap& ov, int pass, double radius, const WarpOptions& o, OverlapWork* work,
                     int* inliers) {
  const auto tiles = RegisterTiles(work->warped, work->coverage, work->previous_crop, radius, o.tiles);
  std::vector<cv::Point2f> from, to;
  for (const auto& t : tiles) {
    from.emplace_back(static_cast<float>(t.fixed_px.x()), static_cast<float>(t.fixed_px.y()));
    to.emplace_back(static_cast<float>(t.moving_px.x()), static_cast<float>(t.moving_px.y()));
  }
  *inliers = 0;
  cv::Mat A;
  if (static_cast<int>(tiles.size()) >= o.min_tile_inliers) {
    std::vector<uchar> inl;
    A = cv::findHomography(from, to, cv::RANSAC, o.tile_inlier_px * o.tiles.reduction, inl, kTileRansacIterations,
                           kRansacConfidence);
    for (uchar v : inl) *inliers += v ? 1 : 0;
  }
  VLOG(1) << "overlap cur " << ov.current_pair << " prev " << ov.previous_pair << " pass " << pass << ": "
          << tiles.size() << " tiles correlated, " << *inliers << " agree on one motion";
  if (A.empty() || *inliers < o.min_tile_inliers) return cv::Mat();
  return A;
}

}  // namespace

OverlapWork WarpOverlap(const PairOverlap& ov, const SitePairState& s, const WarpOptions& o, const GateOptions& gate) {
  OverlapWork work;
  const cv::Matx33d cur_from_prev = ov.previous_from_current.inv();
  work.train_from_previous = cur_from_prev;
  if (!o.warp_current) return work;
  const WorkRegion& prev = s.previous_regions[ov.previous_pair];
  const cv::Rect R = ov.previous_region & prev.region;
  const double z = prev.zoom;
  if (R.area() == 0) {
    work.skipped = true;
    return work;
  }
  // The grid is the zoomed previous region from pixel grid0 of the work
  // image on (cv::resize maps pixel centres).
  const cv::Rect& F = prev.region;
  const cv::Point grid0(static_cast<int>((R.x - F.x) * z), static_cast<int>((R.y - F.y) * z));
  const cv::Matx33d prev_from_grid(1 / z, 0, F.x + (grid0.x + 0.5) / z - 0.5, 0, 1 / z,
                                   F.y + (grid0.y + 0.5) / z - 0.5, 0, 0, 1);
  work.current_from_train = cur_from_prev * prev_from_grid;
  work.train_from_previous = prev_from_grid.inv();
  const cv::Size size(static_cast<int>(R.width * z), static_cast<int>(R.height * z));
  const cv::Mat source = AntiAliased(s.current_filtered[ov.current_pair], ov, z);
  const cv::Rect in_work(grid0.x, grid0.y, size.width, size.height);
  work.previous_crop = prev.image(in_work & cv::Rect(0, 0, prev.image.cols, prev.image.rows));
  const cv::Size current_size = s.current_left[ov.current_pair].gray.size();
  Warp(source, current_size, size, z, o, &work);
  if (o.tile_registration && !work.previous_crop.empty()) {
    // Pass 1 over the whole DR gate (on the previous image's grid a lateral
    // error shears the offsets, a range error stretches them), pass 2 within
    // a few px of the correction.
    const double train_per_cur0 = ov.scale * z;
    double radius = DrGateRadiusPx(ov, gate) * train_per_cur0;
    for (int pass = 0; pass < kTileRegistrationPasses; ++pass) {
      int inliers = 0;
      const cv::Mat A = RegisterPass(ov, pass, radius, o, &work, &inliers);
      if (A.empty()) break;
      work.current_from_train = work.current_from_train * cv::Matx33d(A);  // A: true grid -> predicted grid
      work.tile_inliers = std::max(work.tile_inliers, inliers);
      work.registered = true;
      Warp(source, current_size, size, z, o, &work);
      radius = kSecondPassRadiusTiles * o.tiles.reduction;
    }
  }
  if (const char* dump = std::getenv("VLOC_FRONTEND_DUMP")) {
    const std::string base = std::string(dump) + "/ov_c" + std::to_string(ov.current_pair) + "_p" +
                             std::to_string(ov.previous_pair);
    cv::imwrite(base + "_cur_warped.png", work.warped);
    cv::imwrite(base + "_prev.png", work.previous_crop);
  }
  return work;
}

namespace {

// The part of the warped image its coverage covers, grown by kWarpedSiftMarginPx (SIFT's blur at the finer
// octaves sees the same zeros beyond the coverage) from a corner on a multiple of kWarpedSiftAlignPx (the
// finer octaves sample the same pixels). The rest is zero: SIFT finds nothing there, at the cost of the
// whole image (the current image covers 25-65 % of the previous region's grid).
cv::Rect CoveredPart(const cv::Mat& coverage) {
  const cv::Rect covered = cv::boundingRect(coverage);
  if (covered.area() == 0) return cv::Rect(0, 0, coverage.cols, coverage.rows);
  auto down = [](int v) { return std::max(0, (v - kWarpedSiftMarginPx) / kWarpedSiftAlignPx * kWarpedSiftAlignPx); };
  const int x0 = down(covered.x), y0 = down(covered.y);
  const int x1 = std::min(coverage.cols, covered.br().x + kWarpedSiftMarginPx);
  const int y1 = std::min(coverage.rows, covered.br().y + kWarpedSiftMarginPx);
  return cv::Rect(x0, y0, x1 - x0, y1 - y0);
}

}  // namespace

void DetectWarpedFeatures(const FeatureOptions& o, bool warp_current, double zoom, OverlapWork* work) {
  if (!warp_current || work->skipped) return;
  std::vector<AffineView> views{{1.0, 0.0}};
  for (double t : o.asift.tilts)
    if (t > 1 + 1e-6 && t <= o.warp_max_tilt) views.push_back({t, 0.0}), views.push_back({t, M_PI / 2});
  const cv::Rect part = CoveredPart(work->coverage);
  FeatureSet& f = work->warped_features;
  f = DetectOnGrid(work->warped(part), work->coverage(part), views, zoom, o);
  const Eigen::Vector2d corner(part.x, part.y);
  for (Eigen::Vector2d& p : f.points) p += corner;  // (the keypoints stay in the views of the part)
}

}  // namespace vloc::frontend_internal
