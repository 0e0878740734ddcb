// The front end's steps (internal/frontend_steps.h) on small synthetic
// inputs: options checking, overlap matching, the grid LSM with its relief
// gates, cross-site refinement's duplicate merge, and verification. Fast:
// no rendering, fixed seeds.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <functional>
#include <opencv2/imgproc.hpp>
#include <iostream>
#include <random>

#include "vloc/common/homography.h"
#include "vloc/common/stats.h"
#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc {
namespace {

using namespace frontend_internal;

// ---- options

TEST(FrontendOptions, DefaultsPassCheck) {
  std::string error;
  EXPECT_TRUE(FrontendOptions().Check(&error)) << error;
}

// Every bad value is caught, and the message names the field and the value.
TEST(FrontendOptions, CheckNamesTheFieldAndTheBadValue) {
  struct Case {
    const char* field;
    const char* value;
    std::function<void(FrontendOptions&)> set;
  };
  const std::vector<Case> cases = {
      {"ground_grid_px", "4", [](FrontendOptions& o) { o.ground.ground_grid_px = 4; }},
      {"ground_min_points", "2", [](FrontendOptions& o) { o.ground.ground_min_points = 2; }},
      {"ground_tolerance_m", "0", [](FrontendOptions& o) { o.ground.ground_tolerance_m = 0; }},
      {"ground_max_slope_deg", "95", [](FrontendOptions& o) { o.ground.ground_max_slope_deg = 95; }},
      {"min_zoom", "0", [](FrontendOptions& o) { o.work_regions.min_zoom = 0; }},
      {"max_zoom", "0.5", [](FrontendOptions& o) { o.work_regions.max_zoom = 0.5; }},
      {"max_motion_sigmas", "-1", [](FrontendOptions& o) { o.verification.max_motion_sigmas = -1; }},
      {"sigma_unrefined_px", "0", [](FrontendOptions& o) { o.cross_site.sigma_unrefined_px = 0; }},
      {"warp_max_tilt", "0.5", [](FrontendOptions& o) { o.features.warp_max_tilt = 0.5; }},
      {"max_overlaps_per_image", "-1", [](FrontendOptions& o) { o.work_regions.max_overlaps_per_image = -1; }},
      {"grid_min_zncc", "1.5", [](FrontendOptions& o) { o.grid.grid_min_zncc = 1.5; }},
      {"grid_min_margin", "-0.1", [](FrontendOptions& o) { o.grid.grid_min_margin = -0.1; }},
      {"grid_back_check_px", "-1", [](FrontendOptions& o) { o.grid.grid_back_check_px = -1; }},
      {"grid_max_shear", "-0.5", [](FrontendOptions& o) { o.grid.grid_max_shear = -0.5; }},
      {"grid_search_px", "0", [](FrontendOptions& o) { o.grid.grid_search_px = 0; }},
      {"min_tile_inliers", "3", [](FrontendOptions& o) { o.warp.min_tile_inliers = 3; }},
      {"tile_inlier_px", "0", [](FrontendOptions& o) { o.warp.tile_inlier_px = 0; }},
      {"refine_homography_threshold_px", "0", [](FrontendOptions& o) { o.overlap_matching.refine_homography_threshold_px = 0; }},
      {"stage1_cluster_fraction", "1.5", [](FrontendOptions& o) { o.overlap_matching.stage1_cluster_fraction = 1.5; }},
      {"refine_gate_px", "0", [](FrontendOptions& o) { o.overlap_matching.refine_gate_px = 0; }},
      {"max_gate_px", "-3", [](FrontendOptions& o) { o.gate.max_gate_px = -3; }},
      {"min_stage1_inliers", "2", [](FrontendOptions& o) { o.overlap_matching.min_stage1_inliers = 2; }},
      {"refine_ratio", "0", [](FrontendOptions& o) { o.overlap_matching.refine_ratio = 0; }},
      {"tilt_margin", "0.9", [](FrontendOptions& o) { o.features.tilt_margin = 0.9; }},
      {"longitude_margin_deg", "-5", [](FrontendOptions& o) { o.features.longitude_margin_deg = -5; }},
      {"gate_margin_px", "-1", [](FrontendOptions& o) { o.gate.gate_margin_px = -1; }},
      {"fundamental_threshold_px", "-2", [](FrontendOptions& o) { o.overlap_matching.fundamental_threshold_px = -2; }},
      {"max_points_per_overlap", "0", [](FrontendOptions& o) { o.overlap_matching.max_points_per_overlap = 0; }},
      {"stereo_min_depth", "0", [](FrontendOptions& o) { o.stereo.stereo_min_depth = 0; }},
      {"stereo_max_depth", "0.5", [](FrontendOptions& o) { o.stereo.stereo_max_depth = 0.5; }},
      {"cross_sigma_floor_px", "-1", [](FrontendOptions& o) { o.verification.cross_sigma_floor_px = -1; }},
      {"stereo_sigma_floor_px", "-1", [](FrontendOptions& o) { o.verification.stereo_sigma_floor_px = -1; }},
      {"sigma_angle_px", "-1", [](FrontendOptions& o) { o.stereo.sigma_angle_px = -1; }},
      {"min_sigma_parallax", "0", [](FrontendOptions& o) { o.stereo.min_sigma_parallax = 0; }},
      {"min_region_std", "-1", [](FrontendOptions& o) { o.work_regions.min_region_std = -1; }},
      {"duplicate_radius", "-1", [](FrontendOptions& o) { o.cross_site.duplicate_radius = -1; }},
      {"min_tie_points", "0", [](FrontendOptions& o) { o.min_tie_points = 0; }},
      {"num_threads", "0", [](FrontendOptions& o) { o.num_threads = 0; }},
      {"vehicle_boxes_m", "6 numbers per box", [](FrontendOptions& o) { o.vehicle.vehicle_boxes_m = {-1, 1, -1, 1, 0}; }},
      {"vehicle_boxes_m", "each min below its max", [](FrontendOptions& o) { o.vehicle.vehicle_boxes_m = {-1, 1, -1, 1, 0, 1, 0, 1, 2, 1, 0, 1}; }},
      {"vehicle_boxes_m", "each min below its max", [](FrontendOptions& o) { o.vehicle.vehicle_boxes_m = {-1, 1, -1, 1, 0, std::nan("")}; }},
      {"vehicle_margin_px", "-1", [](FrontendOptions& o) { o.vehicle.vehicle_margin_px = -1; }},
      {"grid_lsm", "", [](FrontendOptions& o) { o.grid.grid_lsm.half_window = 1; }},
      {"cross_lsm", "", [](FrontendOptions& o) { o.cross_site.cross_lsm.max_iterations = 0; }},
      {"tiles", "", [](FrontendOptions& o) { o.warp.tiles.reduction = 0; }},
      {"regions", "", [](FrontendOptions& o) { o.regions.grid_step = 1; }},
  };
  for (const Case& c : cases) {
    FrontendOptions o;
    c.set(o);
    std::string error;
    EXPECT_FALSE(o.Check(&error)) << c.field;
    EXPECT_NE(error.find(c.field), std::string::npos) << c.field << ": " << error;
    EXPECT_NE(error.find(c.value), std::string::npos) << c.field << ": " << error;
  }
  FrontendOptions nan;
  nan.warp.tile_inlier_px = std::nan("");
  std::string error;
  EXPECT_FALSE(nan.Check(&error));
}

// ---- work regions

// One forward overlap: the previous site sees the region at half the
// current site's scale (scale 0.5 previous px per current px).
SitePairState WorkRegionScene(const cv::Mat& previous, const cv::Mat& current, bool backward = false) {
  SitePairState s;
  s.previous.pairs.resize(1);
  s.current.pairs.resize(1);
  s.previous_left = {PreparedImage{previous, LsmImage()}};
  s.current_left = {PreparedImage{current, LsmImage()}};
  PairOverlap ov;
  ov.backward = backward;
  ov.current_region = cv::Rect(20, 20, 100, 100);
  ov.previous_region = cv::Rect(50, 50, 60, 60);
  ov.scale = 0.5;
  ov.tilt = 1.7;
  ov.num_samples = 10;
  s.prediction.overlaps = {ov};
  return s;
}

cv::Mat Texture(cv::Size size, unsigned seed, double blur);

TEST(WorkRegions, ZoomEqualisesTheTwoSitesResolution) {
  const cv::Mat prev = Texture({200, 200}, 51, 2.0), cur = Texture({200, 200}, 52, 2.0);
  struct Mode {
    bool warp_current, zoom_previous;
    double previous_zoom, current_zoom;
  };
  // Warped (default): the previous region is zoomed up (the warp's grid),
  // and the current one down (used only without the warp). Unwarped: one
  // or the other (zoom_previous).
  for (const Mode m : {Mode{true, false, 2.0, 0.5}, Mode{false, true, 2.0, 1.0}, Mode{false, false, 1.0, 0.5}}) {
    SitePairState s = WorkRegionScene(prev, cur);
    WorkRegionOptions o;
    o.zoom_previous = m.zoom_previous;
    EXPECT_EQ(MakeWorkRegions(o, m.warp_current, 1, &s), 2);
    EXPECT_DOUBLE_EQ(s.previous_regions[0].zoom, m.previous_zoom);
    EXPECT_DOUBLE_EQ(s.current_regions[0].zoom, m.current_zoom);
    EXPECT_EQ(s.previous_regions[0].image.cols, static_cast<int>(60 * m.previous_zoom));
    EXPECT_EQ(s.current_regions[0].image.cols, static_cast<int>(100 * m.current_zoom));
    EXPECT_DOUBLE_EQ(s.current_regions[0].max_tilt, 1.7);
    // The previous site's Wallis targets are the current site's filtered statistics.
    EXPECT_NE(s.previous_wallis.target_std, o.wallis.target_std);
  }
}

TEST(WorkRegions, FlatRegionsAndBackwardOverlapsGiveNone) {
  const cv::Mat flat(200, 200, CV_8UC1, cv::Scalar(90));
  SitePairState s = WorkRegionScene(flat, flat);
  EXPECT_EQ(MakeWorkRegions(WorkRegionOptions(), true, 1, &s), 0);
  EXPECT_LT(s.largest_region_std, WorkRegionOptions().min_region_std);
  SitePairState b = WorkRegionScene(Texture({200, 200}, 53, 2.0), Texture({200, 200}, 54, 2.0), true);
  MakeWorkRegions(WorkRegionOptions(), true, 1, &b);
  EXPECT_EQ(b.previous_regions[0].region.area(), 0);  // backward overlaps are matched on the ground
  EXPECT_TRUE(b.current_regions[0].image.empty());
}

// ---- ASIFT on the regions

// Without the warp, a current region is described on the views its
// predicted tilt allows (t <= max_tilt * tilt_margin, longitudes within
// longitude_margin_deg of the predicted one); previous regions at t = 1.
TEST(RegionFeatures, ViewsAreRestrictedByThePrediction) {
  SitePairState s;
  s.previous_regions.resize(1);
  s.current_regions.resize(1);
  WorkRegion& cur = s.current_regions[0];
  cur.region = cv::Rect(100, 200, 160, 160);
  cur.image = Texture({160, 160}, 71, 1.5);
  cur.max_tilt = 1.7;  // * 1.25: tilts 1, sqrt 2 and 2 (not 2 sqrt 2)
  cur.longitude = 0.3;
  WorkRegion& prev = s.previous_regions[0];
  prev.region = cv::Rect(400, 300, 120, 120);
  prev.zoom = 2.0;
  prev.image = Texture({240, 240}, 72, 1.5);
  FeatureOptions o;
  EXPECT_GT(DetectRegionFeatures(o, /*warp_current=*/false, 2, &s), 0);
  ASSERT_EQ(cur.views.size(), 3u);  // 72 / t deg steps: one longitude per tilt within 30 deg
  EXPECT_DOUBLE_EQ(cur.views[1].longitude, 0.3);
  EXPECT_DOUBLE_EQ(cur.views[2].tilt, 2.0);
  EXPECT_EQ(prev.views.size(), 1u);
  EXPECT_EQ(s.num_current_features, cur.features.size());
  // Features in px of the full image: inside the region (zoom undone for the previous one).
  for (const auto& p : cur.features.points) EXPECT_TRUE(cv::Rect2d(99.5, 199.5, 161, 161).contains({p.x(), p.y()}));
  for (const auto& p : prev.features.points) EXPECT_TRUE(cv::Rect2d(399.5, 299.5, 121, 121).contains({p.x(), p.y()}));
  // Wider longitude margin: three longitudes per tilt.
  SitePairState wide = s;
  wide.current_regions[0].views.clear();
  wide.current_regions[0].features = FeatureSet();
  wide.previous_regions[0].views.clear();
  wide.previous_regions[0].features = FeatureSet();
  o.longitude_margin_deg = 60;
  DetectRegionFeatures(o, /*warp_current=*/false, 2, &wide);
  EXPECT_EQ(wide.current_regions[0].views.size(), 7u);
  // With the warp the current regions are not described here (the warped images are).
  SitePairState warped = s;
  warped.current_regions[0].views.clear();
  warped.current_regions[0].features = FeatureSet();
  warped.previous_regions[0].views.clear();
  warped.previous_regions[0].features = FeatureSet();
  warped.num_current_features = 0;
  DetectRegionFeatures(FeatureOptions(), /*warp_current=*/true, 2, &warped);
  EXPECT_TRUE(warped.current_regions[0].views.empty());
  EXPECT_EQ(warped.num_current_features, 0u);
}

// sift_max_zoom: SIFT on a grid zoomed 2x runs on the grid resized back to zoom 1 and its features are mapped onto
// the grid: they are the features of the unzoomed texture, at twice their place. Off (or a grid zoomed no more than
// the limit), the grid itself is described, as before the option.
TEST(RegionFeatures, SiftMaxZoomDescribesTheGridAtThatZoom) {
  const cv::Mat texture = Texture({200, 160}, 73, 1.5);
  cv::Mat grid;
  cv::resize(texture, grid, cv::Size(), 2.0, 2.0, cv::INTER_LINEAR);
  const std::vector<AffineView> views{{1.0, 0.0}};
  FeatureOptions o;
  AsiftOptions single = o.asift;
  single.num_threads = 1;
  const FeatureSet plain = DetectAsift(grid, cv::Mat(), views, single);
  o.sift_max_zoom = 0.0;
  const FeatureSet off = DetectOnGrid(grid, cv::Mat(), views, 2.0, o);
  EXPECT_EQ(off.size(), plain.size());
  o.sift_max_zoom = 2.0;
  EXPECT_EQ(DetectOnGrid(grid, cv::Mat(), views, 2.0, o).size(), plain.size()) << "not zoomed beyond the limit";
  o.sift_max_zoom = 1.0;
  const FeatureSet reduced = DetectOnGrid(grid, cv::Mat(), views, 2.0, o);
  const FeatureSet at_one = DetectAsift(texture, cv::Mat(), views, single);
  ASSERT_GT(at_one.size(), 50u);
  EXPECT_LT(reduced.size(), plain.size()) << "the grid's own upsampled octave finds more";
  EXPECT_NEAR(static_cast<double>(reduced.size()), static_cast<double>(at_one.size()), 0.15 * at_one.size());
  int near = 0;
  for (const Eigen::Vector2d& p : reduced.points) {
    EXPECT_TRUE(p.x() > -1 && p.y() > -1 && p.x() < grid.cols && p.y() < grid.rows);
    for (const Eigen::Vector2d& q : at_one.points)
      if ((p - (2.0 * q + Eigen::Vector2d(0.5, 0.5))).norm() < 1.0) {
        ++near;
        break;
      }
  }
  EXPECT_GT(near, 0.8 * reduced.size()) << "features of the texture at its zoom 1, mapped onto the grid";
}

// ---- input and preparation

TEST(PrepareImages, InputSortedCheckedAndUndistorted) {
  NavcamModel navcam;
  navcam.rig.left.width = navcam.rig.right.width = 64;
  navcam.rig.left.height = navcam.rig.right.height = 48;
  navcam.rig.left.cx = navcam.rig.right.cx = 31.5;
  navcam.rig.left.cy = navcam.rig.right.cy = 23.5;
  navcam.rig.left.fx = navcam.rig.left.fy = navcam.rig.right.fx = navcam.rig.right.fy = 50;
  navcam.rig.left.k1 = -0.2;  // the left camera is distorted (2.6 px at the corners)
  const cv::Mat image = Texture({64, 48}, 5, 1.0);
  SiteImages previous, current;
  for (int k : {2, 0, 1}) {
    StereoPair p;
    p.pair_index = k;
    p.utime = 100 + k;
    p.left = p.right = image;
    previous.pairs.push_back(p);
    current.pairs.push_back(p);
  }
  SitePairState s;
  ASSERT_FALSE(CheckInput(previous, current, navcam, &s).has_value());
  EXPECT_EQ(s.current.pairs[0].pair_index, 0);
  EXPECT_EQ(s.current.pairs[2].pair_index, 2);
  TiePointSet tps;
  InitTiePointSet(s, &tps);
  EXPECT_EQ(tps.utime, 102);
  EXPECT_EQ(tps.current_pointing.size(), 3u);
  PrepareImages(navcam, VehicleOptions(), UsesBspline(FrontendOptions()), 2, &s);
  ASSERT_EQ(s.previous_right.size(), 3u);
  EXPECT_EQ(cv::norm(s.previous_right[1].gray, image, cv::NORM_INF), 0.0);  // no distortion: as it came
  EXPECT_GT(cv::norm(s.previous_left[1].gray, image, cv::NORM_INF), 0.0);   // undistorted
  EXPECT_EQ(s.current_left[2].lsm.gray.size(), image.size());
  // A wrong size names the site and pair.
  current.pairs[2].right = cv::Mat(10, 10, CV_8UC1);  // pair_index 1
  current.site_id = 7;
  const auto problem = CheckInput(previous, current, navcam, &s);
  ASSERT_TRUE(problem.has_value());
  EXPECT_NE(problem->find("site 7 pair 1"), std::string::npos) << *problem;
}

// ---- overlap matching

// Random SIFT-like descriptors (128 floats in [0, 100)).
cv::Mat RandomDescriptors(int n, std::mt19937& rng) {
  cv::Mat d(n, 128, CV_32F);
  std::uniform_real_distribution<float> u(0, 100);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < 128; ++c) d.at<float>(r, c) = u(rng);
  return d;
}

