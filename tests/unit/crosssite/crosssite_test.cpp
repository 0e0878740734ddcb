// Region prediction and the front end's failure paths on synthetic geometry.
#include <gtest/gtest.h>

#include <iostream>

#include "vloc/common/homography.h"
#include "vloc/common/options.h"
#include "vloc/crosssite/frontend.h"
#include "vloc/crosssite/regions.h"

namespace vloc {
namespace {

std::vector<MastPointing> Panorama() {
  std::vector<MastPointing> p;
  for (int k = 0; k < 7; ++k) p.push_back({(3 - k) * 26.0 * M_PI / 180, 25.0 * M_PI / 180});
  return p;
}

NavcamModel Navcam() { return LoadOptionsFile<NavcamModel>("config/navcam.yaml"); }

TEST(Regions, DefaultOptionsPassCheck) {
  std::string error;
  EXPECT_TRUE(RegionOptions().Check(&error)) << error;
  EXPECT_TRUE(FrontendOptions().Check(&error)) << error;
}

// Flat ground: true correspondences from the true poses must fall inside the
// regions predicted from DR poses that are off by less than 2 sigma.
TEST(Regions, PredictionContainsTheTrueOverlap) {
  const NavcamModel navcam = Navcam();
  const auto pointing = Panorama();
  PoseWithCovariance prev, cur_dr;
  const Pose3 cur_true = MakePose(10.0, 0.5, 0.0, 0, 0, 0.1);
  cur_dr.pose = cur_true;
  cur_dr.pose.translation() += Eigen::Vector3d(1.0, -1.2, 0.05);  // 1.6 m: 16 % of the distance
  cur_dr.pose.linear() = ExpSO3(Eigen::Vector3d(0, 0, 0.04)) * cur_dr.pose.linear();  // 2.3 deg
  Vector6d sigma;
  sigma << 1.5, 1.5, 0.5, 0.02, 0.02, 0.05;
  cur_dr.covariance = sigma.cwiseAbs2().asDiagonal();
  RegionOptions o;
  const RegionPrediction pred = PredictRegions(navcam, prev, cur_dr, pointing, pointing, o);
  ASSERT_FALSE(pred.overlaps.empty());
  const auto& cam = navcam.rig.left;
  int true_points = 0, covered = 0, pairs_with_truth = 0, pairs_found = 0, miss_ov = 0, miss_cur = 0, miss_prev = 0;
  for (size_t i = 0; i < pointing.size(); ++i) {
    const Pose3 body_from_cur = navcam.mast.BodyFromLeft(pointing[i].pan, pointing[i].tilt, navcam.rig);
    for (size_t j = 0; j < pointing.size(); ++j) {
      const Pose3 prev_cam_from_body =
          navcam.mast.BodyFromLeft(pointing[j].pan, pointing[j].tilt, navcam.rig).inverse();
      const PairOverlap* ov = nullptr;
      for (const auto& x : pred.overlaps)
        if (x.current_pair == static_cast<int>(i) && x.previous_pair == static_cast<int>(j)) ov = &x;
      int n = 0;
      for (int v = 16; v < cam.height; v += 32) {
        for (int u = 16; u < cam.width; u += 32) {
          const Eigen::Vector3d d = body_from_cur.linear() * cam.Ray({double(u), double(v)});
          const Eigen::Vector3d c = body_from_cur.translation();
          if (d.z() >= 0) continue;
          const Eigen::Vector3d g = c - c.z() / d.z() * d;  // ground z = 0 (body and world agree here)
          if ((g - c).norm() > 0.8 * o.max_range_current || (g - c).norm() < 1.2 * o.min_range_current) continue;
          const Eigen::Vector3d pc = prev_cam_from_body * (cur_true * g);
          if (pc.norm() > 0.8 * o.max_range_previous) continue;
          const auto q = cam.ProjectIdeal(pc);
          if (!q || !cam.InImage(*q, 20)) continue;
          ++n;
          ++true_points;
          if (ov && ov->previous_region.contains(cv::Point(int(q->x()), int(q->y()))) &&
              ov->current_region.contains(cv::Point(u, v)))
            ++covered;
          else if (!ov) ++miss_ov;
          else if (!ov->current_region.contains(cv::Point(u, v))) ++miss_cur;
          else ++miss_prev;
        }
      }
      if (n >= 10) {
        ++pairs_with_truth;
        if (ov) ++pairs_found;
      }
    }
  }
  ASSERT_GT(true_points, 300);
  EXPECT_EQ(pairs_found, pairs_with_truth);
  EXPECT_GE(covered, 0.99 * true_points) << covered << " of " << true_points << ": no overlap " << miss_ov
                                               << ", outside the current region " << miss_cur << ", outside the previous region " << miss_prev;
  // Forward-forward: the previous view of the common ground is smaller.
  int forward = 0;
  for (const auto& ov : pred.overlaps) {
    if (ov.backward) continue;  // outermost pairs looking across each other
    ++forward;
    // Looking ahead at the common ground, the previous view is the smaller one.
    if (ov.current_pair == ov.previous_pair) {
      EXPECT_LT(ov.scale, 1.0);
    }
    EXPECT_GE(ov.tilt, 1.0);
    EXPECT_GT(ov.growth_px, 10.0);
  }
  EXPECT_GT(forward, 0.8 * pred.overlaps.size());
}

TEST(Regions, OppositeViewsAreBackward) {
  const NavcamModel navcam = Navcam();
  PoseWithCovariance prev, cur;
  cur.pose = MakePose(8.0, 0, 0, 0, 0, 0);
  // The current site looks back at the previous one.
  const std::vector<MastPointing> fwd{{0.0, 0.45}}, back{{M_PI, 0.45}};
  const RegionPrediction pred = PredictRegions(navcam, prev, cur, fwd, back, RegionOptions());
  ASSERT_EQ(pred.overlaps.size(), 1u);
  EXPECT_TRUE(pred.overlaps[0].backward);
  EXPECT_GT(pred.overlaps[0].ground_max.x(), 3.0);
  EXPECT_LT(pred.overlaps[0].ground_min.x(), 7.0);
}

// Far terrain (a hill 80-120 m ahead, sites 30 m apart, the DR 15 % and
// 3 deg off): its stereo points make a far overlap whose previous region
// holds the points' true projections and whose homography predicts them
// within its gate (growth_px, the 90th percentile of the samples' growth).
TEST(Regions, FarTerrainPointsMakeAFarOverlapCoveringTheTruth) {
  const NavcamModel navcam = Navcam();
  const std::vector<MastPointing> pointing = {{0.0, 5.0 * M_PI / 180}};
  const Pose3 cur_true = MakePose(30.0, 2.0, 0.0, 0, 0, 0.05);
  PoseWithCovariance prev, cur_dr;
  prev.covariance = Matrix6d::Identity() * 1e-8;
  cur_dr.pose = MakePose(34.5, 2.0, 0.0, 0, 0, 0.05 + 3 * M_PI / 180);
  Vector6d sigma;
  sigma << 4.5, 4.5, 4.5, M_PI / 180, M_PI / 180, 3 * M_PI / 180;
  cur_dr.covariance = Matrix6d(sigma.cwiseAbs2().asDiagonal()) + prev.covariance;
  RegionOptions o;
  o.far_min_range = 40, o.far_max_range = 400;
  std::string error;
  ASSERT_TRUE(o.Check(&error)) << error;
  const auto& cam = navcam.rig.left;
  const Pose3 body_from_cur = navcam.mast.BodyFromLeft(0, pointing[0].tilt, navcam.rig);
  std::vector<ScenePoint> far;
  for (int v = 16; v < cam.height / 2; v += 24)
    for (int u = 16; u < cam.width; u += 24) {
      const double range = 80 + 40.0 * u / cam.width;  // m, a hill slanted across the view
      const double range_sigma = range * range / (navcam.rig.Baseline() * cam.fx) * 0.5;
      const Eigen::Vector3d ray = body_from_cur.linear() * cam.Ray({double(u), double(v)});
      far.push_back({Eigen::Vector2d(u, v), body_from_cur.translation() + range * ray, range_sigma});
    }
  const RegionPrediction pred = PredictRegions(navcam, prev, cur_dr, pointing, pointing, o, {}, {far});
  const PairOverlap* ov = nullptr;
  for (const auto& x : pred.overlaps)
    if (x.far) ov = &x;
  ASSERT_NE(ov, nullptr);
  const Pose3 prev_cam_from_body = navcam.mast.BodyFromLeft(0, pointing[0].tilt, navcam.rig).inverse();
  int seen = 0, in_region = 0, in_gate = 0;
  for (const ScenePoint& sp : far) {
    const auto q = cam.ProjectIdeal(prev_cam_from_body * (cur_true * sp.p_body));
    if (!q || q->x() < 0 || q->y() < 0 || q->x() >= cam.width || q->y() >= cam.height) continue;
    ++seen;
    in_region += ov->previous_region.contains(cv::Point(static_cast<int>(q->x()), static_cast<int>(q->y())));
    in_gate += (ApplyHomography(ov->previous_from_current, sp.px) - *q).norm() <= ov->growth_px;
  }
  std::cout << seen << " far points seen from the previous site: " << in_region << " in its region, " << in_gate
            << " within the gate (" << ov->growth_px << " px)\n";
  ASSERT_GT(seen, 100);
  EXPECT_EQ(in_region, seen);
  EXPECT_GE(in_gate, 0.9 * seen);
  // Without far points (or with far_max_range 0) there is no far overlap.
  for (const auto& x : PredictRegions(navcam, prev, cur_dr, pointing, pointing, RegionOptions(), {}, {far}).overlaps)
    EXPECT_FALSE(x.far);
  o.far_min_range = 500;
  EXPECT_FALSE(o.Check(&error));
  EXPECT_NE(error.find("far_max_range = 400: must be 0 (off) or > far_min_range > 0"), std::string::npos) << error;
}

TEST(Regions, OrthoHomographyProjectsGroundPoints) {
  const NavcamModel navcam = Navcam();
  const Pose3 body_from_cam = navcam.mast.BodyFromLeft(0.2, 0.4, navcam.rig);
  const Eigen::Vector2d origin(2.0, 3.0);
  const double res = 0.02;
  const cv::Matx33d H = ImageFromOrtho(navcam.rig.left, body_from_cam, origin, res, 0.0);
  const Eigen::Vector2d ortho(150, 80);
  const Eigen::Vector3d ground(origin.x() + ortho.x() * res, origin.y() - ortho.y() * res, 0.0);
  const auto truth = navcam.rig.left.ProjectIdeal(body_from_cam.inverse() * ground);
  ASSERT_TRUE(truth);
  const cv::Vec3d h = H * cv::Vec3d(ortho.x(), ortho.y(), 1.0);
  EXPECT_NEAR(h[0] / h[2], truth->x(), 1e-6);
  EXPECT_NEAR(h[1] / h[2], truth->y(), 1e-6);
}

SiteImages FlatSite(int id, const Pose3& pose, uint8_t grey) {
  SiteImages s;
  s.site_id = id;
  s.world_from_body.pose = pose;
  const auto pointing = Panorama();
  for (size_t k = 0; k < pointing.size(); ++k) {
    StereoPair p;
    p.site_id = id;
    p.pair_index = static_cast<int>(k);
    p.num_pairs = 7;
    p.mast_pan = pointing[k].pan;
    p.mast_tilt = pointing[k].tilt;
    p.left = cv::Mat(1024, 1024, CV_8UC1, cv::Scalar(grey));
    p.right = p.left.clone();
    s.pairs.push_back(p);
  }
  return s;
}

TEST(Frontend, TexturelessImagesGiveLowTextureStatus) {
  const CrossSiteFrontend fe(Navcam(), FrontendOptions());
  const FrontendResult r = fe.Run(FlatSite(0, Pose3::Identity(), 90), FlatSite(1, MakePose(10, 0, 0, 0, 0, 0), 95));
  EXPECT_EQ(r.summary.status, FrontendStatus::kLowTexture) << r.summary.BriefReport();
  EXPECT_NE(r.summary.message.find("texture"), std::string::npos);
  EXPECT_TRUE(r.tie_points.points.empty());
  // The steps run up to the one that found the regions flat.
  std::vector<std::string> names;
  for (const StageReport& st : r.summary.stages) names.push_back(st.name);
  EXPECT_EQ(names, (std::vector<std::string>{"prepare_images", "ground_planes", "region_prediction",
                                             "ground_alignment", "region_wallis_zoom"}));
}

TEST(Frontend, MissingOrBadImagesGiveMissingInput) {
  const CrossSiteFrontend fe(Navcam(), FrontendOptions());
  SiteImages empty;
  FrontendResult r = fe.Run(empty, FlatSite(1, Pose3::Identity(), 90));
  EXPECT_EQ(r.summary.status, FrontendStatus::kMissingInput);
  SiteImages bad = FlatSite(0, Pose3::Identity(), 90);
  bad.pairs[3].right = cv::Mat(10, 10, CV_8UC1);
  r = fe.Run(bad, FlatSite(1, MakePose(10, 0, 0, 0, 0, 0), 90));
  EXPECT_EQ(r.summary.status, FrontendStatus::kMissingInput);
  EXPECT_NE(r.summary.message.find("pair 3"), std::string::npos) << r.summary.message;
}

TEST(Frontend, FarApartSitesHaveNoOverlap) {
  const CrossSiteFrontend fe(Navcam(), FrontendOptions());
  PoseWithCovariance p;
  const FrontendResult r =
      fe.Run(FlatSite(0, Pose3::Identity(), 90), FlatSite(1, MakePose(500, 0, 0, 0, 0, 0), 90));
  EXPECT_EQ(r.summary.status, FrontendStatus::kNoOverlap) << r.summary.BriefReport();
}

}  // namespace
}  // namespace vloc
