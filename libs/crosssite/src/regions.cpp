#include "vloc/crosssite/regions.h"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "vloc/common/homography.h"
#include "vloc/common/options.h"

namespace vloc {

void RegionOptions::Visit(OptionsReader& r) {
  r.Optional("ground_height", &ground_height, "m, ground plane z in the body frame");
  r.Optional("max_range_previous", &max_range_previous, "m, farthest ground point from the previous camera", Positive());
  r.Optional("max_range_current", &max_range_current, "m, farthest ground point from the current camera", Positive());
  r.Optional("min_range_current", &min_range_current, "m, nearest ground point from the current camera");
  r.Optional("grid_step", &grid_step, "px, footprint sampling step", AtLeast(2));
  r.Optional("sigma_scale", &sigma_scale, "regions cover the pose perturbed by this many sigma", NonNegative());
  r.Optional("max_growth_px", &max_growth_px, "px, cap of one sample's growth", Positive());
  r.Optional("default_position_sigma_fraction", &default_position_sigma_fraction,
             "relative position sigma as a fraction of the distance when no covariance", NonNegative());
  r.Optional("default_yaw_sigma_deg", &default_yaw_sigma_deg, "deg, relative yaw sigma when no covariance");
  r.Optional("default_tilt_sigma_deg", &default_tilt_sigma_deg, "deg, relative roll/pitch sigma when no covariance");
  r.Optional("max_position_sigma_fraction", &max_position_sigma_fraction,
             "cap of the relative position sigma, fraction of the distance", Positive());
  r.Optional("min_samples", &min_samples, "ground samples an overlap needs", AtLeast(4));
  r.Optional("backward_angle_deg", &backward_angle_deg, "deg, viewing directions further apart: backward pair",
             InLeftOpen(0, 180));
  r.Optional("image_margin", &image_margin, "px, samples closer to the border are dropped");
  r.Optional("far_min_range", &far_min_range, "m, nearest far-terrain stereo point from the current camera",
             NonNegative());
  r.Optional("far_max_range", &far_max_range, "m, farthest far-terrain stereo point (0 = no far-terrain overlaps)",
             NonNegative());
  r.Optional("far_disparity_sigma_px", &far_disparity_sigma_px, "px, disparity sigma of a far-terrain stereo point",
             Positive());
  r.Relation("far_max_range", far_max_range == 0 || (far_min_range > 0 && far_max_range > far_min_range),
             "must be 0 (off) or > far_min_range > 0");
}

bool RegionOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

Vector6d RelativePoseSigma(const PoseWithCovariance& prev, const PoseWithCovariance& cur, const RegionOptions& o) {
  const double distance = (cur.pose.translation() - prev.pose.translation()).norm();
  Vector6d sigma = Vector6d::Zero();
  const bool known = !cur.covariance.isZero(0.0);
  if (known) {
    for (int k = 0; k < 6; ++k) sigma(k) = std::sqrt(std::max(cur.covariance(k, k) - prev.covariance(k, k), 0.0));
  }
  if (!known || sigma.isZero(1e-12)) {
    const double sp = o.default_position_sigma_fraction * distance;
    const double st = o.default_tilt_sigma_deg * M_PI / 180, sy = o.default_yaw_sigma_deg * M_PI / 180;
    sigma << sp, sp, 0.5 * sp, st, st, sy;
  }
  const double cap = std::max(o.max_position_sigma_fraction * distance, 0.05);
  for (int k = 0; k < 3; ++k) sigma(k) = std::min(sigma(k), cap);
  return sigma;
}

namespace {

struct Sample {
  Eigen::Vector2d px;          // current left ideal px
  Eigen::Vector3d p_current;   // ground point, current body
  Eigen::Vector3d range_step = Eigen::Vector3d::Zero();  // m, far points: sigma_scale range sigmas along the ray
};

cv::Rect ClipRect(double x0, double y0, double x1, double y1, const PinholeCamera& cam) {
  const int a = std::max(0, static_cast<int>(std::floor(x0))), b = std::max(0, static_cast<int>(std::floor(y0)));
  const int c = std::min(cam.width, static_cast<int>(std::ceil(x1)) + 1);
  const int d = std::min(cam.height, static_cast<int>(std::ceil(y1)) + 1);
  if (c <= a || d <= b) return cv::Rect();
  return cv::Rect(a, b, c - a, d - b);
}

// Perturbed relative poses: 0 = nominal, then +-k sigma per axis (world frame).
std::vector<Pose3> PerturbedPoses(const Pose3& previous_from_world, const Pose3& world_from_current,
                                  const RegionPrediction& out, const RegionOptions& o) {
  std::vector<Pose3> perturbed{out.previous_from_current};
  for (int axis = 0; axis < 6; ++axis) {
    for (int sign = -1; sign <= 1; sign += 2) {
      const double delta = sign * o.sigma_scale * out.relative_sigma(axis);
      if (delta == 0) continue;
      Pose3 w = world_from_current;
      if (axis < 3) {
        w.translation()(axis) += delta;
      } else {
        Eigen::Vector3d rv = Eigen::Vector3d::Zero();
        rv(axis - 3) = delta;
        w.linear() = ExpSO3(rv) * w.linear();
      }
      perturbed.push_back(previous_from_world * w);
    }
  }
  return perturbed;
}

// The current image's footprint: grid samples whose ray meets the ground
// plane (n . p + e = 0, body frame) within the current range limits.
std::vector<Sample> GroundSamples(const Pose3& body_from_cur, const Eigen::Vector4d& plane, const PinholeCamera& cam_l,
                                  const RegionOptions& o) {
  std::vector<Sample> samples;
  const Eigen::Vector3d n = plane.head<3>();
  for (double v = o.image_margin; v < cam_l.height - o.image_margin; v += o.grid_step) {
    for (double u = o.image_margin; u < cam_l.width - o.image_margin; u += o.grid_step) {
      const Eigen::Vector3d d = body_from_cur.linear() * cam_l.Ray({u, v});
      const Eigen::Vector3d c = body_from_cur.translation();
      if (n.dot(d) >= -1e-9) continue;
      const double lambda = -(n.dot(c) + plane(3)) / n.dot(d);
      if (lambda <= 0) continue;
      const Eigen::Vector3d p = c + lambda * d;
      const double range = (p - c).norm();
      if (range > o.max_range_current || range < o.min_range_current) continue;
      samples.push_back({{u, v}, p});
    }
  }
  return samples;
}

// Scale, tilt and tilt longitude of the overlap's homography at the median
// member sample (the region centre can be a grazing point near the horizon).
void SetViewpointChange(const std::vector<cv::Point2d>& cur_px, PairOverlap* ov) {
  std::vector<double> us, vs;
  for (const auto& p : cur_px) us.push_back(p.x), vs.push_back(p.y);
  std::nth_element(us.begin(), us.begin() + us.size() / 2, us.end());
  std::nth_element(vs.begin(), vs.begin() + vs.size() / 2, vs.end());
  const Eigen::Vector2d c(us[us.size() / 2], vs[vs.size() / 2]);
  ov->median_current_px = c;
  const Eigen::Vector2d f0 = ApplyHomography(ov->previous_from_current, c);
  Eigen::Matrix2d J;
  J.col(0) = ApplyHomography(ov->previous_from_current, c + Eigen::Vector2d(1, 0)) - f0;
  J.col(1) = ApplyHomography(ov->previous_from_current, c + Eigen::Vector2d(0, 1)) - f0;
  Eigen::JacobiSVD<Eigen::Matrix2d> svd(J, Eigen::ComputeFullV);
  const Eigen::Vector2d sv = svd.singularValues();
  ov->scale = std::sqrt(std::max(sv(0) * sv(1), 1e-12));
  ov->tilt = sv(1) > 1e-9 ? sv(0) / sv(1) : 1.0;
  const Eigen::Vector2d v2 = svd.matrixV().col(1);
  double lon = std::atan2(v2.y(), v2.x());
  if (lon < 0) lon += M_PI;
  if (lon >= M_PI) lon -= M_PI;
  ov->tilt_longitude = lon;
}

// What one (current pair, previous pair) overlap is made from.
struct OverlapGeometry {
  const RegionPrediction& prediction;
  const std::vector<Pose3>& perturbed;  // relative poses: nominal, then +-sigma_scale sigma per axis
  const PinholeCamera& cam;             // left camera (both sites)
  const Pose3& prev_cam_from_body;      // previous left camera from the previous body
  int current_pair, previous_pair;
  bool backward;
};

// How far a member sample's projection q into the previous image can move
// (px, per axis): per perturbed axis the larger of the +/- displacements,
// summed over the 6 axes (so errors on several axes at once stay inside);
// far samples add the stereo range's uncertainty as one more axis; at most
// max_growth_px.
Eigen::Vector2d ProjectionSpread(const OverlapGeometry& g, const Sample& s, const Eigen::Vector3d& p_cam,
                                 const Eigen::Vector2d& q, bool far, const RegionOptions& o) {
  const std::vector<Pose3>& perturbed = g.perturbed;
  Eigen::Vector2d ext(0, 0);
  for (size_t k = 1; k + 1 < perturbed.size(); k += 2) {
    Eigen::Vector2d e(0, 0);
    for (size_t m = k; m <= k + 1; ++m) {
      const Eigen::Vector3d pk = g.prev_cam_from_body * (perturbed[m] * s.p_current);
      const auto qk = pk.z() > 0.3 * p_cam.z() ? g.cam.ProjectIdeal(pk) : std::nullopt;
      if (!qk) {
        e = Eigen::Vector2d::Constant(o.max_growth_px);
        break;
      }
      e = e.cwiseMax((*qk - q).cwiseAbs());
    }
    ext += e;
  }
  if (far) {  // the stereo range's uncertainty, as one more axis
    Eigen::Vector2d e(0, 0);
    for (const double sign : {-1.0, 1.0}) {
      const Eigen::Vector3d pk = g.prev_cam_from_body * (g.prediction.previous_from_current * (s.p_current + sign * s.range_step));
      const auto qk = pk.z() > 0.3 * p_cam.z() ? g.cam.ProjectIdeal(pk) : std::nullopt;
      e = qk ? Eigen::Vector2d(e.cwiseMax((*qk - q).cwiseAbs())) : Eigen::Vector2d::Constant(o.max_growth_px);
      if (!qk) break;
    }
    ext += e;
  }
  return ext.cwiseMin(o.max_growth_px);
}

// An axis-aligned box grown point by point.
struct Box {
  double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
  void Add(double x, double y) { x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y); }
};

// The overlap's member samples: in the current image, their projection in
// the previous one, the boxes they span (the previous one grown by each
// spread) and their spreads' lengths.
struct OverlapMembers {
  std::vector<cv::Point2d> cur_px, prev_px;
  Box current, previous, ground;
  std::vector<double> growths;
};

// A sample belongs to the overlap when the ground point lies within the
// previous camera's range (not for far samples) and projects into the
// previous image under the nominal or any perturbed relative pose.
OverlapMembers MemberSamples(const OverlapGeometry& g, const std::vector<Sample>& samples, bool far,
                             const RegionOptions& o) {
  const PinholeCamera& cam_l = g.cam;
  OverlapMembers m;
  for (const auto& s : samples) {
    const Eigen::Vector3d p_prev = g.prediction.previous_from_current * s.p_current;
    const Eigen::Vector3d p_cam = g.prev_cam_from_body * p_prev;
    const auto q = cam_l.ProjectIdeal(p_cam);
    if (!q || (!far && p_cam.norm() > o.max_range_previous)) continue;
    const Eigen::Vector2d ext = ProjectionSpread(g, s, p_cam, *q, far, o);
    const Eigen::Vector2d lo = *q - ext, hi = *q + ext;
    const bool member = hi.x() >= o.image_margin && hi.y() >= o.image_margin &&
                        lo.x() <= cam_l.width - 1 - o.image_margin && lo.y() <= cam_l.height - 1 - o.image_margin;
    if (!member) continue;
    m.growths.push_back(ext.norm());
    m.cur_px.emplace_back(s.px.x(), s.px.y());
    m.prev_px.emplace_back(q->x(), q->y());
    m.current.Add(s.px.x(), s.px.y());
    m.ground.Add(p_prev.x(), p_prev.y());
    for (const auto& qi : {lo, hi}) m.previous.Add(qi.x(), qi.y());
  }
  return m;
}

// The overlap the samples make in the previous image, or nullopt with fewer
// than min_samples members. Ground samples lie within max_range_previous;
// far samples (far) also grow by their range step, and their homography's
// fit residual (90th percentile) is added to the gate.
std::optional<PairOverlap> MakeOverlap(const OverlapGeometry& g, const std::vector<Sample>& samples, bool far,
                                       const RegionOptions& o) {
  PairOverlap ov;
  ov.far = far;
  ov.current_pair = g.current_pair;
  ov.previous_pair = g.previous_pair;
  ov.backward = g.backward;
  OverlapMembers m = MemberSamples(g, samples, far, o);
  ov.num_samples = static_cast<int>(m.cur_px.size());
  if (ov.num_samples < o.min_samples) return std::nullopt;
  const double half = 0.5 * o.grid_step;
  // The current region reaches a full grid step past the samples (to the
  // image border where the grid ends near it).
  const Box& c = m.current;
  ov.current_region = ClipRect(c.x0 - o.grid_step, c.y0 - o.grid_step, c.x1 + o.grid_step, c.y1 + o.grid_step, g.cam);
  ov.previous_region = ClipRect(m.previous.x0 - half, m.previous.y0 - half, m.previous.x1 + half, m.previous.y1 + half, g.cam);
  if (ov.current_region.area() == 0 || ov.previous_region.area() == 0) return std::nullopt;
  const double gs = o.sigma_scale * std::max(g.prediction.relative_sigma(0), g.prediction.relative_sigma(1));
  ov.ground_min = {m.ground.x0 - gs, m.ground.y0 - gs};
  ov.ground_max = {m.ground.x1 + gs, m.ground.y1 + gs};
  // Gate: the 90th percentile of the samples' growth (a few grazing
  // samples near the horizon would otherwise open it to the whole image).
  std::sort(m.growths.begin(), m.growths.end());
  ov.growth_px = m.growths[static_cast<size_t>(0.9 * (m.growths.size() - 1))];
  cv::Mat H = cv::findHomography(m.cur_px, m.prev_px, 0);
  if (H.empty()) return std::nullopt;
  ov.previous_from_current = cv::Matx33d(H);
  if (far) {  // far terrain is no plane: the homography's own miss widens the gate
    std::vector<double> miss;
    for (size_t k = 0; k < m.cur_px.size(); ++k)
      miss.push_back((ApplyHomography(ov.previous_from_current, Eigen::Vector2d(m.cur_px[k].x, m.cur_px[k].y)) -
                      Eigen::Vector2d(m.prev_px[k].x, m.prev_px[k].y)).norm());
    std::sort(miss.begin(), miss.end());
    ov.growth_px = std::min(ov.growth_px + miss[static_cast<size_t>(0.9 * (miss.size() - 1))], o.max_growth_px);
  }
  SetViewpointChange(m.cur_px, &ov);
  return ov;
}

}  // namespace

