// A wooded survey like the one of issue 14 (a DJI Phantom 3 at 40 m over
// forest canopy, 13.7 m between photos, about 60 % overlap at the crowns):
// the simulated UAV world with 700 trees 15-20 m tall (their crowns are seen
// from 20-25 m, so they move about twice as fast as the ground between
// photos: real parallax). 17 nadir photos through the mosaicker with the
// stills configuration (SIFT, the looser second matching try, earlier frames
// kept for matching): at least 16 registered and the height within 2 % RMS,
// as issue 14 asks (A-KAZE alone registered 8 of 17). The crowns' parallax
// itself is tested first.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdlib>
#include <iostream>

#include "vloc/common/options.h"
#include "vloc/mosaic/uav_mosaicker.h"
#include "vloc/sim/uav_world.h"

namespace vloc::mosaic {
namespace {

// One crown 18 m tall: moving the camera 2 m east moves the ground by
// f 2 / 40 px and the crown by f 2 / (40 - 18) px.
TEST(WoodedSurvey, CrownsShowParallax) {
  UavWorldOptions wo;
  wo.marker.enabled = false;
  wo.render.moving_objects = false;
  wo.render.noise_sigma = 0;
  wo.trees.num_trees = 1;
  wo.trees.area_radius = 0.01;
  wo.trees.min_height = wo.trees.max_height = 18.0;
  wo.trees.min_radius = wo.trees.max_radius = 3.0;
  UavWorldOptions bare_options = wo;
  bare_options.trees.num_trees = 0;
  const UavWorld world(wo), bare(bare_options);
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  std::vector<cv::Point2d> centres;
  for (const double x : {0.0, 2.0}) {
    Pose3 pose = Pose3::Identity();
    pose.linear() = R;
    pose.translation() = Eigen::Vector3d(x, 0, 40.0);
    cv::Mat diff;
    cv::absdiff(world.Render(pose, 0.0), bare.Render(pose, 0.0), diff);
    cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
    const cv::Moments mo = cv::moments(diff > 0, true);
    ASSERT_GT(mo.m00, 1000);
    centres.emplace_back(mo.m10 / mo.m00, mo.m01 / mo.m00);
    // A 3 m crown seen from 22 m: radius f 3 / 22 = 136 px.
    EXPECT_NEAR(std::sqrt(mo.m00 / M_PI), world.camera().fx * 3.0 / 22.0, 3.0);
  }
  const double shift = centres[0].x - centres[1].x;  // camera east = scene moves left
  EXPECT_NEAR(shift, world.camera().fx * 2.0 / 22.0, 1.0);
  EXPECT_GT(shift, 1.5 * world.camera().fx * 2.0 / 40.0);  // far more than the ground's 50 px
}

TEST(WoodedSurvey, SeventeenPhotosOverTallTrees) {
  UavWorldOptions wo;
  wo.marker.enabled = false;
  wo.render.moving_objects = false;
  wo.trees.num_trees = 700;
  wo.trees.centre = Eigen::Vector2d(0, 0);
  wo.trees.area_radius = 130;
  const UavWorld world(wo);
  MosaickerOptions o = LoadOptionsFile<MosaickerOptions>("config/procs/uav_mosaic_files.yaml", "mosaicker");
  o.camera = world.camera();
  o.calibration.source = "config";
  const double height = 40.0;
  o.calibration.height = height;
  o.async_mosaic = false;
  o.matcher.downscale = 0.8;  // 1280 px photos: A-KAZE at 1024 px, as uav_mosaic_files does above 1000 px
  std::string error;
  ASSERT_TRUE(o.Check(&error)) << error;
  UavMosaicker mosaicker(o);
  // Nadir camera, image up = north: camera x east, y south, z down.
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  // The crowns are there: most of a photo differs from the same view without trees.
  {
    UavWorldOptions bare = wo;
    bare.trees.num_trees = 0;
    Pose3 pose = Pose3::Identity();
    pose.linear() = R;
    pose.translation() = Eigen::Vector3d(0, 0, height);
    const cv::Mat with = world.Render(pose, 0.0), without = UavWorld(bare).Render(pose, 0.0);
    cv::Mat diff;
    cv::absdiff(with, without, diff);
    cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
    const double covered = cv::countNonZero(diff > 20) / static_cast<double>(diff.total());
    EXPECT_GT(covered, 0.4) << "crowns cover only " << covered << " of the photo";
    if (const char* dump = std::getenv("VLOC_WOODED_DUMP")) cv::imwrite(dump, with);
  }
  int registered = 0;
  double sum2 = 0;
  for (int i = 0; i < 17; ++i) {
    Pose3 pose = Pose3::Identity();
    pose.linear() = R;
    pose.translation() = Eigen::Vector3d(-110.0 + 13.7 * i, 2.0 * std::sin(0.7 * i), height);
    const FrameState s = mosaicker.ProcessFrame(world.Render(pose, 0.0), static_cast<int64_t>(i) * 2000000);
    const bool ok = s.status == TrackStatus::kTracking || s.status == TrackStatus::kRecovered;
    registered += ok ? 1 : 0;
    if (ok) sum2 += std::pow((s.height_raw - height) / height, 2);
    if (!ok) std::cout << "frame " << i << " " << ToString(s.status) << ": " << s.message << "\n";
  }
  const double rms = 100 * std::sqrt(sum2 / std::max(1, registered));
  std::cout << "wooded survey: " << registered << " of 17 registered, height RMS " << rms << " %\n";
  EXPECT_GE(registered, 16);
  EXPECT_LT(rms, 2.0);
}

}  // namespace
}  // namespace vloc::mosaic
