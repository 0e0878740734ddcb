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

#include "vloc/ba/crosssite_ba.h"
#include "vloc/common/options.h"
#include "vloc/common/stats.h"
#include "vloc/crosssite/frontend.h"
#include "vloc/features/stereo_pair_check.h"

namespace vloc {
namespace {

constexpr double kDeg = M_PI / 180.0;
const char* kNavcamFile = "config/navcam_devon_xb3.yaml";
const char* kFrontendFile = "config/procs/feature_frontend_devon.yaml";

std::string DevonDir() { return std::string(VLOC_SOURCE_DIR) + "/../shared/data/real/rover_devon/"; }

struct DevonPair {
  cv::Mat left, right;            // CV_8UC3 BGR, as the dataset ships them
  cv::Mat left_grey, right_grey;  // CV_8UC1
  bool ok = false;
};

DevonPair LoadDevon(int n) {
  DevonPair p;
  const std::string base = DevonDir() + "devon" + std::to_string(n);
  p.left = cv::imread(base + "-left.png", cv::IMREAD_COLOR);
  p.right = cv::imread(base + "-right.png", cv::IMREAD_COLOR);
  if (p.left.empty() || p.right.empty()) return p;
  cv::cvtColor(p.left, p.left_grey, cv::COLOR_BGR2GRAY);
  cv::cvtColor(p.right, p.right_grey, cv::COLOR_BGR2GRAY);
  p.ok = true;
  return p;
}

bool DevonAbsent() { return !std::ifstream(DevonDir() + "devon2-left.png"); }
const char* kSkip = "../shared/data/real/rover_devon absent (real data beside the repo, see ../shared/data/README.md)";

// ---- the peer's stereo: SGBM on pair 2, rows aligned as the camera file says

// SGBM disparity (px, NaN = none) after the right image is shifted by the
// rig's row offset (right cy - left cy), as a user who read the camera file
// would rectify it.
cv::Mat SgbmDisparity(const DevonPair& p, const StereoRig& rig) {
  const cv::Mat right = AlignRows(p.right_grey, rig.right.cy - rig.left.cy);
  const int block = 5;
  auto sgbm = cv::StereoSGBM::create(0, 160, block, 8 * block * block, 32 * block * block, 1, 63, 10, 100, 32,
                                     cv::StereoSGBM::MODE_SGBM);
  cv::Mat d16, d;
  sgbm->compute(p.left_grey, right, d16);
  d16.convertTo(d, CV_32F, 1.0 / 16);
  d.setTo(std::numeric_limits<float>::quiet_NaN(), d16 <= 0);
  return d;
}

// Left-camera point of a disparity (rectified pair, left ideal px).
Eigen::Vector3d StereoPoint(const StereoRig& rig, double u, double v, double disparity) {
  const double z = rig.left.fx * rig.Baseline() / disparity;
  return {(u - rig.left.cx) * z / rig.left.fx, (v - rig.left.cy) * z / rig.left.fy, z};
}

// ---- calibration check: the stereo ground plane

struct GroundPlane {
  Eigen::Vector3d up_camera = Eigen::Vector3d::Zero();  // unit normal, pointing up, left camera frame
  double height_m = 0;     // camera centre above the plane
  double tilt_deg = 0;     // optical axis below the horizon
  double roll_deg = 0;     // camera x above the horizon (right side up)
  int points = 0, inliers = 0;
  double rms_m = 0;        // inliers' distance to the plane
};

// RANSAC plane (fixed seed) through SGBM points 2-12 m ahead in the lower
// half, inliers within 4 cm + 1 % of the range, refined by least squares.
GroundPlane FitGroundPlane(const cv::Mat& disparity, const StereoRig& rig) {
  std::vector<Eigen::Vector3d> pts;
  for (int v = disparity.rows / 2; v < disparity.rows; v += 6)
    for (int u = 0; u < disparity.cols; u += 6) {
      const float d = disparity.at<float>(v, u);
      if (!std::isfinite(d) || d < 1) continue;
      const Eigen::Vector3d p = StereoPoint(rig, u, v, d);
      if (p.z() > 2 && p.z() < 12) pts.push_back(p);
    }
  GroundPlane g;
  g.points = static_cast<int>(pts.size());
  if (pts.size() < 100) return g;
  std::mt19937 rng(7);
  std::uniform_int_distribution<size_t> pick(0, pts.size() - 1);
  auto tol = [](const Eigen::Vector3d& p) { return 0.04 + 0.01 * p.norm(); };
  Eigen::Vector4d best = Eigen::Vector4d::Zero();
  int best_count = 0;
  for (int it = 0; it < 500; ++it) {
    const Eigen::Vector3d a = pts[pick(rng)], b = pts[pick(rng)], c = pts[pick(rng)];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-9) continue;
    n.normalize();
    const double e = -n.dot(a);
    int count = 0;
    for (const auto& p : pts) count += std::abs(n.dot(p) + e) < tol(p);
    if (count > best_count) best_count = count, best << n, e;
  }
  std::vector<Eigen::Vector3d> in;
  for (const auto& p : pts)
    if (std::abs(best.head<3>().dot(p) + best(3)) < tol(p)) in.push_back(p);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : in) mean += p;
  mean /= static_cast<double>(in.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : in) scatter += (p - mean) * (p - mean).transpose();
  Eigen::Vector3d n = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors().col(0);
  if (n.y() > 0) n = -n;  // up is -y in the camera frame (y down)
  g.up_camera = n;
  g.height_m = -n.dot(mean);  // camera (origin) above the plane
  g.inliers = static_cast<int>(in.size());
  double ss = 0;
  for (const auto& p : in) ss += std::pow(n.dot(p - mean), 2);
  g.rms_m = std::sqrt(ss / in.size());
  g.tilt_deg = std::asin(std::clamp(-n.z(), -1.0, 1.0)) / kDeg;  // optical axis (z) toward down (-n)
  g.roll_deg = std::asin(std::clamp(n.x(), -1.0, 1.0)) / kDeg;
  return g;
}

