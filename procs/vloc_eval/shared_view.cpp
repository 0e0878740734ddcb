#include "shared_view.h"

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

// Range from the first current left camera that sees `x` in its image, unoccluded and within range; 0 if none.
double SeenFrom(const SiteCameras& current, const Eigen::Vector3d& x, const NavcamModel& navcam,
                const sim::Terrain& terrain, const SharedViewOptions& o) {
  for (const Pose3& cam : current.world_from_left) {
    const Eigen::Vector3d to_x = x - cam.translation();
    const double range = to_x.norm();
    if (range < o.min_range_current_m || range > o.max_range_current_m) continue;
    const auto px = navcam.rig.left.ProjectIdeal(cam.inverse() * x);
    if (!px || !navcam.rig.left.InImage(*px)) continue;
    const auto hit = terrain.Raycast(cam.translation(), to_x / range, range + 1.0);
    if (hit && hit->range < range - o.occlusion_tolerance_m) continue;
    return range;
  }
  return 0;
}

SharedViewRow SharedView(const SiteCameras& previous, const SiteCameras& current, const NavcamModel& navcam,
                         const sim::Terrain& terrain, const SharedViewOptions& o) {
  SharedViewRow row;
  std::vector<double> ratios;
  const PinholeCamera& cam = navcam.rig.left;
  for (const Pose3& world_from_left : previous.world_from_left)
    for (int v = o.grid_px / 2; v < cam.height; v += o.grid_px)
      for (int u = o.grid_px / 2; u < cam.width; u += o.grid_px) {
        const auto x = GroundAt(world_from_left, Eigen::Vector2d(u, v), navcam, terrain, o.max_range_previous_m);
        if (!x) continue;
        ++row.samples;
        const double range = SeenFrom(current, *x, navcam, terrain, o);
        if (range <= 0) continue;
        ++row.shared;
        ratios.push_back(range / (*x - world_from_left.translation()).norm());
      }
  row.median_range_ratio = Median(ratios);
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
  f << "reference,site,samples,shared,shared_pct,median_range_ratio\n";
  for (const SharedViewRow& r : rows)
    f << r.reference << ',' << r.site << ',' << r.samples << ',' << r.shared << ',' << r.SharedPct() << ','
      << r.median_range_ratio << '\n';
}

std::string SharedViewSummary(const std::vector<SharedViewRow>& rows, const std::vector<TiePointSet>& localized) {
  if (rows.empty()) return "";
  std::set<std::pair<int, int>> with_ties;
  for (const TiePointSet& s : localized) with_ties.insert({s.previous_site_id, s.current_site_id});
  std::vector<double> pct_localized;
  std::ostringstream failed;
  failed.setf(std::ios::fixed);
  failed.precision(1);
  for (const SharedViewRow& r : rows) {
    if (with_ties.count({r.reference, r.site})) {
      pct_localized.push_back(r.SharedPct());
    } else {
      failed << (failed.tellp() > 0 ? ", " : "") << r.reference << " -> " << r.site << ": " << r.SharedPct()
             << " % (range ratio " << r.median_range_ratio << ")";
    }
  }
  std::ostringstream os;
  os.setf(std::ios::fixed);
  os.precision(1);
  os << "shared view (previous site's ground within range seen again from the current site): pairs with tie points "
     << "median " << Median(pct_localized) << " %, lowest "
     << (pct_localized.empty() ? NAN : *std::min_element(pct_localized.begin(), pct_localized.end())) << " %";
  if (failed.tellp() > 0) os << "; pairs without: " << failed.str();
  os << "\n";
  return os.str();
}

}  // namespace vloc::eval