FeatureSet MakeFeatures(const std::vector<Eigen::Vector2d>& points, const cv::Mat& descriptors) {
  FeatureSet f;
  f.views = {{1.0, 0.0}};
  f.points = points;
  f.keypoints.resize(points.size());
  f.view.assign(points.size(), 0);
  f.descriptors = descriptors.clone();
  return f;
}

// A previous and a current region whose features are the same points
// shifted by the DR error `offset` (px) plus a random parallax along x of
// up to +-`parallax` px (a camera moved sideways over relief: the epipolar
// lines are the rows y' = y + offset.y), with descriptor noise and clutter.
struct OverlapScene {
  SitePairState state;
  PairOverlap overlap;
  OverlapWork work;
  Eigen::Vector2d offset;
  int num_true = 0;
  std::vector<Eigen::Vector2d> truth;  // current px of each previous feature
};

OverlapScene MakeOverlapScene(const Eigen::Vector2d& offset, int num_true, int num_clutter, unsigned seed,
                              double parallax = 0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(100, 900), dx(-parallax, parallax);
  std::normal_distribution<float> noise(0, 2);
  OverlapScene s;
  s.offset = offset;
  s.num_true = num_true;
  std::vector<Eigen::Vector2d> prev_pts, cur_pts;
  for (int i = 0; i < num_true; ++i) {
    prev_pts.emplace_back(u(rng), u(rng));
    cur_pts.push_back(prev_pts.back() + offset + Eigen::Vector2d(dx(rng), 0));
  }
  s.truth = cur_pts;
  const cv::Mat d = RandomDescriptors(num_true, rng);
  cv::Mat dc = d.clone();
  for (int r = 0; r < dc.rows; ++r)
    for (int c = 0; c < dc.cols; ++c) dc.at<float>(r, c) += noise(rng);
  for (int i = 0; i < num_clutter; ++i) cur_pts.emplace_back(u(rng), u(rng));
  cv::vconcat(dc, RandomDescriptors(num_clutter, rng), dc);
  s.state.previous_regions.resize(1);
  s.state.current_regions.resize(1);
  s.state.previous_regions[0].features = MakeFeatures(prev_pts, d);
  s.state.current_regions[0].features = MakeFeatures(cur_pts, dc);
  s.overlap.previous_region = cv::Rect(0, 0, 1024, 1024);
  s.overlap.growth_px = 40;  // the DR gate: 40 / scale + gate_margin_px
  // The unwarped mode: train image = current image, predicted by identity.
  s.work.train_from_previous = cv::Matx33d::eye();
  s.work.current_from_train = cv::Matx33d::eye();
  return s;
}