// ---- the peer's relative pose: SGBM points + SIFT + solvePnPRansac

// Matches of two images by one detector: nearest neighbours passing Lowe's
// ratio test, as (first image px, second image px).
std::vector<std::pair<cv::Point2f, cv::Point2f>> RatioMatches(cv::Feature2D& detector, int norm, const cv::Mat& a,
                                                              const cv::Mat& b, float ratio) {
  std::vector<cv::KeyPoint> ka, kb;
  cv::Mat da, db;
  detector.detectAndCompute(a, cv::noArray(), ka, da);
  detector.detectAndCompute(b, cv::noArray(), kb, db);
  std::vector<std::vector<cv::DMatch>> knn;
  cv::BFMatcher(norm).knnMatch(da, db, knn, 2);
  std::vector<std::pair<cv::Point2f, cv::Point2f>> out;
  for (const auto& m : knn)
    if (m.size() == 2 && m[0].distance < ratio * m[1].distance) out.emplace_back(ka[m[0].queryIdx].pt, kb[m[0].trainIdx].pt);
  return out;
}


struct RelativePose {
  Pose3 left2_from_left3 = Pose3::Identity();
  Matrix6d covariance = Matrix6d::Zero();  // [x y z rx ry rz] in the left2 frame (vloc's convention)
  Matrix6d covariance_bootstrap = Matrix6d::Zero();  // the peer's: inliers resampled, SGBM depths as measured
  int matches = 0, points = 0, inliers = 0;
  double rms_px = 0;
  std::vector<cv::Point2f> left2_px, left3_px;  // the inliers
};

// solvePnP's (rvec, tvec): the pose taking object-frame points into the camera.
Pose3 PoseFromPnp(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat R;
  cv::Rodrigues(rvec, R);
  Eigen::Matrix3d Re;
  for (int a = 0; a < 3; ++a)
    for (int c = 0; c < 3; ++c) Re(a, c) = R.at<double>(a, c);
  return MakePose(Re, Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)));
}

// The peer's stated SGBM error model: a disparity bias common to the whole
// pair (sigma 0.1 px: the rows of pairs 1-3 scatter 0.15 px about their
// offset, and the camera file's calibration is the dataset's, not ours)
// plus 0.2 px of independent noise per point. Most common points are the
// mesa and hills, 40-200 m away at 1-6 px of disparity: a 0.1 px bias moves
// them by 2-10 %.
constexpr double kSgbmBiasSigmaPx = 0.1;
constexpr double kSgbmNoiseSigmaPx = 0.2;

