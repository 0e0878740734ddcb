// Equation 3 fits, the foreground filter of equation 2 and the height from
// known scale changes (zoom in and out) on synthetic nadir frames.
#include <gtest/gtest.h>

#include <cmath>

#include "synthetic_nadir.h"
#include "vloc/mosaic/frame_matcher.h"
#include "vloc/mosaic/geometry.h"

namespace vloc::mosaic {
namespace {

using testing::MakeGround;
using testing::NadirCamera;
using testing::RenderNadir;

TEST(MosaicGeometry, SimilarityAndAxisScaleFitsRecoverKnownTransform) {
  cv::RNG rng(11);
  const Similarity2 truth = Similarity2::FromScaleAngle(1.07, 0.2, 13.0, -7.0);
  std::vector<cv::Point2f> a, b;
  for (int i = 0; i < 400; ++i) {
    const cv::Point2d p(rng.uniform(0.0, 640.0), rng.uniform(0.0, 360.0));
    const cv::Point2d q = truth.Apply(p);
    a.emplace_back(p);
    b.emplace_back(q.x + rng.gaussian(0.3), q.y + rng.gaussian(0.3));
  }
  Similarity2 fit;
  double rms = 0;
  ASSERT_TRUE(FitSimilarity(a, b, &fit, &rms));
  // 400 points with 0.3 px noise over a 640 px spread: scale to ~1e-4.
  EXPECT_NEAR(fit.Scale(), 1.07, 5e-4);
  EXPECT_NEAR(fit.Angle(), 0.2, 5e-4);
  EXPECT_NEAR(rms, 0.3 * std::sqrt(2.0), 0.05);
  const Similarity2 round = fit * fit.Inverse();
  EXPECT_NEAR(round.a, 1.0, 1e-12);
  EXPECT_NEAR(round.tx, 0.0, 1e-9);
  // Eq. 3 as printed (no rotation) is exact for a pure zoom.
  std::vector<cv::Point2f> c;
  for (const auto& p : a) c.emplace_back(0.9 * p.x + 5, 0.9 * p.y - 3);
  const AxisScaleFit axis = FitAxisScale(a, c);
  ASSERT_TRUE(axis.ok);
  EXPECT_NEAR(axis.lambda_x, 0.9, 1e-6);
  EXPECT_NEAR(axis.lambda_y, 0.9, 1e-6);
  EXPECT_NEAR(axis.tau_x, 5, 1e-4);
}

TEST(MosaicForeground, Equation2RemovesPlantedMovingPoints) {
  cv::RNG rng(5);
  const cv::Matx33d H(1.05, -0.02, 12.0, 0.02, 1.05, -4.0, 0.0, 0.0, 1.0);
  std::vector<cv::Point2f> from, to;
  std::vector<bool> planted;
  for (int i = 0; i < 600; ++i) {
    const cv::Point2d p(rng.uniform(0.0, 1280.0), rng.uniform(0.0, 720.0));
    const cv::Vec3d h = H * cv::Vec3d(p.x, p.y, 1);
    cv::Point2d q(h[0] / h[2], h[1] / h[2]);
    const bool moving = i % 10 == 0;  // 60 points on "cars"
    if (moving) {
      // A car moving 8 m/s seen at 2 cm/px over 1/30 s: ~13 px, along its road (away from the motion).
      const cv::Point2d dir = q - p;
      q += 13.0 * dir / (cv::norm(dir) + 1e-9);
    } else {
      q += cv::Point2d(rng.gaussian(0.3), rng.gaussian(0.3));
    }
    from.emplace_back(p);
    to.emplace_back(q);
    planted.push_back(moving);
  }
  for (const std::string rule : {"eq2", "reprojection"}) {
    const std::vector<bool> fg = ForegroundFilter(from, to, H, 2.0, rule);
    int caught = 0, false_alarm = 0;
    for (size_t i = 0; i < fg.size(); ++i) {
      if (planted[i] && fg[i]) ++caught;
      if (!planted[i] && fg[i]) ++false_alarm;
    }
    EXPECT_EQ(caught, 60) << rule;
    // 0.3 px noise vs rho = 2 px: |e| >= 2 is > 6 sigma.
    EXPECT_EQ(false_alarm, 0) << rule;
  }
  // A mover displaced sideways (same distance travelled) escapes eq. 2 as printed but
  // not the reprojection rule.
  std::vector<cv::Point2f> f1 = {cv::Point2f(100, 100)};
  const cv::Vec3d h = H * cv::Vec3d(100, 100, 1);
  const cv::Point2d q(h[0] / h[2], h[1] / h[2]);
  const cv::Point2d d = q - cv::Point2d(100, 100);
  const double ang = 0.3;
  const cv::Point2d rotated(100 + d.x * std::cos(ang) - d.y * std::sin(ang), 100 + d.x * std::sin(ang) + d.y * std::cos(ang));
  std::vector<cv::Point2f> t1 = {cv::Point2f(rotated)};
  EXPECT_FALSE(ForegroundFilter(f1, t1, H, 2.0, "eq2")[0]);
  EXPECT_TRUE(ForegroundFilter(f1, t1, H, 2.0, "reprojection")[0]);
}

class MosaicHeight : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { ground_ = new testing::SyntheticGround(MakeGround(3000, 0.05, 7)); }
  static void TearDownTestSuite() { delete ground_; }
  static testing::SyntheticGround* ground_;
};
testing::SyntheticGround* MosaicHeight::ground_ = nullptr;

TEST_F(MosaicHeight, ScaleChangeGivesHeightForZoomInAndOut) {
  const NadirCamera cam;
  MatcherOptions options;
  const double h0 = 40.0;
  const cv::Mat f0 = RenderNadir(*ground_, cam, 0, 0, h0, 0.1, 2.0, 1);
  const FrameFeatures a = ExtractFeatures(f0, options);
  ASSERT_GT(a.points.size(), 150u);
  // Descend (zoom in) and climb (zoom out), with some drift and yaw.
  for (const double h1 : {34.0, 37.0, 43.0, 47.0}) {
    const cv::Mat f1 = RenderNadir(*ground_, cam, 1.5, -0.8, h1, 0.14, 2.0, 2);
    const FrameFeatures b = ExtractFeatures(f1, options);
    const MotionEstimate m = EstimateMotion(a, b, options);
    ASSERT_TRUE(m.ok) << m.why;
    const double lambda_true = h0 / h1;  // > 1 when descending
    EXPECT_NEAR(m.lambda, lambda_true, 0.003 * lambda_true) << "h1 " << h1;
    // Eqs. 4-5: h' = h / lambda.
    EXPECT_NEAR(h0 / m.lambda, h1, 0.004 * h1);
    EXPECT_NEAR(std::abs(m.similarity.Angle()), 0.04, 0.002);  // the yaw change
    EXPECT_GT(m.num_background, 50);
  }
}

TEST_F(MosaicHeight, ForegroundFilterRemovesMovingPatchesInImages) {
  const NadirCamera cam;
  MatcherOptions options;
  cv::Mat f0 = RenderNadir(*ground_, cam, 0, 0, 30, 0.0, 1.0, 3);
  cv::Mat f1 = RenderNadir(*ground_, cam, 0.6, 0.2, 29.0, 0.0, 1.0, 4);
  // Textured "cars": the same patch pasted at positions that move 25 px between frames.
  for (int i = 0; i < 6; ++i) {
    const cv::Mat car = ground_->image(cv::Rect(2000 + 100 * i, 2400, 80, 40)).clone();  // a different car each
    const cv::Point p0(20 + 100 * i, 40 + 90 * (i % 3));
    car.copyTo(f0(cv::Rect(p0, car.size())));
    car.copyTo(f1(cv::Rect(p0 + cv::Point(25, 12), car.size())));
  }
  const MotionEstimate m = EstimateMotion(ExtractFeatures(f0, options), ExtractFeatures(f1, options), options);
  ASSERT_TRUE(m.ok) << m.why;
  EXPECT_GT(m.num_foreground, 5);
  EXPECT_NEAR(m.lambda, 30.0 / 29.0, 0.003);
}

TEST_F(MosaicHeight, BlankFrameFailsWithReason) {
  MatcherOptions options;
  const NadirCamera cam;
  const FrameFeatures a = ExtractFeatures(RenderNadir(*ground_, cam, 0, 0, 30, 0.0), options);
  const FrameFeatures blank = ExtractFeatures(cv::Mat(cam.size, CV_8UC3, cv::Scalar::all(90)), options);
  const MotionEstimate m = EstimateMotion(a, blank, options);
  EXPECT_FALSE(m.ok);
  EXPECT_NE(m.why.find("features"), std::string::npos) << m.why;
}

}  // namespace
}  // namespace vloc::mosaic