TEST(OverlapMatching, DensestOffsetClusterIsTheDrError) {
  OverlapScene s = MakeOverlapScene({17.0, -9.0}, 60, 0, 3);
  const FeatureSet& fp = s.state.previous_regions[0].features;
  const FeatureSet& fc = s.state.current_regions[0].features;
  std::vector<FeatureMatch> matches;
  for (int i = 0; i < s.num_true; ++i) matches.push_back({i, i, 1.0});
  // Wrong matches scattered over the gate.
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> any(0, s.num_true - 1);
  for (int i = 0; i < 30; ++i) matches.push_back({any(rng), any(rng), 2.0});
  Eigen::Vector2d mode;
  int count = 0;
  const auto cluster = DensestOffsetCluster(matches, fc, fp.points, 3.0, &mode, &count);
  EXPECT_NEAR((mode - s.offset).norm(), 0.0, 1e-9);
  EXPECT_GE(count, s.num_true);
  for (const auto& m : cluster) EXPECT_NEAR((fc.points[m.train] - fp.points[m.query] - s.offset).norm(), 0.0, 6.0);
  EXPECT_GE(static_cast<int>(cluster.size()), s.num_true);
  EXPECT_LT(static_cast<int>(cluster.size()), s.num_true + 5);
}

TEST(OverlapMatching, SpreadSelectTakesOnePerCellFirst) {
  std::vector<Candidate> c(6);
  // Three in one 24 px cell (best first), three in three other cells.
  const double x[6] = {5, 6, 7, 50, 100, 150}, dist[6] = {1, 2, 3, 4, 5, 6};
  for (int k = 0; k < 6; ++k) c[k].cur_left = {x[k], 5}, c[k].descriptor_distance = dist[k];
  const std::vector<int> idx = {0, 1, 2, 3, 4, 5};
  EXPECT_EQ(SpreadSelect(c, idx, 4, kSpreadCellPx), (std::vector<int>{0, 3, 4, 5}));
  EXPECT_EQ(SpreadSelect(c, idx, 10, kSpreadCellPx), (std::vector<int>{0, 3, 4, 5, 1, 2}));
}

