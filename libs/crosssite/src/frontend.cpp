#include "vloc/crosssite/frontend.h"

#include <omp.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <unordered_map>

#include <glog/logging.h>

#include "vloc/common/options.h"
#include "vloc/features/tile_registration.h"

namespace vloc {

void FrontendOptions::Visit(OptionsReader& r) {
  r.Child("regions", [&](OptionsReader& c) { regions.Visit(c); });
  r.Child("wallis", [&](OptionsReader& c) { wallis.Visit(c); });
  r.Child("asift", [&](OptionsReader& c) { asift.Visit(c); });
  r.Child("matching", [&](OptionsReader& c) { matching.Visit(c); });
  r.Child("zncc", [&](OptionsReader& c) { zncc.Visit(c); });
  r.Child("median_filter", [&](OptionsReader& c) { median.Visit(c); });
  r.Child("lsm", [&](OptionsReader& c) { lsm.Visit(c); });
  r.Child("cross_lsm", [&](OptionsReader& c) { cross_lsm.Visit(c); });
  r.Child("consistency", [&](OptionsReader& c) { consistency.Visit(c); });
  r.Child("tiles", [&](OptionsReader& c) { tiles.Visit(c); });
  r.Child("motion", [&](OptionsReader& c) { motion.Visit(c); });
  r.Optional("fit_ground_planes", &fit_ground_planes, "fit each current image's ground plane to sparse stereo");
  r.Optional("ground_grid_px", &ground_grid_px, "px, grid of the stereo points for the ground plane");
  r.Optional("ground_min_points", &ground_min_points, "stereo points (and plane inliers) a ground plane needs");
  r.Optional("ground_tolerance_m", &ground_tolerance_m, "m, plane inlier tolerance at short range");
  r.Optional("ground_max_slope_deg", &ground_max_slope_deg, "deg, steepest accepted ground plane");
  r.Optional("motion_consistency", &motion_consistency, "keep only points that agree under one rigid motion");
  r.Child("grid_lsm", [&](OptionsReader& c) { grid_lsm.Visit(c); });
  r.Optional("grid_search_px", &grid_search_px, "px (grid), correlation search around a match before grid LSM");
  r.Optional("grid_min_zncc", &grid_min_zncc, "correlation peak needed before the grid LSM");
  r.Optional("grid_min_margin", &grid_min_margin, "peak minus the best correlation >= 3 px away");
  r.Optional("grid_back_check_px", &grid_back_check_px, "px (grid), LSM back from the warped current image must return this close (0 = off)");
  r.Optional("grid_max_shear", &grid_max_shear, "largest |dx/dy| of the grid LSM's affine (relief parallax), 0 = off");
  r.Optional("grid_lsm_enabled", &grid_lsm_enabled, "refine cross-site matches by LSM on the previous region's grid");
  r.Optional("keep_grid_unrefined", &keep_grid_unrefined, "keep matches the grid LSM could not refine");
  r.Optional("tile_registration", &tile_registration, "register the warped current image by tile correlation first");
  r.Optional("min_tile_inliers", &min_tile_inliers, "tiles agreeing on one motion needed to register");
  r.Optional("tile_inlier_px", &tile_inlier_px, "reduced px, RANSAC threshold of the tile motion");
  r.Optional("max_zoom", &max_zoom, "largest zoom of the previous region");
  r.Optional("min_zoom", &min_zoom, "smallest zoom of the previous region");
  r.Optional("tilt_margin", &tilt_margin, "simulate tilts up to the predicted tilt times this");
  r.Optional("longitude_margin_deg", &longitude_margin_deg, "deg, simulated longitudes around the predicted one");
  r.Optional("gate_margin_px", &gate_margin_px, "px, added to the predicted growth for the match gate");
  r.Optional("fundamental_threshold_px", &fundamental_threshold_px, "px, RANSAC threshold (0 = off)");
  r.Optional("max_motion_sigmas", &max_motion_sigmas, "tie-point motion vs DR gate in sigmas (0 = off)");
  r.Optional("keep_unrefined_cross", &keep_unrefined_cross, "keep matches whose cross-site LSM failed");
  r.Optional("sigma_unrefined_px", &sigma_unrefined_px, "px, sigma of an unrefined cross-site position");
  r.Optional("warp_current", &warp_current, "match on the current image warped by the ground homography");
  r.Optional("match_previous_resolution", &match_previous_resolution,
             "blur the warped current image to the zoomed previous region's resolution");
  r.Optional("warp_max_tilt", &warp_max_tilt, "largest tilt simulated on the warped image");
  r.Optional("max_overlaps_per_image", &max_overlaps_per_image, "overlaps matched per current image (0 = all)");
  r.Optional("zoom_previous", &zoom_previous, "zoom the previous region up (else shrink the current one)");
  r.Optional("refine_homography_threshold_px", &refine_homography_threshold_px, "px, stage-1 homography RANSAC threshold");
  r.Optional("stage1_cluster_fraction", &stage1_cluster_fraction,
             "radius of the stage-1 offset cluster as a fraction of the gate");
  r.Optional("refine_gate_px", &refine_gate_px, "px, stage-2 gate");
  r.Optional("max_gate_px", &max_gate_px, "px, largest stage-1 gate");
  r.Optional("min_stage1_inliers", &min_stage1_inliers, "stage-1 epipolar inliers needed to refine the prediction");
  r.Optional("refine_ratio", &refine_ratio, "stage-2 ratio test");
  r.Optional("max_points_per_overlap", &max_points_per_overlap, "matches kept per overlap");
  r.Optional("stereo_min_depth", &stereo_min_depth, "m, nearest depth searched along the epipolar line");
  r.Optional("stereo_max_depth", &stereo_max_depth, "m, farthest depth searched along the epipolar line");
  r.Optional("cross_sigma_floor_px", &cross_sigma_floor_px, "px (previous image), least cross-site sigma");
  r.Optional("stereo_sigma_floor_px", &stereo_sigma_floor_px, "px, least stereo (right image) sigma");
  r.Optional("sigma_angle_px", &sigma_angle_px, "px, lateral error for the consistency threshold");
  r.Optional("min_sigma_parallax", &min_sigma_parallax, "px, floor of the parallax sigma in eq. 7");
  r.Optional("min_region_std", &min_region_std, "grey level, texture needed in the regions");
  r.Optional("duplicate_radius", &duplicate_radius, "px, tie points closer than this are merged");
  r.Optional("min_tie_points", &min_tie_points, "verified tie points needed for status OK");
  r.Optional("num_threads", &num_threads, "OpenMP threads of the whole front end");
}

bool FrontendOptions::Check(std::string* error) const {
  if (!regions.Check(error) || !wallis.Check(error) || !asift.Check(error) || !matching.Check(error) ||
      !zncc.Check(error) || !median.Check(error) || !lsm.Check(error) || !cross_lsm.Check(error) ||
      !consistency.Check(error) || !tiles.Check(error) || !motion.Check(error) || !grid_lsm.Check(error))
    return false;
  if (min_zoom <= 0 || max_zoom < min_zoom) return Fail(error, "min_zoom must be > 0 and max_zoom >= min_zoom");
  if (tilt_margin < 1) return Fail(error, "tilt_margin must be >= 1");
  if (longitude_margin_deg < 0) return Fail(error, "longitude_margin_deg must be >= 0");
  if (fundamental_threshold_px < 0) return Fail(error, "fundamental_threshold_px must be >= 0");
  if (refine_homography_threshold_px <= 0 || refine_gate_px <= 0) return Fail(error, "refine thresholds must be > 0");
  if (stage1_cluster_fraction <= 0 || stage1_cluster_fraction > 1)
    return Fail(error, "stage1_cluster_fraction must be in (0, 1]");
  if (refine_ratio <= 0 || refine_ratio > 1) return Fail(error, "refine_ratio must be in (0, 1]");
  if (max_points_per_overlap < 1) return Fail(error, "max_points_per_overlap must be >= 1");
  if (stereo_min_depth <= 0 || stereo_max_depth <= stereo_min_depth)
    return Fail(error, "stereo depths must satisfy 0 < stereo_min_depth < stereo_max_depth");
  if (cross_sigma_floor_px < 0 || stereo_sigma_floor_px < 0) return Fail(error, "sigma floors must be >= 0");
  if (sigma_angle_px < 0 || min_sigma_parallax <= 0) return Fail(error, "sigma_angle_px >= 0, min_sigma_parallax > 0");
  if (min_tile_inliers < 3 || tile_inlier_px <= 0) return Fail(error, "min_tile_inliers must be >= 3 and tile_inlier_px > 0");
  if (min_tie_points < 1) return Fail(error, "min_tie_points must be >= 1");
  if (num_threads < 1) return Fail(error, "num_threads must be >= 1");
  return true;
}

const char* FrontendStatusName(FrontendStatus s) {
  switch (s) {
    case FrontendStatus::kOk: return "ok";
    case FrontendStatus::kNoOverlap: return "no overlap";
    case FrontendStatus::kLowTexture: return "too little texture";
    case FrontendStatus::kTooFewPoints: return "too few tie points";
    case FrontendStatus::kMissingInput: return "missing input";
    case FrontendStatus::kError: return "error";
  }
  return "unknown";
}

std::string FrontendSummary::BriefReport() const {
  std::ostringstream os;
  os << "front end: " << FrontendStatusName(status);
  if (!message.empty()) os << " (" << message << ")";
  os << ", " << num_tie_points << " tie points in " << total_seconds << " s;";
  for (const auto& s : stages) os << " " << s.name << " " << s.count << " (" << s.seconds << " s)";
  return os.str();
}

CrossSiteFrontend::CrossSiteFrontend(NavcamModel navcam, FrontendOptions options)
    : navcam_(std::move(navcam)), options_(std::move(options)) {}

namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct Prepared {
  cv::Mat gray;    // CV_8UC1, ideal (undistorted)
  LsmImage lsm;    // float + gradients
};

Prepared Prepare(const cv::Mat& raw, const PinholeCamera& cam) {
  Prepared p;
  if (cam.HasDistortion()) {
    cv::undistort(raw, p.gray, cv::Mat(cam.K()), cam.DistortionCoeffs(), cv::Mat(cam.K()));
  } else {
    p.gray = raw;
  }
  p.lsm = MakeLsmImage(p.gray);
  return p;
}

Eigen::Vector2d ApplyH(const cv::Matx33d& H, const Eigen::Vector2d& p) {
  const double w = H(2, 0) * p.x() + H(2, 1) * p.y() + H(2, 2);
  return {(H(0, 0) * p.x() + H(0, 1) * p.y() + H(0, 2)) / w, (H(1, 0) * p.x() + H(1, 1) * p.y() + H(1, 2)) / w};
}

Eigen::Matrix2d JacobianH(const cv::Matx33d& H, const Eigen::Vector2d& p) {
  const Eigen::Vector2d f0 = ApplyH(H, p);
  Eigen::Matrix2d J;
  J.col(0) = ApplyH(H, p + Eigen::Vector2d(0.5, 0)) - ApplyH(H, p - Eigen::Vector2d(0.5, 0));
  J.col(1) = ApplyH(H, p + Eigen::Vector2d(0, 0.5)) - ApplyH(H, p - Eigen::Vector2d(0, 0.5));
  (void)f0;
  return J;
}

// A cross-site candidate on its way through the stages.
struct Candidate {
  int overlap = 0;
  int prev_pair = 0, cur_pair = 0;
  Eigen::Vector2d prev_left = Eigen::Vector2d::Zero(), cur_left = Eigen::Vector2d::Zero();
  Eigen::Vector2d prev_right = Eigen::Vector2d::Zero(), cur_right = Eigen::Vector2d::Zero();
  double descriptor_distance = 0;
  double sigma_cross = 0, sigma_prev_right = 0, sigma_cur_right = 0;
  Eigen::Vector3d p_prev = Eigen::Vector3d::Zero(), p_cur = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov_prev = Eigen::Matrix3d::Zero(), cov_cur = Eigen::Matrix3d::Zero();
  bool ok = true;
  bool grid_refined = false;  // cross-site position already refined by LSM on the previous region's grid
  double grid_correlation = 0, grid_sigma_max = 0;                 // of the grid LSM (grid px)
  Eigen::Matrix2d grid_affine = Eigen::Matrix2d::Identity();       // its shape
  const char* why = "";
  Eigen::Matrix2d initial_affine = Eigen::Matrix2d::Identity();  // current px per previous px
};

// Features of one image restricted to a region, in ideal pixels.
struct ImageFeatures {
  FeatureSet set;
  cv::Rect region;
  double zoom = 1.0;
  std::vector<AffineView> views;
};

// Keeps the `cap` best (by descriptor distance) matches spread over a grid.
std::vector<int> SpreadSelect(const std::vector<Candidate>& c, const std::vector<int>& idx, int cap, double cell) {
  std::vector<int> order = idx;
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return c[a].descriptor_distance < c[b].descriptor_distance; });
  std::unordered_map<long long, int> used;
  std::vector<int> first, rest;
  for (int k : order) {
    const long long key = (static_cast<long long>(std::floor(c[k].cur_left.x() / cell)) << 32) ^
                          static_cast<unsigned>(static_cast<int>(std::floor(c[k].cur_left.y() / cell)));
    if (used[key]++ == 0) first.push_back(k); else rest.push_back(k);
  }
  first.insert(first.end(), rest.begin(), rest.end());
  if (static_cast<int>(first.size()) > cap) first.resize(cap);
  return first;
}