// Covariance of left2_from_left3 over 200 draws (fixed seed): the inliers
// resampled (bootstrap), and with `disparity_model` their SGBM disparities
// perturbed by the error model above before the points are made again.
Matrix6d PnpCovariance(const std::vector<Eigen::Vector3d>& uvd, const std::vector<cv::Point2f>& img,
                       const StereoRig& rig, const cv::Mat& rvec, const cv::Mat& tvec, const Pose3& estimate,
                       bool disparity_model) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<size_t> pick(0, uvd.size() - 1);
  std::normal_distribution<double> unit(0.0, 1.0);
  const cv::Mat K = cv::Mat(rig.left.K());
  const int kDraws = 200;
  Matrix6d cov = Matrix6d::Zero();
  for (int b = 0; b < kDraws; ++b) {
    const double bias = disparity_model ? kSgbmBiasSigmaPx * unit(rng) : 0.0;
    std::vector<cv::Point3f> o;
    std::vector<cv::Point2f> i;
    for (size_t k = 0; k < uvd.size(); ++k) {
      const size_t j = pick(rng);
      const double d = uvd[j].z() + bias + (disparity_model ? kSgbmNoiseSigmaPx * unit(rng) : 0.0);
      const Eigen::Vector3d p = StereoPoint(rig, uvd[j].x(), uvd[j].y(), std::max(d, 0.3));
      o.emplace_back(p.x(), p.y(), p.z());
      i.push_back(img[j]);
    }
    cv::Mat r = rvec.clone(), t = tvec.clone();
    cv::solvePnP(o, i, K, cv::noArray(), r, t, true, cv::SOLVEPNP_ITERATIVE);
    const Pose3 draw = PoseFromPnp(r, t).inverse();
    Vector6d d;
    d.head<3>() = draw.translation() - estimate.translation();
    d.tail<3>() = LogSO3(draw.linear() * estimate.linear().transpose());
    cov += d * d.transpose();
  }
  return cov / kDraws;
}

RelativePose OpenCvRelativePose(const DevonPair& p2, const DevonPair& p3, const cv::Mat& disparity2,
                                const StereoRig& rig) {
  RelativePose r;
  const auto sift = cv::SIFT::create();  // every keypoint
  std::vector<cv::Point3f> obj;
  std::vector<cv::Point2f> img, from;
  std::vector<Eigen::Vector3d> uvd_all;
  for (const auto& [a, b] : RatioMatches(*sift, cv::NORM_L2, p2.left_grey, p3.left_grey, 0.8f)) {
    ++r.matches;
    const int u = cvRound(a.x), v = cvRound(a.y);
    const float d = disparity2.at<float>(v, u);
    if (!std::isfinite(d) || d < 1) continue;  // beyond 232 m: the sky's noise
    const Eigen::Vector3d p = StereoPoint(rig, a.x, a.y, d);
    obj.emplace_back(p.x(), p.y(), p.z());
    uvd_all.emplace_back(a.x, a.y, d);
    img.push_back(b);
    from.push_back(a);
  }
  r.points = static_cast<int>(obj.size());
  if (obj.size() < 12) return r;
  const cv::Mat K = cv::Mat(rig.left.K());
  cv::Mat rvec, tvec;
  std::vector<int> inl;
  cv::theRNG().state = 1234;
  cv::solvePnPRansac(obj, img, K, cv::noArray(), rvec, tvec, false, 5000, 2.0, 0.999, inl, cv::SOLVEPNP_EPNP);
  std::vector<cv::Point3f> o;
  std::vector<cv::Point2f> i;
  std::vector<Eigen::Vector3d> uvd;
  for (int k : inl) o.push_back(obj[k]), i.push_back(img[k]), r.left2_px.push_back(from[k]), uvd.push_back(uvd_all[k]);
  r.left3_px = i;
  r.inliers = static_cast<int>(o.size());
  if (o.size() < 12) return r;
  cv::solvePnP(o, i, K, cv::noArray(), rvec, tvec, true, cv::SOLVEPNP_ITERATIVE);
  std::vector<cv::Point2f> proj;
  cv::projectPoints(o, rvec, tvec, K, cv::noArray(), proj);
  double ss = 0;
  for (size_t k = 0; k < o.size(); ++k) ss += std::pow(cv::norm(proj[k] - i[k]), 2);
  r.rms_px = std::sqrt(ss / o.size());
  r.left2_from_left3 = PoseFromPnp(rvec, tvec).inverse();
  r.covariance_bootstrap = PnpCovariance(uvd, i, rig, rvec, tvec, r.left2_from_left3, false);
  r.covariance = PnpCovariance(uvd, i, rig, rvec, tvec, r.left2_from_left3, true);
  return r;
}

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