// The DR error (a 27 px shift) within the stage-1 gate: stage 1 finds the
// offset cluster, stage 2 matches within the refined gate, the epipolar
// RANSAC keeps them, and every candidate is a true match.
TEST(OverlapMatching, RefinedGateFindsTheTrueMatches) {
  OverlapScene s = MakeOverlapScene({25.0, 10.0}, 150, 150, 11, 3.0);
  const OverlapMatchOptions o;
  MatchOverlap(4, s.overlap, s.state, o, GateOptions(), /*warp_current=*/false, &s.work);
  const auto& cands = s.work.candidates;
  const FeatureSet& fp = s.state.previous_regions[0].features;
  EXPECT_GE(static_cast<int>(cands.size()), 0.9 * s.num_true);
  for (const Candidate& c : cands) {
    EXPECT_EQ(c.overlap, 4);
    int q = 0;
    while (q < s.num_true && (fp.points[q] - c.prev_left).norm() > 1e-9) ++q;
    ASSERT_LT(q, s.num_true);
    EXPECT_NEAR((c.cur_left - s.truth[q]).norm(), 0.0, 1e-6);
  }
  // Without the epipolar RANSAC's 12 matches nothing passes the epipolar test.
  OverlapScene few = MakeOverlapScene({25.0, 10.0}, 11, 0, 11, 3.0);
  OverlapMatchOptions o2 = o;
  o2.min_stage1_inliers = 4;
  MatchOverlap(0, few.overlap, few.state, o2, GateOptions(), /*warp_current=*/false, &few.work);
  EXPECT_TRUE(few.work.candidates.empty());
}

// A DR error beyond the gate: no cluster of min_stage1_inliers, no candidates.
TEST(OverlapMatching, ErrorBeyondTheGateGivesNoCandidates) {
  OverlapScene s = MakeOverlapScene({250.0, 0.0}, 150, 150, 13);
  MatchOverlap(0, s.overlap, s.state, OverlapMatchOptions(), GateOptions(), /*warp_current=*/false, &s.work);
  EXPECT_TRUE(s.work.candidates.empty());
}

// ---- the warp and its tile registration

// The current image is the previous one moved by s = (10, 5) px; the DR
// prediction is off by (6, -4) px. Warped with the prediction, the current
// image is misaligned by that error; the tile registration finds it.
struct WarpScene {
  SitePairState state;
  PairOverlap overlap;
  Eigen::Vector2d s{10, 5};
};

cv::Mat Texture(cv::Size size, unsigned seed, double blur = 2.0);

WarpScene MakeWarpScene(double blur = 3.0) {
  WarpScene w;
  const cv::Mat texture = Texture({512, 512}, 31, blur);
  cv::Mat current;
  const cv::Matx23d shift(1, 0, w.s.x(), 0, 1, w.s.y());
  cv::warpAffine(texture, current, shift, texture.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  SitePairState& st = w.state;
  st.previous_regions.resize(1);
  st.previous_regions[0].region = cv::Rect(0, 0, 512, 512);
  st.previous_regions[0].image = texture;
  st.current_filtered = {current};
  st.current_left.resize(1);
  st.current_left[0].gray = current;
  const Eigen::Vector2d e(6, -4);  // DR error, px
  w.overlap.previous_from_current = cv::Matx33d(1, 0, -w.s.x() + e.x(), 0, 1, -w.s.y() + e.y(), 0, 0, 1);
  w.overlap.previous_region = cv::Rect(40, 40, 432, 432);
  w.overlap.median_current_px = {256, 256};
  w.overlap.growth_px = 20;  // gate: 20 + gate_margin_px (20) px
  return w;
}

TEST(OverlapWarp, TileRegistrationCorrectsTheDrError) {
  const WarpScene w = MakeWarpScene();
  const OverlapWork work = WarpOverlap(w.overlap, w.state, WarpOptions(), GateOptions());
  ASSERT_FALSE(work.skipped);
  EXPECT_TRUE(work.registered);
  EXPECT_GE(work.tile_inliers, WarpOptions().min_tile_inliers);
  // Previous px -> grid -> current px is the true motion within a fraction of a px.
  for (const Eigen::Vector2d& p : {Eigen::Vector2d(150, 150), Eigen::Vector2d(350, 300)}) {
    const Eigen::Vector2d c = ApplyHomography(work.current_from_train, ApplyHomography(work.train_from_previous, p));
    EXPECT_NEAR((c - (p + w.s)).norm(), 0.0, 0.3) << p.transpose();
  }
  EXPECT_EQ(work.warped.size(), cv::Size(432, 432));
  EXPECT_EQ(work.previous_crop.size(), cv::Size(432, 432));
}

TEST(OverlapWarp, WithoutTileRegistrationTheWarpIsThePrediction) {
  const WarpScene w = MakeWarpScene();
  WarpOptions o;
  o.tile_registration = false;
  const OverlapWork work = WarpOverlap(w.overlap, w.state, o, GateOptions());
  EXPECT_FALSE(work.registered);
  const Eigen::Vector2d p(200, 200);
  const Eigen::Vector2d c = ApplyHomography(work.current_from_train, ApplyHomography(work.train_from_previous, p));
  EXPECT_NEAR((c - (p + w.s - Eigen::Vector2d(6, -4))).norm(), 0.0, 1e-9);
}

TEST(OverlapWarp, NoCommonRegionIsSkipped) {
  WarpScene w = MakeWarpScene();
  w.overlap.previous_region = cv::Rect(600, 600, 50, 50);
  EXPECT_TRUE(WarpOverlap(w.overlap, w.state, WarpOptions(), GateOptions()).skipped);
}

// match_previous_resolution: with the previous region zoomed up 2x the
// warped current image is blurred to its resolution (less fine detail).
TEST(OverlapWarp, WarpedImageIsBlurredToTheZoomedPreviousResolution) {
  WarpScene w = MakeWarpScene(0.7);
  w.state.previous_regions[0].zoom = 2.0;
  cv::resize(w.state.previous_regions[0].image, w.state.previous_regions[0].image, cv::Size(), 2.0, 2.0);
  WarpOptions o;
  o.tile_registration = false;
  auto detail = [](const cv::Mat& m) {
    cv::Mat lap;
    cv::Laplacian(m, lap, CV_32F);
    cv::Scalar mean, sd;
    cv::meanStdDev(lap, mean, sd);
    return sd[0];
  };
  const OverlapWork blurred = WarpOverlap(w.overlap, w.state, o, GateOptions());
  o.match_previous_resolution = false;
  const OverlapWork sharp = WarpOverlap(w.overlap, w.state, o, GateOptions());
  EXPECT_EQ(blurred.warped.size(), cv::Size(864, 864));
  EXPECT_LT(detail(blurred.warped), 0.7 * detail(sharp.warped));  // 7.1 vs 17.3
}

// ---- grid LSM and its relief gates

// Smooth random texture, CV_8UC1.
cv::Mat Texture(cv::Size size, unsigned seed, double blur) {
  cv::Mat noise(size, CV_32F);
  cv::theRNG().state = seed;
  cv::randu(noise, 0, 255);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), blur);
  cv::Mat out;
  cv::normalize(noise, noise, 0, 255, cv::NORM_MINMAX);
  noise.convertTo(out, CV_8U);
  return out;
}

