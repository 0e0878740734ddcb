// A real rover's stereo through the cross-site front end and the bundle
// adjustment (issue 33, item 3): UTIAS Devon Island pairs 2 and 3
// (../shared/data/real/rover_devon; Furgale et al., IJRR 2012) as two
// sites of one stereo pair each, the XB3's colour 1280 x 960 images, its
// camera file config/navcam_devon_xb3.yaml and the front end options
// config/procs/feature_frontend_devon.yaml. Beside it, the estimate a user
// of OpenCV would make on the same images: SGBM points of pair 2, SIFT
// matches of pair 2's left image to pair 3's, solvePnPRansac, its
// covariance by bootstrap over the inliers. No ground truth comes with the
// three frames: the two estimates check each other within their stated
// covariances.
//
// The dead-reckoning prior (stated, then perturbed): the pushcart has no
// odometry in these frames, so the prior is the OpenCV estimate perturbed
// by 15 % of the distance (four directions) and 3 deg of yaw, with a
// covariance of 15 % of the distance per axis, 3 deg of yaw, 1 deg of
// roll and pitch (a wheel-odometry + IMU DR of the paper's class). The
// front end uses it to predict its regions and gate its matches; the BA
// starts from a resection and has no prior term, but the tie points the
// front end finds depend on the regions, so the answers under the four
// priors must agree within the BA's stated covariance (chi^2, 6 DoF, 99 %:
// asserted).
//
// What the pair turned out to be: 33-34 m apart (both estimates), not "a
// few metres"; the common scene is the mesa and hills 40-200 m from pair 2,
// the shared ground at ~1 deg grazing. With ground-plane regions alone the
// automatic front end found 0 tie points under every prior; with far-terrain
// regions (config: regions.far_min_range / far_max_range, the current pair's
// stereo points 40-400 m away, grown by their range sigma; see regions.h) it
// finds 46-51 under each of the four priors (asserted: all four usable;
// the DR check compares yaw only, frontend.dr_check_translation: the 3D-3D
// translation of 40-400 m stereo points is not determined within the DR's
// sigma). Kept as a fallback, the operator's path (RunManual) on AKAZE
// "clicks" (another detector than the peer's SIFT; refined by vloc's
// cross-site LSM and stereo at both sites) feeds the BA where the automatic
// path finds too few. vloc and OpenCV agree
// per axis within 3 combined sigma (asserted), not always jointly
// (Mahalanobis^2 printed; see the assertion's comment).
//
// VLOC_TEST_DEVON_PICTURE=<file.jpg> writes the tie points over the two
// left images (the README's picture).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>
#include <sstream>

#include "devon_peer.h"
#include "vloc/ba/crosssite_ba.h"
#include "vloc/common/options.h"
#include "vloc/common/stats.h"
#include "vloc/crosssite/frontend.h"
#include "vloc/features/stereo_pair_check.h"

