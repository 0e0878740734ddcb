#include "vloc/ba/synthetic.h"

#include <random>

#include "vloc/ba/crosssite_ba.h"
#include "vloc/ba/geometry.h"

namespace vloc {

namespace {

// The first pair of [first, last) (in a random order) that sees p in both
// cameras; -1 if none.
int FindPair(const std::vector<Pose3>& lefts, const std::vector<Pose3>& rights, const NavcamModel& navcam,
             const Eigen::Vector3d& p, std::mt19937_64& rng, Eigen::Vector2d* uv_left, Eigen::Vector2d* uv_right,
             int first = 0, int last = -1) {
  if (last < 0) last = static_cast<int>(lefts.size());
  std::vector<int> order;
  for (int i = first; i < last; ++i) order.push_back(i);
  std::shuffle(order.begin(), order.end(), rng);
  for (int i : order) {
    const auto l = CameraView::Make(lefts[i], navcam.rig.left).Project(p);
    const auto r = CameraView::Make(rights[i], navcam.rig.right).Project(p);
    if (l && r && navcam.rig.left.InImage(*l, 5.0) && navcam.rig.right.InImage(*r, 5.0)) {
      *uv_left = *l;
      *uv_right = *r;
      return i;
    }
  }
  return -1;
}

// The set without points: site ids, the previous pose (held fixed) and
// the current DR pose with their covariances, both sites' mast pointing.
TiePointSet EmptySet(const Pose3& world_from_previous, const Pose3& world_from_current_dr,
                     const SyntheticTiePointOptions& o) {
  TiePointSet set;
  set.previous_site_id = 1;
  set.current_site_id = 2;
  set.previous_site_pose.pose = world_from_previous;
  set.previous_site_pose.covariance = Matrix6d::Identity() * 1e-6;
  set.current_site_pose_dr.pose = world_from_current_dr;
  set.current_site_pose_dr.covariance = Matrix6d::Identity() * 0.25;
  for (int i = 0; i < o.num_pairs; ++i) {
    const double pan = (i - 0.5 * (o.num_pairs - 1)) * o.pan_step;
    set.previous_pointing.push_back({pan, o.tilt});
    set.current_pointing.push_back({pan, o.tilt});
  }
  if (o.backward_pair) set.current_pointing.push_back({M_PI, o.tilt});
  return set;
}

// A random ground point: on the degenerate line (collinear), or on the
// level ground patch ahead of the previous site, in its heading (short of
// the current site for a backward pair's point).
Eigen::Vector3d RandomGroundPoint(const SyntheticTiePointOptions& o, const Pose3& world_from_previous, double spacing,
                                  bool behind_current, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  if (o.collinear) {
    // The degenerate line: through the ground ahead of both sites, along the travel direction.
    const Eigen::Vector3d line_origin = world_from_previous * Eigen::Vector3d(14.0, 0.7, -0.2);
    const Eigen::Vector3d line_dir = world_from_previous.linear() * Eigen::Vector3d(1.0, 0.15, 0.0).normalized();
    return line_origin + line_dir * (-3.0 + 12.0 * uni(rng));
  }
  const double heading = Heading(world_from_previous);
  const double far = behind_current ? std::max(o.min_range, spacing - 2.0) : o.max_range;
  const double ahead = o.min_range + (far - o.min_range) * uni(rng);
  const double side = o.half_width * (2.0 * uni(rng) - 1.0);
  const Eigen::Vector3d local(ahead, side, 0.0);
  const Eigen::Vector3d rotated(std::cos(heading) * local.x() - std::sin(heading) * local.y(),
                                std::sin(heading) * local.x() + std::cos(heading) * local.y(), 0.0);
  Eigen::Vector3d p = world_from_previous.translation() + rotated;
  p.z() = world_from_previous.translation().z() - 0.0 + o.ground_roughness * (2.0 * uni(rng) - 1.0);
  return p;
}

// Where a tie point is seen: a pair at each site and its four pixels.
struct Sightings {
  int previous_pair = -1, current_pair = -1;
  Eigen::Vector2d pl, pr, cl, cr;
};

// The four noisy observations of a tie point (the current site's moved
// 10-40 px together for an outlier).
std::vector<TieObservation> NoisyObservations(const Sightings& at, const SyntheticTiePointOptions& o,
                                              std::normal_distribution<double>& noise, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const bool outlier = uni(rng) < o.outlier_fraction;
  std::vector<TieObservation> obs;
  auto add = [&](SiteRole site, int pair, CameraSide side, const Eigen::Vector2d& uv) {
    TieObservation ob;
    ob.site = site;
    ob.pair_index = pair;
    ob.camera = side;
    ob.uv = uv + Eigen::Vector2d(noise(rng), noise(rng));
    ob.sigma = o.noise_px;
    obs.push_back(ob);
  };
  add(SiteRole::kPrevious, at.previous_pair, CameraSide::kLeft, at.pl);
  add(SiteRole::kPrevious, at.previous_pair, CameraSide::kRight, at.pr);
  Eigen::Vector2d shift = Eigen::Vector2d::Zero();
  if (outlier) {
    const double mag = 10.0 + 30.0 * uni(rng), ang = 2.0 * M_PI * uni(rng);
    shift = mag * Eigen::Vector2d(std::cos(ang), std::sin(ang));
  }
  add(SiteRole::kCurrent, at.current_pair, CameraSide::kLeft, at.cl + shift);
  add(SiteRole::kCurrent, at.current_pair, CameraSide::kRight, at.cr + shift);
  return obs;
}

}  // namespace

SyntheticTiePoints MakeSyntheticTiePoints(const NavcamModel& navcam, const Pose3& world_from_previous,
                                          const Pose3& world_from_current, const Pose3& world_from_current_dr,
                                          const SyntheticTiePointOptions& o) {
  SyntheticTiePoints out;
  out.world_from_current_true = world_from_current;
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> noise(0.0, o.noise_px);
  TiePointSet& set = out.set;
  set = EmptySet(world_from_previous, world_from_current_dr, o);
  std::vector<Pose3> prev_left, prev_right, cur_left, cur_right;
  SiteCameraPoses(world_from_previous, set.previous_pointing, navcam, &prev_left, &prev_right);
  SiteCameraPoses(world_from_current, set.current_pointing, navcam, &cur_left, &cur_right);
  const Pose3 previous_from_world = world_from_previous.inverse();
  const Pose3 current_from_world = world_from_current.inverse();
  const double spacing = (world_from_current.translation() - world_from_previous.translation()).norm();
  const int forward = o.num_pairs;
  for (int tries = 0; tries < 200 * o.num_points && static_cast<int>(set.points.size()) < o.num_points; ++tries) {
    const bool behind_current = o.backward_pair && static_cast<int>(set.points.size()) < o.backward_points;
    const Eigen::Vector3d p = RandomGroundPoint(o, world_from_previous, spacing, behind_current, rng);
    Sightings at;
    at.previous_pair = FindPair(prev_left, prev_right, navcam, p, rng, &at.pl, &at.pr);
    if (at.previous_pair < 0) continue;
    at.current_pair = behind_current ? FindPair(cur_left, cur_right, navcam, p, rng, &at.cl, &at.cr, forward, forward + 1)
                                     : FindPair(cur_left, cur_right, navcam, p, rng, &at.cl, &at.cr, 0, forward);
    if (at.current_pair < 0) continue;
    TiePoint tp;
    tp.id = static_cast<int>(set.points.size());
    tp.p_previous = previous_from_world * p;
    tp.p_current = current_from_world * p;
    tp.weight = 1;
    tp.observations = NoisyObservations(at, o, noise, rng);
    set.points.push_back(tp);
    out.points_world.push_back(p);
  }
  return out;
}

}  // namespace vloc