// The previous crop and the warped current image: the crop moved by the
// affine x' = A x + t about the centre.
OverlapWork GridScene(const Eigen::Matrix2d& A, const Eigen::Vector2d& t) {
  OverlapWork w;
  w.previous_crop = Texture({200, 160}, 21);
  const Eigen::Vector2d c(100, 80);
  const Eigen::Vector2d b = c + t - A * c;
  const cv::Matx23d M(A(0, 0), A(0, 1), b.x(), A(1, 0), A(1, 1), b.y());
  cv::warpAffine(w.previous_crop, w.warped, M, w.previous_crop.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
  w.coverage = cv::Mat(w.warped.size(), CV_8UC1, cv::Scalar(255));
  return w;  // train_from_previous = current_from_train = identity
}

bool GridRefine(const OverlapWork& w, const GridLsmStepOptions& o, Candidate* c) {
  const LsmImage lt = MakeLsmImage(w.previous_crop), lw = MakeLsmImage(w.warped);
  return RefineOnGrid(w, lt, lw, o, o.grid_lsm, c);
}

TEST(GridLsm, RefinesASubPixelShift) {
  const Eigen::Vector2d t(0.37, -0.21);
  const OverlapWork w = GridScene(Eigen::Matrix2d::Identity(), t);
  Candidate c;
  c.prev_left = {100, 80};
  c.cur_left = {102, 79};  // the features' positions differ by a few px
  ASSERT_TRUE(GridRefine(w, GridLsmStepOptions(), &c));
  EXPECT_TRUE(c.grid_refined);
  // Within 0.1 px: the shift is made by cubic interpolation, which the LSM's
  // bilinear model does not reproduce exactly (it finds 0.06 px here).
  EXPECT_NEAR((c.cur_left - (c.prev_left + t)).norm(), 0.0, 0.1);
  EXPECT_GT(c.grid_correlation, 0.9);
}

// Relief gate: a window whose x shift changes along its rows (shear 0.7)
// is the parallax of relief; dropped with grid_max_shear 0.5, kept without.
TEST(GridLsm, ShearGateDropsReliefParallax) {
  Eigen::Matrix2d A = Eigen::Matrix2d::Identity();
  A(0, 1) = 0.7;
  const OverlapWork w = GridScene(A, {0.2, 0.1});
  GridLsmStepOptions o;
  o.grid_back_check_px = 0;
  Candidate c;
  c.prev_left = c.cur_left = {100, 80};
  EXPECT_FALSE(GridRefine(w, o, &c));
  EXPECT_FALSE(c.grid_refined);
  o.grid_max_shear = 0;
  Candidate d;
  d.prev_left = d.cur_left = {100, 80};
  ASSERT_TRUE(GridRefine(w, o, &d));
  EXPECT_NEAR(d.grid_affine(0, 1), 0.7, 0.05);
}

// Another texture: no correlation peak, nothing refined.
TEST(GridLsm, UnrelatedTextureIsNotRefined) {
  OverlapWork w = GridScene(Eigen::Matrix2d::Identity(), {0, 0});
  w.warped = Texture(w.previous_crop.size(), 99);
  Candidate c;
  c.prev_left = c.cur_left = {100, 80};
  EXPECT_FALSE(GridRefine(w, GridLsmStepOptions(), &c));
}

TEST(GridLsm, OverlapRefinementCountsTheRefined) {
  OverlapWork w = GridScene(Eigen::Matrix2d::Identity(), {0.25, 0.0});
  for (double x : {60.0, 100.0, 140.0}) {
    Candidate c;
    c.prev_left = c.cur_left = {x, 80};
    w.candidates.push_back(c);
  }
  Candidate edge;  // too close to the border for the 53 x 11 window
  edge.prev_left = edge.cur_left = {10, 80};
  w.candidates.push_back(edge);
  EXPECT_EQ(RefineOverlapOnGrid(GridLsmStepOptions(), /*warp_current=*/true, &w), 3);
  EXPECT_EQ(RefineOverlapOnGrid(GridLsmStepOptions(), /*warp_current=*/false, &w), 0);  // no warp: no grid
}

// ---- backward overlaps

// The current site 12 m ahead looks back at the ground the previous site
// looks at: both images are views of one ground texture; matched on the
// ground plane, each candidate's two pixels are the same ground point.
TEST(BackwardOverlaps, OppositeViewsMatchOnTheGround) {
  const NavcamModel navcam;
  const PinholeCamera& cam = navcam.rig.left;
  const MastPointing mp{0.0, 0.35};
  const double res = 0.02;
  const Eigen::Vector2d origin(0, 7);  // texture: x in [0, 14], y in [-7, 7] m
  const cv::Mat ground = Texture({700, 700}, 91, 1.5);
  SitePairState s;
  s.prediction.previous_from_current = MakePose(0, 0, M_PI, 12, 0, 0);
  s.prediction.relative_sigma << 0.1, 0.1, 0.05, 0.01, 0.01, 0.01;
  const Pose3 prev_cam = navcam.mast.BodyFromLeft(mp.pan, mp.tilt, navcam.rig);
  const Pose3 cur_cam = s.prediction.previous_from_current * prev_cam;
  const cv::Matx33d Hp = ImageFromOrtho(cam, prev_cam, origin, res, 0.0);
  const cv::Matx33d Hc = ImageFromOrtho(cam, cur_cam, origin, res, 0.0);
  cv::Mat prev_img, cur_img;
  cv::warpPerspective(ground, prev_img, cv::Mat(Hp), {cam.width, cam.height}, cv::INTER_LINEAR, cv::BORDER_REFLECT);
  cv::warpPerspective(ground, cur_img, cv::Mat(Hc), {cam.width, cam.height}, cv::INTER_LINEAR, cv::BORDER_REFLECT);
  s.previous_left = {PreparedImage{prev_img, LsmImage()}};
  s.current_left = {PreparedImage{cur_img, LsmImage()}};
  s.previous_wallis = WallisOptions();
  PairOverlap ov;
  ov.backward = true;
  ov.ground_min = {3, -3};
  ov.ground_max = {9, 3};
  s.prediction.overlaps = {ov};
  TiePointSet tps;
  tps.previous_pointing = tps.current_pointing = {mp};
  const std::vector<Candidate> c = MatchBackwardOverlap(0, navcam, tps, s, BackwardMatchOptions());
  const cv::Matx33d Hp_inv = Hp.inv(), Hc_inv = Hc.inv();
  int right = 0;
  for (const Candidate& m : c) {
    const Eigen::Vector2d gp = ApplyHomography(Hp_inv, m.prev_left), gc = ApplyHomography(Hc_inv, m.cur_left);
    right += (gp - gc).norm() * res < 0.03 ? 1 : 0;
    EXPECT_EQ(m.overlap, 0);
  }
  std::cout << "backward: " << right << " of " << c.size() << " within 3 cm\n";
  // 1254 of 1261 at the time of writing; no RANSAC here: the stereo and
  // consistency steps remove the few wrong ones.
  EXPECT_GE(right, 500);
  EXPECT_GE(right, 0.98 * c.size());

  // The cross-site LSM starts from the ground plane's local affine (about a
  // half turn here) and takes the features, placed on the 2 cm ortho grid,
  // to the current pixel of the same ground point; matches it cannot refine
  // are dropped.
  s.previous_left[0].lsm = MakeLsmImage(prev_img);
  s.current_left[0].lsm = MakeLsmImage(cur_img);
  s.candidates = c;
  const cv::Matx33d current_from_previous = Hc * Hp_inv;
  auto errors = [&](const std::vector<Candidate>& cands) {
    std::vector<double> e;
    for (const Candidate& m : cands) e.push_back((m.cur_left - ApplyHomography(current_from_previous, m.prev_left)).norm());
    return e;
  };
  const double before = Median(errors(s.candidates));
  ASSERT_GE(RefineCrossSite(CrossSiteLsmOptions(), /*grid_refined_only=*/true, 2, &s), static_cast<int>(c.size() / 2));
  const std::vector<double> after = errors(s.candidates);
  std::cout << "backward LSM: " << s.candidates.size() << " of " << c.size() << " refined, median error " << before
            << " -> " << Median(after) << " px\n";
  EXPECT_LT(Median(after), 0.1);
  EXPECT_LT(Quantile(after, 0.95), 0.3);
  EXPECT_GT(before, 2 * Median(after));
}

// ---- cross-site refinement

TEST(CrossSiteRefinement, DuplicatesMergeToTheMostPrecise) {
  std::vector<Candidate> c(4);
  c[0].cur_left = {100, 100}, c[0].sigma_cross = 0.3;
  c[1].cur_left = {100.8, 100.5}, c[1].sigma_cross = 0.1;  // the same point, more precise
  c[2].cur_left = {100.8, 100.5}, c[2].sigma_cross = 0.2, c[2].cur_pair = 1;  // another image
  c[3].cur_left = {110, 100}, c[3].sigma_cross = 0.4;
  MergeDuplicates(1.5, &c);
  ASSERT_EQ(c.size(), 3u);
  EXPECT_DOUBLE_EQ(c[0].sigma_cross, 0.1);
  EXPECT_EQ(c[1].cur_pair, 1);
  EXPECT_DOUBLE_EQ(c[2].sigma_cross, 0.4);
}

// With the grid LSM (warp_current), forward matches it did not refine are
// dropped and refined ones kept as they are.
TEST(CrossSiteRefinement, GridUnrefinedForwardMatchesAreDropped) {
  SitePairState s;
  s.prediction.overlaps.resize(1);
  s.candidates.resize(3);
  for (int k = 0; k < 3; ++k) s.candidates[k].cur_left = {100.0 + 10 * k, 50}, s.candidates[k].sigma_cross = 0.1;
  s.candidates[1].grid_refined = true;
  EXPECT_EQ(RefineCrossSite(CrossSiteLsmOptions(), /*grid_refined_only=*/true, 2, &s), 1);
  EXPECT_TRUE(s.candidates[0].grid_refined);
  EXPECT_DOUBLE_EQ(s.candidates[0].cur_left.x(), 110);
}

// Without the warp (no grid LSM) a forward match goes to the
// full-resolution cross-site LSM; one it cannot refine is dropped.
TEST(CrossSiteRefinement, UnwarpedMatchesAreRefinedOrDropped) {
  SitePairState s;
  s.prediction.overlaps.resize(1);
  const cv::Mat texture = Texture({160, 160}, 41);
  s.previous_left = {PreparedImage{texture, MakeLsmImage(texture)}};
  cv::Mat moved;
  cv::warpAffine(texture, moved, cv::Matx23d(1, 0, 0.3, 0, 1, 0), texture.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
  const cv::Mat flat(160, 160, CV_8UC1, cv::Scalar(128));
  s.current_left = {PreparedImage{moved, MakeLsmImage(moved)}, PreparedImage{flat, MakeLsmImage(flat)}};
  s.candidates.resize(2);
  s.candidates[0].prev_left = s.candidates[0].cur_left = {80, 80};
  s.candidates[1].prev_left = s.candidates[1].cur_left = {80, 80};
  s.candidates[1].cur_pair = 1;  // nothing to match in a flat image
  const CrossSiteLsmOptions o;
  ASSERT_EQ(RefineCrossSite(o, /*grid_refined_only=*/false, 2, &s), 1);
  EXPECT_NEAR(s.candidates[0].cur_left.x(), 80.3, 0.1);
  EXPECT_LT(s.candidates[0].sigma_cross, o.sigma_unrefined_px);
}

// ---- stereo at both sites

// A textured wall at depth 10 m in front of both sites' cameras (the same
// images at both): the right image is the left one moved by f b / Z px.
struct StereoScene {
  NavcamModel navcam;
  SitePairState state;
  TiePointSet tps;
  double depth = 10.0;
  double disparity = 0;
};

StereoScene MakeStereoScene() {
  StereoScene sc;
  const PinholeCamera& cam = sc.navcam.rig.left;
  sc.disparity = cam.fx * sc.navcam.rig.Baseline() / sc.depth;
  const cv::Mat left = Texture({cam.width, cam.height}, 61, 2.0);
  cv::Mat right;
  cv::warpAffine(left, right, cv::Matx23d(1, 0, -sc.disparity, 0, 1, 0), left.size(), cv::INTER_CUBIC,
                 cv::BORDER_REFLECT);
  SitePairState& s = sc.state;
  s.previous_left = s.current_left = {PreparedImage{left, MakeLsmImage(left)}};
  s.previous_right = s.current_right = {PreparedImage{right, MakeLsmImage(right)}};
  sc.tps.previous_pointing = sc.tps.current_pointing = {MastPointing{}};
  for (double u : {300.0, 420.0, 540.0, 660.0, 780.0}) {
    for (double v : {400.0, 500.0, 600.0}) {
      Candidate c;
      c.prev_left = c.cur_left = {u, v};
      c.sigma_cross = 0.1;
      s.candidates.push_back(c);
    }
  }
  return sc;
}

TEST(Stereo, CorrelationAndLsmFindTheDisparityAndTheDepth) {
  StereoScene sc = MakeStereoScene();
  const StereoStepOptions o;
  const int n = static_cast<int>(sc.state.candidates.size());
  ASSERT_EQ(CorrelateStereo(sc.navcam, o, 2, &sc.state), n);
  for (const Candidate& c : sc.state.candidates)
    EXPECT_NEAR(c.prev_left.x() - c.prev_right.x(), sc.disparity, 1.0);  // ZNCC: to the px
  EXPECT_EQ(MedianFilterDisparities(o, &sc.state), n);
  ASSERT_EQ(RefineStereoAndIntersect(sc.navcam, sc.tps, o, 2, &sc.state), n);
  const Pose3 body_from_left = sc.navcam.mast.BodyFromLeft(0, 0, sc.navcam.rig);
  for (const Candidate& c : sc.state.candidates) {
    EXPECT_NEAR(c.prev_left.x() - c.prev_right.x(), sc.disparity, 0.05);  // LSM: sub-pixel
    // 0.05 px of disparity is 0.016 m of depth at 10 m.
    EXPECT_NEAR((body_from_left.inverse() * c.p_prev).z(), sc.depth, 0.03);
    EXPECT_NEAR((c.p_prev - c.p_cur).norm(), 0.0, 1e-9);  // the same images at both sites
    EXPECT_GT(c.cov_prev(0, 0) + c.cov_prev(1, 1) + c.cov_prev(2, 2), 0.0);
  }
}

// A disparity unlike its neighbours' (a wrong stereo match) is dropped.
TEST(Stereo, MedianFilterDropsADisparityUnlikeItsNeighbours) {
  StereoScene sc = MakeStereoScene();
  // 15 points 20 px apart (neighbours within the filter's 50 px radius).
  for (size_t k = 0; k < sc.state.candidates.size(); ++k) {
    Candidate& c = sc.state.candidates[k];
    c.prev_left = c.cur_left = Eigen::Vector2d(500 + 20.0 * (k % 5), 500 + 20.0 * (k / 5));
    c.prev_right = c.cur_right = c.prev_left - Eigen::Vector2d(sc.disparity, 0);
  }
  sc.state.candidates[7].prev_right.x() -= 15;  // at the previous site only
  const int n = static_cast<int>(sc.state.candidates.size());
  EXPECT_EQ(MedianFilterDisparities(StereoStepOptions(), &sc.state), n - 1);
  for (const Candidate& c : sc.state.candidates) EXPECT_NEAR(c.prev_left.x() - c.prev_right.x(), sc.disparity, 1e-9);
}

// ---- verification

// Points seen from two sites related by a known motion; `num_outliers` of
// them are moved by 1 m at the current site.
std::vector<Candidate> VerificationScene(const Eigen::Isometry3d& previous_from_current, int n, int num_outliers) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> x(4, 20), y(-8, 8), z(-1.6, -1.2);
  std::vector<Candidate> c(n);
  for (int k = 0; k < n; ++k) {
    c[k].p_prev = {x(rng), y(rng), z(rng)};
    c[k].p_cur = previous_from_current.inverse() * c[k].p_prev;
    if (k < num_outliers) c[k].p_cur += Eigen::Vector3d(0.0, 1.0, 0.0);
    c[k].cov_prev = c[k].cov_cur = Eigen::Matrix3d::Identity() * 1e-4;  // 1 cm
    c[k].sigma_cross = 0.2;
  }
  return c;
}

RegionPrediction PredictionOf(const Eigen::Isometry3d& previous_from_current) {
  RegionPrediction p;
  p.previous_from_current.linear() = previous_from_current.linear();
  p.previous_from_current.translation() = previous_from_current.translation();
  p.relative_sigma << 0.5, 0.5, 0.2, 0.01, 0.01, 0.03;
  p.overlaps.resize(1);
  p.overlaps[0].scale = 0.5;
  return p;
}

TEST(Verification, OutliersFailTheConsistencyChecks) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(9.5, 1.0, 0.1);
  const std::vector<Candidate> c = VerificationScene(T, 60, 5);
  const VerificationOptions o;
  Verification v = CheckConsistency(c, o);
  CheckMotion(c, o, &v);
  for (int k = 0; k < 60; ++k) EXPECT_EQ(v.keep[k], k >= 5) << k;
  EXPECT_EQ(v.num_kept, 55);
  TiePointSet tps;
  MakeTiePoints(c, v, PredictionOf(T), o, &tps);
  ASSERT_EQ(tps.points.size(), 55u);
  // Sigmas: the cross-site error split over the two left observations,
  // floored (previous px; current px = previous px / scale).
  const TiePoint& tp = tps.points[0];
  ASSERT_EQ(tp.observations.size(), 4u);
  EXPECT_NEAR(tp.observations[0].sigma, o.cross_sigma_floor_px / std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(tp.observations[2].sigma, o.cross_sigma_floor_px * 2 / std::sqrt(2.0), 1e-12);
  EXPECT_FALSE(CheckAgainstDeadReckoning(PredictionOf(T), o, &tps).has_value());
  EXPECT_EQ(tps.points.size(), 55u);
}

// Without motion_consistency the rigid-motion check is skipped.
TEST(Verification, MotionConsistencyCanBeSwitchedOff) {
  const std::vector<Candidate> c = VerificationScene(Eigen::Isometry3d::Identity(), 30, 0);
  VerificationOptions o;
  o.motion_consistency = false;
  Verification v = CheckConsistency(c, o);
  v.keep.assign(c.size(), false);  // left as they are when the check is off
  CheckMotion(c, o, &v);
  EXPECT_EQ(std::count(v.keep.begin(), v.keep.end(), true), 0);
}

// Tie points consistent among themselves but 5 m from dead reckoning
// (sigma 0.5 m): one wrong rigid motion (repeated texture); cleared.
TEST(Verification, MotionFarFromDeadReckoningIsRejected) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(10, 0, 0);
  const std::vector<Candidate> c = VerificationScene(T, 40, 0);
  const VerificationOptions o;
  Verification v = CheckConsistency(c, o);
  CheckMotion(c, o, &v);
  TiePointSet tps;
  MakeTiePoints(c, v, PredictionOf(T), o, &tps);
  ASSERT_EQ(tps.points.size(), 40u);
  Eigen::Isometry3d dr = T;
  dr.translation().x() += 5;
  const auto problem = CheckAgainstDeadReckoning(PredictionOf(dr), o, &tps);
  ASSERT_TRUE(problem.has_value());
  EXPECT_NE(problem->find("dead reckoning"), std::string::npos);
  EXPECT_TRUE(tps.points.empty());
}

