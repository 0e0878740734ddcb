// The mosaicker's parts that are not registration: the GPS tie and its
// predictions (gps_tie.h), the asynchronous blender (mosaic_blender.h) and
// the calibration step (calibration_step.h).
#include <gtest/gtest.h>

#include <cmath>

#include "synthetic_nadir.h"
#include "vloc/mosaic/calibration_step.h"
#include "vloc/mosaic/gps_tie.h"
#include "vloc/mosaic/mosaic_blender.h"

namespace vloc::mosaic {
namespace {

// A straight flight east at 5 m/s, one frame and one fix every 0.5 s; the
// mosaic is 0.1 m/px and rotated 30 degrees from ENU, GPS noise +-0.2 m.
struct Flight {
  double mpp = 0.1, rot = M_PI / 6;
  cv::Point2d MosaicOf(const cv::Point2d& enu) const {  // mosaic px of an ENU point (y down)
    const cv::Point2d r(std::cos(rot) * enu.x - std::sin(rot) * enu.y, std::sin(rot) * enu.x + std::cos(rot) * enu.y);
    return {r.x / mpp, -r.y / mpp};
  }
  static cv::Point2d Enu(int i) { return {2.5 * i, 0.0}; }
  static GpsFix Fix(int i, double noise) {
    GpsFix f;
    f.utime = i * 500000;
    f.valid = true;
    f.horizontal_sigma = 0.5;
    EnuToLatLon(Enu(i) + cv::Point2d(noise, -noise), 45.0, 7.0, &f.latitude, &f.longitude);
    return f;
  }
};

// Frames [first, last) registered on the true route, each with its fix.
void Fly(const Flight& flight, int first, int last, double noise, GpsTie* tie) {
  for (int i = first; i < last; ++i) {
    tie->AddFix(Flight::Fix(i, noise * ((i % 3) - 1)));
    tie->AddRoutePoint(i * 500000, flight.MosaicOf(Flight::Enu(i)));
    tie->PairPendingFixes();
  }
}

GeoOptions TestGeo() {
  GeoOptions o;
  o.min_fixes = 5;
  o.min_spread = 5.0;
  return o;
}

TEST(GpsTie, TiesAfterEnoughSpreadAndMapsTheRouteBackToEnu) {
  GpsTie tie(TestGeo());
  const Flight flight;
  EXPECT_FALSE(tie.AddFix(GpsFix()));  // no horizontal fix
  Fly(flight, 0, 4, 0.2, &tie);
  EXPECT_FALSE(tie.tied());  // 4 fixes over 7.5 m
  Fly(flight, 4, 12, 0.2, &tie);
  ASSERT_TRUE(tie.tied());
  EXPECT_EQ(tie.tie_pairs(), 12);
  EXPECT_LT(tie.tie_rms(), 0.3);
  const cv::Point2d enu = tie.MosaicToLocal(flight.MosaicOf({20, 7}), 0);
  EXPECT_NEAR(enu.x, 20, 0.3);
  EXPECT_NEAR(enu.y, 7, 0.3);
  const std::optional<double> course = tie.GpsCourseAt(11 * 500000);
  ASSERT_TRUE(course.has_value());
  EXPECT_NEAR(*course, 0.0, 0.2);  // east
}

TEST(GpsTie, PredictsFromTheGpsWhenTiedElseFromConstantMotion) {
  GpsTie tie(TestGeo());
  const Flight flight;
  const cv::Point2d c(319.5, 179.5);
  const double s = 0.5;  // mosaic px per frame px
  auto pose_at = [&](int i) {
    const cv::Point2d at = flight.MosaicOf(Flight::Enu(i));
    return Similarity2{s, 0, at.x - s * c.x, at.y - s * c.y};
  };
  LastPoses poses{pose_at(1), pose_at(0), std::nullopt};
  // Not tied: the last frame-to-frame motion once more.
  std::optional<Prediction> p = tie.Predict(2 * 500000, cv::Size(640, 360), c, poses, PredictionGates{});
  ASSERT_TRUE(p.has_value());
  EXPECT_FALSE(p->from_gps);
  EXPECT_LT(cv::norm(p->mosaic_from_frame.Apply(c) - pose_at(2).Apply(c)), 1e-6);
  poses.prev_good.reset();
  EXPECT_FALSE(tie.Predict(2 * 500000, cv::Size(640, 360), c, poses, PredictionGates{}).has_value());
  Fly(flight, 0, 10, 0.0, &tie);
  tie.AddFix(Flight::Fix(10, 0));
  // Tied: where the GPS puts frame 10, from the last registered frame (9).
  poses = LastPoses{pose_at(9), pose_at(8), tie.GpsEnuAt(9 * 500000)};
  p = tie.Predict(10 * 500000, cv::Size(640, 360), c, poses, PredictionGates{});
  ASSERT_TRUE(p.has_value());
  EXPECT_TRUE(p->from_gps);
  EXPECT_LT(cv::norm(p->gps_px - flight.MosaicOf(Flight::Enu(10))), 1.0);
  EXPECT_GT(p->gate_px, 0.12 * 640);
}

TEST(MosaicBlender, AsynchronousBlendingGivesTheSameCanvasAsSynchronous) {
  const auto ground = testing::MakeGround(1200, 0.05, 3);
  const testing::NadirCamera cam;
  CanvasOptions co;
  MosaicBlender sync(co, false), async(co, true);
  EXPECT_FALSE(sync.Blend(cv::Mat(cam.size, CV_8UC3), Similarity2{}).done);  // not started
  sync.Start();
  async.Start();
  for (int i = 0; i < 4; ++i) {
    const cv::Mat frame = testing::RenderNadir(ground, cam, 2.0 * i, 0, 30, 0);
    const Similarity2 S{0.5, 0, 40.0 * i, 0};
    EXPECT_TRUE(sync.Blend(frame, S).done);
    EXPECT_TRUE(async.Blend(frame, S).done);
    async.Flush();  // one job at a time: a queued job would be replaced
  }
  cv::Mat a, b;
  double sa = 0, sb = 0;
  cv::Point2d oa, ob;
  ASSERT_TRUE(sync.Export(&a, &sa, &oa, nullptr));
  ASSERT_TRUE(async.Export(&b, &sb, &ob, nullptr));
  EXPECT_EQ(sync.blends(), 4);
  EXPECT_EQ(async.blends(), 4);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
}

TEST(MosaicBlender, AQueueDropsNothingAndRendersAfterTheQueuedBlends) {
  const auto ground = testing::MakeGround(1200, 0.05, 4);
  const testing::NadirCamera cam;
  CanvasOptions co;
  MosaicBlender sync(co, false), queued(co, true, 2);
  sync.Start();
  queued.Start();
  cv::Mat view_sync, view_queued, mask;
  for (int i = 0; i < 6; ++i) {
    const cv::Mat frame = testing::RenderNadir(ground, cam, 2.0 * i, 0, 30, 0);
    const Similarity2 S{0.5, 0, 30.0 * i, 0};
    EXPECT_TRUE(sync.Blend(frame, S).done);
    EXPECT_TRUE(queued.Blend(frame, S).done);  // no Flush: up to 2 wait
  }
  const Similarity2 view{0.5, 0, 60, 0};
  EXPECT_EQ(sync.Render(view, cam.size, &view_sync, &mask), queued.Render(view, cam.size, &view_queued, &mask));
  EXPECT_EQ(cv::norm(view_sync, view_queued, cv::NORM_INF), 0.0);
  queued.Flush();
  EXPECT_EQ(queued.blends(), 6);
  EXPECT_GT(queued.seconds(), 0.0);
}

TEST(CalibrationStep, ConfigAtOnceGpsWhenAHeightArrives) {
  CalibrationOptions co;
  co.source = "config";
  co.height = 40;
  std::string why;
  const Calibration c = CalibrationStep(co).Try(cv::Mat(), 500, std::nan(""), &why);
  ASSERT_TRUE(c.valid);
  EXPECT_DOUBLE_EQ(c.pixels_per_metre, 500.0 / 40);
  co.source = "gps";
  CalibrationStep gps(co);
  EXPECT_FALSE(gps.Try(cv::Mat(), 500, std::nan(""), &why).valid);
  EXPECT_NE(why.find("waiting for a GPS fix"), std::string::npos);
  const Calibration g = gps.Try(cv::Mat(), 500, 25, &why);
  ASSERT_TRUE(g.valid);
  EXPECT_DOUBLE_EQ(g.height, 25);
}

}  // namespace
}  // namespace vloc::mosaic
