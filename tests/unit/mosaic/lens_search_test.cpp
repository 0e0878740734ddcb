// The lens's k1 found from height ties alone (lens_search.h): two strips of
// tilted nadir photos over flat ground, seen through a barrel lens; the
// links along each strip and the ties across are measured on raw (distorted)
// pixels, as a run with an uncalibrated camera measures them.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "vloc/mosaic/lens_search.h"

namespace vloc::mosaic {
namespace {

struct View {
  cv::Matx33d camera_from_world;
  cv::Vec3d centre;
};

PinholeCamera Compact(double k1) {
  PinholeCamera c;
  c.width = 960, c.height = 720, c.fx = c.fy = 670, c.cx = 479.5, c.cy = 359.5, c.k1 = k1;
  return c;
}

cv::Matx33d Rotation(double ax, double ay) {
  cv::Matx33d rx(1, 0, 0, 0, std::cos(ax), -std::sin(ax), 0, std::sin(ax), std::cos(ax));
  cv::Matx33d ry(std::cos(ay), 0, std::sin(ay), 0, 1, 0, -std::sin(ay), 0, std::cos(ay));
  return rx * ry;
}

// Looking down (camera z = world -z), tilted by a few degrees.
View Looking(double x, double y, double h, double ax, double ay) {
  return View{Rotation(ax, ay) * cv::Matx33d(1, 0, 0, 0, -1, 0, 0, 0, -1), cv::Vec3d(x, y, h)};
}

// Ground points (z = 0) on a grid seen by both views, as raw pixels of `lens`, with noise.
HeightObservation Pair(int from, int to, const std::vector<View>& views, const PinholeCamera& lens, std::mt19937* rng,
                       double noise_px) {
  std::normal_distribution<double> noise(0.0, noise_px);
  HeightObservation o;
  o.from = from, o.to = to, o.support = 100;
  const View& a = views[from];
  const View& b = views[to];
  o.from_normal = a.camera_from_world * cv::Vec3d(0, 0, -1);
  const cv::Vec3d mid = 0.5 * (a.centre + b.centre);
  for (double gx = mid[0] - 60; gx <= mid[0] + 60; gx += 4) {
    for (double gy = mid[1] - 60; gy <= mid[1] + 60; gy += 4) {
      std::optional<Eigen::Vector2d> pa, pb;
      for (const View* v : {&a, &b}) {
        const cv::Vec3d pc = v->camera_from_world * (cv::Vec3d(gx, gy, 0) - v->centre);
        std::optional<Eigen::Vector2d> raw = lens.Project(Eigen::Vector3d(pc[0], pc[1], pc[2]));
        if (raw && !lens.InImage(*raw, 5)) raw.reset();
        (v == &a ? pa : pb) = raw;
      }
      if (!pa || !pb) continue;
      o.from_px.emplace_back(static_cast<float>(pa->x() + noise(*rng)), static_cast<float>(pa->y() + noise(*rng)));
      o.to_px.emplace_back(static_cast<float>(pb->x() + noise(*rng)), static_cast<float>(pb->y() + noise(*rng)));
    }
  }
  return o;
}

// Two strips of 8 photos 30 m apart, 55 m between the strips, heights 58-72 m, tilts up to 4 degrees; links along
// each strip and a tie from each photo of the second strip to the first strip's photo beside it.
HeightObservations TwoStrips(const PinholeCamera& lens, double noise_px, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> height(58, 72), tilt(-0.07, 0.07);
  std::vector<View> views;
  for (int strip = 0; strip < 2; ++strip)
    for (int i = 0; i < 8; ++i) views.push_back(Looking(30.0 * i, 55.0 * strip, height(rng), tilt(rng), tilt(rng)));
  HeightObservations obs;
  for (size_t i = 0; i < views.size(); ++i) obs.frames.emplace_back(static_cast<int>(i), 0.0);
  for (int strip = 0; strip < 2; ++strip)
    for (int i = 0; i + 1 < 8; ++i) obs.pairs.push_back(Pair(8 * strip + i, 8 * strip + i + 1, views, lens, &rng, noise_px));
  for (int i = 0; i < 8; ++i) obs.pairs.push_back(Pair(i, 8 + i, views, lens, &rng, noise_px));
  return obs;
}

TEST(LensSearch, FindsTheBarrelFromTheTiesAlone) {
  const PinholeCamera lens = Compact(-0.04), uncalibrated = Compact(0.0);
  HeightGraphOptions graph;
  LensSearchOptions options;
  options.min_ties = 10;
  for (uint32_t seed : {1u, 2u, 3u}) {
    const LensSearch s = SearchRadialDistortion(TwoStrips(lens, 0.3, seed), uncalibrated, graph, options);
    ASSERT_TRUE(s.ok) << s.why;
    EXPECT_GE(s.pairs, 20);  // of 22 (a pair some candidate cannot decompose is left out)
    EXPECT_NEAR(s.k1, -0.04, 0.01) << "seed " << seed;
    EXPECT_LT(s.residual, 0.5 * s.residual_as_run) << "seed " << seed;
    EXPECT_EQ(s.curve.size(), 25u);
  }
}

TEST(LensSearch, APinholeLensStaysAPinhole) {
  const PinholeCamera pinhole = Compact(0.0);
  LensSearchOptions options;
  options.min_ties = 10;
  const LensSearch s = SearchRadialDistortion(TwoStrips(pinhole, 0.3, 7), pinhole, HeightGraphOptions(), options);
  ASSERT_TRUE(s.ok) << s.why;
  EXPECT_NEAR(s.k1, 0.0, 0.01);
}

// Points a calibrated run undistorted are taken back to raw pixels first: the same k1 is found.
TEST(LensSearch, ARunWithADistortedCameraIsSearchedFromItsRawPixels) {
  const PinholeCamera lens = Compact(-0.04), run = Compact(0.03);
  HeightObservations obs = TwoStrips(lens, 0.0, 5);
  for (HeightObservation& o : obs.pairs)
    for (auto* points : {&o.from_px, &o.to_px})
      for (cv::Point2f& p : *points) {
        const Eigen::Vector2d ideal = run.Undistort(Eigen::Vector2d(p.x, p.y));
        p = cv::Point2f(static_cast<float>(ideal.x()), static_cast<float>(ideal.y()));
      }
  LensSearchOptions options;
  options.min_ties = 10;
  const LensSearch s = SearchRadialDistortion(obs, run, HeightGraphOptions(), options);
  ASSERT_TRUE(s.ok) << s.why;
  EXPECT_NEAR(s.k1, -0.04, 0.005);
}

TEST(LensSearch, TooFewTiesSayHowMany) {
  const PinholeCamera pinhole = Compact(0.0);
  HeightObservations obs = TwoStrips(pinhole, 0.3, 9);
  obs.pairs.resize(5);
  const LensSearch s = SearchRadialDistortion(obs, pinhole, HeightGraphOptions());
  EXPECT_FALSE(s.ok);
  EXPECT_NE(s.why.find("5 photo pairs"), std::string::npos) << s.why;
}

}  // namespace
}  // namespace vloc::mosaic