// Epipolar segment in the right image for depths [z0, z1] of the left pixel.
bool EpipolarSegment(const StereoRig& rig, const Eigen::Vector2d& left_px, double z0, double z1, Eigen::Vector2d* a,
                     Eigen::Vector2d* b) {
  const Pose3 right_from_left = rig.left_from_right.inverse();
  const Eigen::Vector3d ray = rig.left.Ray(left_px);
  const auto pa = rig.right.ProjectIdeal(right_from_left * (ray * z1));
  const auto pb = rig.right.ProjectIdeal(right_from_left * (ray * z0));
  if (!pa || !pb) return false;
  *a = *pa;
  *b = *pb;
  // Clip to the image (keep a small margin for the correlation window).
  const Eigen::Vector2d d = *b - *a;
  double t0 = 0, t1 = 1;
  const double lo[2] = {0, 0}, hi[2] = {static_cast<double>(rig.right.width - 1), static_cast<double>(rig.right.height - 1)};
  for (int k = 0; k < 2; ++k) {
    if (std::abs(d(k)) < 1e-12) {
      if ((*a)(k) < lo[k] || (*a)(k) > hi[k]) return false;
      continue;
    }
    double ta = (lo[k] - (*a)(k)) / d(k), tb = (hi[k] - (*a)(k)) / d(k);
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (t0 >= t1) return false;
  const Eigen::Vector2d a0 = *a;
  *a = a0 + t0 * d;
  *b = a0 + t1 * d;
  return true;
}

// The correlation peak of the window around `templ_px` of `templ` within
// +-radius px of *target_px in `target` (both CV_8UC1), sub-pixel by a
// parabola fit; false without a clear peak of at least min_score.
bool ZnccPeakNear(const cv::Mat& templ, const Eigen::Vector2d& templ_px, const cv::Mat& target, int radius, int half,
                  int half_y, double min_score, double min_margin, Eigen::Vector2d* target_px) {
  const int tx = static_cast<int>(std::lround(templ_px.x())), ty = static_cast<int>(std::lround(templ_px.y()));
  const int gx = static_cast<int>(std::lround(target_px->x())), gy = static_cast<int>(std::lround(target_px->y()));
  const cv::Rect tr(tx - half, ty - half_y, 2 * half + 1, 2 * half_y + 1);
  const cv::Rect sr(gx - half - radius, gy - half_y - radius, 2 * (half + radius) + 1, 2 * (half_y + radius) + 1);
  if ((tr & cv::Rect(0, 0, templ.cols, templ.rows)) != tr || (sr & cv::Rect(0, 0, target.cols, target.rows)) != sr)
    return false;
  cv::Mat score;
  cv::matchTemplate(target(sr), templ(tr), score, cv::TM_CCOEFF_NORMED);
  double best;
  cv::Point p;
  cv::minMaxLoc(score, nullptr, &best, nullptr, &p);
  if (!(best >= min_score) || p.x == 0 || p.y == 0 || p.x == score.cols - 1 || p.y == score.rows - 1) return false;
  // Unique: texture streaked along the view (a grazing look at the ground)
  // correlates almost as well a few px to the side.
  cv::Mat away = score.clone();
  cv::rectangle(away, cv::Rect(p.x - 2, p.y - 2, 5, 5), cv::Scalar(-2), cv::FILLED);
  double second;
  cv::minMaxLoc(away, nullptr, &second);
  if (best - second < min_margin) return false;
  auto peak = [](double a, double b, double c) {
    const double den = a - 2 * b + c;
    return std::abs(den) < 1e-12 ? 0.0 : std::clamp(0.5 * (a - c) / den, -0.5, 0.5);
  };
  const double sx = peak(score.at<float>(p.y, p.x - 1), best, score.at<float>(p.y, p.x + 1));
  const double sy = peak(score.at<float>(p.y - 1, p.x), best, score.at<float>(p.y + 1, p.x));
  // Offsets from the integer template centre carry over (templ_px sub-pixel).
  *target_px = Eigen::Vector2d(sr.x + half + p.x + sx + (templ_px.x() - tx), sr.y + half_y + p.y + sy + (templ_px.y() - ty));
  return true;
}

// Midpoint triangulation of two rays (origins o, directions d) in one frame.
bool Triangulate(const Eigen::Vector3d& o1, const Eigen::Vector3d& d1, const Eigen::Vector3d& o2,
                 const Eigen::Vector3d& d2, Eigen::Vector3d* p) {
  const Eigen::Vector3d w = o1 - o2;
  const double a = d1.dot(d1), b = d1.dot(d2), c = d2.dot(d2), d = d1.dot(w), e = d2.dot(w);
  const double den = a * c - b * b;
  if (den < 1e-12) return false;
  const double s = (b * e - c * d) / den, t = (a * e - b * d) / den;
  if (s <= 0 || t <= 0) return false;
  *p = 0.5 * ((o1 + s * d1) + (o2 + t * d2));
  return true;
}

// The ground seen by one current pair as a plane n . p + e = 0 (n up, unit)
// in the body frame: ZNCC stereo on a coarse grid of the image, points
// within the region ranges, RANSAC, least squares on the inliers. A zero
// vector when there are too few points or the plane is implausible.
Eigen::Vector4d FitGroundPlane(const NavcamModel& navcam, const MastPointing& pointing, const cv::Mat& left,
                               const cv::Mat& right, const FrontendOptions& o) {
  const Pose3 bl = navcam.mast.BodyFromLeft(pointing.pan, pointing.tilt, navcam.rig);
  const Pose3 br = bl * navcam.rig.left_from_right;
  const PinholeCamera& cam = navcam.rig.left;
  std::vector<Eigen::Vector3d> pts;
  const int step = std::max(8, o.ground_grid_px);
  for (int v = step / 2; v < cam.height; v += step) {
    for (int u = step / 2; u < cam.width; u += step) {
      const Eigen::Vector2d px(u, v);
      Eigen::Vector2d a, b;
      if (!EpipolarSegment(navcam.rig, px, 0.5 * o.regions.min_range_current, 1.5 * o.regions.max_range_current, &a, &b))
        continue;
      const ZnccMatch z = ZnccAlongSegment(left, right, px, a, b, o.zncc);
      if (!z.ok) continue;
      Eigen::Vector3d p;
      if (!Triangulate(bl.translation(), bl.linear() * cam.Ray(px), br.translation(),
                       br.linear() * navcam.rig.right.Ray(z.right), &p))
        continue;
      const double range = (p - bl.translation()).norm();
      if (range < 0.5 * o.regions.min_range_current || range > o.regions.max_range_current) continue;
      pts.push_back(p);
    }
  }
  const int n = static_cast<int>(pts.size());
  if (n < o.ground_min_points) return Eigen::Vector4d::Zero();
  // Inlier tolerance grows with range (stereo range error, eq. 7).
  auto tolerance = [&](const Eigen::Vector3d& p) {
    const double r = (p - bl.translation()).norm();
    return o.ground_tolerance_m + 3 * RangeSigma(r, navcam.rig.Baseline(), cam.fx, 0.5) * 0.2;
  };
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> pick(0, n - 1);
  Eigen::Vector4d best = Eigen::Vector4d::Zero();
  int best_n = 0;
  for (int it = 0; it < 300; ++it) {
    const Eigen::Vector3d &a = pts[pick(rng)], &b = pts[pick(rng)], &c = pts[pick(rng)];
    Eigen::Vector3d nrm = (b - a).cross(c - a);
    if (nrm.norm() < 1e-6) continue;
    nrm.normalize();
    if (nrm.z() < 0) nrm = -nrm;
    if (nrm.z() < std::cos(o.ground_max_slope_deg * M_PI / 180)) continue;
    const double e = -nrm.dot(a);
    int k = 0;
    for (const auto& p : pts) k += std::abs(nrm.dot(p) + e) <= tolerance(p) ? 1 : 0;
    if (k > best_n) best_n = k, best << nrm, e;
  }
  if (best_n < o.ground_min_points || best_n < 0.3 * n) return Eigen::Vector4d::Zero();
  // Least squares on the inliers.
  std::vector<Eigen::Vector3d> in;
  for (const auto& p : pts)
    if (std::abs(best.head<3>().dot(p) + best(3)) <= tolerance(p)) in.push_back(p);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : in) mean += p;
  mean /= in.size();
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (const auto& p : in) C += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
  Eigen::Vector3d nrm = es.eigenvectors().col(0);
  if (nrm.z() < 0) nrm = -nrm;
  if (nrm.z() < std::cos(o.ground_max_slope_deg * M_PI / 180)) return Eigen::Vector4d::Zero();
  Eigen::Vector4d plane;
  plane << nrm, -nrm.dot(mean);
  return plane;
}

}  // namespace

