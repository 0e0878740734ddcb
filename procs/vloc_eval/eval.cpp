#include "eval.h"

#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include "vloc/common/stats.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/log_reader.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/localization_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/tie_points_t.hpp"
#include "vloc/traverse_t.hpp"
#include "vloc/uav_state_t.hpp"

namespace vloc::eval {

namespace {

template <class Msg>
bool DecodeEvent(const lcm::LogEvent& ev, Msg* msg) {
  return Decode(static_cast<const uint8_t*>(ev.data), static_cast<size_t>(ev.datalen), msg);
}

double Deg(double rad) { return rad * 180.0 / M_PI; }

double HeadingError(const Pose3& est, const Pose3& truth) { return Deg(std::abs(WrapAngle(Heading(est) - Heading(truth)))); }

// Angle between the world's up axis as the estimate and as the truth see it
// from the body, deg: roll / pitch error, whatever the heading error.
double TiltError(const Pose3& est, const Pose3& truth) {
  const double c = est.linear().row(2).dot(truth.linear().row(2));
  return Deg(std::acos(std::clamp(c, -1.0, 1.0)));
}

double VerticalError(const Pose3& est, const Pose3& truth) { return est.translation().z() - truth.translation().z(); }

double Pct(double err, double dist) { return dist > 0 ? 100.0 * err / dist : NAN; }

std::string F(double v, int prec = 3) {
  if (!std::isfinite(v)) return "-";
  std::ostringstream os;
  os << std::fixed << std::setprecision(prec) << v;
  return os.str();
}

// Absolute fixes (SITE_POSE_FIX) against the site's truth: error and NEES in x, y, heading.
void EvaluateFixes(const LogData& d, Summary* s) {
  std::vector<double> errs, headings;
  double nees2 = 0, nees3 = 0;
  int nees_count = 0;
  for (const auto& [id, fix] : d.fix) {
    const auto gt = d.gt.find(id);
    if (gt == d.gt.end()) continue;
    FixRow r;
    r.site = id;
    r.x = fix.pose.translation().x();
    r.y = fix.pose.translation().y();
    r.heading_deg = Deg(Heading(fix.pose));
    r.err_x = r.x - gt->second.pose.translation().x();
    r.err_y = r.y - gt->second.pose.translation().y();
    r.err_xy = std::hypot(r.err_x, r.err_y);
    const double dh = WrapAngle(Heading(fix.pose) - Heading(gt->second.pose));
    r.heading_err_deg = Deg(dh);
    Eigen::Matrix3d cov;  // x, y, yaw of the 6x6 (x y z roll pitch yaw)
    const int idx[3] = {0, 1, 5};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) cov(i, j) = fix.covariance(idx[i], idx[j]);
    r.sigma_x = std::sqrt(std::max(0.0, cov(0, 0)));
    r.sigma_y = std::sqrt(std::max(0.0, cov(1, 1)));
    r.sigma_heading_deg = Deg(std::sqrt(std::max(0.0, cov(2, 2))));
    const Eigen::Vector3d e(r.err_x, r.err_y, dh);
    if (cov.determinant() > 0) {
      r.nees_xy = e.head<2>().dot(cov.topLeftCorner<2, 2>().ldlt().solve(e.head<2>()));
      r.nees_xyh = e.dot(cov.ldlt().solve(e));
      nees2 += r.nees_xy;
      nees3 += r.nees_xyh;
      ++nees_count;
    }
    errs.push_back(r.err_xy);
    headings.push_back(std::abs(r.heading_err_deg));
    s->fixes.push_back(r);
  }
  if (!errs.empty()) {
    s->fix_median_err = Median(errs);
    s->fix_max_err = *std::max_element(errs.begin(), errs.end());
    s->fix_median_heading = Median(headings);
    s->fix_max_heading = *std::max_element(headings.begin(), headings.end());
  }
  if (nees_count) {
    s->fix_mean_nees_xy = nees2 / nees_count;
    s->fix_mean_nees_xyh = nees3 / nees_count;
  }
}

}  // namespace