// ---- ground planes

// Stereo images of a textured ground plane n . p + e = 0 (body frame): the
// right image is the left one mapped by the plane-induced homography.
void GroundStereo(const NavcamModel& navcam, const MastPointing& mp, const Eigen::Vector4d& plane, cv::Mat* left,
                  cv::Mat* right) {
  const PinholeCamera& cam = navcam.rig.left;
  const Pose3 bl = navcam.mast.BodyFromLeft(mp.pan, mp.tilt, navcam.rig);
  const Eigen::Vector3d n_l = bl.linear().transpose() * plane.head<3>();
  const double d_l = plane.head<3>().dot(bl.translation()) + plane(3);
  const Pose3 right_from_left = navcam.rig.left_from_right.inverse();
  Eigen::Matrix3d K;
  K << cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1;
  const Eigen::Matrix3d H =
      K * (right_from_left.linear() - right_from_left.translation() * n_l.transpose() / d_l) * K.inverse();
  *left = Texture({cam.width, cam.height}, 81, 1.5);
  cv::Matx33d Hcv;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) Hcv(r, c) = H(r, c);
  cv::warpPerspective(*left, *right, cv::Mat(Hcv), left->size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
}

TEST(GroundPlanes, FittedToSparseStereoOfTheGround) {
  const NavcamModel navcam;
  const MastPointing mp{0.0, 0.25};  // looking 14 deg down: ground from ~2 to ~20 m
  const double slope = 5 * M_PI / 180;
  for (const Eigen::Vector4d& truth : {Eigen::Vector4d(0, 0, 1, 0),
                                      Eigen::Vector4d(-std::sin(slope), 0, std::cos(slope), 0.1)}) {
    cv::Mat left, right;
    GroundStereo(navcam, mp, truth, &left, &right);
    const LsmImage l = MakeLsmImage(left), r = MakeLsmImage(right);
    const Eigen::Vector4d plane =
        FitGroundPlane(navcam, mp, l.gray, r.gray, GroundPlaneOptions(), RegionOptions(), ZnccOptions());
    ASSERT_GT(plane.head<3>().norm(), 0.5) << truth.transpose();
    EXPECT_GT(plane.head<3>().dot(truth.head<3>()), std::cos(0.5 * M_PI / 180)) << plane.transpose();
    EXPECT_NEAR(plane(3), truth(3), 0.03) << plane.transpose();
  }
}

