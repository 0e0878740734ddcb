// Space intersection and resection on synthetic data with known answers.
#include <gtest/gtest.h>

#include <random>

#include "vloc/ba/crosssite_ba.h"
#include "vloc/ba/geometry.h"
#include "vloc/common/options.h"

namespace vloc {
namespace {

NavcamModel Navcam() { return LoadOptionsFile<NavcamModel>("config/navcam.yaml"); }

TEST(Intersection, ExactStereoPointIsRecovered) {
  const NavcamModel navcam = Navcam();
  const Pose3 world_from_body = MakePose(1.0, -2.0, 0.1, 0.02, -0.03, 0.7);
  const Pose3 left = world_from_body * navcam.mast.BodyFromLeft(0.2, 0.3, navcam.rig);
  const Pose3 right = left * navcam.rig.left_from_right;
  const std::vector<CameraView> views = {CameraView::Make(left, navcam.rig.left),
                                         CameraView::Make(right, navcam.rig.right)};
  const Eigen::Vector3d p = left * Eigen::Vector3d(0.8, 0.5, 9.0);
  const std::vector<Eigen::Vector2d> uv = {*views[0].Project(p), *views[1].Project(p)};
  const IntersectionResult r = IntersectPoint(views, uv);
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_LT((r.p_world - p).norm(), 1e-8);
  EXPECT_LT(r.rms_px, 1e-8);
}

TEST(Intersection, NoisyDepthErrorMatchesStereoRangeSigma) {
  // Depth error of a 0.27 m stereo pair at 10 m with sigma 0.3 px per image:
  // sigma_z = z^2 / (B f) * sigma_parallax, sigma_parallax = sqrt(2) * 0.3 px.
  const NavcamModel navcam = Navcam();
  const Pose3 left = navcam.mast.BodyFromLeft(0.0, 0.3, navcam.rig);
  const Pose3 right = left * navcam.rig.left_from_right;
  const std::vector<CameraView> views = {CameraView::Make(left, navcam.rig.left),
                                         CameraView::Make(right, navcam.rig.right)};
  const Eigen::Vector3d p_cam(0.3, -0.2, 10.0);
  const Eigen::Vector3d p = left * p_cam;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n(0.0, 0.3);
  double sum2 = 0;
  const int trials = 2000;
  for (int t = 0; t < trials; ++t) {
    std::vector<Eigen::Vector2d> uv = {*views[0].Project(p) + Eigen::Vector2d(n(rng), n(rng)),
                                       *views[1].Project(p) + Eigen::Vector2d(n(rng), n(rng))};
    const IntersectionResult r = IntersectPoint(views, uv, {0.3, 0.3});
    ASSERT_TRUE(r.ok);
    sum2 += std::pow((left.inverse() * r.p_world).z() - p_cam.z(), 2);
  }
  const double expected = 100.0 / (0.27 * 1189.0) * std::sqrt(2.0) * 0.3;
  EXPECT_NEAR(std::sqrt(sum2 / trials), expected, 0.1 * expected);  // 2000 samples: ~1.6 % standard error
}

TEST(Intersection, ParallelRaysAreRefused) {
  const NavcamModel navcam = Navcam();
  const Pose3 left = Pose3::Identity();
  const std::vector<CameraView> views = {CameraView::Make(left, navcam.rig.left),
                                         CameraView::Make(left, navcam.rig.left)};
  const std::vector<Eigen::Vector2d> uv = {{500, 500}, {500, 500}};
  EXPECT_FALSE(IntersectPoint(views, uv).ok);
  EXPECT_FALSE(IntersectPoint({views[0]}, {uv[0]}).ok);
}

TEST(Resection, RigidSiteRecoveredFromPerturbedStart) {
  const NavcamModel navcam = Navcam();
  const Pose3 truth = MakePose(10.0, 0.5, 0.1, 0.01, 0.02, 0.05);
  std::vector<Pose3> body_from_camera;
  std::vector<PinholeCamera> intrinsics;
  for (double pan : {-0.6, 0.0, 0.6}) {
    body_from_camera.push_back(navcam.mast.BodyFromLeft(pan, 0.35, navcam.rig));
    body_from_camera.push_back(body_from_camera.back() * navcam.rig.left_from_right);
    intrinsics.push_back(navcam.rig.left);
    intrinsics.push_back(navcam.rig.right);
  }
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<ResectionObservation> obs;
  for (int i = 0; i < 60; ++i) {
    const Eigen::Vector3d p = truth * Eigen::Vector3d(9.0 + 6.0 * u(rng), 5.0 * u(rng), -0.1 + 0.3 * u(rng));
    for (size_t c = 0; c < body_from_camera.size(); ++c) {
      const auto px = CameraView::Make(truth * body_from_camera[c], intrinsics[c]).Project(p);
      if (!px || !intrinsics[c].InImage(*px)) continue;
      obs.push_back({p, *px, 0.3, static_cast<int>(c)});
    }
  }
  ASSERT_GT(obs.size(), 60u);
  // 1.2 m and 5 degrees away: a dead-reckoning error of 12 % over 10 m.
  const Pose3 start = truth * MakePose(-0.8, 0.9, 0.05, 0.0, 0.0, 0.09);
  const ResectionResult r = ResectBody(body_from_camera, intrinsics, obs, start);
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_LT((r.world_from_body.translation() - truth.translation()).norm(), 1e-6);
  EXPECT_LT(LogSO3(r.world_from_body.linear() * truth.linear().transpose()).norm(), 1e-8);
  EXPECT_LT(r.rms_px, 1e-5);
}

TEST(Resection, TooFewObservationsFail) {
  const NavcamModel navcam = Navcam();
  const std::vector<Pose3> cams = {navcam.mast.BodyFromLeft(0, 0.35, navcam.rig)};
  const std::vector<ResectionObservation> obs = {{Eigen::Vector3d(5, 0, 0), Eigen::Vector2d(500, 600), 0.3, 0}};
  EXPECT_FALSE(ResectBody(cams, {navcam.rig.left}, obs, Pose3::Identity()).ok);
}

}  // namespace
}  // namespace vloc
