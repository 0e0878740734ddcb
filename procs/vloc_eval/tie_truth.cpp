#include "tie_truth.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "vloc/common/stats.h"

namespace vloc::eval {

namespace {

const TieObservation* Find(const TiePoint& tp, SiteRole site) {
  for (const auto& o : tp.observations)
    if (o.site == site && o.camera == CameraSide::kLeft) return &o;
  return nullptr;
}

// Signed relative range error (%) of a stereo point against the true point, both in the body frame.
double RangeErrorPct(const Pose3& body_from_left, const Eigen::Vector3d& stereo_body, const Eigen::Vector3d& true_body) {
  const Pose3 left_from_body = body_from_left.inverse();
  const double r_true = (left_from_body * true_body).norm();
  return 100.0 * ((left_from_body * stereo_body).norm() - r_true) / r_true;
}

struct PairCheck {
  std::vector<TieTruthPoint> points;  // the checked ones
  std::vector<double> range_prev_pct, range_cur_pct;
};

// One tie point, by its two left observations; false when the terrain gives no truth or the previous camera
// cannot see it.
bool CheckOne(const TiePointSet& set, const TiePoint& tp, const TieObservation* pl, const TieObservation* cl,
              const Pose3& world_from_previous, const Pose3& world_from_current, const NavcamModel& navcam,
              const sim::Terrain& terrain, const TieTruthOptions& o, PairCheck* out) {
  if (pl->pair_index >= static_cast<int>(set.previous_pointing.size()) ||
      cl->pair_index >= static_cast<int>(set.current_pointing.size()))
    return false;
  const MastPointing& mc = set.current_pointing[cl->pair_index];
  const MastPointing& mp = set.previous_pointing[pl->pair_index];
  const Pose3 body_from_cl = navcam.mast.BodyFromLeft(mc.pan, mc.tilt, navcam.rig);
  const Pose3 body_from_pl = navcam.mast.BodyFromLeft(mp.pan, mp.tilt, navcam.rig);
  const Pose3 world_from_cl = world_from_current * body_from_cl, world_from_pl = world_from_previous * body_from_pl;
  const Eigen::Vector3d dir = (world_from_cl.linear() * navcam.rig.left.Ray(cl->uv)).normalized();
  const auto hit = terrain.Raycast(world_from_cl.translation(), dir, o.max_range_m);
  if (!hit) return false;
  const Eigen::Vector3d x = world_from_cl.translation() + hit->range * dir;
  // Seen from the previous left camera?
  const Eigen::Vector3d to_x = x - world_from_pl.translation();
  const auto back = terrain.Raycast(world_from_pl.translation(), to_x.normalized(), o.max_range_m);
  if (!back || back->range < to_x.norm() - o.occlusion_tolerance_m) return false;
  const auto q = navcam.rig.left.ProjectIdeal(world_from_pl.inverse() * x);
  if (!q) return false;
  TieTruthPoint p;
  p.reference = set.previous_site_id;
  p.site = set.current_site_id;
  p.previous_pair = pl->pair_index;
  p.current_pair = cl->pair_index;
  p.previous_px = pl->uv;
  p.error_px = pl->uv - *q;
  p.range_m = to_x.norm();
  p.current_range_m = hit->range;
  out->points.push_back(p);
  out->range_prev_pct.push_back(RangeErrorPct(body_from_pl, tp.p_previous, world_from_previous.inverse() * x));
  out->range_cur_pct.push_back(RangeErrorPct(body_from_cl, tp.p_current, world_from_current.inverse() * x));
  return true;
}

}  // namespace

std::vector<TieTruthRow> CheckTiePoints(const std::vector<TiePointSet>& sets,
                                        const std::map<int, PoseWithCovariance>& truth, const NavcamModel& navcam,
                                        const sim::Terrain& terrain, const TieTruthOptions& o,
                                        std::vector<TieTruthPoint>* points) {
  std::vector<TieTruthRow> rows;
  for (const TiePointSet& set : sets) {
    const auto prev = truth.find(set.previous_site_id), cur = truth.find(set.current_site_id);
    if (prev == truth.end() || cur == truth.end()) continue;
    TieTruthRow row;
    row.reference = set.previous_site_id;
    row.site = set.current_site_id;
    PairCheck c;
    for (const TiePoint& tp : set.points) {
      const TieObservation *pl = Find(tp, SiteRole::kPrevious), *cl = Find(tp, SiteRole::kCurrent);
      if (!pl || !cl) continue;
      ++row.points;
      if (!CheckOne(set, tp, pl, cl, prev->second.pose, cur->second.pose, navcam, terrain, o, &c)) continue;
      ++row.checked;
      if (c.points.back().CoarseErrorPx() > o.wrong_px) ++row.wrong;
    }
    std::vector<double> cross_px, du_px, dv_px;
    for (const TieTruthPoint& p : c.points) {
      cross_px.push_back(p.CoarseErrorPx());
      du_px.push_back(p.error_px.x());
      dv_px.push_back(p.error_px.y());
    }
    row.cross_median_px = Quantile(cross_px, 0.5);
    row.cross_p90_px = Quantile(cross_px, 0.9);
    row.cross_median_du_px = Quantile(du_px, 0.5);
    row.cross_median_dv_px = Quantile(dv_px, 0.5);
    row.range_error_median_pct_previous = Quantile(c.range_prev_pct, 0.5);
    row.range_error_median_pct_current = Quantile(c.range_cur_pct, 0.5);
    rows.push_back(row);
    if (points) points->insert(points->end(), c.points.begin(), c.points.end());
  }
  return rows;
}

void WriteTieTruth(const std::vector<TieTruthRow>& rows, const std::vector<TieTruthPoint>& points,
                   const std::string& dir) {
  {
    std::ofstream f(dir + "/tiepoint_errors.csv");
    f << "reference,site,previous_pair,current_pair,u,v,err_u,err_v,range_m,current_range_m,coarse_err_px\n";
    for (const TieTruthPoint& p : points)
      f << p.reference << ',' << p.site << ',' << p.previous_pair << ',' << p.current_pair << ',' << p.previous_px.x()
        << ',' << p.previous_px.y() << ',' << p.error_px.x() << ',' << p.error_px.y() << ',' << p.range_m << ','
        << p.current_range_m << ',' << p.CoarseErrorPx() << '\n';
  }
  std::ofstream f(dir + "/tiepoints.csv");
  f << "reference,site,points,checked,wrong,cross_median_px,cross_p90_px,cross_median_du_px,cross_median_dv_px,"
       "range_err_median_pct_previous,"
       "range_err_median_pct_current\n";
  for (const TieTruthRow& r : rows)
    f << r.reference << ',' << r.site << ',' << r.points << ',' << r.checked << ',' << r.wrong << ','
      << r.cross_median_px << ',' << r.cross_p90_px << ',' << r.cross_median_du_px << ',' << r.cross_median_dv_px << ','
      << r.range_error_median_pct_previous << ','
      << r.range_error_median_pct_current << '\n';
}

std::string TieTruthSummary(const std::vector<TieTruthRow>& rows, const TieTruthOptions& options) {
  if (rows.empty()) return "";
  int points = 0, checked = 0, wrong = 0;
  std::vector<double> medians;
  for (const TieTruthRow& r : rows) {
    points += r.points;
    checked += r.checked;
    wrong += r.wrong;
    if (std::isfinite(r.cross_median_px)) medians.push_back(r.cross_median_px);
  }
  std::ostringstream os;
  os.setf(std::ios::fixed);
  os.precision(2);
  os << "tie points against the terrain: " << checked << " of " << points << " checked over " << rows.size()
     << " sets, " << wrong << " more than " << std::defaultfloat << options.wrong_px << std::fixed << " px off in the coarser image ("
     << (checked > 0 ? 100.0 * wrong / checked : 0.0) << " %); median per set " << Quantile(medians, 0.5) << " px\n";
  return os.str();
}

}  // namespace vloc::eval
