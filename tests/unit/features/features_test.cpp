// Known-answer tests of the matching building blocks on synthetic images.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

#include "test_images.h"
#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "vloc/common/options.h"
#include "vloc/common/pose.h"
#include "vloc/features/asift.h"
#include "vloc/features/consistency.h"
#include "vloc/features/lsm.h"
#include "vloc/features/stereo_match.h"
#include "vloc/features/template_ncc.h"
#include "vloc/features/tile_registration.h"
#include "vloc/features/wallis.h"

namespace vloc {
namespace {

using testing::TexturedImage;

TEST(Wallis, DefaultOptionsPassCheck) {
  std::string error;
  EXPECT_TRUE(WallisOptions().Check(&error)) << error;
  EXPECT_TRUE(ZnccOptions().Check(&error)) << error;
  EXPECT_TRUE(MedianFilterOptions().Check(&error)) << error;
  EXPECT_TRUE(LsmOptions().Check(&error)) << error;
  EXPECT_TRUE(ConsistencyOptions().Check(&error)) << error;
  EXPECT_TRUE(AsiftOptions().Check(&error)) << error;
  EXPECT_TRUE(GatedMatchOptions().Check(&error)) << error;
}

TEST(Wallis, LocalMeanAndStdHitTheTargets) {
  // Four quadrants of the same texture with very different gain and offset.
  cv::Mat tex = TexturedImage(256, 256, 7, 1.0, 10.0);
  cv::Mat img(256, 256, CV_8UC1);
  const double gains[4] = {0.4, 1.0, 2.0, 3.0}, offsets[4] = {40, 150, 60, 100};
  for (int q = 0; q < 4; ++q) {
    const cv::Rect r((q % 2) * 128, (q / 2) * 128, 128, 128);
    cv::Mat f;
    tex(r).convertTo(f, CV_32F);
    f = (f - 128) * gains[q] + offsets[q];
    f.convertTo(img(r), CV_8U);
  }
  WallisOptions o;
  o.window = 31;
  o.target_mean = 127;
  o.target_std = 40;
  o.contrast = 1.0;
  o.brightness = 1.0;
  const cv::Mat out = WallisFilter(img, o);
  for (int q = 0; q < 4; ++q) {
    // Interior of each quadrant (away from the quadrant borders by a window).
    const cv::Rect r((q % 2) * 128 + 24, (q / 2) * 128 + 24, 80, 80);
    const ImageStats before = ComputeImageStats(img(r));
    const ImageStats after = ComputeImageStats(out(r));
    EXPECT_NEAR(after.mean, 127.0, 3.0) << "quadrant " << q << " before mean " << before.mean;
    // The window std varies about the quadrant std by sampling: within 10 %.
    EXPECT_NEAR(after.std, 40.0, 4.0) << "quadrant " << q << " before std " << before.std;
  }
}

TEST(Wallis, PartialContrastMovesStdTowardsTarget) {
  cv::Mat img = TexturedImage(200, 200, 3, 1.0, 8.0);
  WallisOptions o;
  o.target_std = 40;
  o.contrast = 0.75;
  o.brightness = 1.0;
  const ImageStats after = ComputeImageStats(WallisFilter(img, o)(cv::Rect(30, 30, 140, 140)));
  // r1 = c sf / (c sg + (1 - c) sf) with sg ~ 8: std between 8 and 40.
  const double expected = 0.75 * 40 / (0.75 * 8 + 0.25 * 40) * 8;
  EXPECT_NEAR(after.std, expected, 0.15 * expected);
  EXPECT_GT(after.std, 12.0);
}

TEST(Wallis, RejectsBadOptions) {
  WallisOptions o;
  o.window = 10;
  std::string error;
  EXPECT_FALSE(o.Check(&error));
  EXPECT_NE(error.find("window"), std::string::npos);
}

// Right image = left shifted by `disparity` px to the left (rectified pair).
void MakeShiftedPair(double disparity, cv::Mat* left, cv::Mat* right, uint64_t seed = 11) {
  const cv::Mat base = TexturedImage(400, 200, seed);
  base.convertTo(*left, CV_32F);
  const cv::Matx23d shift(1, 0, -disparity, 0, 1, 0);
  cv::warpAffine(*left, *right, shift, left->size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
}

TEST(Zncc, PeakAtTheKnownDisparity) {
  cv::Mat left, right;
  const double disparity = 23.4;
  MakeShiftedPair(disparity, &left, &right);
  ZnccOptions o;
  int checked = 0;
  for (int y = 40; y < 160; y += 30) {
    for (int x = 150; x < 350; x += 50) {
      const Eigen::Vector2d l(x, y);
      const ZnccMatch m = ZnccAlongSegment(left, right, l, l - Eigen::Vector2d(100, 0), l, o);
      ASSERT_TRUE(m.ok) << m.why << " at " << x << "," << y;
      EXPECT_NEAR(l.x() - m.right.x(), disparity, 0.3);
      EXPECT_NEAR(m.right.y(), y, 1e-9);
      EXPECT_GT(m.score, 0.9);
      ++checked;
    }
  }
  EXPECT_EQ(checked, 16);
}

TEST(Zncc, FlatTemplateIsRejected) {
  cv::Mat flat(100, 200, CV_32F, cv::Scalar(90));
  const ZnccMatch m = ZnccAlongSegment(flat, flat, {120, 50}, {20, 50}, {120, 50}, ZnccOptions());
  EXPECT_FALSE(m.ok);
  EXPECT_STREQ(m.why, "too little texture");
}

TEST(MedianFilter, RemovesPlantedDisparityOutliers) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(0, 1000), uy(300, 1000), noise(-0.3, 0.3), jump(15, 40);
  std::vector<Eigen::Vector2d> pts;
  std::vector<double> disp;
  std::vector<bool> planted;
  // Dense enough that every point has neighbours (about 17 within 50 px).
  for (int i = 0; i < 1500; ++i) {
    const Eigen::Vector2d p(ux(rng), uy(rng));
    // Ground plane: disparity grows linearly with the image row.
    double d = 0.08 * (p.y() - 250) + noise(rng);
    const bool out = i % 20 == 0;
    if (out) {
      const double j = jump(rng);
      d += (i % 40 == 0 || d - j < 1.0) ? j : -j;  // a disparity stays positive
    }
    pts.push_back(p);
    disp.push_back(d);
    planted.push_back(out);
  }
  const auto keep = MedianDisparityFilter(pts, disp, MedianFilterOptions());
  int removed_out = 0, removed_good = 0, n_out = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    n_out += planted[i];
    if (!keep[i]) (planted[i] ? removed_out : removed_good)++;
  }
  EXPECT_EQ(removed_out, n_out);
  EXPECT_LE(removed_good, 7);  // 0.5 % of the good ones
}

struct AffineCase {
  Eigen::Vector2d shift;
  Eigen::Matrix2d A;
};

// The target shows the template's texture under y = A (x - c) + c + shift,
// both rendered exactly from a continuous texture.
void CheckLsm(const AffineCase& k, bool estimate_affine, double tolerance, int half_height = 0) {
  const testing::BlobTexture tex(160, 160, 1400, 21);
  const Eigen::Vector2d c(80, 80);
  const Eigen::Matrix2d Ainv = k.A.inverse();
  const cv::Mat templ_f = tex.Render(160, 160, [](int x, int y) { return std::make_pair<double, double>(x, y); });
  cv::Mat target_f = tex.Render(160, 160, [&](int x, int y) {
    const Eigen::Vector2d s = Ainv * (Eigen::Vector2d(x, y) - c - k.shift) + c;
    return std::make_pair(s.x(), s.y());
  });
  target_f = target_f * 0.8 + 20;  // radiometric difference
  const LsmImage a = MakeLsmImage(templ_f), b = MakeLsmImage(target_f);
  LsmOptions o;
  o.estimate_affine = estimate_affine;
  o.half_window = half_height > 0 ? 18 : 10;
  o.half_height = half_height;
  int n = 0;
  for (int dy = -20; dy <= 20; dy += 20) {
    for (int dx = -20; dx <= 20; dx += 20) {
      const Eigen::Vector2d p = c + Eigen::Vector2d(dx, dy);
      const Eigen::Vector2d truth = k.A * (p - c) + c + k.shift;
      const Eigen::Vector2d start = truth.array().round();  // integer start, up to 0.5 px off
      const LsmResult r = LeastSquaresMatch(a, p, b, start, Eigen::Matrix2d::Identity(), o);
      ASSERT_TRUE(r.ok) << r.why;
      EXPECT_LT((r.target - truth).norm(), tolerance) << "at offset " << dx << "," << dy << " error "
                                                      << (r.target - truth).transpose();
      EXPECT_LT(r.sigma_px, 0.1);
      if (estimate_affine) {
        EXPECT_LT((r.affine - k.A).norm(), 0.01);
      }
      EXPECT_NEAR(r.r1, 1.25, 0.05);  // T = r0 + r1 G with G = 0.8 T + 20
      ++n;
    }
  }
  EXPECT_EQ(n, 9);
}

TEST(Lsm, RecoversSubPixelShift) {
  CheckLsm({{0.37, -0.21}, Eigen::Matrix2d::Identity()}, false, 0.03);
}

TEST(Lsm, RecoversAffineDistortion) {
  Eigen::Matrix2d A;
  A << 1.08, 0.06, -0.04, 0.93;
  CheckLsm({{-0.42, 0.28}, A}, true, 0.05);
}

// A wide, short window (the cross-site grid LSM's shape) on the same case.
TEST(Lsm, WideShortWindowRecoversAffineDistortion) {
  Eigen::Matrix2d A;
  A << 1.08, 0.06, -0.04, 0.93;
  CheckLsm({{-0.42, 0.28}, A}, true, 0.05, 4);
}

// A rectangular window near the top edge: only its half height counts.
TEST(Lsm, WideShortWindowFitsNearTheTopEdge) {
  const testing::BlobTexture tex(160, 160, 1400, 21);
  const cv::Mat img = tex.Render(160, 160, [](int x, int y) { return std::make_pair<double, double>(x, y); });
  const LsmImage a = MakeLsmImage(img);
  LsmOptions o;
  o.half_window = 18;
  o.half_height = 4;
  const LsmResult r = LeastSquaresMatch(a, {80, 9}, a, {80.4, 9.3}, Eigen::Matrix2d::Identity(), o);
  ASSERT_TRUE(r.ok) << r.why;
  EXPECT_LT((r.target - Eigen::Vector2d(80, 9)).norm(), 0.02);
  o.half_height = 0;  // square 37 x 37: does not fit
  EXPECT_FALSE(LeastSquaresMatch(a, {80, 9}, a, {80.4, 9.3}, Eigen::Matrix2d::Identity(), o).ok);
}

TEST(Lsm, FlatTemplateIsRejected) {
  cv::Mat flat(64, 64, CV_32F, cv::Scalar(50));
  const LsmImage a = MakeLsmImage(flat);
  const LsmResult r = LeastSquaresMatch(a, {32, 32}, a, {32, 32}, Eigen::Matrix2d::Identity(), LsmOptions());
  EXPECT_FALSE(r.ok);
}

TEST(Consistency, RejectsPlantedOutliers) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> ux(3, 30), uy(-10, 10), uz(-0.5, 0.5), usign(0, 1), umag(0.4, 2.0);
  std::normal_distribution<double> gauss(0, 1);
  const Pose3 site2_from_site1 = MakePose(-9.5, 0.8, 0.1, 0.01, -0.02, 0.12);
  const double baseline = 0.27, focal = 1189, sigma_p = 0.1, sigma_a = 0.5 / focal;
  std::vector<Eigen::Vector3d> p1, p2;
  std::vector<Eigen::Matrix3d> c1, c2;
  std::vector<bool> planted;
  const Eigen::Vector3d cam(0, 0, 1.5);
  for (int i = 0; i < 300; ++i) {
    const Eigen::Vector3d truth(ux(rng), uy(rng), uz(rng));
    const Eigen::Vector3d t2 = site2_from_site1 * truth;
    Eigen::Vector3d m1 = truth, m2 = t2;
    // Noise along the ray per eq. 7 at each site.
    for (int s = 0; s < 2; ++s) {
      Eigen::Vector3d& m = s == 0 ? m1 : m2;
      const Eigen::Vector3d ray = m - cam;
      const double r = ray.norm();
      const Eigen::Matrix3d cov = StereoPointCovariance(ray, r, baseline, focal, sigma_p, sigma_a);
      const Eigen::LLT<Eigen::Matrix3d> llt(cov);
      m += llt.matrixL() * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
      (s == 0 ? c1 : c2).push_back(cov);
    }
    // Outliers: a wrong match moves the point by more than the noise model
    // allows (10 range sigmas at its range, and at least 1 m).
    const bool out = i % 10 == 3;
    const double sr = RangeSigma((t2 - cam).norm(), baseline, focal, sigma_p);
    if (out) m2 += Eigen::Vector3d(usign(rng) - 0.5, usign(rng) - 0.5, 0.2 * (usign(rng) - 0.5)).normalized() *
                   std::max(1.0 + umag(rng), 10 * sr);
    p1.push_back(m1);
    p2.push_back(m2);
    planted.push_back(out);
  }
  const ConsistencyResult res = DistanceConsistencyCheck(p1, c1, p2, c2, ConsistencyOptions());
  int outliers_kept = 0, inliers_lost = 0;
  for (size_t i = 0; i < planted.size(); ++i) {
    if (planted[i] && res.inlier[i]) ++outliers_kept;

    if (!planted[i] && !res.inlier[i]) ++inliers_lost;
  }
  EXPECT_EQ(outliers_kept, 0);
  EXPECT_LE(inliers_lost, 6);  // 2 % of 270
  EXPECT_GT(res.weight_threshold, 50);
}