LogData ReadLog(const std::string& path, bool progress) {
  LogReader log(path);
  if (!log.good()) throw std::runtime_error(log.error());
  LogData d;
  const double size = static_cast<double>(log.file_size());
  int last_pct = -1;
  while (const lcm::LogEvent* ev = log.Next()) {
    ++d.messages;
    if (progress && size > 0) {
      const int pct = static_cast<int>(100.0 * static_cast<double>(log.position()) / size);
      if (pct / 5 != last_pct / 5) {
        std::fprintf(stderr, "\rvloc_eval: reading %s: %3d %%", path.c_str(), pct);
        last_pct = pct;
      }
    }
    const std::string& ch = ev->channel;
    try {
      if (ch == "SITE_POSE_GT" || ch == "SITE_POSE_DR" || ch == "SITE_POSE_FIX") {
        site_pose_t m;
        if (!DecodeEvent(*ev, &m)) throw std::invalid_argument("decode");
        (ch == "SITE_POSE_GT" ? d.gt : ch == "SITE_POSE_DR" ? d.dr : d.fix)[m.site_id] = PoseFromMessage(m.pose);
      } else if (ch == "SITE_POSE_VISUAL") {
        localization_t m;
        if (!DecodeEvent(*ev, &m)) throw std::invalid_argument("decode");
        VisualPair p;
        p.reference = m.reference_site_id;
        p.site = m.site_id;
        p.status = m.status;
        p.relative = PoseFromMessage(m.relative_pose);
        p.pose = PoseFromMessage(m.pose);
        d.visual.push_back(p);
      } else if (ch == "TIE_POINTS") {
        tie_points_t m;
        if (!DecodeEvent(*ev, &m)) throw std::invalid_argument("decode");
        d.tie_points.push_back(TiePointsFromMessage(m));
      } else if (ch == "TRAVERSE") {
        traverse_t m;
        if (!DecodeEvent(*ev, &m)) throw std::invalid_argument("decode");
        d.traverse.clear();
        for (int i = 0; i < m.num_sites; ++i) d.traverse[m.site_ids[i]] = PoseFromMessage(m.poses[i]);
      } else if (ch == "UAV_GT") {
        pose_t m;
        if (!DecodeEvent(*ev, &m)) throw std::invalid_argument("decode");
        d.uav_gt.emplace_back(m.utime, PoseFromMessage(m).pose);
      } else if (ch == "UAV_STATE") {
        uav_state_t m;
        if (!DecodeEvent(*ev, &m)) throw std::invalid_argument("decode");
        d.uav_state.push_back({m.utime, m.height, m.route_local[0], m.route_local[1], m.status});
      }
    } catch (const std::exception&) {
      ++d.decode_failures;
    }
  }
  if (progress) std::fprintf(stderr, "\rvloc_eval: reading %s: 100 %%\n", path.c_str());
  d.read_problem = log.EndProblem();
  return d;
}