FrontendResult CrossSiteFrontend::Run(const SiteImages& previous_in, const SiteImages& current_in) const {
  FrontendResult result;
  FrontendSummary& sum = result.summary;
  const FrontendOptions& o = options_;
  const auto t_start = Clock::now();
  auto stage = [&](const std::string& name, int count, Clock::time_point t0) {
    sum.stages.push_back({name, count, Since(t0)});
  };
  auto finish = [&](FrontendStatus status, const std::string& message) {
    sum.status = status;
    sum.message = message;
    sum.total_seconds = Since(t_start);
    sum.num_tie_points = static_cast<int>(result.tie_points.points.size());
    return result;
  };
  try {
    // ---- input
    SiteImages prev = previous_in, cur = current_in;
    auto by_index = [](const StereoPair& a, const StereoPair& b) { return a.pair_index < b.pair_index; };
    std::sort(prev.pairs.begin(), prev.pairs.end(), by_index);
    std::sort(cur.pairs.begin(), cur.pairs.end(), by_index);
    if (prev.pairs.empty() || cur.pairs.empty())
      return finish(FrontendStatus::kMissingInput, prev.pairs.empty() ? "no stereo pairs of the previous site"
                                                                      : "no stereo pairs of the current site");
    const PinholeCamera& cam = navcam_.rig.left;
    for (const SiteImages* s : {&prev, &cur}) {
      for (const auto& p : s->pairs) {
        for (const cv::Mat* m : {&p.left, &p.right}) {
          if (m->empty() || m->type() != CV_8UC1 || m->cols != cam.width || m->rows != cam.height) {
            std::ostringstream os;
            os << "site " << s->site_id << " pair " << p.pair_index << ": image is not " << cam.width << "x"
               << cam.height << " 8-bit grey (check the Navcam calibration file)";
            return finish(FrontendStatus::kMissingInput, os.str());
          }
        }
      }
    }
    TiePointSet& tps = result.tie_points;
    tps.previous_site_id = prev.site_id;
    tps.current_site_id = cur.site_id;
    tps.previous_site_pose = prev.world_from_body;
    tps.current_site_pose_dr = cur.world_from_body;
    for (const auto& p : prev.pairs) tps.previous_pointing.push_back({p.mast_pan, p.mast_tilt});
    for (const auto& p : cur.pairs) {
      tps.current_pointing.push_back({p.mast_pan, p.mast_tilt});
      tps.utime = std::max(tps.utime, p.utime);
    }
    const int np = static_cast<int>(prev.pairs.size()), nc = static_cast<int>(cur.pairs.size());

    // ---- prepare (undistort)
    auto t0 = Clock::now();
    std::vector<Prepared> prev_l(np), prev_r(np), cur_l(nc), cur_r(nc);
#pragma omp parallel for schedule(dynamic, 1) num_threads(o.num_threads)
    for (int k = 0; k < 2 * (np + nc); ++k) {
      if (k < np) prev_l[k] = Prepare(prev.pairs[k].left, navcam_.rig.left);
      else if (k < 2 * np) prev_r[k - np] = Prepare(prev.pairs[k - np].right, navcam_.rig.right);
      else if (k < 2 * np + nc) cur_l[k - 2 * np] = Prepare(cur.pairs[k - 2 * np].left, navcam_.rig.left);
      else cur_r[k - 2 * np - nc] = Prepare(cur.pairs[k - 2 * np - nc].right, navcam_.rig.right);
    }
    // ---- ground planes of the current images from sparse stereo: the
    // rover's own footprint (z = 0 in the body frame) is a poor model of
    // ground 5-30 m away when it stands on a slope or a crater rim.
    std::vector<Eigen::Vector4d> planes(nc, Eigen::Vector4d::Zero());
    int num_planes = 0;
    if (o.fit_ground_planes) {
#pragma omp parallel for schedule(dynamic, 1) num_threads(o.num_threads) reduction(+ : num_planes)
      for (int i = 0; i < nc; ++i) {
        planes[i] = FitGroundPlane(navcam_, tps.current_pointing[i], cur_l[i].lsm.gray, cur_r[i].lsm.gray, o);
        num_planes += planes[i].head<3>().norm() > 0.5 ? 1 : 0;
      }
    }
    stage("ground", num_planes, t0);
    // ---- regions
    t0 = Clock::now();
    const RegionPrediction pred = PredictRegions(navcam_, prev.world_from_body, cur.world_from_body,
                                                 tps.previous_pointing, tps.current_pointing, o.regions, planes);
    stage("regions", static_cast<int>(pred.overlaps.size()), t0);
    sum.num_overlaps = static_cast<int>(pred.overlaps.size());
    if (pred.overlaps.empty())
      return finish(FrontendStatus::kNoOverlap,
                    "no current image sees ground that a previous image sees within the range limits "
                    "(check the DR poses, mast pointing and regions.max_range_*)");
    t0 = Clock::now();
    // Union of the regions per image; forward overlaps only (backward ones are matched on the ground).
    std::vector<ImageFeatures> fprev(np), fcur(nc);
    std::vector<double> tilt_max(nc, 1.0), lon_sum(nc, 0.0), lon_w(nc, 0.0), zoom_sum(np, 0.0);
    std::vector<int> zoom_n(np, 0), shrink_n(nc, 0);
    std::vector<double> shrink_sum(nc, 0.0);
    for (const auto& ov : pred.overlaps) {
      if (ov.backward) continue;
      fcur[ov.current_pair].region |= ov.current_region;
      fprev[ov.previous_pair].region |= ov.previous_region;
      tilt_max[ov.current_pair] = std::max(tilt_max[ov.current_pair], ov.tilt);
      // Longitudes are axial (mod pi): average the doubled angle.
      lon_sum[ov.current_pair] += ov.num_samples * std::sin(2 * ov.tilt_longitude);
      lon_w[ov.current_pair] += ov.num_samples * std::cos(2 * ov.tilt_longitude);
      zoom_sum[ov.previous_pair] += std::clamp(1.0 / ov.scale, o.min_zoom, o.max_zoom);
      ++zoom_n[ov.previous_pair];
      shrink_sum[ov.current_pair] += std::clamp(ov.scale, 1.0 / o.max_zoom, 1.0 / o.min_zoom);
      ++shrink_n[ov.current_pair];
    }
    double best_std = 0;
    std::vector<cv::Mat> cur_work(nc), prev_work(np);
    cv::Mat stats_mask_vals;
    std::vector<double> cur_means, cur_stds;
    for (int i = 0; i < nc; ++i) {
      if (fcur[i].region.area() == 0) continue;
      const ImageStats raw = ComputeImageStats(cur_l[i].gray(fcur[i].region));
      best_std = std::max(best_std, raw.std);
      cur_work[i] = WallisFilter(cur_l[i].gray(fcur[i].region), o.wallis);
      const ImageStats st = ComputeImageStats(cur_work[i]);
      if (!o.zoom_previous) {
        // The same relative zoom, applied as a reduction of the current region
        // (the cheaper side to process).
        fcur[i].zoom = shrink_sum[i] / std::max(1, shrink_n[i]);
        if (std::abs(fcur[i].zoom - 1.0) > 1e-3)
          cv::resize(cur_work[i], cur_work[i], cv::Size(), fcur[i].zoom, fcur[i].zoom, cv::INTER_AREA);
      }
      cur_means.push_back(st.mean);
      cur_stds.push_back(st.std);
    }
    for (int j = 0; j < np; ++j) {
      if (fprev[j].region.area() == 0) continue;
      best_std = std::max(best_std, ComputeImageStats(prev_l[j].gray(fprev[j].region)).std);
    }
    if (best_std < o.min_region_std) {
      std::ostringstream os;
      os << "the overlap regions are flat (largest grey-level std " << best_std << " < min_region_std "
         << o.min_region_std << "): too little texture to match";
      stage("wallis", 0, t0);
      return finish(FrontendStatus::kLowTexture, os.str());
    }
    // Previous site's Wallis targets from the current site's filtered regions (grey-level consistency).
    WallisOptions wprev = o.wallis;
    if (!cur_means.empty()) {
      wprev.target_mean = std::accumulate(cur_means.begin(), cur_means.end(), 0.0) / cur_means.size();
      wprev.target_std = std::max(1.0, std::accumulate(cur_stds.begin(), cur_stds.end(), 0.0) / cur_stds.size());
    }
    int num_regions = 0;
    for (int i = 0; i < nc; ++i) num_regions += cur_work[i].empty() ? 0 : 1;
    for (int j = 0; j < np; ++j) {
      if (fprev[j].region.area() == 0) continue;
      fprev[j].zoom = (o.zoom_previous || o.warp_current) ? zoom_sum[j] / std::max(1, zoom_n[j]) : 1.0;
      cv::Mat filtered = WallisFilter(prev_l[j].gray(fprev[j].region), wprev);
      if (std::abs(fprev[j].zoom - 1.0) > 1e-3) {
        cv::resize(filtered, prev_work[j], cv::Size(), fprev[j].zoom, fprev[j].zoom, cv::INTER_CUBIC);
      } else {
        prev_work[j] = filtered;
      }
      ++num_regions;
    }
    stage("wallis", num_regions, t0);

    std::vector<cv::Mat> cur_wallis_full(nc);
    if (o.warp_current) {
#pragma omp parallel for schedule(dynamic, 1) num_threads(o.num_threads)
      for (int i = 0; i < nc; ++i)
        if (!cur_work[i].empty()) cur_wallis_full[i] = WallisFilter(cur_l[i].gray, o.wallis);
    }
    // Overlaps matched: per current image the ones with the most ground samples.
    std::vector<bool> use_overlap(pred.overlaps.size(), true);
    if (o.max_overlaps_per_image > 0) {
      for (int i = 0; i < nc; ++i) {
        std::vector<std::pair<int, int>> by_samples;
        for (size_t k = 0; k < pred.overlaps.size(); ++k)
          if (pred.overlaps[k].current_pair == i) by_samples.emplace_back(-pred.overlaps[k].num_samples, static_cast<int>(k));
        std::sort(by_samples.begin(), by_samples.end());
        for (size_t r = o.max_overlaps_per_image; r < by_samples.size(); ++r) use_overlap[by_samples[r].second] = false;
      }
    }
    // ---- ASIFT: flat job list of (image, view) over both sites.
    t0 = Clock::now();
    struct Job {
      bool current;
      int image;
      AffineView view;
    };
    std::vector<Job> jobs;
    const double lon_margin = o.longitude_margin_deg * M_PI / 180;
    for (int i = 0; i < nc; ++i) {
      if (cur_work[i].empty() || o.warp_current) continue;
      fcur[i].views.push_back({1.0, 0.0});
      const double lon = 0.5 * std::atan2(lon_sum[i], lon_w[i]);
      for (double t : o.asift.tilts) {
        if (t <= 1.0 + 1e-6 || t > tilt_max[i] * o.tilt_margin) continue;
        const double step = o.asift.longitude_step_deg * M_PI / 180 / t;
        const int kmax = static_cast<int>(std::floor(lon_margin / step + 1e-9));
        for (int k = -kmax; k <= kmax; ++k) fcur[i].views.push_back({t, lon + k * step});
      }
      for (const auto& v : fcur[i].views) jobs.push_back({true, i, v});
    }
    for (int j = 0; j < np; ++j) {
      if (prev_work[j].empty()) continue;
      fprev[j].views.push_back({1.0, 0.0});
      jobs.push_back({false, j, {1.0, 0.0}});
    }
    for (int i = 0; i < nc; ++i)
      if (!cur_work[i].empty())
        VLOG(1) << "current image " << i << ": region " << fcur[i].region << " zoom " << fcur[i].zoom << " views "
                << fcur[i].views.size() << " (max tilt " << tilt_max[i] << ")";
    for (int j = 0; j < np; ++j)
      if (!prev_work[j].empty())
        VLOG(1) << "previous image " << j << ": region " << fprev[j].region << " zoom " << fprev[j].zoom;
    std::vector<FeatureSet> job_sets(jobs.size());
    AsiftOptions single = o.asift;
    single.num_threads = 1;
#pragma omp parallel for schedule(dynamic, 1) num_threads(o.num_threads)
    for (int k = 0; k < static_cast<int>(jobs.size()); ++k) {
      const Job& jb = jobs[k];
      const cv::Mat& img = jb.current ? cur_work[jb.image] : prev_work[jb.image];
      job_sets[k] = DetectAsift(img, cv::Mat(), {jb.view}, single);
    }
    // Assemble per image, in ideal pixels of the full image.
    for (size_t k = 0; k < jobs.size(); ++k) {
      ImageFeatures& f = jobs[k].current ? fcur[jobs[k].image] : fprev[jobs[k].image];
      FeatureSet& s = job_sets[k];
      const int view_index = static_cast<int>(f.set.views.size());
      f.set.views.push_back(jobs[k].view);
      for (size_t q = 0; q < s.size(); ++q) {
        f.set.keypoints.push_back(s.keypoints[q]);
        // cv::resize maps pixel centres: work px u is region px (u + 0.5) / zoom - 0.5.
        f.set.points.push_back(Eigen::Vector2d(f.region.x, f.region.y) +
                               (s.points[q] + Eigen::Vector2d::Constant(0.5)) / f.zoom - Eigen::Vector2d::Constant(0.5));
        f.set.view.push_back(view_index);
      }
      if (!s.descriptors.empty()) {
        if (f.set.descriptors.empty()) f.set.descriptors = s.descriptors.clone();
        else cv::vconcat(f.set.descriptors, s.descriptors, f.set.descriptors);
      }
    }
    size_t num_cur_features = 0, num_warped_features = 0;
    for (const auto& f : fcur) num_cur_features += f.set.size();
    // Gated matching per forward overlap: previous features predicted into the current image.
    std::vector<std::vector<Candidate>> per_overlap(pred.overlaps.size());
    GatedMatchOptions gm = o.matching;
    gm.num_threads = 1;
#pragma omp parallel for schedule(dynamic, 1) num_threads(o.num_threads)
    for (int k = 0; k < static_cast<int>(pred.overlaps.size()); ++k) {
      const PairOverlap& ov = pred.overlaps[k];
      if (ov.backward || !use_overlap[k]) continue;
      const FeatureSet& fp = fprev[ov.previous_pair].set;
      const cv::Matx33d cur_from_prev = ov.previous_from_current.inv();
      // Train features and the map from their coordinates to current-left px.
      FeatureSet warped;
      cv::Mat coverage;  // warped current image's coverage of the train grid
      cv::Mat warped_image, previous_crop;  // the warped current image and the previous region on the train grid
      bool registered = false;              // the warp is corrected by tile registration
      int tile_inliers = 0;
      cv::Matx33d cur_from_train = cv::Matx33d::eye();
      cv::Matx33d train_from_prev = cur_from_prev;
      if (o.warp_current) {
        // Ground-plane normalisation: the current image is warped onto the
        // (zoomed) previous region with the predicted ground homography, so
        // the remaining distortion is what the DR error leaves.
        const cv::Rect R = ov.previous_region & fprev[ov.previous_pair].region;
        const double z = fprev[ov.previous_pair].zoom;
        if (R.area() == 0) continue;
        // The grid is the zoomed previous region from pixel in_work of the
        // work image on (cv::resize maps pixel centres).
        const cv::Rect& F = fprev[ov.previous_pair].region;
        const cv::Point grid0(static_cast<int>((R.x - F.x) * z), static_cast<int>((R.y - F.y) * z));
        const cv::Matx33d prev_from_grid(1 / z, 0, F.x + (grid0.x + 0.5) / z - 0.5, 0, 1 / z,
                                         F.y + (grid0.y + 0.5) / z - 0.5, 0, 0, 1);
        cur_from_train = cur_from_prev * prev_from_grid;
        train_from_prev = prev_from_grid.inv();
        const cv::Size size(static_cast<int>(R.width * z), static_cast<int>(R.height * z));
        // Anti-aliasing: blur the current image by the local reduction of the
        // warp (train px per current px at the overlap's median sample).
        const Eigen::Matrix2d Jc = z * JacobianH(ov.previous_from_current, ov.median_current_px);
        const double sx = Jc.col(0).norm(), sy = Jc.col(1).norm();
        const double bx = sx < 1 ? 0.8 * std::sqrt(1 / (sx * sx) - 1) : 0.0;
        const double by = sy < 1 ? 0.8 * std::sqrt(1 / (sy * sy) - 1) : 0.0;
        // A blurred copy: several overlaps (threads) share the current image.
        cv::Mat source = cur_wallis_full[ov.current_pair];
        if (bx > 0.3 || by > 0.3) {
          cv::Mat blurred;
          cv::GaussianBlur(source, blurred, cv::Size(0, 0), std::max(bx, 0.01), std::max(by, 0.01));
          source = blurred;
        }
        {
          const cv::Rect in_work(grid0.x, grid0.y, size.width, size.height);
          previous_crop = prev_work[ov.previous_pair](in_work & cv::Rect(0, 0, prev_work[ov.previous_pair].cols,
                                                                          prev_work[ov.previous_pair].rows));
        }
        cv::Mat img, mask;
        auto warp = [&]() {
          cv::warpPerspective(source, img, cv::Mat(cur_from_train), size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                              cv::BORDER_CONSTANT, 0);
          cv::warpPerspective(cv::Mat(cur_l[ov.current_pair].gray.size(), CV_8UC1, cv::Scalar(255)), mask,
                              cv::Mat(cur_from_train), size, cv::INTER_NEAREST | cv::WARP_INVERSE_MAP,
                              cv::BORDER_CONSTANT, 0);
          // The previous region was zoomed up by z: its finest detail is z
          // grid px, while the warped current image still holds detail down
          // to one grid px (the previous site saw this ground from farther
          // away). Blur the warped image to the previous region's
          // resolution, or SIFT describes different texture at the two sites.
          if (z > 1.05 && o.match_previous_resolution) {
            const double bz = 0.8 * std::sqrt(z * z - 1);
            cv::GaussianBlur(img, img, cv::Size(0, 0), bz, bz);
          }
          cv::erode(mask, mask, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(9, 9)));
        };
        warp();
        // Stage 1 (registration): where the tiles of the warped current image
        // lie in the previous region, correlated over the whole DR gate; a
        // pose error of the camera maps the ground plane by a homography (on
        // the previous image's grid a lateral error shears the offsets, a
        // range error stretches them). Then the current image is warped
        // again with the correction, and once more registered within a few
        // px, so that features are detected on an image aligned with the
        // previous region.
        if (o.tile_registration && !previous_crop.empty()) {
          const double train_per_cur0 = ov.scale * z;
          double radius =
              std::min(ov.growth_px / std::max(ov.scale, 1e-3) + o.gate_margin_px, o.max_gate_px) * train_per_cur0;
          for (int pass = 0; pass < 2; ++pass) {
            const auto tiles = RegisterTiles(img, mask, previous_crop, radius, o.tiles);
            std::vector<cv::Point2f> from, to;
            for (const auto& t : tiles) {
              from.emplace_back(static_cast<float>(t.fixed_px.x()), static_cast<float>(t.fixed_px.y()));
              to.emplace_back(static_cast<float>(t.moving_px.x()), static_cast<float>(t.moving_px.y()));
            }
            int n_in = 0;
            cv::Mat A;
            if (static_cast<int>(tiles.size()) >= o.min_tile_inliers) {
              std::vector<uchar> inl;
              A = cv::findHomography(from, to, cv::RANSAC, o.tile_inlier_px * o.tiles.reduction, inl, 5000, 0.999);
              for (uchar v : inl) n_in += v ? 1 : 0;
            }
            VLOG(1) << "overlap cur " << ov.current_pair << " prev " << ov.previous_pair << " pass " << pass << ": "
                    << tiles.size() << " tiles correlated, " << n_in << " agree on one motion";
            if (A.empty() || n_in < o.min_tile_inliers) break;
            cur_from_train = cur_from_train * cv::Matx33d(A);  // A: true grid -> predicted grid
            tile_inliers = std::max(tile_inliers, n_in);
            registered = true;
            warp();
            radius = 3.0 * o.tiles.reduction;
          }
        }
        coverage = mask;
        std::vector<AffineView> views{{1.0, 0.0}};
        for (double t : o.asift.tilts)
          if (t > 1 + 1e-6 && t <= o.warp_max_tilt) views.push_back({t, 0.0}), views.push_back({t, M_PI / 2});
        warped = DetectAsift(img, mask, views, single);
        warped_image = img;
        if (const char* dump = std::getenv("VLOC_FRONTEND_DUMP")) {
          const std::string base = std::string(dump) + "/ov_c" + std::to_string(ov.current_pair) + "_p" +
                                   std::to_string(ov.previous_pair);
          const cv::Rect in_work(grid0.x, grid0.y, size.width, size.height);
          cv::imwrite(base + "_cur_warped.png", img);
          cv::imwrite(base + "_prev.png", prev_work[ov.previous_pair](in_work & cv::Rect(0, 0, prev_work[ov.previous_pair].cols, prev_work[ov.previous_pair].rows)));
        }
      }
      const FeatureSet& fc = o.warp_current ? warped : fcur[ov.current_pair].set;
      if (o.warp_current) {
#pragma omp atomic
        num_warped_features += warped.size();
      }
      if (fp.size() == 0 || fc.size() == 0) continue;
      std::vector<Eigen::Vector2d> predicted(fp.size(), Eigen::Vector2d::Constant(NAN));
      for (size_t q = 0; q < fp.size(); ++q) {
        const auto& p = fp.points[q];
        if (!ov.previous_region.contains(cv::Point(static_cast<int>(p.x()), static_cast<int>(p.y())))) continue;
        predicted[q] = ApplyH(train_from_prev, p);
        // A previous feature whose ground the current image does not see has
        // no true match: left in, it pairs with whatever lies at the gate's
        // edge nearest the covered part (one common, wrong, offset).
        if (o.warp_current && !coverage.empty()) {
          const int x = static_cast<int>(std::lround(predicted[q].x())), y = static_cast<int>(std::lround(predicted[q].y()));
          if (x < 0 || y < 0 || x >= coverage.cols || y >= coverage.rows || !coverage.at<uchar>(y, x))
            predicted[q] = Eigen::Vector2d::Constant(NAN);
        }
      }
      // Gate scale: train px per current px.
      const double train_per_cur = o.warp_current ? ov.scale * fprev[ov.previous_pair].zoom : 1.0;
      // Stage 1: the DR prediction with a gate as wide as its uncertainty.
      GatedMatchOptions g = gm;
      // ASIFT views of one point land a few (view) px apart: in full-image
      // px that is distinct_radius / zoom.
      if (!o.warp_current) g.distinct_radius = gm.distinct_radius / std::min(fcur[ov.current_pair].zoom, 1.0);
      g.gate_radius = std::min(ov.growth_px / std::max(ov.scale, 1e-3) + o.gate_margin_px, o.max_gate_px) * train_per_cur;
      auto matches = GatedMatch(fp, predicted, fc, g);
      auto to_points = [&](const std::vector<FeatureMatch>& ms, std::vector<cv::Point2f>* a, std::vector<cv::Point2f>* b) {
        a->clear();
        b->clear();
        for (const auto& m : ms) {
          a->emplace_back(static_cast<float>(fp.points[m.query].x()), static_cast<float>(fp.points[m.query].y()));
          const Eigen::Vector2d pc = ApplyH(cur_from_train, fc.points[m.train]);
          b->emplace_back(static_cast<float>(pc.x()), static_cast<float>(pc.y()));
        }
      };
      std::vector<cv::Point2f> a, b;
      cv::Mat F;
      cv::Matx33d refined = cur_from_prev;
      const size_t stage1 = matches.size();
      size_t stage1_inliers = 0;
      // Stage 2: re-predict with a refined map H (prev px -> train
      // coordinates) and match again in a tight gate.
      auto stage2 = [&](const cv::Matx33d& H) {
        refined = cur_from_train * H;
        for (size_t q = 0; q < fp.size(); ++q)
          if (predicted[q].allFinite()) predicted[q] = ApplyH(H, fp.points[q]);
        GatedMatchOptions g2 = g;
        g2.gate_radius = o.refine_gate_px * train_per_cur;
        g2.ratio = o.refine_ratio;
        matches = GatedMatch(fp, predicted, fc, g2);
        // Epipolar RANSAC on the (now mostly right) stage-2 matches.
        if (matches.size() >= 12) {
          to_points(matches, &a, &b);
          std::vector<uchar> inl;
          F = cv::findFundamentalMat(a, b, cv::FM_RANSAC, o.fundamental_threshold_px, 0.999, inl);
          if (F.empty() || F.rows != 3) F = cv::Mat();
        }
      };
      if (registered) {
        stage1_inliers = tile_inliers;
        stage2(train_from_prev);  // the warp is aligned with the previous region
      }
      if (!registered && o.fundamental_threshold_px > 0) {
        // Stage 1 -> refined prediction. The DR error shifts the true
        // matches by nearly one offset from their predictions (the warp
        // removed the perspective), while wrong matches (repeated texture)
        // scatter over the whole gate: keep the densest cluster of offsets,
        // then fit the ground homography to it. An epipolar RANSAC on all
        // stage-1 matches is not enough: with 8 points it fits a dozen
        // random matches at 2 px and the stage-2 gate then follows a wrong
        // motion.
        std::vector<Eigen::Vector2d> off;
        for (const auto& m : matches) off.push_back(fc.points[m.train] - predicted[m.query]);
        const double r = std::max(8.0 * train_per_cur, o.stage1_cluster_fraction * g.gate_radius);
        int best = -1, best_n = 0;
        for (size_t q = 0; q < off.size(); ++q) {
          int n = 0;
          for (size_t w = 0; w < off.size(); ++w) n += (off[w] - off[q]).norm() <= r ? 1 : 0;
          if (n > best_n) best_n = n, best = static_cast<int>(q);
        }
        std::vector<FeatureMatch> cluster;
        if (best >= 0) {
          Eigen::Vector2d mean = Eigen::Vector2d::Zero();
          int n = 0;
          for (size_t w = 0; w < off.size(); ++w)
            if ((off[w] - off[best]).norm() <= r) mean += off[w], ++n;
          mean /= std::max(n, 1);
          for (size_t w = 0; w < off.size(); ++w)
            if ((off[w] - mean).norm() <= 2 * r) cluster.push_back(matches[w]);
        }
        stage1_inliers = cluster.size();
        {
          int n0 = 0;
          for (const auto& v : off) n0 += v.norm() <= r ? 1 : 0;
          VLOG(1) << "overlap cur " << ov.current_pair << " prev " << ov.previous_pair << ": offset mode "
                  << (best >= 0 ? Eigen::Vector2d(off[best]) : Eigen::Vector2d::Zero()).transpose() << " n " << best_n
                  << ", near zero " << n0 << " r " << r << " z " << fprev[ov.previous_pair].zoom;
        }
        if (static_cast<int>(cluster.size()) < o.min_stage1_inliers) {
          VLOG(1) << "overlap cur " << ov.current_pair << " prev " << ov.previous_pair << ": stage 1 " << stage1
                  << " matches, densest offset cluster " << cluster.size() << " < min_stage1_inliers: skipped";
          continue;
        }
        to_points(cluster, &a, &b);
        std::vector<uchar> hin;
        cv::Mat Hr = cv::findHomography(a, b, cv::RANSAC, o.refine_homography_threshold_px, hin);
        int n_h = 0;
        for (uchar v : hin) n_h += v ? 1 : 0;
        if (Hr.empty() || n_h < o.min_stage1_inliers) continue;
        stage2(cur_from_train.inv() * cv::Matx33d(Hr));
      }
      std::vector<Candidate> cands;
      const cv::Matx33d Fm = F.empty() ? cv::Matx33d::zeros() : cv::Matx33d(F);
      for (const auto& m : matches) {
        Candidate c;
        c.overlap = k;
        c.prev_pair = ov.previous_pair;
        c.cur_pair = ov.current_pair;
        c.prev_left = fp.points[m.query];
        c.cur_left = ApplyH(cur_from_train, fc.points[m.train]);
        c.descriptor_distance = m.distance;
        // Initial LSM shape: the local affine of the refined (or predicted) homography.
        c.initial_affine = JacobianH(refined, c.prev_left);
        if (!F.empty()) {
          // Distance of the current point from the epipolar line of the previous one.
          const cv::Vec3d l = Fm * cv::Vec3d(c.prev_left.x(), c.prev_left.y(), 1.0);
          const double d = std::abs(l[0] * c.cur_left.x() + l[1] * c.cur_left.y() + l[2]) / std::hypot(l[0], l[1]);
          if (!(d <= 2 * o.fundamental_threshold_px)) continue;
        } else if (o.fundamental_threshold_px > 0) {
          continue;
        }
        cands.push_back(c);
      }
      VLOG(1) << "overlap cur " << ov.current_pair << " prev " << ov.previous_pair << ": scale " << ov.scale << " tilt "
              << ov.tilt << " gate " << g.gate_radius << " px, stage 1 " << stage1 << " matches (" << stage1_inliers
              << " epipolar inliers), stage 2 " << matches.size() << " -> " << cands.size();
      std::vector<int> idx(cands.size());
      std::iota(idx.begin(), idx.end(), 0);
      std::vector<Candidate> sel;
      for (int q : SpreadSelect(cands, idx, o.max_points_per_overlap, 24.0)) sel.push_back(cands[q]);
      // Cross-site LSM on the previous region's grid: the previous window
      // against the warped current image, which the refined prediction has
      // brought to the same scale, shape and (anti-aliased) resolution. The
      // full-resolution current image holds detail the previous site never
      // saw, and LSM from the coarse window into it rarely converges.
      if (o.grid_lsm_enabled && o.warp_current && !warped_image.empty() && !previous_crop.empty() && !sel.empty()) {
        const LsmImage lt = MakeLsmImage(previous_crop), lw = MakeLsmImage(warped_image);
        int refined_here = 0;
        for (Candidate& c : sel) {
          const Eigen::Vector2d pt = ApplyH(train_from_prev, c.prev_left);
          Eigen::Vector2d wt = ApplyH(cur_from_train.inv(), c.cur_left);
          // The feature positions of the two sites differ by a few grid px
          // (different scales of detection): start LSM at the correlation
          // peak near them.
          if (!ZnccPeakNear(previous_crop, pt, warped_image, o.grid_search_px, o.grid_lsm.half_window,
                            o.grid_lsm.half_height > 0 ? o.grid_lsm.half_height : o.grid_lsm.half_window, o.grid_min_zncc,
                            o.grid_min_margin, &wt))
            continue;
          const LsmResult r = LeastSquaresMatch(lt, pt, lw, wt, Eigen::Matrix2d::Identity(), o.grid_lsm);
          if (!r.ok) {
            VLOG(2) << "grid LSM: " << r.why << " corr " << r.correlation << " sigma " << r.sigma_px;
            continue;
          }

          if (o.grid_back_check_px > 0) {
            const LsmResult back = LeastSquaresMatch(lw, r.target, lt, pt, r.affine.inverse(), o.grid_lsm);
            if (!back.ok || (back.target - pt).norm() > o.grid_back_check_px) {
              VLOG(2) << "grid LSM: back match " << (back.ok ? "misses" : back.why) << " by " << (back.target - pt).norm();
              continue;
            }
          }
          if (o.grid_max_shear > 0 && std::abs(r.affine(0, 1)) > o.grid_max_shear) {
            VLOG(2) << "grid LSM: shear " << r.affine(0, 1) << " beyond grid_max_shear";
            continue;
          }
          const Eigen::Matrix2d J = JacobianH(cur_from_train, r.target);  // current px per grid px
          c.cur_left = ApplyH(cur_from_train, r.target);
          c.sigma_cross = r.sigma_px * std::sqrt(std::abs(J.determinant()));
          c.grid_refined = true;
          c.grid_correlation = r.correlation;
          c.grid_sigma_max = r.sigma_max_px;
          c.grid_affine = r.affine;
          VLOG(2) << "grid LSM ok at " << c.prev_left.transpose() << " sigma " << r.sigma_px << " max " << r.sigma_max_px
                  << " corr " << r.correlation;
          ++refined_here;
        }
        VLOG(1) << "overlap cur " << ov.current_pair << " prev " << ov.previous_pair << ": grid LSM refined "
                << refined_here << " of " << sel.size();
      }
      per_overlap[k] = std::move(sel);
    }
    // Backward overlaps: match on the ground plane.
    for (int k = 0; k < static_cast<int>(pred.overlaps.size()); ++k) {
      const PairOverlap& ov = pred.overlaps[k];
      if (!ov.backward) continue;
      const double res = 0.02;  // m per ortho pixel
      const Eigen::Vector2d ext = ov.ground_max - ov.ground_min;
      const cv::Size size(std::min(2000, static_cast<int>(ext.x() / res)), std::min(2000, static_cast<int>(ext.y() / res)));
      if (size.width < 32 || size.height < 32) continue;
      const Eigen::Vector2d origin(ov.ground_min.x(), ov.ground_max.y());
      const Pose3 prev_cam = navcam_.mast.BodyFromLeft(tps.previous_pointing[ov.previous_pair].pan,
                                                       tps.previous_pointing[ov.previous_pair].tilt, navcam_.rig);
      const Pose3 cur_cam_in_prev = pred.previous_from_current *
                                    navcam_.mast.BodyFromLeft(tps.current_pointing[ov.current_pair].pan,
                                                              tps.current_pointing[ov.current_pair].tilt, navcam_.rig);
      const cv::Matx33d Hp = ImageFromOrtho(cam, prev_cam, origin, res, o.regions.ground_height);
      const cv::Matx33d Hc = ImageFromOrtho(cam, cur_cam_in_prev, origin, res, o.regions.ground_height);
      const cv::Mat op = WallisFilter(GroundOrthoImage(prev_l[ov.previous_pair].gray, Hp, size), wprev);
      const cv::Mat oc = WallisFilter(GroundOrthoImage(cur_l[ov.current_pair].gray, Hc, size), o.wallis);
      AsiftOptions plain = o.asift;
      const FeatureSet sp = DetectAsift(op, op > 0, {{1.0, 0.0}}, plain);
      const FeatureSet sc = DetectAsift(oc, oc > 0, {{1.0, 0.0}}, plain);
      GatedMatchOptions g = gm;
      g.gate_radius = o.regions.sigma_scale * std::max(pred.relative_sigma(0), pred.relative_sigma(1)) / res + o.gate_margin_px;
      const auto matches = GatedMatch(sp, sp.points, sc, g);
      for (const auto& m : matches) {
        Candidate c;
        c.overlap = k;
        c.prev_pair = ov.previous_pair;
        c.cur_pair = ov.current_pair;
        c.prev_left = ApplyH(Hp, sp.points[m.query]);
        c.cur_left = ApplyH(Hc, sc.points[m.train]);
        c.descriptor_distance = m.distance;
        if (cam.InImage(c.prev_left, 10) && cam.InImage(c.cur_left, 10)) per_overlap[k].push_back(c);
      }
    }
    std::vector<Candidate> cands;
    for (auto& v : per_overlap) cands.insert(cands.end(), v.begin(), v.end());
    stage("asift", static_cast<int>(cands.size()), t0);
    num_cur_features += num_warped_features;
    if (num_cur_features < 20)
      return finish(FrontendStatus::kLowTexture, "ASIFT found almost no features in the current regions (" +
                                                     std::to_string(num_cur_features) + "): too little texture");

    // ---- cross-site LSM: previous-left window into the current left image.
    t0 = Clock::now();
    const int n0 = static_cast<int>(cands.size());
#pragma omp parallel for schedule(dynamic, 16) num_threads(o.num_threads)
    for (int k = 0; k < n0; ++k) {
      Candidate& c = cands[k];
      if (c.grid_refined) continue;
      if (o.grid_lsm_enabled && o.warp_current && !pred.overlaps[c.overlap].backward && !o.keep_grid_unrefined) {
        c.ok = false;
        c.why = "grid LSM failed";
        continue;
      }
      const PairOverlap& ov = pred.overlaps[c.overlap];
      Eigen::Matrix2d A = ov.backward ? Eigen::Matrix2d::Identity() : c.initial_affine;
      const LsmResult r = LeastSquaresMatch(prev_l[c.prev_pair].lsm, c.prev_left, cur_l[c.cur_pair].lsm, c.cur_left, A,
                                            o.cross_lsm);
      c.ok = r.ok || o.keep_unrefined_cross;
      c.why = r.why;
      if (r.ok) {
        c.cur_left = r.target;
        c.sigma_cross = r.sigma_px;
      } else {
        c.sigma_cross = o.sigma_unrefined_px;  // feature position only
      }
    }
    if (VLOG_IS_ON(1)) {
      std::map<std::string, int> reasons;
      for (const auto& c : cands)
        if (c.why && *c.why) ++reasons[c.why];
      for (const auto& [why, n] : reasons) VLOG(1) << "cross-site LSM rejected " << n << ": " << why;
    }
    int num_refined = 0;
    for (const auto& c : cands) num_refined += c.ok && (c.grid_refined || c.sigma_cross < o.sigma_unrefined_px) ? 1 : 0;
    VLOG(1) << "cross-site LSM refined " << num_refined << " of " << cands.size();
    cands.erase(std::remove_if(cands.begin(), cands.end(), [](const Candidate& c) { return !c.ok; }), cands.end());
    // Merge duplicates (the same current pixel matched through two overlaps).
    {
      std::sort(cands.begin(), cands.end(), [](const Candidate& a, const Candidate& b) { return a.sigma_cross < b.sigma_cross; });
      std::unordered_map<long long, std::vector<int>> grid;
      const double cell = std::max(o.duplicate_radius, 0.5);
      std::vector<Candidate> kept;
      for (const auto& c : cands) {
        const int gx = static_cast<int>(std::floor(c.cur_left.x() / cell)), gy = static_cast<int>(std::floor(c.cur_left.y() / cell));
        bool dup = false;
        for (int dx = -1; dx <= 1 && !dup; ++dx)
          for (int dy = -1; dy <= 1 && !dup; ++dy) {
            const long long key = (static_cast<long long>(c.cur_pair) << 48) ^ (static_cast<long long>(gx + dx) << 24) ^ (gy + dy);
            auto it = grid.find(key);
            if (it == grid.end()) continue;
            for (int q : it->second)
              if ((kept[q].cur_left - c.cur_left).norm() < o.duplicate_radius) dup = true;
          }
        if (dup) continue;
        const long long key = (static_cast<long long>(c.cur_pair) << 48) ^ (static_cast<long long>(gx) << 24) ^ gy;
        grid[key].push_back(static_cast<int>(kept.size()));
        kept.push_back(c);
      }
      cands.swap(kept);
    }
    stage("cross_lsm", static_cast<int>(cands.size()), t0);

    // ---- stereo ZNCC at both sites
    t0 = Clock::now();
    const int n1 = static_cast<int>(cands.size());
#pragma omp parallel for schedule(dynamic, 16) num_threads(o.num_threads)
    for (int k = 0; k < n1; ++k) {
      Candidate& c = cands[k];
      Eigen::Vector2d a, b;
      c.ok = false;
      if (!EpipolarSegment(navcam_.rig, c.prev_left, o.stereo_min_depth, o.stereo_max_depth, &a, &b)) continue;
      const ZnccMatch zp = ZnccAlongSegment(prev_l[c.prev_pair].lsm.gray, prev_r[c.prev_pair].lsm.gray, c.prev_left, a, b, o.zncc);
      if (!zp.ok) continue;
      if (!EpipolarSegment(navcam_.rig, c.cur_left, o.stereo_min_depth, o.stereo_max_depth, &a, &b)) continue;
      const ZnccMatch zc = ZnccAlongSegment(cur_l[c.cur_pair].lsm.gray, cur_r[c.cur_pair].lsm.gray, c.cur_left, a, b, o.zncc);
      if (!zc.ok) continue;
      c.prev_right = zp.right;
      c.cur_right = zc.right;
      c.ok = true;
    }
    cands.erase(std::remove_if(cands.begin(), cands.end(), [](const Candidate& c) { return !c.ok; }), cands.end());
    stage("stereo", static_cast<int>(cands.size()), t0);

    // ---- median filter of the disparities, per image of each site
    t0 = Clock::now();
    for (int site = 0; site < 2; ++site) {
      std::map<int, std::vector<int>> by_image;
      for (int k = 0; k < static_cast<int>(cands.size()); ++k) by_image[site == 0 ? cands[k].prev_pair : cands[k].cur_pair].push_back(k);
      for (const auto& [image, idx] : by_image) {
        std::vector<Eigen::Vector2d> pts;
        std::vector<double> disp;
        for (int k : idx) {
          const Candidate& c = cands[k];
          pts.push_back(site == 0 ? c.prev_left : c.cur_left);
          disp.push_back(site == 0 ? (c.prev_left - c.prev_right).norm() : (c.cur_left - c.cur_right).norm());
        }
        const auto keep = MedianDisparityFilter(pts, disp, o.median);
        for (size_t q = 0; q < idx.size(); ++q)
          if (!keep[q]) cands[idx[q]].ok = false;
      }
    }
    cands.erase(std::remove_if(cands.begin(), cands.end(), [](const Candidate& c) { return !c.ok; }), cands.end());
    stage("median", static_cast<int>(cands.size()), t0);

    // ---- stereo LSM at both sites + intersection
    t0 = Clock::now();
    const int n2 = static_cast<int>(cands.size());
    const double baseline = navcam_.rig.Baseline(), focal = cam.fx;
#pragma omp parallel for schedule(dynamic, 16) num_threads(o.num_threads)
    for (int k = 0; k < n2; ++k) {
      Candidate& c = cands[k];
      c.ok = false;
      const LsmResult lp = LeastSquaresMatch(prev_l[c.prev_pair].lsm, c.prev_left, prev_r[c.prev_pair].lsm, c.prev_right,
                                             Eigen::Matrix2d::Identity(), o.lsm);
      if (!lp.ok) continue;
      const LsmResult lc = LeastSquaresMatch(cur_l[c.cur_pair].lsm, c.cur_left, cur_r[c.cur_pair].lsm, c.cur_right,
                                             Eigen::Matrix2d::Identity(), o.lsm);
      if (!lc.ok) continue;
      c.prev_right = lp.target;
      c.cur_right = lc.target;
      c.sigma_prev_right = lp.sigma_px;
      c.sigma_cur_right = lc.sigma_px;
      // Intersect at both sites, in each site's body frame.
      bool good = true;
      for (int site = 0; site < 2 && good; ++site) {
        const MastPointing& mp = site == 0 ? tps.previous_pointing[c.prev_pair] : tps.current_pointing[c.cur_pair];
        const Pose3 bl = navcam_.mast.BodyFromLeft(mp.pan, mp.tilt, navcam_.rig);
        const Pose3 br = bl * navcam_.rig.left_from_right;
        const Eigen::Vector2d& ul = site == 0 ? c.prev_left : c.cur_left;
        const Eigen::Vector2d& ur = site == 0 ? c.prev_right : c.cur_right;
        const Eigen::Vector3d dl = bl.linear() * navcam_.rig.left.Ray(ul);
        const Eigen::Vector3d dr = br.linear() * navcam_.rig.right.Ray(ur);
        Eigen::Vector3d p;
        if (!Triangulate(bl.translation(), dl, br.translation(), dr, &p)) {
          good = false;
          break;
        }
        const double range = (p - bl.translation()).norm();
        const double sp = std::max(o.min_sigma_parallax, site == 0 ? lp.sigma_px : lc.sigma_px);
        const double sa = std::hypot(o.sigma_angle_px, c.sigma_cross) / focal;
        const Eigen::Matrix3d cov = StereoPointCovariance(p - bl.translation(), range, baseline, focal, sp, sa);
        if (site == 0) {
          c.p_prev = p;
          c.cov_prev = cov;
        } else {
          c.p_cur = p;
          c.cov_cur = cov;
        }
      }
      c.ok = good;
    }
    cands.erase(std::remove_if(cands.begin(), cands.end(), [](const Candidate& c) { return !c.ok; }), cands.end());
    stage("lsm", static_cast<int>(cands.size()), t0);

    // ---- distance consistency (eq. 2)
    t0 = Clock::now();
    std::vector<Eigen::Vector3d> p1, p2;
    std::vector<Eigen::Matrix3d> c1, c2;
    for (const auto& c : cands) {
      p1.push_back(c.p_prev);
      p2.push_back(c.p_cur);
      c1.push_back(c.cov_prev);
      c2.push_back(c.cov_cur);
    }
    const ConsistencyResult cons = DistanceConsistencyCheck(p1, c1, p2, c2, o.consistency);
    stage("consistency", cons.num_inliers, t0);
    // ---- motion consistency (one rigid motion, per-point covariances)
    t0 = Clock::now();
    std::vector<bool> keep = cons.inlier;
    if (o.motion_consistency) {
      std::vector<Eigen::Vector3d> q1, q2;
      std::vector<Eigen::Matrix3d> d1, d2;
      std::vector<size_t> where;
      for (size_t k = 0; k < cands.size(); ++k) {
        if (!cons.inlier[k]) continue;
        q1.push_back(p1[k]), q2.push_back(p2[k]), d1.push_back(c1[k]), d2.push_back(c2[k]);
        where.push_back(k);
      }
      const MotionConsistencyResult mc = MotionConsistencyCheck(q1, d1, q2, d2, o.motion);
      for (size_t q = 0; q < where.size(); ++q) keep[where[q]] = mc.ok && mc.inlier[q];
    }
    int id = 0;
    for (size_t k = 0; k < cands.size(); ++k) {
      if (!keep[k]) continue;
      const Candidate& c = cands[k];
      TiePoint tp;
      tp.id = id++;
      tp.p_previous = c.p_prev;
      tp.p_current = c.p_cur;
      tp.weight = cons.weights[k];
      // The cross-site error is split between the two left observations:
      // the floor in previous px, scaled to current px by the overlap's scale.
      const double cur_per_prev = 1.0 / std::max(pred.overlaps[c.overlap].scale, 1e-3);
      const double s_prev = std::max(c.sigma_cross / cur_per_prev, o.cross_sigma_floor_px) / std::sqrt(2.0);
      const double s_cur = std::max(c.sigma_cross, o.cross_sigma_floor_px * cur_per_prev) / std::sqrt(2.0);
      tp.observations.push_back({SiteRole::kPrevious, c.prev_pair, CameraSide::kLeft, c.prev_left, s_prev});
      tp.observations.push_back({SiteRole::kPrevious, c.prev_pair, CameraSide::kRight, c.prev_right,
                                 std::hypot(std::max(c.sigma_prev_right, o.stereo_sigma_floor_px), s_prev)});
      tp.observations.push_back({SiteRole::kCurrent, c.cur_pair, CameraSide::kLeft, c.cur_left, s_cur});
      tp.observations.push_back({SiteRole::kCurrent, c.cur_pair, CameraSide::kRight, c.cur_right,
                                 std::hypot(std::max(c.sigma_cur_right, o.stereo_sigma_floor_px), s_cur)});
      VLOG(2) << "tie point at previous " << c.prev_left.transpose() << " range " << c.p_prev.norm() << " corr "
              << c.grid_correlation << " sigma_max " << c.grid_sigma_max << " affine " << c.grid_affine(0, 0) << " "
              << c.grid_affine(0, 1) << " " << c.grid_affine(1, 0) << " " << c.grid_affine(1, 1) << " weight "
              << cons.weights[k];
      tps.points.push_back(std::move(tp));
    }
    stage("motion", static_cast<int>(tps.points.size()), t0);
    // The distance check is blind to a set of matches that is wrong by one
    // rigid motion (repeated texture): compare the motion the tie points
    // imply with the dead-reckoning prediction.
    if (tps.points.size() >= 3 && o.max_motion_sigmas > 0) {
      Eigen::Matrix3Xd a(3, tps.points.size()), b(3, tps.points.size());
      for (size_t k = 0; k < tps.points.size(); ++k) {
        a.col(k) = tps.points[k].p_current;
        b.col(k) = tps.points[k].p_previous;
      }
      const Eigen::Matrix4d T = Eigen::umeyama(a, b, false);  // previous_from_current
      const Eigen::Vector3d dt = T.block<3, 1>(0, 3) - pred.previous_from_current.translation();
      const double dyaw = std::abs(WrapAngle(std::atan2(T(1, 0), T(0, 0)) -
                                             std::atan2(pred.previous_from_current.linear()(1, 0),
                                                        pred.previous_from_current.linear()(0, 0))));
      const double sp = std::max(std::hypot(pred.relative_sigma(0), pred.relative_sigma(1)), 0.05);
      const double sy = std::max(pred.relative_sigma(5), 1e-3);
      if (dt.head<2>().norm() > o.max_motion_sigmas * sp || dyaw > o.max_motion_sigmas * sy) {
        std::ostringstream os;
        os << "the " << tps.points.size() << " consistent tie points imply a motion " << dt.head<2>().norm()
           << " m / " << dyaw * 180 / M_PI << " deg from dead reckoning (beyond " << o.max_motion_sigmas
           << " sigma): likely repeated texture; not used";
        tps.points.clear();
        return finish(FrontendStatus::kTooFewPoints, os.str());
      }
    }
    if (static_cast<int>(tps.points.size()) < o.min_tie_points) {
      std::ostringstream os;
      os << "only " << tps.points.size() << " verified tie points (need " << o.min_tie_points << ")";
      if (cands.empty()) os << "; matches were lost before the consistency check";
      return finish(FrontendStatus::kTooFewPoints, os.str());
    }
    return finish(FrontendStatus::kOk, "");
  } catch (const std::exception& e) {
    result.tie_points.points.clear();
    return finish(FrontendStatus::kError, std::string("internal error: ") + e.what());
  }
}

}  // namespace vloc
