#pragma once
// The UTIAS Devon Island pairs (../shared/data/real/rover_devon; Furgale et
// al., IJRR 2012) and the OpenCV peer's estimate of pair 2 -> 3 on them:
// SGBM points of pair 2, SIFT matches of pair 2's left image to pair 3's,
// solvePnPRansac, its covariance by bootstrap and a stated SGBM error model;
// the stereo ground plane (the calibration check and the mast tilt).
// Shared by devon_site_pair_test (the library) and devon_log_proc_test (the
// processes over a log). Header-only.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <iomanip>
#include <sstream>

#include "vloc/common/camera.h"
#include "vloc/common/rover_data.h"
#include "vloc/common/pose.h"
#include "vloc/features/stereo_pair_check.h"

namespace vloc::devon {

constexpr double kDeg = M_PI / 180.0;

inline std::string DevonDir() { return std::string(VLOC_SOURCE_DIR) + "/../shared/data/real/rover_devon/"; }

struct DevonPair {
  cv::Mat left, right;            // CV_8UC3 BGR, as the dataset ships them
  cv::Mat left_grey, right_grey;  // CV_8UC1
  bool ok = false;
};

inline DevonPair LoadDevon(int n) {
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

inline bool DevonAbsent() { return !std::ifstream(DevonDir() + "devon2-left.png"); }
inline const char* kSkip = "../shared/data/real/rover_devon absent (real data beside the repo, see ../shared/data/README.md)";

// ---- the peer's stereo: SGBM on pair 2, rows aligned as the camera file says

// SGBM disparity (px, NaN = none) after the right image is shifted by the
// rig's row offset (right cy - left cy), as a user who read the camera file
// would rectify it.
inline cv::Mat SgbmDisparity(const DevonPair& p, const StereoRig& rig) {
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
inline Eigen::Vector3d StereoPoint(const StereoRig& rig, double u, double v, double disparity) {
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
inline GroundPlane FitGroundPlane(const cv::Mat& disparity, const StereoRig& rig) {
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
inline Pose3 PoseFromPnp(const cv::Mat& rvec, const cv::Mat& tvec) {
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
inline Matrix6d PnpCovariance(const std::vector<Eigen::Vector3d>& uvd, const std::vector<cv::Point2f>& img,
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

inline RelativePose OpenCvRelativePose(const DevonPair& p2, const DevonPair& p3, const cv::Mat& disparity2,
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

// ---- the two sites as vloc sees them

inline StereoPair SitePair(const DevonPair& d, int site, double tilt) {
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
inline Matrix6d DrCovariance(double distance) {
  Vector6d s;
  s << 0.15 * distance, 0.15 * distance, 0.15 * distance, 1 * kDeg, 1 * kDeg, 3 * kDeg;
  return s.cwiseAbs2().asDiagonal();
}

// The stated DR prior k (0-3) of body2_from_body3 (the pushcart has no
// odometry): `nominal` moved by 15 % of the distance forward, left, back or
// right, turned by +3, -3, +3, -3 deg of yaw.
inline Pose3 DrPrior(const Pose3& nominal, int k) {
  const double distance = nominal.translation().norm();
  const double dir = k * M_PI / 2;  // forward, left, back, right
  const Eigen::Vector3d dp = 0.15 * distance * Eigen::Vector3d(std::cos(dir), std::sin(dir), 0);
  const double dyaw = (k % 2 ? -3.0 : 3.0) * kDeg;
  return MakePose(RotationFromRollPitchYaw(0, 0, dyaw) * nominal.linear(), nominal.translation() + dp);
}

// left2_from_left3 and its covariance from vloc's body2_from_body3 (the
// BA's previous_from_current) and the two sites' mast tilts.
inline RelativePose LeftCameras(const NavcamModel& navcam, double tilt2, double tilt3,
                                const PoseWithCovariance& body2_from_body3) {
  RelativePose r;
  const Pose3 body2_from_left2 = navcam.mast.BodyFromLeft(0, tilt2, navcam.rig);
  const Pose3 body3_from_left3 = navcam.mast.BodyFromLeft(0, tilt3, navcam.rig);
  const Matrix6d zero = Matrix6d::Zero();
  const Pose3 left2_from_body3 = body2_from_left2.inverse() * body2_from_body3.pose;
  const Matrix6d c1 =
      ComposeCovariance(body2_from_left2.inverse(), zero, body2_from_body3.pose, body2_from_body3.covariance);
  r.left2_from_left3 = left2_from_body3 * body3_from_left3;
  r.covariance = ComposeCovariance(left2_from_body3, c1, body3_from_left3, zero);
  return r;
}

// [dx dy dz drx dry drz] of a against b, in their parent frame.
inline Vector6d Difference(const Pose3& a, const Pose3& b) {
  Vector6d d;
  d.head<3>() = a.translation() - b.translation();
  d.tail<3>() = LogSO3(a.linear() * b.linear().transpose());
  return d;
}

inline std::string Describe(const RelativePose& r) {
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

}  // namespace vloc::devon