// Far points moved across the line of sight by 12 lateral sigmas (a match
// a few px off along a streak of grazing texture): the pairwise distances
// hide most of them in the range error; one rigid motion within each
// point's covariance does not.
TEST(Consistency, MotionCheckRejectsLateralOutliersAtRange) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> ux(12, 28), uy(-8, 8), usign(0, 1);
  std::normal_distribution<double> gauss(0, 1);
  const Pose3 site2_from_site1 = MakePose(-10.0, 0.5, 0.05, 0.0, 0.01, 0.1);
  const double baseline = 0.27, focal = 1189, sigma_p = 0.1, sigma_a = 0.5 / focal;
  const Eigen::Vector3d cam(0, 0, 1.5);
  std::vector<Eigen::Vector3d> p1, p2;
  std::vector<Eigen::Matrix3d> c1, c2;
  std::vector<bool> planted;
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d truth(ux(rng), uy(rng), 0.0);
    Eigen::Vector3d m1 = truth, m2 = site2_from_site1 * truth;
    for (int s = 0; s < 2; ++s) {
      Eigen::Vector3d& m = s == 0 ? m1 : m2;
      const Eigen::Vector3d ray = m - cam;
      const Eigen::Matrix3d cov = StereoPointCovariance(ray, ray.norm(), baseline, focal, sigma_p, sigma_a);
      m += Eigen::LLT<Eigen::Matrix3d>(cov).matrixL() * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
      (s == 0 ? c1 : c2).push_back(cov);
    }
    const bool out = i % 8 == 5;
    if (out) {
      const Eigen::Vector3d ray = (m2 - cam).normalized();
      const Eigen::Vector3d across = ray.cross(Eigen::Vector3d::UnitZ()).normalized();
      // 12 sigma of the two sites' lateral errors combined.
      const double s_lat = sigma_a * std::hypot((m1 - cam).norm(), (m2 - cam).norm());
      m2 += (usign(rng) < 0.5 ? -1.0 : 1.0) * 12 * s_lat * across;
    }
    p1.push_back(m1);
    p2.push_back(m2);
    planted.push_back(out);
  }
  const MotionConsistencyResult res = MotionConsistencyCheck(p1, c1, p2, c2, MotionConsistencyOptions());
  ASSERT_TRUE(res.ok);
  int kept = 0, lost = 0, planted_n = 0;
  for (size_t i = 0; i < planted.size(); ++i) {
    planted_n += planted[i] ? 1 : 0;
    if (planted[i] && res.inlier[i]) ++kept;
    if (!planted[i] && !res.inlier[i]) ++lost;
  }
  // A shift across the current view can lie along the previous view's ray
  // (the rays differ by tens of degrees near the rover), where the range
  // error hides it from both checks: allow a tenth.
  const ConsistencyResult eq2 = DistanceConsistencyCheck(p1, c1, p2, c2, ConsistencyOptions());
  int kept_eq2 = 0;
  for (size_t i = 0; i < planted.size(); ++i) kept_eq2 += planted[i] && eq2.inlier[i] ? 1 : 0;
  EXPECT_LE(kept, planted_n / 10) << "of " << planted_n;
  EXPECT_LT(kept, kept_eq2) << "eq. 2 alone keeps " << kept_eq2;
  EXPECT_LE(lost, 4);  // 99.9 % gate: ~0.2 of 175 expected
  // The motion is the true one.
  const Eigen::Matrix4d truth = site2_from_site1.inverse().matrix();
  EXPECT_LT((res.site1_from_site2.block<3, 1>(0, 3) - truth.block<3, 1>(0, 3)).norm(), 0.05);
}

