// Step 7: gated matching of one forward overlap (Wan et al. 2.2). Stage 1
// predicts the previous features into the train image with the DR pose and
// a gate as wide as its uncertainty; stage 2 re-predicts them with a
// refined map (from the tile registration, else from the densest cluster of
// stage-1 offsets) and matches again in a tight gate; an epipolar RANSAC on
// the stage-2 matches and a spread selection give the overlap's candidates.
#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <unordered_map>

#include <glog/logging.h>

#include "vloc/common/homography.h"
#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

namespace {

// The previous features' predicted positions in the train image (NaN: the
// feature is outside the overlap, or its ground is not in the warped image).
std::vector<Eigen::Vector2d> PredictInTrain(const PairOverlap& ov, const FeatureSet& fp, const OverlapWork& work,
                                            bool warp_current) {
  std::vector<Eigen::Vector2d> predicted(fp.size(), Eigen::Vector2d::Constant(NAN));
  for (size_t q = 0; q < fp.size(); ++q) {
    const auto& p = fp.points[q];
    if (!ov.previous_region.contains(cv::Point(static_cast<int>(p.x()), static_cast<int>(p.y())))) continue;
    predicted[q] = ApplyHomography(work.train_from_previous, p);
    // A previous feature whose ground the current image does not see has no
    // true match: left in, it pairs with whatever lies at the gate's edge
    // nearest the covered part (one common, wrong, offset).
    if (warp_current && !work.coverage.empty()) {
      const int x = static_cast<int>(std::lround(predicted[q].x())), y = static_cast<int>(std::lround(predicted[q].y()));
      if (x < 0 || y < 0 || x >= work.coverage.cols || y >= work.coverage.rows || !work.coverage.at<uchar>(y, x))
        predicted[q] = Eigen::Vector2d::Constant(NAN);
    }
  }
  return predicted;
}

// Previous-left and current-left px of the matches.
void MatchPoints(const std::vector<FeatureMatch>& ms, const FeatureSet& fp, const FeatureSet& fc,
                 const cv::Matx33d& current_from_train, std::vector<cv::Point2f>* a, std::vector<cv::Point2f>* b) {
  a->clear();
  b->clear();
  for (const auto& m : ms) {
    a->emplace_back(static_cast<float>(fp.points[m.query].x()), static_cast<float>(fp.points[m.query].y()));
    const Eigen::Vector2d pc = ApplyHomography(current_from_train, fc.points[m.train]);
    b->emplace_back(static_cast<float>(pc.x()), static_cast<float>(pc.y()));
  }
}

struct Stage2 {
  cv::Matx33d refined;               // current-left px per previous-left px, for the LSM's initial shape
  std::vector<FeatureMatch> matches;
  cv::Mat F;                         // epipolar geometry of the matches (empty: too few or failed)
};

// Stage 2: re-predict with H (previous px -> train px) and match in a tight
// gate; epipolar RANSAC on the (now mostly right) matches.
Stage2 MatchStage2(const cv::Matx33d& H, const FeatureSet& fp, const FeatureSet& fc, const OverlapWork& work,
                   std::vector<Eigen::Vector2d> predicted, GatedMatchOptions g, double train_per_cur,
                   const OverlapMatchOptions& o) {
  Stage2 st;
  st.refined = work.current_from_train * H;
  for (size_t q = 0; q < fp.size(); ++q)
    if (predicted[q].allFinite()) predicted[q] = ApplyHomography(H, fp.points[q]);
  g.gate_radius = o.refine_gate_px * train_per_cur;
  g.ratio = o.refine_ratio;
  st.matches = GatedMatch(fp, predicted, fc, g);
  if (st.matches.size() >= static_cast<size_t>(kMinEpipolarMatches)) {
    std::vector<cv::Point2f> a, b;
    MatchPoints(st.matches, fp, fc, work.current_from_train, &a, &b);
    std::vector<uchar> inl;
    st.F = cv::findFundamentalMat(a, b, cv::FM_RANSAC, o.fundamental_threshold_px, kRansacConfidence, inl);
    if (st.F.empty() || st.F.rows != 3) st.F = cv::Mat();
  }
  return st;
}

// The stage-2 matches within 2 fundamental_threshold_px of their epipolar line.
std::vector<Candidate> EpipolarCandidates(int k, const PairOverlap& ov, const Stage2& st, const FeatureSet& fp,
                                          const FeatureSet& fc, const OverlapWork& work, const OverlapMatchOptions& o) {
  std::vector<Candidate> cands;
  const cv::Matx33d Fm = st.F.empty() ? cv::Matx33d::zeros() : cv::Matx33d(st.F);
  for (const auto& m : st.matches) {
    Candidate c;
    c.overlap = k;
    c.prev_pair = ov.previous_pair;
    c.cur_pair = ov.current_pair;
    c.prev_left = fp.points[m.query];
    c.cur_left = ApplyHomography(work.current_from_train, fc.points[m.train]);
    c.descriptor_distance = m.distance;
    // Initial LSM shape: the local affine of the refined (or predicted) homography.
    c.initial_affine = HomographyJacobian(st.refined, c.prev_left);
    if (!st.F.empty()) {
      // Distance of the current point from the epipolar line of the previous one.
      const cv::Vec3d l = Fm * cv::Vec3d(c.prev_left.x(), c.prev_left.y(), 1.0);
      const double d = std::abs(l[0] * c.cur_left.x() + l[1] * c.cur_left.y() + l[2]) / std::hypot(l[0], l[1]);
      if (!(d <= 2 * o.fundamental_threshold_px)) continue;
    } else if (o.fundamental_threshold_px > 0) {
      continue;
    }
    cands.push_back(c);
  }
  return cands;
}

}  // namespace