// A camera looking at the sky (no ground within range): no plane.
TEST(GroundPlanes, NoGroundNoPlane) {
  const NavcamModel navcam;
  const MastPointing up{0.0, -0.6};
  cv::Mat left, right;
  GroundStereo(navcam, up, Eigen::Vector4d(0, 0, 1, 0), &left, &right);
  const LsmImage l = MakeLsmImage(left), r = MakeLsmImage(right);
  EXPECT_TRUE(FitGroundPlane(navcam, up, l.gray, r.gray, GroundPlaneOptions(), RegionOptions(), ZnccOptions()).isZero());
}

TEST(GroundPlanes, OffGivesNoPlanes) {
  SitePairState s;
  s.current.pairs.resize(3);
  GroundPlaneOptions o;
  o.fit_ground_planes = false;
  EXPECT_EQ(FitGroundPlanes(NavcamModel(), TiePointSet(), o, RegionOptions(), ZnccOptions(), 2, &s), 0);
  ASSERT_EQ(s.ground_planes.size(), 3u);
  for (const auto& p : s.ground_planes) EXPECT_TRUE(p.isZero());
}


// Ground with relief in every direction, sampled as stereo points from a camera 1.5 m above it, looking along +x.
GroundPointSet GroundSeenFrom(const Pose3& world_from_body, double noise_m, std::mt19937* rng) {
  auto height = [](double x, double y) { return 0.4 * std::sin(x / 3.0) + 0.3 * std::cos(y / 2.5) + 0.05 * x; };
  std::normal_distribution<double> n(0.0, noise_m);
  GroundPointSet set;
  set.camera = Eigen::Vector3d(0, 0, 1.5);
  const Pose3 body_from_world = world_from_body.inverse();
  for (double r = 5; r <= 25; r += 0.5)
    for (double a = -0.6; a <= 0.6; a += 0.04) {
      const Eigen::Vector3d in_body(r * std::cos(a), r * std::sin(a), 0);
      const Eigen::Vector3d w = world_from_body * in_body;
      set.points.push_back(body_from_world * Eigen::Vector3d(w.x(), w.y(), height(w.x(), w.y()) + n(*rng)));
    }
  return set;
}

