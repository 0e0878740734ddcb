// Step 9: overlaps whose views point in opposite directions ("backward",
// Wan et al. 2.2): both sites' images are projected onto the ground plane
// (ortho images of kOrthoResolutionM per px), where the views agree, and
// matched there with a gate from the DR position sigma. Each match carries
// the plane's local affine between the two images for the cross-site LSM.
#include <algorithm>

#include "vloc/common/homography.h"
#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

BackwardMatchOptions BackwardMatchOptions::Of(const FrontendOptions& o) {
  return {o.regions, o.work_regions.wallis, o.features.asift, o.overlap_matching.matching, o.gate};
}

std::vector<Candidate> MatchBackwardOverlap(int k, const NavcamModel& navcam, const TiePointSet& tps,
                                            const SitePairState& s, const BackwardMatchOptions& o) {
  const RegionOptions& regions = o.regions;
  std::vector<Candidate> out;
  const PairOverlap& ov = s.prediction.overlaps[k];
  const double res = kOrthoResolutionM;
  const Eigen::Vector2d ext = ov.ground_max - ov.ground_min;
  const cv::Size size(std::min(kMaxOrthoPx, static_cast<int>(ext.x() / res)),
                      std::min(kMaxOrthoPx, static_cast<int>(ext.y() / res)));
  if (size.width < kMinOrthoPx || size.height < kMinOrthoPx) return out;
  const Eigen::Vector2d origin(ov.ground_min.x(), ov.ground_max.y());
  const MastPointing& pp = tps.previous_pointing[ov.previous_pair];
  const MastPointing& pc = tps.current_pointing[ov.current_pair];
  const Pose3 prev_cam = navcam.mast.BodyFromLeft(pp.pan, pp.tilt, navcam.rig);
  const Pose3 cur_cam_in_prev = s.prediction.previous_from_current * navcam.mast.BodyFromLeft(pc.pan, pc.tilt, navcam.rig);
  const PinholeCamera& cam = navcam.rig.left;
  const cv::Matx33d Hp = ImageFromOrtho(cam, prev_cam, origin, res, regions.ground_height);
  const cv::Matx33d Hc = ImageFromOrtho(cam, cur_cam_in_prev, origin, res, regions.ground_height);
  const cv::Mat op = WallisFilter(GroundOrthoImage(s.previous_left[ov.previous_pair].gray, Hp, size), s.previous_wallis);
  const cv::Mat oc = WallisFilter(GroundOrthoImage(s.current_left[ov.current_pair].gray, Hc, size), o.wallis);
  const FeatureSet sp = DetectAsift(op, op > 0, {{1.0, 0.0}}, o.asift);
  const FeatureSet sc = DetectAsift(oc, oc > 0, {{1.0, 0.0}}, o.asift);
  GatedMatchOptions g = o.matching;
  g.num_threads = 1;
  const Vector6d& sigma = s.prediction.relative_sigma;
  g.gate_radius = regions.sigma_scale * std::max(sigma(0), sigma(1)) / res + o.gate.gate_margin_px;
  const cv::Matx33d current_from_previous = Hc * Hp.inv();
  for (const auto& m : GatedMatch(sp, sp.points, sc, g)) {
    Candidate c;
    c.overlap = k;
    c.prev_pair = ov.previous_pair;
    c.cur_pair = ov.current_pair;
    c.prev_left = ApplyHomography(Hp, sp.points[m.query]);
    c.cur_left = ApplyHomography(Hc, sc.points[m.train]);
    c.descriptor_distance = m.distance;
    // Initial LSM shape: the ground plane's local affine between the views
    // (about a half turn; LSM cannot start from the identity).
    c.initial_affine = HomographyJacobian(current_from_previous, c.prev_left);
    if (cam.InImage(c.prev_left, kBackwardImageMarginPx) && cam.InImage(c.cur_left, kBackwardImageMarginPx))
      out.push_back(c);
  }
  return out;
}

}  // namespace vloc::frontend_internal