std::vector<FeatureMatch> DensestOffsetCluster(const std::vector<FeatureMatch>& matches, const FeatureSet& train,
                                               const std::vector<Eigen::Vector2d>& predicted, double r,
                                               Eigen::Vector2d* mode, int* mode_count) {
  std::vector<Eigen::Vector2d> off;
  for (const auto& m : matches) off.push_back(train.points[m.train] - predicted[m.query]);
  int best = -1, best_n = 0;
  for (size_t q = 0; q < off.size(); ++q) {
    int n = 0;
    for (size_t w = 0; w < off.size(); ++w) n += (off[w] - off[q]).norm() <= r ? 1 : 0;
    if (n > best_n) best_n = n, best = static_cast<int>(q);
  }
  if (mode) *mode = best >= 0 ? Eigen::Vector2d(off[best]) : Eigen::Vector2d::Zero();
  if (mode_count) *mode_count = best_n;
  std::vector<FeatureMatch> cluster;
  if (best < 0) return cluster;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  int n = 0;
  for (size_t w = 0; w < off.size(); ++w)
    if ((off[w] - off[best]).norm() <= r) mean += off[w], ++n;
  mean /= std::max(n, 1);
  for (size_t w = 0; w < off.size(); ++w)
    if ((off[w] - mean).norm() <= 2 * r) cluster.push_back(matches[w]);
  return cluster;
}

std::vector<int> SpreadSelect(const std::vector<Candidate>& c, const std::vector<int>& idx, int cap, double cell) {
  std::vector<int> order = idx;
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return c[a].descriptor_distance < c[b].descriptor_distance; });
  std::unordered_map<long long, int> used;
  std::vector<int> first, rest;
  for (int k : order) {
    const long long key = (static_cast<long long>(std::floor(c[k].cur_left.x() / cell)) << 32) ^
                          static_cast<unsigned>(static_cast<int>(std::floor(c[k].cur_left.y() / cell)));
    if (used[key]++ == 0) first.push_back(k); else rest.push_back(k);
  }
  first.insert(first.end(), rest.begin(), rest.end());
  if (static_cast<int>(first.size()) > cap) first.resize(cap);
  return first;
}

double DrGateRadiusPx(const PairOverlap& ov, const GateOptions& gate) {
  return std::min(ov.growth_px / std::max(ov.scale, 1e-3) + gate.gate_margin_px, gate.max_gate_px);
}

