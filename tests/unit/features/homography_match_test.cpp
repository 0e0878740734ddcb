// Homography without a prior (vloc::MatchHomography): a synthetic plane
// seen from far apart (always), and Oxford's Graffiti 1 -> 3 from Debian's
// opencv-doc with its ground-truth homography (skipped when absent). Also
// the keypoint localisation of ASIFT's simulated views.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "real_pairs.h"
#include "test_images.h"
#include "vloc/features/asift.h"
#include "vloc/features/homography_match.h"

namespace vloc {
namespace {

cv::Mat ToU8(const cv::Mat& f) {
  cv::Mat out;
  f.convertTo(out, CV_8U);
  return out;
}

TEST(HomographyMatch, DefaultOptionsPassCheck) {
  std::string error;
  EXPECT_TRUE(HomographyMatchOptions().Check(&error)) << error;
  HomographyMatchOptions bad;
  bad.coarse_scale = 0;
  EXPECT_FALSE(bad.Check(&error));
}

// A keypoint found in a simulated tilt-2 view must land where the same
// blob is in an image rendered compressed by 2 along x: the mapping back
// from the view has to follow cv::resize's pixel-centre convention
// (before the fix, keypoints sat 0.5 px off along the tilt).
TEST(HomographyMatch, TiltedViewKeypointsMapBackWithoutOffset) {
  const testing::BlobTexture tex(640, 240, 640 * 240 / 18, 3, 2.5, 6.0);
  const cv::Mat full = ToU8(tex.Render(640, 240, [](int x, int y) { return std::make_pair<double, double>(x, y); }));
  // Pixel u of the compressed image covers full-image pixels 2u and 2u + 1.
  cv::Mat blurred;
  cv::GaussianBlur(tex.Render(640, 240, [](int x, int y) { return std::make_pair<double, double>(x, y); }), blurred,
                   cv::Size(0, 0), 0.8 * std::sqrt(3.0), 0.01);
  cv::Mat half;
  cv::resize(blurred, half, cv::Size(320, 240), 0, 0, cv::INTER_LINEAR);
  AsiftOptions o;
  const FeatureSet tilted = DetectAsift(full, cv::Mat(), {{2.0, 0.0}}, o);
  const FeatureSet plain = DetectAsift(ToU8(half), cv::Mat(), {{1.0, 0.0}}, o);
  std::vector<double> dx;
  for (size_t i = 0; i < tilted.size(); ++i) {
    double best = 1e9, off = 0;
    for (size_t j = 0; j < plain.size(); ++j) {
      const double ux = 2 * plain.points[j].x() + 0.5, uy = plain.points[j].y();
      const double e = std::hypot(tilted.points[i].x() - ux, tilted.points[i].y() - uy);
      if (e < best) best = e, off = tilted.points[i].x() - ux;
    }
    if (best < 0.5 * 2) dx.push_back(off);
  }
  ASSERT_GT(dx.size(), 50u);
  std::nth_element(dx.begin(), dx.begin() + dx.size() / 2, dx.end());
  EXPECT_LT(std::abs(dx[dx.size() / 2]), 0.1) << "median x offset of tilted-view keypoints, px";
}

// A textured plane seen from two viewpoints about 50 degrees apart
// (foreshortening 1.7 across, perspective), rendered exactly: the
// homography must be right to 0.1 px at the corners.
TEST(HomographyMatch, SyntheticPlaneToATenthOfAPixel) {
  const testing::BlobTexture tex(700, 560, 700 * 560 / 18, 9, 1.5, 4.0);
  const cv::Matx33d b_from_a(0.62, -0.18, 150, 0.22, 0.95, -40, 2.4e-4, -6e-5, 1.0);
  const cv::Matx33d a_from_b = b_from_a.inv();
  const cv::Mat a = ToU8(tex.Render(640, 480, [](int x, int y) { return std::make_pair<double, double>(x, y); }));
  const cv::Mat b = ToU8(tex.Render(640, 480, [&](int x, int y) {
    const cv::Vec3d p = a_from_b * cv::Vec3d(x, y, 1);
    return std::make_pair(p[0] / p[2], p[1] / p[2]);
  }));
  HomographyMatchOptions o;
  const HomographyMatchResult r = MatchHomography(a, b, o);
  ASSERT_TRUE(r.summary.usable) << r.summary.BriefReport();
  double mean, worst;
  testing::CornerErrors(r.b_from_a, b_from_a, a.size(), &mean, &worst);
  EXPECT_LT(worst, 0.1) << r.summary.BriefReport();
  EXPECT_GT(r.summary.refine_inliers, 500);
  EXPECT_LT(r.summary.rms_px, 0.1);
}

// Graffiti 1 -> 3 (a wall, about 40 degrees apart), no prior: sub-pixel at
// the corners against the published homography. The wall departs from one
// homography by about 0.5 px RMS, which bounds what any fit can reach.
TEST(HomographyMatch, GraffitiSubPixelAtTheCorners) {
  const testing::GrafPair g = testing::LoadGraf();
  if (!g.ok) GTEST_SKIP() << "missing " << g.missing << ": apt-get install opencv-doc";
  HomographyMatchOptions o;
  const HomographyMatchResult r = MatchHomography(g.a, g.b, o);
  ASSERT_TRUE(r.summary.usable) << r.summary.BriefReport();
  double mean, worst;
  testing::CornerErrors(r.b_from_a, g.b_from_a, g.a.size(), &mean, &worst);
  std::cout << r.summary.BriefReport() << "\ncorner error mean " << mean << " max " << worst << " px\n";
  EXPECT_LT(mean, 0.8);
  EXPECT_LT(worst, 1.0);
  EXPECT_GT(r.summary.refine_inliers, 1000);
}

}  // namespace
}  // namespace vloc
