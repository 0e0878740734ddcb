// The whole pipeline on a short synthetic flight with known truth: height
// RMS error <= 2 % of the height, route error <= 1 % of the distance flown,
// no loss of track; GPS tie through a drop-out; LOST on blank/blurred frames
// and RECOVERED after; bounded canvas memory with identical content.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "synthetic_nadir.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {
namespace {

using testing::NadirCamera;
using testing::TruthPose;

// 15 s at 10 frames/s: east at 4 m/s with a turn north, height 30 -> 45 -> 33 m, yaw swinging.
TruthPose Truth(double t) {
  TruthPose p;
  p.east = 4.0 * t - 30.0;
  p.north = 0.08 * t * t - 20.0;
  p.height = 37.0 + 8.0 * std::sin(2 * M_PI * t / 15.0 - 0.9) + 0.0;
  p.yaw = 0.25 * std::sin(2 * M_PI * t / 20.0);
  return p;
}

MosaickerOptions TestOptions(const NadirCamera& cam, double h0) {
  MosaickerOptions o = testing::OptionsForCamera(cam, h0);
  o.canvas.metres_per_pixel = 0.12;
  o.geo.min_spread = 5.0;
  return o;
}

class MosaickerFlight : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { ground_ = new testing::SyntheticGround(testing::MakeGround(3200, 0.05, 21)); }
  static void TearDownTestSuite() { delete ground_; }
  static cv::Mat Frame(const NadirCamera& cam, double t, int seed) {
    const TruthPose p = Truth(t);
    return testing::RenderNadir(*ground_, cam, p.east, p.north, p.height, p.yaw, 2.0, seed);
  }
  static testing::SyntheticGround* ground_;
};
testing::SyntheticGround* MosaickerFlight::ground_ = nullptr;

