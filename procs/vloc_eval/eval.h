#pragma once
// vloc_eval: accuracy of a recorded run against the ground truth in its log.
// Reads SITE_POSE_GT / SITE_POSE_DR / SITE_POSE_FIX (site_pose_t; FIX: the
// map_localizer's absolute fixes), SITE_POSE_VISUAL (localization_t),
// TIE_POINTS (tie_points_t; checked against the terrain: tie_truth.h), the
// last TRAVERSE (traverse_t), UAV_GT (pose_t) and UAV_STATE (uav_state_t);
// writes CSVs and report.md into an output folder.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "vloc/common/pose.h"
#include "vloc/common/rover_data.h"

namespace vloc::eval {

struct VisualPair {
  int reference = -1, site = -1, status = 0;
  PoseWithCovariance relative;  // reference_from_current
  PoseWithCovariance pose;      // world_from_body of site
};

struct UavSample {
  int64_t utime = 0;
  double height = 0, east = 0, north = 0;
  int status = 0;
};

// Everything read from a log.
struct LogData {
  std::map<int, PoseWithCovariance> gt, dr;
  std::map<int, PoseWithCovariance> fix;       // SITE_POSE_FIX, the last per site
  std::vector<VisualPair> visual;
  std::map<int, PoseWithCovariance> traverse;  // the last TRAVERSE
  std::vector<TiePointSet> tie_points;         // TIE_POINTS, every set
  std::vector<std::pair<int64_t, Pose3>> uav_gt;
  std::vector<UavSample> uav_state;
  int64_t messages = 0, decode_failures = 0;
  std::string read_problem;  // "" when the whole log was read; else where and why it stopped
};

// Reads the log, printing progress (% of bytes) to stderr when `progress`.
// Throws std::runtime_error naming the file when it cannot be read.
LogData ReadLog(const std::string& path, bool progress);

struct SiteRow {
  int site = 0;
  double distance = 0;  // m driven from site 0 (ground truth, site to site)
  Pose3 gt;
  bool has_dr = false, has_visual = false, has_opt = false;
  Pose3 dr, visual, opt;
  Matrix6d opt_cov = Matrix6d::Zero();
  double dr_err = NAN, dr_heading_err = NAN, vis_err = NAN, vis_heading_err = NAN, opt_err = NAN,
         opt_heading_err = NAN;  // m, deg
};

struct PairRow {
  int reference = 0, site = 0, status = 0;
  double spacing = 0, err = NAN, err_pct = NAN, nees = NAN;
  Eigen::Vector3d err_xyz = Eigen::Vector3d::Constant(NAN);    // m, estimate - truth in the reference site's frame
  Eigen::Vector3d sigma_xyz = Eigen::Vector3d::Constant(NAN);  // m, the BA's stated sigma per axis
};

// An absolute fix against a map (SITE_POSE_FIX) against the site's truth.
struct FixRow {
  int site = 0;
  double x = 0, y = 0, heading_deg = 0, sigma_x = 0, sigma_y = 0, sigma_heading_deg = 0;
  double err_x = 0, err_y = 0, err_xy = 0, heading_err_deg = 0;  // fix - truth (m, m, m, deg signed)
  double nees_xy = NAN, nees_xyh = NAN;                           // dim 2 / 3, with the fix's covariance
};

struct UavRow {
  int64_t utime = 0;
  double t = 0, height = 0, gt_height = 0, east = 0, north = 0, gt_east = 0, gt_north = 0, flown = 0;
};

struct Summary {
  std::vector<SiteRow> sites;
  std::vector<PairRow> pairs;
  std::vector<FixRow> fixes;
  double fix_median_err = NAN, fix_max_err = NAN, fix_median_heading = NAN, fix_max_heading = NAN,
         fix_mean_nees_xy = NAN, fix_mean_nees_xyh = NAN;
  std::vector<UavRow> uav;
  // End of traverse (last site with ground truth), m and % of distance.
  double distance = 0;
  double dr_end = NAN, vis_end = NAN, opt_end = NAN;
  double dr_end_heading = NAN, vis_end_heading = NAN, opt_end_heading = NAN;
  // Of the end position error, the vertical part (m, signed, estimate - truth) and the error of the
  // estimated up axis (deg): a tilt carried from the first site turns every step's height.
  double dr_end_vertical = NAN, vis_end_vertical = NAN, opt_end_vertical = NAN;
  double dr_end_tilt = NAN, vis_end_tilt = NAN, opt_end_tilt = NAN;
  double pair_median_pct = NAN, pair_mean_nees = NAN;
  int pairs_ok = 0;
  double uav_height_rms = NAN, uav_height_rms_pct = NAN, uav_route_end = NAN, uav_route_end_pct = NAN,
         uav_flown = 0;
};

Summary Evaluate(const LogData& data);

// Writes sites.csv, pairs.csv, fixes.csv, uav.csv and report.md into `dir` (created).
void WriteOutputs(const Summary& s, const std::string& dir);
// The short accuracy table printed to stdout.
std::string ShortTable(const Summary& s);

}  // namespace vloc::eval