// The current site 6 m ahead and turned 10 deg; DR has its height off by 0.25 m (wheel slip on a slope) and its
// horizontal position by 0.1 m. The alignment finds the height correction within 3 cm, and refuses one the
// DR's sigma says is impossible, and one without ground in common.
TEST(GroundAlignment, RecoversTheDrHeightErrorFromBothSitesGround) {
  std::mt19937 rng(3);
  const Pose3 previous = Pose3::Identity();
  Pose3 current = Pose3::Identity();
  current.linear() = Eigen::AngleAxisd(10 * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  current.translation() = Eigen::Vector3d(6, 0.5, 0.0);
  const std::vector<GroundPointSet> prev{GroundSeenFrom(previous, 0.01, &rng)};
  const std::vector<GroundPointSet> cur{GroundSeenFrom(current, 0.01, &rng)};
  const Eigen::Vector3d dr_error(0.1, -0.05, 0.25), up = Eigen::Vector3d::UnitZ();
  Pose3 dr = current;
  dr.translation() += dr_error;
  const NavcamModel navcam;
  const GroundAlignOptions o;
  const GroundAlignment a = AlignGround(prev, cur, dr, up, 0.3, navcam, o, 2);
  ASSERT_TRUE(a.ok) << a.why;
  EXPECT_GT(a.points, 500);  // the current points over the previous site's ground
  EXPECT_NEAR(a.delta.z(), -dr_error.z(), 0.03) << a.delta.transpose();
  EXPECT_NEAR(a.delta.head<2>().norm(), 0.0, 1e-12);  // along up only
  EXPECT_LT(a.rms_after, 0.7 * a.rms_before);
  // A DR that claims 2 cm: the 0.25 m correction is refused, the DR stands.
  const GroundAlignment tight = AlignGround(prev, cur, dr, up, 0.02, navcam, o, 2);
  EXPECT_FALSE(tight.ok);
  EXPECT_NE(tight.why.find("beyond the DR"), std::string::npos) << tight.why;
  // No ground in common (the current site behind the previous one, looking back): no correction.
  Pose3 away = current;
  away.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  away.translation() = Eigen::Vector3d(-3, 0, 0);
  const std::vector<GroundPointSet> behind{GroundSeenFrom(away, 0.01, &rng)};
  EXPECT_FALSE(AlignGround(prev, behind, away, up, 0.3, navcam, o, 2).ok);
}

}  // namespace
}  // namespace vloc