RegionPrediction PredictRegions(const NavcamModel& navcam, const PoseWithCovariance& world_from_previous,
                                const PoseWithCovariance& world_from_current,
                                const std::vector<MastPointing>& previous_pointing,
                                const std::vector<MastPointing>& current_pointing, const RegionOptions& o,
                                const std::vector<Eigen::Vector4d>& current_ground_planes,
                                const std::vector<std::vector<ScenePoint>>& current_far_points) {
  RegionPrediction out;
  const Pose3 previous_from_world = world_from_previous.pose.inverse();
  out.previous_from_current = previous_from_world * world_from_current.pose;
  out.relative_sigma = RelativePoseSigma(world_from_previous, world_from_current, o);
  const std::vector<Pose3> perturbed = PerturbedPoses(previous_from_world, world_from_current.pose, out, o);
  const PinholeCamera& cam_l = navcam.rig.left;
  std::vector<Pose3> prev_cams, prev_cams_inv;
  for (const auto& pt : previous_pointing) {
    prev_cams.push_back(navcam.mast.BodyFromLeft(pt.pan, pt.tilt, navcam.rig));
    prev_cams_inv.push_back(prev_cams.back().inverse());
  }
  const double cos_backward = std::cos(o.backward_angle_deg * M_PI / 180);
  for (size_t i = 0; i < current_pointing.size(); ++i) {
    const Pose3 body_from_cur = navcam.mast.BodyFromLeft(current_pointing[i].pan, current_pointing[i].tilt, navcam.rig);
    Eigen::Vector4d plane(0, 0, 1, -o.ground_height);
    if (i < current_ground_planes.size() && current_ground_planes[i].head<3>().norm() > 0.5)
      plane = current_ground_planes[i];
    const std::vector<Sample> samples = GroundSamples(body_from_cur, plane, cam_l, o);
    if (samples.empty() && (i >= current_far_points.size() || current_far_points[i].empty())) continue;
    const Eigen::Vector3d cur_axis = out.previous_from_current.linear() * body_from_cur.linear().col(2);
    std::vector<Sample> far_samples;
    if (i < current_far_points.size())
      for (const ScenePoint& sp : current_far_points[i]) {
        const Eigen::Vector3d ray = (sp.p_body - body_from_cur.translation()).normalized();
        far_samples.push_back({sp.px, sp.p_body, o.sigma_scale * sp.range_sigma * ray});
      }
    for (size_t j = 0; j < prev_cams.size(); ++j) {
      const Eigen::Vector3d prev_axis = prev_cams[j].linear().col(2);
      const Eigen::Vector2d a(cur_axis.x(), cur_axis.y()), b(prev_axis.x(), prev_axis.y());
      const bool backward = a.norm() > 1e-6 && b.norm() > 1e-6 && a.normalized().dot(b.normalized()) < cos_backward;
      const OverlapGeometry g{out, perturbed, cam_l, prev_cams_inv[j], static_cast<int>(i), static_cast<int>(j), backward};
      if (std::optional<PairOverlap> ov = MakeOverlap(g, samples, false, o)) out.overlaps.push_back(*ov);
      if (!backward && o.far_max_range > 0 && far_samples.size() >= static_cast<size_t>(o.min_samples))
        if (std::optional<PairOverlap> ov = MakeOverlap(g, far_samples, true, o)) out.overlaps.push_back(*ov);
    }
  }
  return out;
}

cv::Matx33d ImageFromOrtho(const PinholeCamera& camera, const Pose3& body_from_camera, const Eigen::Vector2d& origin,
                           double resolution, double ground_height) {
  // Ground point of ortho (u, v): G * (u, v, 1); camera point: R^T (G - t).
  Eigen::Matrix3d G;
  G << resolution, 0, origin.x(), 0, -resolution, origin.y(), 0, 0, ground_height;
  const Eigen::Matrix3d Rt = body_from_camera.linear().transpose();
  Eigen::Matrix3d M = Rt * G;
  M.col(2) -= Rt * body_from_camera.translation();
  Eigen::Matrix3d K;
  K << camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1;
  const Eigen::Matrix3d H = K * M;
  cv::Matx33d out;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out(r, c) = H(r, c);
  return out;
}

cv::Mat GroundOrthoImage(const cv::Mat& image, const cv::Matx33d& image_from_ortho, const cv::Size& size) {
  cv::Mat out;
  cv::warpPerspective(image, out, cv::Mat(image_from_ortho), size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                      cv::BORDER_CONSTANT, 0);
  return out;
}

}  // namespace vloc