StereoPair SitePair(const DevonPair& d, int site, double tilt) {
  StereoPair p;
  p.site_id = site;
  p.utime = site * 1000000;
  p.pair_index = 0;
  p.num_pairs = 1;
  p.mast_pan = 0;
  p.mast_tilt = tilt;
  p.left = d.left;  // colour: the front end matches the luminance
  p.right = d.right;
  return p;
}

// The stated DR covariance of the current site: 15 % of the distance per
// axis, 3 deg yaw, 1 deg roll and pitch.
Matrix6d DrCovariance(double distance) {
  Vector6d s;
  s << 0.15 * distance, 0.15 * distance, 0.15 * distance, 1 * kDeg, 1 * kDeg, 3 * kDeg;
  return s.cwiseAbs2().asDiagonal();
}

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
  const Pose3 body2_from_left2 = navcam.mast.BodyFromLeft(0, tilt2, navcam.rig);
  const Pose3 body3_from_left3 = navcam.mast.BodyFromLeft(0, tilt3, navcam.rig);
  const Matrix6d zero = Matrix6d::Zero();
  const Pose3 left2_from_body3 = body2_from_left2.inverse() * run.ba.previous_from_current.pose;
  const Matrix6d c1 = ComposeCovariance(body2_from_left2.inverse(), zero, run.ba.previous_from_current.pose,
                                        run.ba.previous_from_current.covariance);
  run.relative.left2_from_left3 = left2_from_body3 * body3_from_left3;
  run.relative.covariance = ComposeCovariance(left2_from_body3, c1, body3_from_left3, zero);
  run.relative.inliers = run.ba.num_tie_points_used;
  run.relative.rms_px = run.ba.final_rms_px;
  return run;
}

// [dx dy dz drx dry drz] of a against b, in their parent frame.
Vector6d Difference(const Pose3& a, const Pose3& b) {
  Vector6d d;
  d.head<3>() = a.translation() - b.translation();
  d.tail<3>() = LogSO3(a.linear() * b.linear().transpose());
  return d;
}

std::string Describe(const RelativePose& r) {
  std::ostringstream os;
  const Eigen::Vector3d t = r.left2_from_left3.translation();
  const Eigen::Vector3d rv = LogSO3(r.left2_from_left3.linear()) / kDeg;
  const Vector6d s = r.covariance.diagonal().cwiseSqrt();
  os << std::fixed << std::setprecision(3) << "t = (" << t.x() << ", " << t.y() << ", " << t.z() << ") m +- ("
     << s(0) << ", " << s(1) << ", " << s(2) << "), |t| " << t.norm() << " m; rotation vector (" << std::setprecision(2)
     << rv.x() << ", " << rv.y() << ", " << rv.z() << ") deg +- (" << s(3) / kDeg << ", " << s(4) / kDeg << ", "
     << s(5) / kDeg << ")";
  return os.str();
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
    const double dir = k * M_PI / 2;  // forward, left, back, right
    const Eigen::Vector3d dp = 0.15 * distance * Eigen::Vector3d(std::cos(dir), std::sin(dir), 0);
    const double dyaw = (k % 2 ? -3.0 : 3.0) * kDeg;
    const Pose3 prior = MakePose(RotationFromRollPitchYaw(0, 0, dyaw) * nominal.linear(), nominal.translation() + dp);
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
  // stated SGBM error model). Jointly they do not (Mahalanobis^2 ~26 with the
  // automatic tie points, ~77 with the manual clicks): each
  // estimate trades lateral translation against rotation along its own line
  // (the common scene is 40-200 m away: 0.9 m sideways looks like 0.4 deg),
  // and the difference lies across both lines. Printed, not asserted.
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