namespace {

// The sites with ground truth, in id order, with the distance driven along
// them and their dead-reckoning and optimised errors.
std::vector<SiteRow> SiteRows(const LogData& d) {
  std::vector<SiteRow> sites;
  double dist = 0;
  const Pose3* prev = nullptr;
  for (const auto& [id, gt] : d.gt) {
    if (prev) dist += (gt.pose.translation() - prev->translation()).norm();
    prev = &gt.pose;
    SiteRow r;
    r.site = id;
    r.distance = dist;
    r.gt = gt.pose;
    if (auto it = d.dr.find(id); it != d.dr.end()) {
      r.has_dr = true;
      r.dr = it->second.pose;
      r.dr_err = (r.dr.translation() - r.gt.translation()).norm();
      r.dr_heading_err = HeadingError(r.dr, r.gt);
    }
    if (auto it = d.traverse.find(id); it != d.traverse.end()) {
      r.has_opt = true;
      r.opt = it->second.pose;
      r.opt_cov = it->second.covariance;
      r.opt_err = (r.opt.translation() - r.gt.translation()).norm();
      r.opt_heading_err = HeadingError(r.opt, r.gt);
    }
    sites.push_back(r);
  }
  return sites;
}

// The visual pairs against the truth (new-site error, NEES), and each
// site's chained visual pose (the BA's own world pose, last OK result).
void EvaluatePairs(const LogData& d, Summary* s) {
  std::vector<double> pcts;
  double nees_sum = 0;
  int nees_n = 0;
  for (const VisualPair& p : d.visual) {
    PairRow row;
    row.reference = p.reference;
    row.site = p.site;
    row.status = p.status;
    const auto ref = d.gt.find(p.reference), cur = d.gt.find(p.site);
    if (ref != d.gt.end() && cur != d.gt.end()) {
      const Pose3 true_rel = ref->second.pose.inverse() * cur->second.pose;
      row.spacing = true_rel.translation().norm();
      if (p.status == 0) {
        const Eigen::Vector3d e = p.relative.pose.translation() - true_rel.translation();  // reference frame
        row.err = e.norm();
        row.err_xyz = e;
        row.err_pct = Pct(row.err, row.spacing);
        pcts.push_back(row.err_pct);
        const Eigen::Matrix3d cov = p.relative.covariance.topLeftCorner<3, 3>();
        row.sigma_xyz = cov.diagonal().cwiseMax(0.0).cwiseSqrt();
        if (cov.determinant() > 0) {
          row.nees = e.dot(cov.ldlt().solve(e));
          nees_sum += row.nees;
          ++nees_n;
        }
        ++s->pairs_ok;
      }
    }
    s->pairs.push_back(row);
    if (p.status == 0)
      for (SiteRow& r : s->sites)
        if (r.site == p.site) {
          r.has_visual = true;
          r.visual = p.pose.pose;
          r.vis_err = (r.visual.translation() - r.gt.translation()).norm();
          r.vis_heading_err = HeadingError(r.visual, r.gt);
        }
  }
  if (!pcts.empty()) s->pair_median_pct = Median(pcts);
  if (nees_n) s->pair_mean_nees = nees_sum / nees_n;
}

// The errors at the last site with ground truth.
void EndOfTraverse(Summary* s) {
  if (s->sites.empty()) return;
  const SiteRow& last = s->sites.back();
  s->distance = last.distance;
  s->dr_end = last.dr_err;
  s->vis_end = last.vis_err;
  s->opt_end = last.opt_err;
  s->dr_end_heading = last.dr_heading_err;
  s->vis_end_heading = last.vis_heading_err;
  s->opt_end_heading = last.opt_heading_err;
  if (last.has_dr) s->dr_end_vertical = VerticalError(last.dr, last.gt), s->dr_end_tilt = TiltError(last.dr, last.gt);
  if (last.has_visual)
    s->vis_end_vertical = VerticalError(last.visual, last.gt), s->vis_end_tilt = TiltError(last.visual, last.gt);
  if (last.has_opt) s->opt_end_vertical = VerticalError(last.opt, last.gt), s->opt_end_tilt = TiltError(last.opt, last.gt);
}

// The UAV: each state matched to the ground truth nearest in time (none
// further than 0.1 s), the height and route errors.
void EvaluateUav(const LogData& d, Summary* s) {
  if (d.uav_gt.empty() || d.uav_state.empty()) return;
  std::vector<double> flown(d.uav_gt.size(), 0.0);
  for (size_t i = 1; i < d.uav_gt.size(); ++i)
    flown[i] = flown[i - 1] + (d.uav_gt[i].second.translation() - d.uav_gt[i - 1].second.translation()).head<2>().norm();
  const Eigen::Vector2d takeoff = d.uav_gt.front().second.translation().head<2>();
  const int64_t t0 = d.uav_gt.front().first;
  double sq = 0, sq_pct = 0;
  int height_samples = 0;
  for (const UavSample& u : d.uav_state) {
    auto it = std::lower_bound(d.uav_gt.begin(), d.uav_gt.end(), u.utime,
                               [](const auto& a, int64_t t) { return a.first < t; });
    if (it == d.uav_gt.end()) --it;
    if (it != d.uav_gt.begin() && std::llabs(std::prev(it)->first - u.utime) < std::llabs(it->first - u.utime)) --it;
    if (std::llabs(it->first - u.utime) > 100000) continue;  // no truth within 0.1 s
    UavRow r;
    r.utime = u.utime;
    r.t = 1e-6 * static_cast<double>(u.utime - t0);
    r.height = u.height;
    r.gt_height = it->second.translation().z();
    r.east = u.east;
    r.north = u.north;
    r.gt_east = it->second.translation().x() - takeoff.x();
    r.gt_north = it->second.translation().y() - takeoff.y();
    r.flown = flown[static_cast<size_t>(it - d.uav_gt.begin())];
    // While calibrating on the marker the mosaicker has no height yet;
    // every later frame counts (a lost frame keeps its last height).
    if (u.status != uav_state_t::STATUS_CALIBRATING && std::isfinite(r.height) && r.gt_height > 0) {
      ++height_samples;
      sq += (r.height - r.gt_height) * (r.height - r.gt_height);
      sq_pct += std::pow(100.0 * (r.height - r.gt_height) / r.gt_height, 2);
    }
    s->uav.push_back(r);
  }
  if (s->uav.empty()) return;
  s->uav_height_rms = std::sqrt(sq / std::max(1, height_samples));
  s->uav_height_rms_pct = std::sqrt(sq_pct / std::max(1, height_samples));
  const UavRow& e = s->uav.back();
  s->uav_flown = e.flown;
  s->uav_route_end = std::hypot(e.east - e.gt_east, e.north - e.gt_north);
  s->uav_route_end_pct = Pct(s->uav_route_end, e.flown);
}

// `dir`/`name` opened for writing, numbers with 10 digits.
std::ofstream OpenOutput(const std::string& dir, const std::string& name) {
  std::ofstream f(dir + "/" + name);
  if (!f) throw std::runtime_error("cannot write " + dir + "/" + name);
  f << std::setprecision(10);
  return f;
}

void WriteSites(const Summary& s, std::ofstream& f) {
  f << "site,distance_m,gt_x,gt_y,gt_z,gt_heading_deg,dr_x,dr_y,dr_err_m,dr_err_pct,dr_heading_err_deg,"
       "vis_x,vis_y,vis_err_m,vis_err_pct,vis_heading_err_deg,opt_x,opt_y,opt_err_m,opt_err_pct,"
       "opt_heading_err_deg,opt_cov_xx,opt_cov_xy,opt_cov_yy,opt_z,opt_tilt_err_deg,opt_sigma_z,dr_tilt_err_deg,"
       "dr_up_err_x,dr_up_err_y\n";
  for (const SiteRow& r : s.sites) {
    auto xy = [&](bool has, const Pose3& p) {
      return has ? std::to_string(p.translation().x()) + "," + std::to_string(p.translation().y()) : ",";
    };
    auto num = [](double v) { return std::isfinite(v) ? std::to_string(v) : std::string(); };
    f << r.site << ',' << r.distance << ',' << r.gt.translation().x() << ',' << r.gt.translation().y() << ','
      << r.gt.translation().z() << ',' << Deg(Heading(r.gt)) << ',' << xy(r.has_dr, r.dr) << ',' << num(r.dr_err)
      << ',' << num(Pct(r.dr_err, r.distance)) << ',' << num(r.dr_heading_err) << ',' << xy(r.has_visual, r.visual)
      << ',' << num(r.vis_err) << ',' << num(Pct(r.vis_err, r.distance)) << ',' << num(r.vis_heading_err) << ','
      << xy(r.has_opt, r.opt) << ',' << num(r.opt_err) << ',' << num(Pct(r.opt_err, r.distance)) << ','
      << num(r.opt_heading_err) << ',' << r.opt_cov(0, 0) << ',' << r.opt_cov(0, 1) << ',' << r.opt_cov(1, 1);
    // The DR's up-axis error in the body frame (x, y): what an accelerometer bias fixed to the body leaves.
    const Eigen::Vector3d dr_up_err = (r.dr.linear().row(2) - r.gt.linear().row(2)).transpose();
    for (const double v : {r.has_opt ? r.opt.translation().z() : NAN, r.has_opt ? TiltError(r.opt, r.gt) : NAN,
                           r.has_opt ? std::sqrt(r.opt_cov(2, 2)) : NAN, r.has_dr ? TiltError(r.dr, r.gt) : NAN,
                           r.has_dr ? dr_up_err.x() : NAN, r.has_dr ? dr_up_err.y() : NAN}) {
      f << ',';
      if (std::isfinite(v)) f << v;
    }
    f << '\n';
  }
}

void WritePairs(const Summary& s, std::ofstream& f) {
  f << "reference,site,status,spacing_m,err_m,err_pct,nees,err_x,err_y,err_z,sigma_x,sigma_y,sigma_z\n";
  for (const PairRow& p : s.pairs) {
    f << p.reference << ',' << p.site << ',' << p.status << ',' << p.spacing << ',' << F(p.err, 6) << ','
      << F(p.err_pct, 6) << ',' << F(p.nees, 6);
    for (int i = 0; i < 3; ++i) f << ',' << F(p.err_xyz[i], 6);
    for (int i = 0; i < 3; ++i) f << ',' << F(p.sigma_xyz[i], 6);
    f << '\n';
  }
}

void WriteFixes(const Summary& s, std::ofstream& f) {
  f << "site,x,y,heading_deg,sigma_x,sigma_y,sigma_heading_deg,err_x,err_y,err_xy,heading_err_deg,nees_xy,nees_xyh\n";
  for (const FixRow& r : s.fixes)
    f << r.site << ',' << r.x << ',' << r.y << ',' << r.heading_deg << ',' << r.sigma_x << ',' << r.sigma_y << ','
      << r.sigma_heading_deg << ',' << r.err_x << ',' << r.err_y << ',' << r.err_xy << ',' << r.heading_err_deg << ','
      << F(r.nees_xy, 4) << ',' << F(r.nees_xyh, 4) << '\n';
}

void WriteUav(const Summary& s, std::ofstream& f) {
  f << "utime,t_s,height_m,gt_height_m,height_err_m,east_m,north_m,gt_east_m,gt_north_m,route_err_m,flown_m\n";
  for (const UavRow& u : s.uav)
    f << u.utime << ',' << u.t << ',' << u.height << ',' << u.gt_height << ',' << u.height - u.gt_height << ','
      << u.east << ',' << u.north << ',' << u.gt_east << ',' << u.gt_north << ','
      << std::hypot(u.east - u.gt_east, u.north - u.gt_north) << ',' << u.flown << '\n';
}

// report.md: the short table, then per site, per map fix and per pair.
void WriteReport(const Summary& s, std::ofstream& f) {
  f << "# vloc evaluation\n\n" << ShortTable(s) << "\n";
  if (!s.sites.empty()) {
    f << "## Per site\n\n| site | distance m | DR err m | DR % | DR heading deg | visual err m | visual % | "
         "optimised err m | optimised % | optimised heading deg |\n|---|---|---|---|---|---|---|---|---|---|\n";
    for (const SiteRow& r : s.sites)
      f << "| " << r.site << " | " << F(r.distance, 1) << " | " << F(r.dr_err) << " | "
        << F(Pct(r.dr_err, r.distance), 2) << " | " << F(r.dr_heading_err, 2) << " | " << F(r.vis_err) << " | "
        << F(Pct(r.vis_err, r.distance), 2) << " | " << F(r.opt_err) << " | " << F(Pct(r.opt_err, r.distance), 2)
        << " | " << F(r.opt_heading_err, 2) << " |\n";
    f << "\n";
  }
  if (!s.fixes.empty()) {
    f << "## Absolute fixes against the map (SITE_POSE_FIX)\n\n| site | error m | error x m | error y m | "
         "sigma x / y m | heading error deg | sigma deg | NEES xy (2) | NEES xyh (3) |\n"
         "|---|---|---|---|---|---|---|---|---|\n";
    for (const FixRow& r : s.fixes)
      f << "| " << r.site << " | " << F(r.err_xy) << " | " << F(r.err_x) << " | " << F(r.err_y) << " | "
        << F(r.sigma_x) << " / " << F(r.sigma_y) << " | " << F(r.heading_err_deg, 2) << " | "
        << F(r.sigma_heading_deg, 2) << " | " << F(r.nees_xy, 2) << " | " << F(r.nees_xyh, 2) << " |\n";
    f << "\n";
  }
  if (!s.pairs.empty()) {
    f << "## Visual localization per pair\n\n| reference | site | status | spacing m | error m | error % of "
         "spacing | NEES (3 dof) |\n|---|---|---|---|---|---|---|\n";
    for (const PairRow& p : s.pairs)
      f << "| " << p.reference << " | " << p.site << " | " << p.status << " | " << F(p.spacing, 2) << " | "
        << F(p.err, 4) << " | " << F(p.err_pct, 3) << " | " << F(p.nees, 2) << " |\n";
    f << "\n";
  }
}

}  // namespace

