#include "shared_view.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "vloc/common/stats.h"

namespace vloc::eval {

namespace {

struct SiteCameras {
  std::vector<Pose3> world_from_left;  // per pointing
};

SiteCameras CamerasAt(const Pose3& world_from_body, const std::vector<MastPointing>& pointing,
                      const NavcamModel& navcam) {
  SiteCameras c;
  for (const MastPointing& p : pointing)
    c.world_from_left.push_back(world_from_body * navcam.mast.BodyFromLeft(p.pan, p.tilt, navcam.rig));
  return c;
}

// The ground point of one previous-left pixel within range, if its ray meets the terrain there.
std::optional<Eigen::Vector3d> GroundAt(const Pose3& world_from_left, const Eigen::Vector2d& px,
                                        const NavcamModel& navcam, const sim::Terrain& terrain, double max_range) {
  const Eigen::Vector3d dir = (world_from_left.linear() * navcam.rig.left.Ray(px)).normalized();
  const auto hit = terrain.Raycast(world_from_left.translation(), dir, max_range);
  if (!hit) return std::nullopt;
  return world_from_left.translation() + hit->range * dir;
}

// Image px per metre of ground along the tangent basis `t` (3 x 2, world) at `x`, seen by `world_from_cam`.
Eigen::Matrix2d GroundToImage(const Pose3& world_from_cam, const Eigen::Vector3d& x, const Eigen::Matrix<double, 3, 2>& t,
                              const PinholeCamera& cam) {
  const Eigen::Vector3d p = world_from_cam.inverse() * x;
  Eigen::Matrix<double, 2, 3> d;
  d << cam.fx / p.z(), 0, -cam.fx * p.x() / (p.z() * p.z()), 0, cam.fy / p.z(), -cam.fy * p.y() / (p.z() * p.z());
  return d * world_from_cam.linear().transpose() * t;
}

// Affine tilt (ratio of singular values) of the map from the previous view of the ground at `x` to the current one.
double ViewTilt(const Pose3& previous, const Pose3& current, const Eigen::Vector3d& x, const sim::Terrain& terrain,
                const PinholeCamera& cam) {
  const Eigen::Vector3d n = terrain.Normal(x.x(), x.y());
  const Eigen::Vector3d e1 = n.unitOrthogonal(), e2 = n.cross(e1);
  Eigen::Matrix<double, 3, 2> t;
  t << e1, e2;
  const Eigen::Matrix2d a = GroundToImage(current, x, t, cam) * GroundToImage(previous, x, t, cam).inverse();
  const Eigen::Vector2d s = Eigen::JacobiSVD<Eigen::Matrix2d>(a).singularValues();
  return s(1) > 1e-12 ? s(0) / s(1) : INFINITY;
}

// The first current left camera that sees `x` in its image, unoccluded and within range; null if none.
const Pose3* SeenFrom(const SiteCameras& current, const Eigen::Vector3d& x, const NavcamModel& navcam,
                      const sim::Terrain& terrain, const SharedViewOptions& o) {
  for (const Pose3& cam : current.world_from_left) {
    const Eigen::Vector3d to_x = x - cam.translation();
    const double range = to_x.norm();
    if (range < o.min_range_current_m || range > o.max_range_current_m) continue;
    const auto px = navcam.rig.left.ProjectIdeal(cam.inverse() * x);
    if (!px || !navcam.rig.left.InImage(*px)) continue;
    const auto hit = terrain.Raycast(cam.translation(), to_x / range, range + 1.0);
    if (hit && hit->range < range - o.occlusion_tolerance_m) continue;
    return &cam;
  }
  return nullptr;
}

SharedViewRow SharedView(const SiteCameras& previous, const SiteCameras& current, const NavcamModel& navcam,
                         const sim::Terrain& terrain, const SharedViewOptions& o) {
  SharedViewRow row;
  std::vector<double> ratios, tilts;
  const PinholeCamera& cam = navcam.rig.left;
  for (const Pose3& world_from_left : previous.world_from_left)
    for (int v = o.grid_px / 2; v < cam.height; v += o.grid_px)
      for (int u = o.grid_px / 2; u < cam.width; u += o.grid_px) {
        const auto x = GroundAt(world_from_left, Eigen::Vector2d(u, v), navcam, terrain, o.max_range_previous_m);
        if (!x) continue;
        ++row.samples;
        const Pose3* seen = SeenFrom(current, *x, navcam, terrain, o);
        if (!seen) continue;
        ++row.shared;
        ratios.push_back((*x - seen->translation()).norm() / (*x - world_from_left.translation()).norm());
        tilts.push_back(ViewTilt(world_from_left, *seen, *x, terrain, cam));
        if (tilts.back() <= o.max_tilt) ++row.matchable;
      }
  row.median_range_ratio = Median(ratios);
  row.median_tilt = Median(tilts);
  return row;
}

}  // namespace

std::vector<SharedViewRow> SharedViews(const std::map<int, PoseWithCovariance>& truth,
                                       const std::vector<MastPointing>& pointing, const NavcamModel& navcam,
                                       const sim::Terrain& terrain, const SharedViewOptions& o) {
  std::vector<SharedViewRow> rows;
  for (auto it = truth.begin(); it != truth.end() && std::next(it) != truth.end(); ++it) {
    const auto next = std::next(it);
    SharedViewRow row = SharedView(CamerasAt(it->second.pose, pointing, navcam),
                                   CamerasAt(next->second.pose, pointing, navcam), navcam, terrain, o);
    row.reference = it->first;
    row.site = next->first;
    rows.push_back(row);
  }
  return rows;
}

void WriteSharedViews(const std::vector<SharedViewRow>& rows, const std::string& dir) {
  std::ofstream f(dir + "/shared_view.csv");
  f << "reference,site,samples,shared,shared_pct,matchable,matchable_pct,median_range_ratio,median_tilt\n";
  for (const SharedViewRow& r : rows)
    f << r.reference << ',' << r.site << ',' << r.samples << ',' << r.shared << ',' << r.SharedPct() << ','
      << r.matchable << ',' << r.MatchablePct() << ',' << r.median_range_ratio << ',' << r.median_tilt << '\n';
}

std::string SharedViewSummary(const std::vector<SharedViewRow>& rows, const std::vector<TiePointSet>& localized,
                              const SharedViewOptions& options) {
  if (rows.empty()) return "";
  std::set<std::pair<int, int>> with_ties;
  for (const TiePointSet& s : localized) with_ties.insert({s.previous_site_id, s.current_site_id});
  std::vector<double> pct_localized, matchable_localized;
  std::ostringstream failed;
  failed.setf(std::ios::fixed);
  failed.precision(1);
  for (const SharedViewRow& r : rows) {
    if (with_ties.count({r.reference, r.site})) {
      pct_localized.push_back(r.SharedPct());
      matchable_localized.push_back(r.MatchablePct());
    } else {
      failed << (failed.tellp() > 0 ? ", " : "") << r.reference << " -> " << r.site << ": " << r.SharedPct()
             << " %, matchable " << r.MatchablePct() << " % (range ratio " << r.median_range_ratio << ", tilt "
             << r.median_tilt << ")";
    }
  }
  std::ostringstream os;
  os.setf(std::ios::fixed);
  os.precision(1);
  os << "shared view (previous site's ground within range seen again from the current site): pairs with tie points "
     << "median " << Median(pct_localized) << " %, lowest " << Quantile(pct_localized, 0.0) << " %; matchable (tilt <= "
     << std::defaultfloat << options.max_tilt << std::fixed << ") median " << Median(matchable_localized) << " %, lowest "
     << Quantile(matchable_localized, 0.0) << " %";
  if (failed.tellp() > 0) os << "; pairs without: " << failed.str();
  os << "\n";
  return os.str();
}

}  // namespace vloc::eval