void MatchOverlap(int k, const PairOverlap& ov, const SitePairState& s, const OverlapMatchOptions& o,
                  const GateOptions& gate, bool warp_current, OverlapWork* work) {
  if (work->skipped) return;
  const WorkRegion& prev = s.previous_regions[ov.previous_pair];
  const FeatureSet& fp = prev.features;
  const FeatureSet& fc = warp_current ? work->warped_features : s.current_regions[ov.current_pair].features;
  if (fp.size() == 0 || fc.size() == 0) return;
  const std::vector<Eigen::Vector2d> predicted = PredictInTrain(ov, fp, *work, warp_current);
  // Gate scale: train px per current px.
  const double train_per_cur = warp_current ? ov.scale * prev.zoom : 1.0;
  // Stage 1: the DR prediction with a gate as wide as its uncertainty.
  GatedMatchOptions g = o.matching;
  g.num_threads = 1;
  // ASIFT views of one point land a few (view) px apart: in full-image px
  // that is distinct_radius / zoom.
  if (!warp_current) g.distinct_radius = o.matching.distinct_radius / std::min(s.current_regions[ov.current_pair].zoom, 1.0);
  g.gate_radius = DrGateRadiusPx(ov, gate) * train_per_cur;
  // A registered overlap's stage 1 is the tile registration: the wide-gate matching runs only without it.
  const std::vector<FeatureMatch> stage1 = work->registered ? std::vector<FeatureMatch>() : GatedMatch(fp, predicted, fc, g);
  Stage2 st{ov.previous_from_current.inv(), stage1, cv::Mat()};
  size_t stage1_inliers = 0;
  if (work->registered) {
    stage1_inliers = work->tile_inliers;
    st = MatchStage2(work->train_from_previous, fp, fc, *work, predicted, g, train_per_cur, o);
  }
  if (!work->registered && o.fundamental_threshold_px > 0) {
    // Stage 1 -> refined prediction. The DR error shifts the true matches
    // by nearly one offset from their predictions (the warp removed the
    // perspective), while wrong matches (repeated texture) scatter over the
    // whole gate: keep the densest cluster of offsets, then fit the ground
    // homography to it. An epipolar RANSAC on all stage-1 matches is not
    // enough: with 8 points it fits a dozen random matches at 2 px and the
    // stage-2 gate then follows a wrong motion.
    const double r = std::max(kMinClusterRadiusPx * train_per_cur, o.stage1_cluster_fraction * g.gate_radius);
    Eigen::Vector2d mode;
    int mode_count = 0;
    const std::vector<FeatureMatch> cluster = DensestOffsetCluster(stage1, fc, predicted, r, &mode, &mode_count);
    stage1_inliers = cluster.size();
    VLOG(1) << "overlap cur " << ov.current_pair << " prev " << ov.previous_pair << ": offset mode "
            << mode.transpose() << " n " << mode_count << " r " << r << " z " << prev.zoom;
    if (static_cast<int>(cluster.size()) < o.min_stage1_inliers) {
      VLOG(1) << "overlap cur " << ov.current_pair << " prev " << ov.previous_pair << ": stage 1 " << stage1.size()
              << " matches, densest offset cluster " << cluster.size() << " < min_stage1_inliers: skipped";
      return;
    }
    std::vector<cv::Point2f> a, b;
    MatchPoints(cluster, fp, fc, work->current_from_train, &a, &b);
    std::vector<uchar> hin;
    cv::Mat Hr = cv::findHomography(a, b, cv::RANSAC, o.refine_homography_threshold_px, hin);
    int n_h = 0;
    for (uchar v : hin) n_h += v ? 1 : 0;
    if (Hr.empty() || n_h < o.min_stage1_inliers) return;
    st = MatchStage2(work->current_from_train.inv() * cv::Matx33d(Hr), fp, fc, *work, predicted, g, train_per_cur, o);
  }
  const std::vector<Candidate> cands = EpipolarCandidates(k, ov, st, fp, fc, *work, o);
  VLOG(1) << "overlap cur " << ov.current_pair << " prev " << ov.previous_pair << ": scale " << ov.scale << " tilt "
          << ov.tilt << " gate " << g.gate_radius << " px, stage 1 " << stage1.size() << " matches ("
          << stage1_inliers << " epipolar inliers), stage 2 " << st.matches.size() << " -> " << cands.size();
  std::vector<int> idx(cands.size());
  std::iota(idx.begin(), idx.end(), 0);
  work->candidates.clear();
  for (int q : SpreadSelect(cands, idx, o.max_points_per_overlap, kSpreadCellPx)) work->candidates.push_back(cands[q]);
}

}  // namespace vloc::frontend_internal
