// Rendering of the simulated UAV: frames agree with the ground-truth
// homographies, the marker is detectable where the truth says, same seed
// gives the same bytes.
#include <gtest/gtest.h>

#include <opencv2/aruco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>

#include "vloc/sim/uav_world.h"

namespace vloc {
namespace {

// The default world (built once: ~1 s).
const UavWorld& DefaultWorld() {
  static const auto world = std::make_unique<UavWorld>(UavWorldOptions());
  return *world;
}

// Mean absolute grey difference between `b` and `a` warped by H (a -> b),
// over pixels valid in both, away from the border and from moving objects.
double WarpedDifference(const UavWorld& world, const cv::Mat& a, const cv::Mat& b, const cv::Matx33d& H, double tb) {
  cv::Mat ga, gb, warped, valid;
  cv::cvtColor(a, ga, cv::COLOR_BGR2GRAY);
  cv::cvtColor(b, gb, cv::COLOR_BGR2GRAY);
  cv::warpPerspective(ga, warped, H, gb.size(), cv::INTER_LINEAR);
  cv::Mat ones(ga.size(), CV_8U, cv::Scalar(255));
  cv::warpPerspective(ones, valid, H, gb.size(), cv::INTER_NEAREST);
  cv::erode(valid, valid, cv::Mat(), cv::Point(-1, -1), 3);
  // Mask out moving objects (they break the ground homography) with a margin.
  const cv::Matx33d hg = world.ImageFromGround(world.flight().WorldFromCamera(tb));
  for (const GroundObject& o : world.ObjectsAt(tb)) {
    std::vector<cv::Point> poly;
    for (const auto& c : o.corners) {
      const cv::Vec3d p = hg * cv::Vec3d(c.x(), c.y(), 1);
      poly.emplace_back(static_cast<int>(p[0] / p[2]), static_cast<int>(p[1] / p[2]));
    }
    const cv::Rect r = cv::boundingRect(poly);
    cv::rectangle(valid, cv::Rect(r.x - 40, r.y - 40, r.width + 80, r.height + 80), cv::Scalar(0), cv::FILLED);
  }
  cv::Mat diff;
  cv::absdiff(warped, gb, diff);
  return cv::mean(diff, valid)[0];
}

TEST(UavWorld, ConsecutiveFramesAreRelatedByTheGroundTruthHomography) {
  const UavWorld& world = DefaultWorld();
  const double sigma = world.options().render.noise_sigma;
  // Low (calibration hover, climb), high, turning, descending parts of the flight.
  for (const double t : {1.0, 6.0, 20.0, 35.0, 50.0, 70.0}) {
    const double t2 = t + 1.0 / world.options().fps;
    const cv::Mat a = world.RenderFrame(t), b = world.RenderFrame(t2);
    ASSERT_EQ(a.size(), cv::Size(1280, 720));
    ASSERT_EQ(a.type(), CV_8UC3);
    const cv::Matx33d H = world.GroundHomography(t, t2);
    const double good = WarpedDifference(world, a, b, H, t2);
    // Noise alone: grey = .299 B + .587 G + .114 R of independent channel noise, and
    // E|n1 - n2| = sqrt(2) sigma_grey sqrt(2 / pi) (about 1.5 for sigma 2); bilinear
    // resampling of the texture and 8-bit rounding add up to 1.5 grey levels.
    const double grey_sigma = sigma * std::sqrt(0.299 * 0.299 + 0.587 * 0.587 + 0.114 * 0.114);
    const double noise_only = std::sqrt(2.0) * grey_sigma * std::sqrt(2.0 / M_PI);
    EXPECT_LT(good, noise_only + 1.5) << "t=" << t;
    // A homography 2 px off is clearly worse: the comparison can fail.
    const cv::Matx33d shifted = cv::Matx33d(1, 0, 2, 0, 1, 0, 0, 0, 1) * H;
    const double bad = WarpedDifference(world, a, b, shifted, t2);
    EXPECT_GT(bad, good * 1.5) << "t=" << t;
    std::cout << "t=" << t << " s, height " << world.flight().StateAt(t).position.z()
              << " m: mean |grey difference| after the ground-truth warp " << good << ", 2 px off " << bad << "\n";
  }
}

TEST(UavWorld, MatchedFeaturesAgreeWithTheGroundTruthHomography) {
  const UavWorld& world = DefaultWorld();
  const cv::Ptr<cv::AKAZE> akaze = cv::AKAZE::create();
  for (const double t : {2.0, 25.0, 55.0}) {
    const double t2 = t + 5.0 / world.options().fps;  // 5 frames apart
    cv::Mat a, b;
    cv::cvtColor(world.RenderFrame(t), a, cv::COLOR_BGR2GRAY);
    cv::cvtColor(world.RenderFrame(t2), b, cv::COLOR_BGR2GRAY);
    std::vector<cv::KeyPoint> ka, kb;
    cv::Mat da, db;
    akaze->detectAndCompute(a, cv::noArray(), ka, da);
    akaze->detectAndCompute(b, cv::noArray(), kb, db);
    ASSERT_GT(ka.size(), 200u) << "too little texture at t=" << t << " (height "
                               << world.flight().StateAt(t).position.z() << " m)";
    cv::BFMatcher matcher(cv::NORM_HAMMING, true);
    std::vector<cv::DMatch> matches;
    matcher.match(da, db, matches);
    std::vector<cv::Point2f> pa, pb;
    for (const auto& m : matches) {
      pa.push_back(ka[static_cast<size_t>(m.queryIdx)].pt);
      pb.push_back(kb[static_cast<size_t>(m.trainIdx)].pt);
    }
    cv::setRNGSeed(1);
    cv::Mat inliers;
    const cv::Mat H_est = cv::findHomography(pa, pb, cv::RANSAC, 2.0, inliers, 2000, 0.999);
    ASSERT_FALSE(H_est.empty());
    EXPECT_GT(cv::countNonZero(inliers), 100) << "t=" << t;
    const cv::Matx33d H_true = world.GroundHomography(t, t2);
    // Image corners and centre map to the same place within a pixel.
    double worst = 0;
    for (const cv::Point2d p : {cv::Point2d(0, 0), cv::Point2d(1279, 0), cv::Point2d(0, 719), cv::Point2d(1279, 719),
                                cv::Point2d(640, 360)}) {
      const cv::Vec3d e = cv::Matx33d(H_est) * cv::Vec3d(p.x, p.y, 1), g = H_true * cv::Vec3d(p.x, p.y, 1);
      worst = std::max(worst, std::hypot(e[0] / e[2] - g[0] / g[2], e[1] / e[2] - g[1] / g[2]));
    }
    EXPECT_LT(worst, 1.5) << "t=" << t;
    std::cout << "t=" << t << " s: AKAZE+RANSAC homography vs ground truth, worst corner " << worst << " px, "
              << cv::countNonZero(inliers) << " inliers\n";
  }
}

TEST(UavWorld, MarkerIsDetectedWhereTheTruthProjectsIt) {
  const UavWorld& world = DefaultWorld();
  const double t = 1.0;  // calibration hover at 15 m
  const cv::Mat frame = world.RenderFrame(t);
  std::vector<std::vector<cv::Point2f>> corners;
  std::vector<int> ids;
  cv::aruco::detectMarkers(frame, cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50), corners, ids);
  ASSERT_EQ(ids.size(), 1u);
  EXPECT_EQ(ids[0], world.options().marker.id);
  const cv::Matx33d hg = world.ImageFromGround(world.flight().WorldFromCamera(t));
  const auto truth = world.MarkerCorners();
  for (int k = 0; k < 4; ++k) {
    const cv::Vec3d p = hg * cv::Vec3d(truth[static_cast<size_t>(k)].x(), truth[static_cast<size_t>(k)].y(), 1);
    EXPECT_NEAR(corners[0][static_cast<size_t>(k)].x, p[0] / p[2], 1.0) << "corner " << k;
    EXPECT_NEAR(corners[0][static_cast<size_t>(k)].y, p[1] / p[2], 1.0) << "corner " << k;
  }
  // Side length: f * size / height (the calibration relation of the paper).
  const double side = cv::norm(corners[0][0] - corners[0][1]);
  EXPECT_NEAR(side, world.camera().fx * world.options().marker.size / world.options().flight.calibration_height, 1.0);
}

UavWorldOptions SmallWorld(int seed) {
  UavWorldOptions o;
  o.orthomap.size = 120;
  o.orthomap.centre = Eigen::Vector2d(20, 0);
  o.orthomap.seed = seed;
  o.orthomap.detail_tile = 512;
  o.flight.waypoints = {40, 0, 30};
  o.gps.dropouts = {};
  return o;
}

TEST(UavWorld, SameSeedSameBytesDifferentSeedDifferentImage) {
  const UavWorld a(SmallWorld(3)), b(SmallWorld(3)), c(SmallWorld(4));
  for (const double t : {0.5, 4.0}) {
    const cv::Mat fa = a.RenderFrame(t), fb = b.RenderFrame(t), fc = c.RenderFrame(t);
    ASSERT_EQ(fa.total() * fa.elemSize(), fb.total() * fb.elemSize());
    EXPECT_EQ(0, std::memcmp(fa.data, fb.data, fa.total() * fa.elemSize())) << "t=" << t;
    EXPECT_GT(cv::norm(fa, fc, cv::NORM_L1) / static_cast<double>(fa.total()), 10.0);
  }
  EXPECT_EQ(a.gps().At(3.0).latitude, b.gps().At(3.0).latitude);
}

TEST(UavWorld, DistortedFrameIsTheIdealFrameSeenThroughTheLens) {
  UavWorldOptions distorted = SmallWorld(3);
  distorted.camera.k1 = -0.15;
  distorted.camera.k2 = 0.05;
  distorted.render.noise_sigma = 0;
  distorted.render.moving_objects = false;
  UavWorldOptions ideal = distorted;
  ideal.camera.k1 = ideal.camera.k2 = 0;
  const UavWorld wd(distorted), wi(ideal);
  const double t = 4.0;
  const cv::Mat fd = wd.RenderFrame(t), fi = wi.RenderFrame(t);
  // Undistorting the distorted frame gives back the ideal frame.
  cv::Mat undistorted;
  cv::undistort(fd, undistorted, wd.camera().K(), wd.camera().DistortionCoeffs());
  cv::Mat gu, gi, diff;
  cv::cvtColor(undistorted, gu, cv::COLOR_BGR2GRAY);
  cv::cvtColor(fi, gi, cv::COLOR_BGR2GRAY);
  cv::absdiff(gu, gi, diff);
  const cv::Rect inner(100, 100, 1080, 520);
  const double err = cv::mean(diff(inner))[0];
  EXPECT_LT(err, 6.0);
  // ... and the distortion is real: the raw frames differ much more.
  cv::Mat gd;
  cv::cvtColor(fd, gd, cv::COLOR_BGR2GRAY);
  cv::absdiff(gd, gi, diff);
  EXPECT_GT(cv::mean(diff(inner))[0], 2 * err);
}

TEST(UavWorld, MovingObjectsMoveAndAreDrawn) {
  const UavWorld& world = DefaultWorld();
  const auto a = world.ObjectsAt(10.0), b = world.ObjectsAt(11.0);
  ASSERT_EQ(a.size(), static_cast<size_t>(world.options().objects.num_cars + world.options().objects.num_people));
  // The first car moves at roughly car_speed (0.6..1.4 times).
  const double moved = (a[0].corners[0] - b[0].corners[0]).norm();
  EXPECT_GT(moved, 0.3 * world.options().objects.car_speed);
  EXPECT_LT(moved, 1.6 * world.options().objects.car_speed);
  // Objects drawn: rendering without them changes pixels somewhere over the flight.
  UavWorldOptions no_objects;
  no_objects.render.moving_objects = false;
  const UavWorld plain(no_objects);
  int changed_frames = 0;
  for (double t = 0; t < 20; t += 2.0) {
    cv::Mat d;
    cv::absdiff(world.RenderFrame(t), plain.RenderFrame(t), d);
    if (cv::countNonZero(d.reshape(1)) > 100) ++changed_frames;
  }
  EXPECT_GT(changed_frames, 0);
}

TEST(UavWorld, UserOrthomapIsSeenAtItsMetresPerPixel) {
  // A 1000 x 1000 textured image at 5 cm/px centred on the world origin.
  cv::Mat image(1000, 1000, CV_8UC3);
  cv::RNG rng(42);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 2.0);
  const std::string path = ::testing::TempDir() + "/uav_user_map_" + std::to_string(getpid()) + ".png";
  ASSERT_TRUE(cv::imwrite(path, image));
  UavWorldOptions o;
  o.orthomap.image = path;
  o.orthomap.metres_per_pixel = 0.05;
  o.orthomap.centre = Eigen::Vector2d(0, 0);
  o.orthomap.detail_amplitude = 0;
  const UavWorld world(o);
  // Nadir at 50 m with image top to the north: one frame pixel = one map pixel (5 cm).
  const Pose3 world_from_camera =
      MakePose(RotationFromRollPitchYaw(0, 0, M_PI / 2), Eigen::Vector3d(0, 0, 50)) * UavBodyFromCamera();
  const cv::Mat frame = world.RenderGroundOnly(world_from_camera);
  // Frame pixel (u, v) sees map pixel (u - 140, v + 140) (centres 639.5/359.5 vs 499.5).
  const cv::Mat seen = frame(cv::Rect(140, 0, 1000, 720)), expected = image(cv::Rect(0, 140, 1000, 720));
  EXPECT_LE(cv::norm(seen, expected, cv::NORM_INF), 1.0);
  std::filesystem::remove(path);

  o.orthomap.image = "/nonexistent/map.png";
  try {
    UavWorld missing(o);
    FAIL() << "missing orthomap accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/map.png cannot be read"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vloc
