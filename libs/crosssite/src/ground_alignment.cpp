// Step 3b: the DR's relative height corrected on the ground both sites
// measured (frontend_steps.h, AlignGround). The previous site's stereo points
// give local planes (its neighbours within ground_align_radius_m in x, y);
// each current point, moved by the DR's relative pose and the correction,
// is compared with the plane under it along the plane's normal.
#include <omp.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include <glog/logging.h>

#include "vloc/crosssite/internal/frontend_steps.h"
#include "vloc/features/consistency.h"

namespace vloc::frontend_internal {

namespace {

struct LocalPlane {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::UnitZ();
};

struct AlignPoint {
  Eigen::Vector3d p;       // previous body frame, before the correction
  Eigen::Vector3d camera;  // the current left camera, previous body frame
};

// The plane of the previous points within `radius` (x, y) of `q`; false with too few or a steep plane.
bool PlaneUnder(const std::vector<Eigen::Vector3d>& previous, const Eigen::Vector3d& q, double radius,
                LocalPlane* plane) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::vector<const Eigen::Vector3d*> near;
  for (const Eigen::Vector3d& p : previous)
    if ((p.head<2>() - q.head<2>()).squaredNorm() <= radius * radius) near.push_back(&p), sum += p;
  if (near.size() < static_cast<size_t>(kAlignMinNeighbours)) return false;
  plane->centre = sum / static_cast<double>(near.size());
  Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d* p : near) c += (*p - plane->centre) * (*p - plane->centre).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(c);
  plane->normal = es.eigenvectors().col(0);
  if (plane->normal.z() < 0) plane->normal = -plane->normal;
  return plane->normal.z() >= kAlignMinNormalZ;
}

// Sigma (m) of a current point along `normal`: its stereo range error along the ray, and the ground's roughness.
double NormalSigma(const AlignPoint& a, const Eigen::Vector3d& normal, const NavcamModel& navcam) {
  const Eigen::Vector3d ray = a.p - a.camera;
  const double range = ray.norm();
  const double along = RangeSigma(range, navcam.rig.Baseline(), navcam.rig.left.fx, kAlignParallaxSigmaPx) *
                       std::abs(normal.dot(ray / range));
  return std::hypot(along, kAlignRoughnessM);
}

// Every k-th element, so that at most `max_size` are left (the plane search is quadratic in the points).
template <typename T>
void Thin(std::vector<T>* v, size_t max_size) {
  if (v->size() <= max_size) return;
  const size_t k = (v->size() + max_size - 1) / max_size;
  std::vector<T> kept;
  for (size_t i = 0; i < v->size(); i += k) kept.push_back((*v)[i]);
  v->swap(kept);
}

// One Gauss-Newton step's sums for the height offset `dz` along `up` (the DR prior's terms included).
struct HeightNormalEquations {
  double h = 0, g = 0;  // d2/d1 of half the robust loss
  double loss = 0;      // robust loss of the points
  int points = 0;       // points with a plane under them
};

HeightNormalEquations HeightStep(const std::vector<AlignPoint>& moved, const std::vector<Eigen::Vector3d>& ground,
                                 const Eigen::Vector3d& up, double dz, double prior_sigma_m, const NavcamModel& navcam,
                                 const GroundAlignOptions& o, int num_threads) {
  // Planes under the points where the current offset puts them.
  std::vector<LocalPlane> planes(moved.size());
  std::vector<char> has(moved.size(), 0);
#pragma omp parallel for schedule(dynamic, 64) num_threads(num_threads)
  for (int i = 0; i < static_cast<int>(moved.size()); ++i)
    has[i] = PlaneUnder(ground, moved[i].p + dz * up, o.ground_align_radius_m, &planes[i]) ? 1 : 0;
  HeightNormalEquations e;
  e.h = 1.0 / (prior_sigma_m * prior_sigma_m);
  e.g = e.h * dz;
  for (size_t i = 0; i < moved.size(); ++i) {
    if (!has[i]) continue;
    const Eigen::Vector3d& nrm = planes[i].normal;
    const double sigma = NormalSigma(moved[i], nrm, navcam);
    const double r = nrm.dot(moved[i].p + dz * up - planes[i].centre) / sigma, j = nrm.dot(up) / sigma;
    const bool inner = std::abs(r) <= kAlignHuber;
    const double w = inner ? 1.0 : kAlignHuber / std::abs(r);  // Huber
    e.loss += inner ? r * r : 2 * kAlignHuber * std::abs(r) - kAlignHuber * kAlignHuber;
    e.h += w * j * j;
    e.g += w * j * r;
    ++e.points;
  }
  return e;
}

}  // namespace

