// The feature front end's revisit logic (SiteArchive): best poses, the
// choice of revisits, and images kept in memory, cached on disk or dropped.
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/core.hpp>

#include "vloc/crosssite/site_archive.h"

namespace vloc {
namespace {

PoseWithCovariance At(double x, double y, double variance = 0.0) {
  PoseWithCovariance p;
  p.pose.translation() = Eigen::Vector3d(x, y, 0);
  p.covariance = Matrix6d::Identity() * variance;
  return p;
}

SiteImages Site(int id, double x) {
  SiteImages s;
  s.site_id = id;
  s.world_from_body = At(x, 0);
  for (int k = 0; k < 2; ++k) {
    StereoPair p;
    p.site_id = id;
    p.pair_index = k;
    p.left = cv::Mat(8, 8, CV_8UC1, cv::Scalar(10 * id + k));
    p.right = cv::Mat(8, 8, CV_8UC1, cv::Scalar(10 * id + k + 5));
    s.pairs.push_back(p);
  }
  return s;
}

RevisitOptions Revisits(double distance, int in_memory = 3, const std::string& dir = "") {
  RevisitOptions o;
  o.max_distance_m = distance;
  o.max_sites_in_memory = in_memory;
  o.cache_dir = dir;
  return o;
}

TEST(SiteArchive, BestPoseIsGraphElseChainedElseDeadReckoning) {
  SiteArchive a(Revisits(5));
  a.SetDrPose(1, At(0, 0, 0.01));
  a.SetDrPose(2, At(10, 0, 0.04));
  a.SetDrPose(3, At(20, 0, 0.09));
  EXPECT_FALSE(a.BestPose(7).has_value());
  EXPECT_DOUBLE_EQ(a.BestPose(3)->pose.translation().x(), 20);  // no graph: DR
  // The graph moved site 2 by 1 m north: site 3 (not in the graph) follows
  // by its DR motion from site 2, and its covariance grows by the DR growth.
  a.SetOptimised({{1, At(0, 0, 0.0)}, {2, At(10, 1, 0.02)}});
  EXPECT_DOUBLE_EQ(a.BestPose(2)->pose.translation().y(), 1);
  const auto p3 = a.BestPose(3);
  ASSERT_TRUE(p3.has_value());
  EXPECT_NEAR((p3->pose.translation() - Eigen::Vector3d(20, 1, 0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(p3->covariance(0, 0), 0.02 + (0.09 - 0.04), 1e-12);
}

TEST(SiteArchive, RevisitsAreNearEnoughFarBackAndNearestFirst) {
  RevisitOptions o = Revisits(6);
  o.max_matches = 2;
  SiteArchive a(o);
  // Sites 1..5 along x, then site 6 back near sites 2 (1 m) and 1 (2 m).
  const double x[] = {0, 0, 3, 10, 20, 30, 2};
  for (int id = 1; id <= 5; ++id) {
    a.SetDrPose(id, At(x[id], 0));
    a.Add(Site(id, x[id]));
  }
  a.SetDrPose(6, At(x[6], 0));
  const auto r = a.ChooseRevisits(6);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_EQ(r[0].site_id, 2);
  EXPECT_NEAR(r[0].distance_m, 1.0, 1e-12);
  EXPECT_EQ(r[1].site_id, 1);
  EXPECT_NEAR(r[1].distance_m, 2.0, 1e-12);
  EXPECT_FALSE(r[0].pose_from_graph);
  // Site 4 is not far enough back (gap 2 < 3), even when close.
  a.SetDrPose(6, At(20, 0));
  EXPECT_TRUE(a.ChooseRevisits(6).empty());
  // Off: no revisits.
  SiteArchive off(Revisits(0));
  off.SetDrPose(1, At(0, 0));
  off.Add(Site(1, 0));
  off.SetDrPose(9, At(0, 0));
  EXPECT_TRUE(off.ChooseRevisits(9).empty());
}

TEST(SiteArchive, OlderSitesAreDroppedWithoutACache) {
  SiteArchive a(Revisits(5, 1));
  a.Add(Site(1, 0));
  a.Add(Site(2, 10));
  EXPECT_FALSE(a.Restore(1).has_value());  // dropped
  const auto s2 = a.Restore(2);
  ASSERT_TRUE(s2.has_value());
  ASSERT_EQ(s2->pairs.size(), 2u);
  EXPECT_EQ(s2->pairs[1].left.at<uchar>(0, 0), 21);
  EXPECT_FALSE(a.Restore(3).has_value());
}

TEST(SiteArchive, OlderSitesComeBackFromTheCache) {
  const std::string dir = (std::filesystem::temp_directory_path() / "vloc_site_archive_test").string();
  std::filesystem::remove_all(dir);
  {
    SiteArchive a(Revisits(5, 1, dir));
    a.Add(Site(1, 0));
    a.Add(Site(2, 10));
    ASSERT_TRUE(std::filesystem::exists(dir + "/site1_pair0_left.png"));
    const auto s1 = a.Restore(1);
    ASSERT_TRUE(s1.has_value());
    ASSERT_EQ(s1->pairs.size(), 2u);
    EXPECT_EQ(s1->pairs[1].left.at<uchar>(3, 3), 11);
    EXPECT_EQ(s1->pairs[1].right.at<uchar>(3, 3), 16);
    EXPECT_EQ(s1->pairs[1].pair_index, 1);
    // A cache file lost: not revisited (and no crash).
    std::filesystem::remove(dir + "/site1_pair0_right.png");
    EXPECT_FALSE(a.Restore(1).has_value());
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vloc