TEST_F(MosaickerFlight, HeightAndRouteMeetTargetsWithoutGps) {
  const NadirCamera cam;
  const double fps = 10.0;
  const int n = 150;
  UavMosaicker m(TestOptions(cam, Truth(0).height));
  double se = 0, dist = 0, worst_route = 0;
  const TruthPose p0 = Truth(0);
  for (int i = 0; i < n; ++i) {
    const double t = i / fps;
    const FrameState s = m.ProcessFrame(Frame(cam, t, i + 1), static_cast<int64_t>(t * 1e6));
    ASSERT_TRUE(s.status == TrackStatus::kTracking) << "frame " << i << ": " << s.message;
    const TruthPose p = Truth(t);
    se += std::pow((s.height - p.height) / p.height, 2);
    if (i > 0) {
      const TruthPose q = Truth((i - 1) / fps);
      dist += std::hypot(p.east - q.east, p.north - q.north);
    }
    // The first frame's centre is the route origin and its image up is north (yaw 0 at t = 0).
    worst_route = std::max(worst_route, std::hypot(s.route_local.x - (p.east - p0.east), s.route_local.y - (p.north - p0.north)));
  }
  const double rms = std::sqrt(se / n);
  const MosaickerSummary summary = m.summary();
  RecordProperty("height_rms_percent", std::to_string(100 * rms));
  RecordProperty("route_error_percent", std::to_string(100 * worst_route / dist));
  std::cout << "height RMS " << 100 * rms << " %, worst route error " << worst_route << " m over " << dist
            << " m (" << 100 * worst_route / dist << " %); " << summary.BriefReport() << "\n";
  EXPECT_LT(rms, 0.02);
  EXPECT_LT(worst_route, 0.01 * dist);
  EXPECT_EQ(summary.lost, 0);
  EXPECT_GT(summary.blends, n / 4);
  const std::string png = ::testing::TempDir() + "/mosaic_test.png";
  std::string error;
  ASSERT_TRUE(m.WriteMosaic(png, &error)) << error;
  const cv::Mat written = cv::imread(png, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(written.channels(), 4);
  // The mosaic covers the flown strip: ~60 m east + a 50 m footprint at 0.12 m/px.
  EXPECT_GT(cv::countNonZero(written.reshape(4).reshape(1, written.total()).col(3)), 600 * 300);
  EXPECT_FALSE(std::filesystem::exists(::testing::TempDir() + "/mosaic_test.pgw"));  // no GPS: no world file
}

TEST_F(MosaickerFlight, GpsTieCarriesRouteThroughDropout) {
  const NadirCamera cam;
  const double fps = 10.0;
  const int n = 150;
  UavMosaicker m(TestOptions(cam, Truth(0).height));
  cv::RNG rng(3);
  const double lat0 = 45.0, lon0 = 9.0;
  const TruthPose p0 = Truth(0);
  double worst_dropout = 0, dist = 0;
  bool saw_unaided = false;
  for (int i = 0; i < n; ++i) {
    const double t = i / fps;
    const TruthPose p = Truth(t);
    const bool dropout = t >= 8.0 && t < 12.0;
    if (i % 2 == 0 && !dropout) {  // 5 Hz GPS, 1 m noise
      GpsFix fix;
      fix.utime = static_cast<int64_t>(t * 1e6);
      fix.valid = true;
      EnuToLatLon({p.east - p0.east + rng.gaussian(1.0), p.north - p0.north + rng.gaussian(1.0)}, lat0, lon0,
                  &fix.latitude, &fix.longitude);
      fix.height_above_ground = p.height + rng.gaussian(0.3);
      m.AddGps(fix);
    }
    const FrameState s = m.ProcessFrame(Frame(cam, t, i + 1), static_cast<int64_t>(t * 1e6));
    ASSERT_EQ(s.status, TrackStatus::kTracking) << s.message;
    if (i > 0) dist += std::hypot(p.east - Truth((i - 1) / fps).east, p.north - Truth((i - 1) / fps).north);
    if (dropout && s.georeferenced) {
      saw_unaided = saw_unaided || !s.gps_aided;
      worst_dropout = std::max(worst_dropout, std::hypot(s.route_local.x - (p.east - p0.east), s.route_local.y - (p.north - p0.north)));
      EXPECT_TRUE(std::isfinite(s.latitude));
    }
  }
  EXPECT_TRUE(saw_unaided);
  std::cout << "worst route error in the drop-out " << worst_dropout << " m of " << dist << " m flown\n";
  EXPECT_LT(worst_dropout, 0.01 * dist + 0.5);  // 0.5 m: GPS noise left in the tie (1 m / sqrt(~40 fixes) x 3)
  EXPECT_TRUE(m.summary().georeferenced);
  const std::string png = ::testing::TempDir() + "/mosaic_geo.png";
  std::string error;
  ASSERT_TRUE(m.WriteMosaic(png, &error)) << error;
  std::ifstream pgw(::testing::TempDir() + "/mosaic_geo.pgw");
  double v[6];
  for (double& x : v) ASSERT_TRUE(pgw >> x);
  EXPECT_NEAR(v[4], lon0, 0.01);
  EXPECT_NEAR(v[5], lat0, 0.01);
}

TEST_F(MosaickerFlight, BlankAndBlurredFramesGiveLostThenRecovered) {
  const NadirCamera cam;
  const double fps = 10.0;
  UavMosaicker m(TestOptions(cam, Truth(0).height));
  std::vector<TrackStatus> statuses;
  FrameState before;
  for (int i = 0; i < 40; ++i) {
    const double t = i / fps;
    cv::Mat frame = Frame(cam, t, i + 1);
    if (i == 20) frame = cv::Mat(cam.size, CV_8UC3, cv::Scalar(70, 90, 80));        // featureless field
    if (i == 21) cv::GaussianBlur(frame, frame, cv::Size(0, 0), 25.0);               // motion-blurred
    if (i == 22) frame = cv::Mat();                                                   // dropped frame
    const FrameState s = m.ProcessFrame(frame, static_cast<int64_t>(t * 1e6));
    statuses.push_back(s.status);
    if (i == 19) before = s;
    if (i >= 20 && i <= 22) {
      EXPECT_EQ(s.status, TrackStatus::kLost) << "frame " << i;
      EXPECT_FALSE(s.message.empty());
      EXPECT_DOUBLE_EQ(s.height, before.height);  // last good state kept
      EXPECT_DOUBLE_EQ(s.route_px.x, before.route_px.x);
    }
    if (i == 23) EXPECT_EQ(s.status, TrackStatus::kRecovered) << s.message;
    if (i > 23) EXPECT_EQ(s.status, TrackStatus::kTracking) << "frame " << i << ": " << s.message;
    if (i == 39) EXPECT_NEAR(s.height, Truth(t).height, 0.02 * Truth(t).height);
  }
  EXPECT_EQ(m.summary().lost, 1);
  EXPECT_EQ(m.summary().recoveries, 1);
}

TEST_F(MosaickerFlight, RecoversAgainstTheMosaicAfterMovingWhileLost) {
  const NadirCamera cam;
  const double fps = 10.0;
  MosaickerOptions o = TestOptions(cam, Truth(0).height);
  o.mosaic_every_n_frames = 1;
  UavMosaicker m(o);
  // Fly 3 s, lose 1.5 s (blank frames), then come back above already-mapped ground
  // but far from the keyframe: the UAV flies back west over mapped ground.
  int recovered_at = -1;
  for (int i = 0; i < 60; ++i) {
    const double t = i < 30 ? i / fps : (60 - i) / fps * 0.9;  // back along the track after frame 30
    cv::Mat frame = (i >= 30 && i < 45) ? cv::Mat(cam.size, CV_8UC3, cv::Scalar::all(60)) : Frame(cam, t, i + 1);
    const FrameState s = m.ProcessFrame(frame, static_cast<int64_t>(i / fps * 1e6));
    if (i >= 30 && i < 45) EXPECT_EQ(s.status, TrackStatus::kLost);
    if (s.status == TrackStatus::kRecovered && recovered_at < 0) {
      recovered_at = i;
      const TruthPose p = Truth(t), p0 = Truth(0);
      EXPECT_NEAR(s.route_local.x, p.east - p0.east, 1.0) << s.message;
      EXPECT_NEAR(s.route_local.y, p.north - p0.north, 1.0);
    }
  }
  EXPECT_EQ(recovered_at, 45);
}

TEST_F(MosaickerFlight, CanvasMemoryIsBoundedAndSpillsLoseNothing) {
  const NadirCamera cam;
  MosaickerOptions bounded = TestOptions(cam, Truth(0).height);
  bounded.canvas.tile_size = 128;
  bounded.canvas.max_tiles_in_memory = 16;
  MosaickerOptions unbounded = bounded;
  unbounded.canvas.max_tiles_in_memory = 100000;
  UavMosaicker a(bounded), b(unbounded);
  for (int i = 0; i < 60; ++i) {
    const double t = i / 4.0;  // 4 frames/s over the whole 15 s path
    const cv::Mat frame = Frame(cam, t, i + 1);
    a.ProcessFrame(frame, static_cast<int64_t>(t * 1e6));
    b.ProcessFrame(frame, static_cast<int64_t>(t * 1e6));
  }
  const CanvasStats sa = a.summary().canvas;
  EXPECT_GT(sa.spills, 0);
  EXPECT_GT(sa.tiles_total, 20);  // more tiles than the budget
  // A region read/write may hold one extra row of tiles before eviction.
  EXPECT_LE(sa.peak_tiles_in_memory, 16 + 8);
  EXPECT_LE(sa.tiles_in_memory, 16);
  std::string e1, e2;
  const std::string pa = ::testing::TempDir() + "/bounded.png", pb = ::testing::TempDir() + "/unbounded.png";
  ASSERT_TRUE(a.WriteMosaic(pa, &e1)) << e1;
  ASSERT_TRUE(b.WriteMosaic(pb, &e2)) << e2;
  const cv::Mat ia = cv::imread(pa, cv::IMREAD_UNCHANGED), ib = cv::imread(pb, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(ia.size(), ib.size());
  EXPECT_EQ(cv::norm(ia, ib, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace vloc::mosaic

namespace vloc::mosaic {
namespace {

TEST_F(MosaickerFlight, AsyncMosaicTracksIdenticallyAndBuildsTheMosaic) {
  const NadirCamera cam;
  MosaickerOptions sync_options = TestOptions(cam, Truth(0).height);
  MosaickerOptions async_options = sync_options;
  async_options.async_mosaic = true;
  UavMosaicker a(sync_options), b(async_options);
  for (int i = 0; i < 40; ++i) {
    const double t = i / 10.0;
    const cv::Mat frame = Frame(cam, t, i + 1);
    const FrameState sa = a.ProcessFrame(frame, static_cast<int64_t>(t * 1e6));
    const FrameState sb = b.ProcessFrame(frame, static_cast<int64_t>(t * 1e6));
    ASSERT_EQ(sb.status, TrackStatus::kTracking) << sb.message;
    EXPECT_DOUBLE_EQ(sa.height, sb.height);  // tracking does not depend on the canvas
    EXPECT_DOUBLE_EQ(sa.route_px.x, sb.route_px.x);
  }
  std::string error;
  const std::string png = ::testing::TempDir() + "/async.png";
  ASSERT_TRUE(b.WriteMosaic(png, &error)) << error;  // waits for the queued blend
  EXPECT_GT(b.summary().blends, 3);
  EXPECT_LE(b.summary().blends, a.summary().blends);
  EXPECT_FALSE(cv::imread(png, cv::IMREAD_UNCHANGED).empty());
}

}  // namespace
}  // namespace vloc::mosaic

namespace vloc::mosaic {
namespace {

// Frames with strong barrel distortion: undistorted with the configured
// camera, the height stays within 1 %; ignoring the distortion costs more.
TEST_F(MosaickerFlight, DistortedFramesAreCorrectedWithTheCameraModel) {
  const NadirCamera cam;
  MosaickerOptions o = TestOptions(cam, Truth(0).height);
  o.camera.k1 = -0.12;
  o.camera.k2 = 0.03;
  // Distorted pixel -> ideal pixel map, to render what a distorting lens sees.
  std::vector<cv::Point2f> grid, ideal;
  for (int v = 0; v < cam.size.height; ++v)
    for (int u = 0; u < cam.size.width; ++u) grid.emplace_back(static_cast<float>(u), static_cast<float>(v));
  cv::undistortPoints(grid, ideal, cv::Mat(o.camera.K()), o.camera.DistortionCoeffs(), cv::noArray(), cv::Mat(o.camera.K()));
  cv::Mat map(cam.size, CV_32FC2, ideal.data());
  map = map.clone();
  MosaickerOptions ignoring = o;
  ignoring.camera.k1 = ignoring.camera.k2 = 0.0;
  UavMosaicker corrected(o), uncorrected(ignoring);
  double worst_corrected = 0, worst_uncorrected = 0;
  for (int i = 0; i < 50; ++i) {
    const double t = i / 10.0;
    cv::Mat distorted;
    cv::remap(Frame(cam, t, i + 1), distorted, map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    const FrameState a = corrected.ProcessFrame(distorted, static_cast<int64_t>(t * 1e6));
    const FrameState b = uncorrected.ProcessFrame(distorted, static_cast<int64_t>(t * 1e6));
    ASSERT_EQ(a.status, TrackStatus::kTracking) << a.message;
    const double h = Truth(t).height;
    worst_corrected = std::max(worst_corrected, std::abs(a.height - h) / h);
    if (b.status == TrackStatus::kTracking) worst_uncorrected = std::max(worst_uncorrected, std::abs(b.height - h) / h);
  }
  std::cout << "worst height error with the distortion model " << 100 * worst_corrected << " %, without "
            << 100 * worst_uncorrected << " %\n";
  EXPECT_LT(worst_corrected, 0.01);
  EXPECT_GT(worst_uncorrected, worst_corrected);
}

}  // namespace
}  // namespace vloc::mosaic