GroundAlignment AlignGround(const std::vector<GroundPointSet>& previous, const std::vector<GroundPointSet>& current,
                            const Pose3& previous_from_current, const Eigen::Vector3d& up, double prior_sigma_m,
                            const NavcamModel& navcam, const GroundAlignOptions& o, int num_threads) {
  GroundAlignment out;
  std::vector<Eigen::Vector3d> ground;
  for (const GroundPointSet& set : previous) ground.insert(ground.end(), set.points.begin(), set.points.end());
  std::vector<AlignPoint> moved;
  for (const GroundPointSet& set : current)
    for (const Eigen::Vector3d& p : set.points) moved.push_back({previous_from_current * p, previous_from_current * set.camera});
  Thin(&ground, kAlignMaxPoints);
  Thin(&moved, kAlignMaxPoints);
  if (static_cast<int>(ground.size()) < o.ground_align_min_points ||
      static_cast<int>(moved.size()) < o.ground_align_min_points) {
    out.why = "too few stereo points (" + std::to_string(ground.size()) + " previous, " + std::to_string(moved.size()) +
              " current)";
    return out;
  }
  double dz = 0;  // m, along `up`
  for (int it = 0; it < kAlignIterations; ++it) {
    const HeightNormalEquations e = HeightStep(moved, ground, up, dz, prior_sigma_m, navcam, o, num_threads);
    if (e.points < o.ground_align_min_points) {
      out.why = "only " + std::to_string(e.points) + " current points over the previous site's ground";
      return out;
    }
    if (it == 0) out.rms_before = std::sqrt(e.loss / e.points);
    out.rms_after = std::sqrt(e.loss / e.points);
    out.points = e.points;
    const double step = -e.g / e.h;
    dz += step;
    if (std::abs(step) < kAlignConvergenceM) break;
  }
  if (!(std::abs(dz) <= kAlignMaxPriorSigmas * prior_sigma_m)) {
    out.why = "the correction is beyond the DR's uncertainty (" + std::to_string(std::abs(dz) / prior_sigma_m) +
              " sigma)";
    return out;
  }
  out.delta = dz * up;
  out.ok = true;
  return out;
}

int AlignToPreviousGround(const NavcamModel& navcam, const TiePointSet& tps, const GroundAlignOptions& o,
                          const GroundPlaneOptions& ground, const RegionOptions& regions, const ZnccOptions& zncc,
                          int num_threads, SitePairState* s) {
  s->dr_previous_from_current = s->prediction.previous_from_current;
  if (!o.ground_align || !ground.fit_ground_planes) return 0;
  const int np = static_cast<int>(s->previous.pairs.size());
  std::vector<GroundPointSet> previous(np);
#pragma omp parallel for schedule(dynamic, 1) num_threads(num_threads)
  for (int j = 0; j < np; ++j)
    previous[j] = GroundStereoPoints(navcam, tps.previous_pointing[j], s->previous_left[j].lsm.gray,
                                     s->previous_right[j].lsm.gray, ground, regions, zncc);
  // In the previous body frame turned level (world axes, origin at the previous body): neighbourhoods are
  // horizontal and "up" is z, on a rolled or pitched rover too.
  Pose3 level_from_previous = Pose3::Identity();
  level_from_previous.linear() = s->previous.world_from_body.pose.linear();
  for (GroundPointSet& set : previous) {
    set.camera = level_from_previous * set.camera;
    for (Eigen::Vector3d& p : set.points) p = level_from_previous * p;
  }
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  const double prior_sigma = std::max(s->prediction.relative_sigma(2), kAlignMinPriorSigmaM);
  const GroundAlignment a = AlignGround(previous, s->current_ground,
                                        level_from_previous * s->prediction.previous_from_current, up, prior_sigma,
                                        navcam, o, num_threads);
  if (!a.ok) {
    VLOG(1) << "ground alignment: none (" << a.why << ")";
    return 0;
  }
  VLOG(1) << "ground alignment: " << a.points << " points, DR height corrected by " << a.delta.z()
          << " m (prior sigma " << prior_sigma << " m), residual " << a.rms_before << " -> " << a.rms_after;
  Pose3 corrected = s->prediction.previous_from_current;
  corrected.translation() += level_from_previous.linear().transpose() * a.delta;
  PoseWithCovariance current = s->current.world_from_body;
  current.pose = s->previous.world_from_body.pose * corrected;
  s->prediction = PredictRegions(navcam, s->previous.world_from_body, current, tps.previous_pointing,
                                 tps.current_pointing, regions, s->ground_planes, s->current_far);
  return a.points;
}

}  // namespace vloc::frontend_internal