TEST(Consistency, RangeSigmaFollowsEquation7) {
  // sigma_r = r^2 / (b f) sigma_p: Yutu numbers, r = 10 m, sigma_p = 1/3 px.
  EXPECT_NEAR(RangeSigma(10.0, 0.27, 1189.0, 1.0 / 3.0), 100.0 / (0.27 * 1189.0) / 3.0, 1e-12);
}

// Counts matches whose points agree with the known map within tol px.
template <class Map>
void CountCorrect(const FeatureSet& a, const FeatureSet& b, const std::vector<FeatureMatch>& m, Map map, double tol,
                  int* correct, int* wrong) {
  *correct = *wrong = 0;
  for (const auto& x : m) ((map(a.points[x.query]) - b.points[x.train]).norm() < tol ? *correct : *wrong)++;
}

TEST(Asift, SimulatedTiltMatchesACompressedView) {
  // View B = A compressed by 2.5 along y (a grazing view of the ground) and shifted.
  const cv::Mat a = TexturedImage(480, 480, 31, 1.4);
  const double tilt = 2.5;
  const cv::Matx23d M(1, 0, 10, 0, 1 / tilt, 30);
  cv::Mat b;
  cv::warpAffine(a, b, M, cv::Size(500, 260), cv::INTER_AREA, cv::BORDER_CONSTANT, 0);
  auto map = [&](const Eigen::Vector2d& p) { return Eigen::Vector2d(p.x() + 10, p.y() / tilt + 30); };
  AsiftOptions plain;
  plain.tilts = {1.0};
  AsiftOptions restricted;
  restricted.tilts = {1.0, 2.0, 2.8284271247461903};
  // Compress A along y: longitude 90 deg only.
  restricted.longitude_min_deg = 90;
  restricted.longitude_max_deg = 91;
  const FeatureSet fa_plain = DetectAsift(a, cv::Mat(), plain);
  const FeatureSet fa = DetectAsift(a, cv::Mat(), restricted);
  const FeatureSet fb = DetectAsift(b, cv::Mat(), plain);
  EXPECT_EQ(restricted.Views().size(), 3u);
  ASSERT_GT(fa.size(), fa_plain.size());
  // Gated matching with a prediction that is 15 px off.
  std::vector<Eigen::Vector2d> pred;
  for (const auto& p : fa.points) pred.push_back(map(p) + Eigen::Vector2d(12, -9));
  GatedMatchOptions g;
  g.gate_radius = 40;
  const auto m_asift = GatedMatch(fa, pred, fb, g);
  std::vector<Eigen::Vector2d> pred_plain;
  for (const auto& p : fa_plain.points) pred_plain.push_back(map(p) + Eigen::Vector2d(12, -9));
  const auto m_plain = GatedMatch(fa_plain, pred_plain, fb, g);
  int ca, wa, cp, wp;
  CountCorrect(fa, fb, m_asift, map, 3.0, &ca, &wa);
  CountCorrect(fa_plain, fb, m_plain, map, 3.0, &cp, &wp);
  EXPECT_GT(ca, 100);
  EXPECT_GT(ca, 2 * cp) << "ASIFT should beat plain SIFT at tilt 2.5";
  EXPECT_LT(wa, 0.05 * (ca + wa));
}