Summary Evaluate(const LogData& d) {
  Summary s;
  s.sites = SiteRows(d);
  EvaluatePairs(d, &s);
  EndOfTraverse(&s);
  EvaluateFixes(d, &s);
  EvaluateUav(d, &s);
  return s;
}

void WriteOutputs(const Summary& s, const std::string& dir) {
  std::filesystem::create_directories(dir);
  const std::pair<const char*, void (*)(const Summary&, std::ofstream&)> files[] = {
      {"sites.csv", WriteSites}, {"pairs.csv", WritePairs}, {"fixes.csv", WriteFixes}, {"uav.csv", WriteUav},
      {"summary.md", [](const Summary& sum, std::ofstream& f) { f << ShortTable(sum); }}, {"report.md", WriteReport}};
  for (const auto& [name, write] : files) {
    std::ofstream f = OpenOutput(dir, name);
    write(s, f);
  }
}

std::string ShortTable(const Summary& s) {
  std::ostringstream os;
  if (!s.sites.empty()) {
    os << "| rover, end of traverse (" << s.sites.size() << " sites, " << F(s.distance, 1)
       << " m) | position error m | % of distance | heading error deg | of which vertical m | tilt error deg |\n"
       << "|---|---|---|---|---|---|\n";
    os << "| dead reckoning | " << F(s.dr_end) << " | " << F(Pct(s.dr_end, s.distance), 2) << " | "
       << F(s.dr_end_heading, 2) << " | " << F(s.dr_end_vertical) << " | " << F(s.dr_end_tilt, 3) << " |\n";
    os << "| chained visual | " << F(s.vis_end) << " | " << F(Pct(s.vis_end, s.distance), 2) << " | "
       << F(s.vis_end_heading, 2) << " | " << F(s.vis_end_vertical) << " | " << F(s.vis_end_tilt, 3) << " |\n";
    os << "| optimised graph | " << F(s.opt_end) << " | " << F(Pct(s.opt_end, s.distance), 2) << " | "
       << F(s.opt_end_heading, 2) << " | " << F(s.opt_end_vertical) << " | " << F(s.opt_end_tilt, 3) << " |\n\n";
    os << "visual pairs OK: " << s.pairs_ok << " of " << s.pairs.size() << "; median new-site error "
       << F(s.pair_median_pct, 3) << " % of spacing; mean NEES " << F(s.pair_mean_nees, 2) << " (3 expected)\n";
    if (!s.fixes.empty())
      os << "map fixes: " << s.fixes.size() << "; horizontal error median " << F(s.fix_median_err) << " m (max "
         << F(s.fix_max_err) << "), heading median " << F(s.fix_median_heading, 2) << " deg (max "
         << F(s.fix_max_heading, 2) << "); mean NEES " << F(s.fix_mean_nees_xy, 2) << " (xy, 2 expected) / "
         << F(s.fix_mean_nees_xyh, 2) << " (xyh, 3)\n";
  }
  if (!s.uav.empty()) {
    os << "\n| UAV (" << s.uav.size() << " frames, " << F(s.uav_flown, 1) << " m flown) | value |\n|---|---|\n";
    os << "| height error RMS m | " << F(s.uav_height_rms) << " |\n";
    os << "| height error RMS % of true height | " << F(s.uav_height_rms_pct, 2) << " |\n";
    os << "| route error at end m | " << F(s.uav_route_end) << " |\n";
    os << "| route error % of distance flown | " << F(s.uav_route_end_pct, 2) << " |\n";
  }
  if (s.sites.empty() && s.uav.empty()) os << "no ground truth (SITE_POSE_GT or UAV_GT) in the log\n";
  return os.str();
}

}  // namespace vloc::eval