namespace vloc {
namespace {

const char* kNavcamFile = "config/navcam_devon_xb3.yaml";
const char* kFrontendFile = "config/procs/feature_frontend_devon.yaml";

using namespace devon;  // NOLINT: the Devon pairs and the OpenCV peer (devon_peer.h)

// Tie "clicks" for RunManual where the automatic front end finds none: AKAZE
// matches of the two left images (another detector than the peer's SIFT),
// ratio 0.8, a fundamental-matrix RANSAC (1.5 px, fixed seed: no pose in
// it), thinned to one per 12 px cell of the current image.
std::vector<ManualTie> AkazeClicks(const DevonPair& p2, const DevonPair& p3) {
  const auto akaze = cv::AKAZE::create();
  std::vector<cv::Point2f> a, b;
  for (const auto& [pa, pb] : RatioMatches(*akaze, cv::NORM_HAMMING, p2.left_grey, p3.left_grey, 0.8f))
    a.push_back(pa), b.push_back(pb);
  std::vector<ManualTie> ties;
  if (a.size() < 8) return ties;
  cv::theRNG().state = 4321;
  std::vector<uchar> inl;
  cv::findFundamentalMat(a, b, cv::FM_RANSAC, 1.5, 0.999, inl);
  std::set<std::pair<int, int>> cells;
  for (size_t k = 0; k < a.size(); ++k) {
    if (!inl[k] || !cells.insert({static_cast<int>(b[k].x / 12), static_cast<int>(b[k].y / 12)}).second) continue;
    ManualTie t;
    t.previous_px = {a[k].x, a[k].y};
    t.current_px = {b[k].x, b[k].y};
    ties.push_back(t);
  }
  return ties;
}

// ---- vloc: the front end and the BA on two sites of one pair each

struct VlocRun {
  FrontendResult automatic;  // Run(): regions predicted from the DR prior
  int clicks = 0;            // AKAZE ties handed to RunManual when Run() found too few
  FrontendResult frontend;   // the tie points the BA adjusted
  CrossSiteBaSummary ba;
  RelativePose relative;  // left2_from_left3 and its covariance from the BA
};

VlocRun RunVloc(const DevonPair& p2, const DevonPair& p3, const NavcamModel& navcam, double tilt2, double tilt3,
                const Pose3& body2_from_body3_prior, const FrontendOptions& fo) {
  VlocRun run;
  SiteImages previous, current;
  previous.site_id = 2;
  previous.world_from_body.pose = Pose3::Identity();
  previous.world_from_body.covariance = Matrix6d::Identity() * 1e-8;
  previous.pairs = {SitePair(p2, 2, tilt2)};
  current.site_id = 3;
  current.world_from_body.pose = body2_from_body3_prior;
  current.world_from_body.covariance =
      DrCovariance(body2_from_body3_prior.translation().norm()) + previous.world_from_body.covariance;
  current.pairs = {SitePair(p3, 3, tilt3)};
  const CrossSiteFrontend frontend(navcam, fo);
  run.automatic = frontend.Run(previous, current);
  run.frontend = run.automatic;
  if (!run.automatic.summary.IsUsable()) {
    const std::vector<ManualTie> ties = AkazeClicks(p2, p3);
    run.clicks = static_cast<int>(ties.size());
    run.frontend = frontend.RunManual(previous, current, ties);
  }
  if (!run.frontend.summary.IsUsable()) return run;
  run.ba = SolveCrossSiteBa(run.frontend.tie_points, navcam, CrossSiteBaOptions());
  if (!run.ba.usable) return run;
  run.relative = LeftCameras(navcam, tilt2, tilt3, run.ba.previous_from_current);
  run.relative.inliers = run.ba.num_tie_points_used;
  run.relative.rms_px = run.ba.final_rms_px;
  return run;
}

// The tie points over the two left images (half size, side by side):
// previous site left, current site right, a line per tie point.
void WritePicture(const DevonPair& p2, const DevonPair& p3, const TiePointSet& tps, const std::string& path) {
  const double k = 0.4;
  cv::Mat a, b, out;
  cv::resize(p2.left, a, cv::Size(), k, k, cv::INTER_AREA);
  cv::resize(p3.left, b, cv::Size(), k, k, cv::INTER_AREA);
  cv::hconcat(a, b, out);
  for (const TiePoint& tp : tps.points) {
    cv::Point2d pa(-1, -1), pb(-1, -1);
    for (const TieObservation& o : tp.observations) {
      if (o.camera != CameraSide::kLeft) continue;
      if (o.site == SiteRole::kPrevious) pa = {o.uv.x() * k, o.uv.y() * k};
      else pb = {o.uv.x() * k + a.cols, o.uv.y() * k};
    }
    if (pa.x < 0 || pb.x < 0) continue;
    cv::line(out, pa, pb, cv::Scalar(0, 200, 255), 1, cv::LINE_AA);
    cv::circle(out, pa, 2, cv::Scalar(0, 255, 0), -1, cv::LINE_AA);
    cv::circle(out, pb, 2, cv::Scalar(0, 255, 0), -1, cv::LINE_AA);
  }
  cv::imwrite(path, out, {cv::IMWRITE_JPEG_QUALITY, 70});
  std::cout << "wrote " << path << "\n";
}

struct DevonSetup {
  DevonPair p2, p3;
  NavcamModel navcam;
  FrontendOptions frontend;
  cv::Mat disparity2;
  GroundPlane ground2;
};

DevonSetup MakeSetup() {
  DevonSetup s;
  s.p2 = LoadDevon(2);
  s.p3 = LoadDevon(3);
  s.navcam = LoadOptionsFile<NavcamModel>(kNavcamFile);
  s.frontend = LoadOptionsFile<FrontendOptions>(kFrontendFile, "frontend");
  s.disparity2 = SgbmDisparity(s.p2, s.navcam.rig);
  s.ground2 = FitGroundPlane(s.disparity2, s.navcam.rig);
  return s;
}

// The reported calibration against the images: rows agree once the camera
// file's right principal point row holds the common offset, and the stereo
// ground plane lies at the camera file's mast height, tilted as it says.
TEST(RealRover, CalibrationAgreesWithTheImages) {
  if (DevonAbsent()) GTEST_SKIP() << kSkip;
  const NavcamModel navcam = LoadOptionsFile<NavcamModel>(kNavcamFile);
  const double offset = navcam.rig.right.cy - navcam.rig.left.cy;
  for (int n = 1; n <= 3; ++n) {
    const DevonPair p = LoadDevon(n);
    ASSERT_TRUE(p.ok);
    ASSERT_EQ(p.left.cols, navcam.rig.left.width);
    ASSERT_EQ(p.left.rows, navcam.rig.left.height);
    const StereoPairCheck c = CheckStereoPair(p.left_grey, p.right_grey, StereoPairCheckOptions());
    std::cout << "Devon pair " << n << ": row offset " << c.row_offset_px << " px (camera file " << offset
              << "), residual median " << c.median_residual_dy_px << " px over " << c.matches << " matches\n";
    EXPECT_LT(std::abs(c.row_offset_px - offset), 0.15) << "pair " << n;
    EXPECT_LT(c.median_residual_dy_px, 0.25) << "pair " << n;
    const GroundPlane g = FitGroundPlane(SgbmDisparity(p, navcam.rig), navcam.rig);
    std::cout << "Devon pair " << n << ": stereo ground plane " << g.height_m << " m below the camera, tilt "
              << g.tilt_deg << " deg down, roll " << g.roll_deg << " deg; " << g.inliers << " of " << g.points
              << " points 2-12 m ahead within 4 cm + 1 % of range, rms " << g.rms_m << " m\n";
    EXPECT_GT(g.inliers, g.points / 2) << "pair " << n;
    EXPECT_LT(g.rms_m, 0.05) << "pair " << n;
    EXPECT_NEAR(g.height_m, navcam.mast.mast_head.z(), 0.05) << "pair " << n;
  }
}

// Pair 2 -> pair 3 as a site pair: vloc's front end + BA beside OpenCV's
// SGBM + SIFT + solvePnPRansac, under four perturbed DR priors.
TEST(RealRover, DevonPair2To3BesideOpenCv) {
  if (DevonAbsent()) GTEST_SKIP() << kSkip;
  const DevonSetup s = MakeSetup();
  ASSERT_TRUE(s.p2.ok && s.p3.ok);
  const GroundPlane g3 = FitGroundPlane(SgbmDisparity(s.p3, s.navcam.rig), s.navcam.rig);
  const double tilt2 = s.ground2.tilt_deg * kDeg, tilt3 = g3.tilt_deg * kDeg;

  const RelativePose cv_pose = OpenCvRelativePose(s.p2, s.p3, s.disparity2, s.navcam.rig);
  std::cout << "OpenCV (SGBM points of pair 2, SIFT to pair 3's left, solvePnPRansac): " << cv_pose.matches
            << " SIFT matches, " << cv_pose.points << " with SGBM depth, " << cv_pose.inliers << " inliers, rms "
            << cv_pose.rms_px << " px; left2_from_left3 " << Describe(cv_pose)
            << " (200 draws: inliers resampled, SGBM disparity bias 0.1 px + noise 0.2 px)\n";
  ASSERT_GE(cv_pose.inliers, 30);

  // The DR prior: the peer's motion in body frames, perturbed.
  const Pose3 b2 = s.navcam.mast.BodyFromLeft(0, tilt2, s.navcam.rig);
  const Pose3 b3 = s.navcam.mast.BodyFromLeft(0, tilt3, s.navcam.rig);
  const Pose3 nominal = b2 * cv_pose.left2_from_left3 * b3.inverse();
  const double distance = nominal.translation().norm();
  std::cout << "sites 2 -> 3: " << distance << " m apart (body frames), tilts " << s.ground2.tilt_deg << " / "
            << g3.tilt_deg << " deg from each pair's stereo ground (an inclinometer's job)\n";
  std::vector<VlocRun> runs;
  for (int k = 0; k < 4; ++k) {
    const Pose3 prior = DrPrior(nominal, k);
    const Eigen::Vector3d dp = prior.translation() - nominal.translation();
    const double dyaw = (k % 2 ? -3.0 : 3.0) * kDeg;
    runs.push_back(RunVloc(s.p2, s.p3, s.navcam, tilt2, tilt3, prior, s.frontend));
    const VlocRun& r = runs.back();
    std::cout << "prior " << k << " (DR off by " << dp.transpose() << " m, yaw " << dyaw / kDeg
              << " deg): automatic " << r.automatic.summary.BriefReport() << "\n";
    if (r.clicks) std::cout << "  " << r.clicks << " AKAZE clicks through RunManual: " << r.frontend.summary.BriefReport() << "\n";
    std::cout << "  " << r.ba.BriefReport() << "\n";
    ASSERT_TRUE(r.frontend.summary.IsUsable());
    ASSERT_TRUE(r.ba.usable);
    std::cout << "  vloc left2_from_left3 " << Describe(r.relative) << "\n";
  }
  const VlocRun& v = runs[0];
  const Vector6d d = Difference(v.relative.left2_from_left3, cv_pose.left2_from_left3);
  const Matrix6d c = v.relative.covariance + cv_pose.covariance;
  const double chi2 = d.dot(c.ldlt().solve(d));
  const Matrix6d cb = v.relative.covariance + cv_pose.covariance_bootstrap;
  std::cout << "OpenCV with the bootstrap alone (SGBM depths as measured): "
            << Describe(RelativePose{cv_pose.left2_from_left3, cv_pose.covariance_bootstrap}) << "; Mahalanobis^2 "
            << d.dot(cb.ldlt().solve(d)) << "\n";
  std::cout << "vloc - OpenCV: dt (" << d.head<3>().transpose() << ") m, drot (" << d.tail<3>().transpose() / kDeg
            << ") deg; Mahalanobis^2 " << chi2 << " (6 DoF: 99 % below 16.8)\n";
  // Each axis agrees within 3 combined sigma (the peer's covariance with its
  // stated SGBM error model). Jointly they do not (Mahalanobis^2 ~53 with the
  // automatic tie points and far terrain; ~26 without the far points): the
  // rotations differ by 0.3-0.4 deg about each axis, 5-7 of vloc's sigmas
  // (the far terrain fixes its rotation) but 1-1.4 of OpenCV's, whose PnP
  // trades lateral translation against rotation along its own line (the
  // common scene is 40-400 m away: 0.9 m sideways looks like 0.4 deg).
  // Printed, not asserted.
  const char* kAxis[6] = {"x", "y", "z", "rx", "ry", "rz"};
  for (int a = 0; a < 6; ++a) {
    std::cout << "  " << kAxis[a] << ": " << d(a) / std::sqrt(c(a, a)) << " combined sigma\n";
    EXPECT_LT(std::abs(d(a)) / std::sqrt(c(a, a)), 3.0) << kAxis[a];
  }
  // The automatic front end finds the tie points under every prior.
  int automatic = 0;
  for (const VlocRun& r : runs) automatic += r.automatic.summary.IsUsable() ? 1 : 0;
  std::cout << "automatic front end usable under " << automatic << " of " << runs.size() << " priors\n";
  EXPECT_EQ(automatic, static_cast<int>(runs.size()));
  // The answers under the four priors agree within the BA's covariance (their tie points differ with the regions).
  for (size_t k = 1; k < runs.size(); ++k) {
    const Vector6d e = Difference(runs[k].relative.left2_from_left3, v.relative.left2_from_left3);
    const double chi2 = e.dot(v.relative.covariance.ldlt().solve(e));
    std::cout << "prior " << k << " vs prior 0: " << e.head<3>().norm() << " m, " << e.tail<3>().norm() / kDeg
              << " deg, Mahalanobis^2 " << chi2 << "\n";
    EXPECT_LT(chi2, 16.8) << "prior " << k;  // 6 DoF, 99 %
  }
  if (const char* path = std::getenv("VLOC_TEST_DEVON_PICTURE")) WritePicture(s.p2, s.p3, v.frontend.tie_points, path);
}

}  // namespace
}  // namespace vloc