TEST(Asift, ViewTransformMapsBackToOriginalPixels) {
  const AffineView v{2.0, 0.6};
  cv::Size vs;
  const cv::Matx23d A = AffineViewTransform(cv::Size(300, 200), v, &vs);
  // The image centre maps to the view centre.
  const double x = A(0, 0) * 149.5 + A(0, 1) * 99.5 + A(0, 2), y = A(1, 0) * 149.5 + A(1, 1) * 99.5 + A(1, 2);
  EXPECT_NEAR(x, (vs.width - 1) / 2.0, 1.0);
  EXPECT_NEAR(y, (vs.height - 1) / 2.0, 1.0);
  // Determinant = view width / canvas width (the resize factor), about 1 / tilt.
  EXPECT_NEAR(A(0, 0) * A(1, 1) - A(0, 1) * A(1, 0), 0.5, 0.005);
}

}  // namespace
}  // namespace vloc

namespace vloc {
namespace {

// A shifted, slightly rotated copy with noise: every clear tile finds the
// true position of its centre within a quarter of a reduced pixel.
TEST(TileRegistration, FindsAKnownOffsetFarOutsideAFeatureGate) {
  const cv::Mat fixed = testing::TexturedImage(640, 480, 11, 2.0);
  const double dx = 37.3, dy = -21.6, angle_deg = 1.0;
  // moving(x) = fixed(M x): moving pixel x shows the ground of fixed pixel M x.
  const cv::Point2f c(320, 240);
  cv::Mat M = cv::getRotationMatrix2D(c, angle_deg, 1.0);
  M.at<double>(0, 2) += dx;
  M.at<double>(1, 2) += dy;
  cv::Mat moving;
  cv::warpAffine(fixed, moving, M, fixed.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, 0);
  cv::Mat noise(moving.size(), CV_8S);
  cv::RNG(5).fill(noise, cv::RNG::NORMAL, 0, 3);
  cv::add(moving, noise, moving, cv::noArray(), CV_8U);
  cv::Mat mask;
  cv::warpAffine(cv::Mat(fixed.size(), CV_8U, cv::Scalar(255)), mask, M, fixed.size(),
                 cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, 0);
  TileRegistrationOptions o;
  const auto tiles = RegisterTiles(moving, mask, fixed, 60.0, o);
  ASSERT_GE(tiles.size(), 40u);
  int good = 0;
  for (const auto& t : tiles) {
    const Eigen::Vector2d truth(M.at<double>(0, 0) * t.moving_px.x() + M.at<double>(0, 1) * t.moving_px.y() + M.at<double>(0, 2),
                                M.at<double>(1, 0) * t.moving_px.x() + M.at<double>(1, 1) * t.moving_px.y() + M.at<double>(1, 2));
    good += (t.fixed_px - truth).norm() < 0.25 * o.reduction + 0.01 * 320 * angle_deg * M_PI / 180 * o.reduction ? 1 : 0;
  }
  EXPECT_GE(good, static_cast<int>(0.95 * tiles.size()));
}

TEST(TileRegistration, UnrelatedImagesGiveFewTiles) {
  const cv::Mat a = testing::TexturedImage(320, 240, 1, 2.0), b = testing::TexturedImage(320, 240, 2, 2.0);
  const TileRegistrationOptions o;
  const auto tiles = RegisterTiles(a, cv::Mat(), b, 40.0, o);
  // Chance peaks of unrelated texture do not agree on one offset: fewer
  // tiles share any tile's offset (within one reduced pixel) than the 6 the
  // front end needs to register an overlap (half-overlapping neighbours
  // share content, so a few do).
  int most = 0;
  for (const auto& t : tiles) {
    int n = 0;
    for (const auto& u : tiles) n += ((u.fixed_px - u.moving_px) - (t.fixed_px - t.moving_px)).norm() <= o.reduction ? 1 : 0;
    most = std::max(most, n);
  }
  EXPECT_LT(most, 6) << tiles.size() << " tiles";
}

TEST(TileRegistration, FlatImageGivesNoTiles) {
  const cv::Mat flat(240, 320, CV_8UC1, cv::Scalar(100));
  EXPECT_TRUE(RegisterTiles(flat, cv::Mat(), flat, 40.0, TileRegistrationOptions()).empty());
}

// TM_CCOEFF_NORMED in double, position by position, for windows with texture.
cv::Mat ExactNcc(const cv::Mat& image, const cv::Mat& templ) {
  cv::Mat img, t;
  image.convertTo(img, CV_64F);
  templ.convertTo(t, CV_64F);
  const double tm = cv::mean(t)[0];
  t -= tm;
  const double tn = cv::norm(t);
  cv::Mat out(image.rows - templ.rows + 1, image.cols - templ.cols + 1, CV_32F);
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) {
      cv::Mat w = img(cv::Rect(x, y, templ.cols, templ.rows)) - cv::mean(img(cv::Rect(x, y, templ.cols, templ.rows)))[0];
      const double wn = cv::norm(w);
      out.at<float>(y, x) = wn > 1e-9 ? static_cast<float>(w.dot(t) / (wn * tn)) : 0.f;
    }
  return out;
}

// MatchTemplateNcc is cv::matchTemplate's TM_CCOEFF_NORMED: on 8-bit and float textures, a registration tile
// (48 x 4 in a 90 x 46 window) and an LSM start search (53 x 11, 9 x 9 positions), within 5e-6 of the exact
// values and 1e-4 of OpenCV's (its DFT's float error grows where a window is nearly flat), the same peak; a
// window whose texture is flat scores 0, a flat template 1 everywhere (as OpenCV).
TEST(TemplateNcc, AgreesWithOpenCv) {
  const cv::Mat texture = testing::TexturedImage(200, 120, 3, 1.2);
  cv::Mat with_flat = texture.clone();
  with_flat(cv::Rect(10, 5, 60, 20)).setTo(77);  // windows wholly inside are flat
  cv::Mat texture32;
  texture.convertTo(texture32, CV_32F, 0.25, 3.0);
  struct Case { cv::Mat image; cv::Rect search, templ; };
  const Case cases[] = {
      {texture, {20, 30, 90, 46}, {41, 51, 48, 4}},
      {texture, {60, 40, 61, 19}, {64, 44, 53, 11}},
      {with_flat, {0, 0, 120, 40}, {100, 60, 48, 4}},
      {texture32, {20, 30, 90, 46}, {41, 51, 48, 4}},
      {texture32, {3, 3, 197, 117}, {150, 80, 16, 16}},
  };
  for (const Case& c : cases) {
    cv::Mat expected, got;
    cv::matchTemplate(c.image(c.search), c.image(c.templ), expected, cv::TM_CCOEFF_NORMED);
    MatchTemplateNcc(c.image(c.search), c.image(c.templ), &got);
    ASSERT_EQ(got.size(), expected.size());
    ASSERT_EQ(got.type(), CV_32FC1);
    EXPECT_LT(cv::norm(got, expected, cv::NORM_INF), 1e-4) << c.search << " " << c.templ;
    EXPECT_LT(cv::norm(got, ExactNcc(c.image(c.search), c.image(c.templ)), cv::NORM_INF), 5e-6) << c.search;
    cv::Point best_expected, best_got;
    cv::minMaxLoc(expected, nullptr, nullptr, nullptr, &best_expected);
    cv::minMaxLoc(got, nullptr, nullptr, nullptr, &best_got);
    EXPECT_EQ(best_got, best_expected);
  }
  cv::Mat flat_scores;
  MatchTemplateNcc(with_flat(cv::Rect(0, 0, 120, 40)), with_flat(cv::Rect(12, 6, 48, 4)), &flat_scores);
  EXPECT_EQ(cv::countNonZero(flat_scores != 1.f), 0);
  EXPECT_DOUBLE_EQ(cv::norm(flat_scores, cv::NORM_INF), 1.0);
}

// A position's score is the same whatever search holds it (8-bit images: the window sums are exact), so the
// tile registration's narrow second pass scores a position as the wide first pass does: searches of 1 to 97
// positions across (whole registers and part ones, 32-position blocks), starting on odd and even rows.
TEST(TemplateNcc, ScoreOfAPositionDoesNotDependOnTheSearchAroundIt) {
  const cv::Mat texture = testing::TexturedImage(240, 160, 5, 1.2);
  const cv::Rect templ(100, 70, 48, 4);
  const cv::Rect wide(20, 30, 48 + 96, 4 + 40);  // 97 x 41 positions
  cv::Mat all;
  MatchTemplateNcc(texture(wide), texture(templ), &all);
  ASSERT_EQ(all.size(), cv::Size(97, 41));
  for (const cv::Rect& sub : {cv::Rect(0, 0, 1, 1), cv::Rect(5, 3, 7, 7), cv::Rect(40, 10, 13, 13),
                              cv::Rect(1, 1, 33, 8), cv::Rect(60, 20, 37, 21), cv::Rect(0, 7, 97, 5)}) {
    cv::Mat part;
    MatchTemplateNcc(texture(cv::Rect(wide.x + sub.x, wide.y + sub.y, sub.width + 47, sub.height + 3)),
                     texture(templ), &part);
    ASSERT_EQ(part.size(), sub.size());
    EXPECT_EQ(cv::countNonZero(part != all(sub)), 0) << sub;
  }
}

// The rival of the ratio test is the best candidate at another place: the
// same point repeated by other ASIFT views (within distinct_radius) is no rival.
TEST(Asift, DistinctRatioTestIgnoresCopiesOfTheSamePoint) {
  const std::vector<Eigen::Vector2d> points = {{10, 10}, {11, 10}, {40, 10}};
  // Best at (10, 10), a copy 1 px away almost as good, a rival 30 px away.
  const std::vector<std::pair<double, int>> sorted = {{1.0, 0}, {1.1, 1}, {4.0, 2}};
  EXPECT_TRUE(DistinctRatioTest(sorted, points, 0.8, 4.0));    // 1 <= 0.64 * 4
  EXPECT_FALSE(DistinctRatioTest(sorted, points, 0.8, 0.5));   // the copy counts as a rival: 1 > 0.64 * 1.1
  EXPECT_FALSE(DistinctRatioTest(sorted, points, 0.45, 4.0));  // 1 > 0.2025 * 4
  EXPECT_TRUE(DistinctRatioTest({{1.0, 0}, {1.1, 1}}, points, 0.8, 4.0));  // no rival
  EXPECT_FALSE(DistinctRatioTest({}, points, 0.8, 4.0));
}

}  // namespace
}  // namespace vloc
