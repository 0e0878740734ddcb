#include "vloc/ba/crosssite_ba.h"

#include <ceres/ceres.h>
#include <ceres/covariance.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include "reprojection.h"
#include "vloc/ba/geometry.h"
#include "vloc/common/options.h"
#include "vloc/common/stopwatch.h"

namespace vloc {

void CrossSiteBaOptions::Visit(OptionsReader& r) {
  r.Optional("min_tie_points", &min_tie_points, "count, usable tie points needed", AtLeast(3));
  r.Optional("huber_sigmas", &huber_sigmas, "sigmas, Huber loss threshold", Positive());
  r.Optional("outlier_sigmas", &outlier_sigmas, "sigmas, tie-point rejection threshold", Positive());
  r.Optional("rejection_rounds", &rejection_rounds, "count, robust solve + rejection rounds", NonNegative());
  r.Optional("max_iterations", &max_iterations, "count, Ceres iterations per solve", AtLeast(1));
  r.Optional("function_tolerance", &function_tolerance, "relative cost change to stop", Positive());
  r.Optional("max_condition_number", &max_condition_number, "scaled pose covariance condition limit", Above(1));
  r.Optional("max_final_rms_sigmas", &max_final_rms_sigmas, "sigmas, final normalised RMS limit", Positive());
  r.Optional("max_correction_m", &max_correction_m, "m, largest accepted move from dead reckoning", Positive());
  r.Optional("min_intersection_parallax_rad", &min_intersection_parallax_rad, "rad, intersection ray angle",
             Positive());
  r.Optional("far_points", &far_points, "points with nearly parallel previous-site rays enter as inverse depths");
  r.Optional("inflate_by_variance_factor", &inflate_by_variance_factor, "scale covariance by max(1, s0^2)");
  r.Optional("max_independent_points", &max_independent_points,
             "covariance scaled by max(1, points / this): shared errors do not average down (0 = off)", NonNegative());
  r.Optional("num_threads", &num_threads, "count, Ceres threads", AtLeast(1));
}

bool CrossSiteBaOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

const char* ToString(CrossSiteBaStatus status) {
  switch (status) {
    case CrossSiteBaStatus::kOk: return "OK";
    case CrossSiteBaStatus::kTooFewPoints: return "TOO_FEW_POINTS";
    case CrossSiteBaStatus::kIllConditioned: return "ILL_CONDITIONED";
    case CrossSiteBaStatus::kNotConverged: return "NOT_CONVERGED";
    case CrossSiteBaStatus::kBadInput: return "BAD_INPUT";
  }
  return "UNKNOWN";
}

std::string CrossSiteBaSummary::BriefReport() const {
  std::ostringstream s;
  s << "site " << previous_site_id << " -> " << current_site_id << ": " << ToString(status) << " (" << message
    << "); points used " << num_tie_points_used << ", rejected " << num_tie_points_rejected << ", unusable "
    << num_tie_points_unusable << " of " << num_tie_points_in << " (far " << num_far_points << "); observations "
    << num_observations
    << "; RMS " << initial_rms_px << " -> " << final_rms_px << " px; " << iterations << " iterations, "
    << solve_seconds << " s; condition " << condition_number;
  return s.str();
}

void SiteCameraPoses(const Pose3& world_from_body, const std::vector<MastPointing>& pointing,
                     const NavcamModel& navcam, std::vector<Pose3>* world_from_left,
                     std::vector<Pose3>* world_from_right) {
  world_from_left->clear();
  world_from_right->clear();
  for (const auto& p : pointing) {
    const Pose3 left = world_from_body * navcam.mast.BodyFromLeft(p.pan, p.tilt, navcam.rig);
    world_from_left->push_back(left);
    world_from_right->push_back(left * navcam.rig.left_from_right);
  }
}

namespace {

bool PoseIsValid(const Pose3& pose) {
  PoseWithCovariance p;
  p.pose = pose;
  return IsPlausiblePose(p);
}

// Image coordinates and sigmas beyond these are corrupt, not measurements:
// they would turn the residuals non-finite inside Ceres.
constexpr double kMaxImageCoordinatePx = 1e5;
constexpr double kMaxObservationSigmaPx = 1e3;
constexpr double kMaxMastAngleRad = 100.0;

// A tie point prepared for the adjustment: a point in the world, or a far
// point (its previous-site rays nearly parallel) as an inverse depth
// q = [a, b, rho] in its anchor camera, p_anchor = (a, b, 1) / rho with
// rho >= 0 (0: at infinity).
struct BaPoint {
  int id = 0;
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();  // not far
  bool far = false;
  Pose3 world_from_anchor = Pose3::Identity();        // far: the first previous observation's camera
  Eigen::Vector3d q = Eigen::Vector3d::Zero();        // far: [a, b, rho]
  std::vector<TieObservation> previous;  // validated observations
  std::vector<TieObservation> current;
  bool inlier = true;
};

struct Network {
  std::vector<Pose3> prev_left, prev_right;          // world_from_camera, fixed
  std::vector<Pose3> body_from_left, body_from_right;  // current site
  const NavcamModel* navcam = nullptr;

  const PinholeCamera& Intrinsics(CameraSide side) const {
    return side == CameraSide::kLeft ? navcam->rig.left : navcam->rig.right;
  }
  const Pose3& PreviousCamera(const TieObservation& o) const {
    return o.camera == CameraSide::kLeft ? prev_left[o.pair_index] : prev_right[o.pair_index];
  }
  const Pose3& BodyFromCurrentCamera(const TieObservation& o) const {
    return o.camera == CameraSide::kLeft ? body_from_left[o.pair_index] : body_from_right[o.pair_index];
  }
  // Reprojection error (px) of an observation of `p` given the current site pose.
  Eigen::Vector2d Residual(const TieObservation& o, const BaPoint& p, const Pose3& world_from_current) const {
    const Pose3 world_from_camera = o.site == SiteRole::kPrevious ? PreviousCamera(o)
                                                                 : world_from_current * BodyFromCurrentCamera(o);
    if (!p.far) {
      const auto px = CameraView::Make(world_from_camera, Intrinsics(o.camera)).Project(p.p_world);
      return px ? Eigen::Vector2d(*px - o.uv) : Eigen::Vector2d(1e4, 1e4);
    }
    const Pose3 camera_from_anchor = world_from_camera.inverse() * p.world_from_anchor;
    const Eigen::Vector3d h = camera_from_anchor.linear() * Eigen::Vector3d(p.q.x(), p.q.y(), 1.0) +
                              p.q.z() * camera_from_anchor.translation();  // rho p_camera
    if (!(h.z() > 1e-9)) return Eigen::Vector2d(1e4, 1e4);
    const PinholeCamera& k = Intrinsics(o.camera);
    return Eigen::Vector2d(k.fx * h.x() / h.z() + k.cx, k.fy * h.y() / h.z() + k.cy) - o.uv;
  }
};

struct PassResult {
  bool converged = false;
  int iterations = 0;
  std::string message;
};

// The reprojection residuals of the inlier points' observations: the
// previous site's cameras fixed, the current site's through the body pose
// `pose` (translation, rotation update about R0); a Huber loss when
// `robust`.
void AddObservations(const Network& net, const Eigen::Matrix3d& R0, bool robust, const CrossSiteBaOptions& options,
                     std::vector<BaPoint>* points, double* pose, ceres::Problem* problem) {
  auto loss = [&]() -> ceres::LossFunction* { return robust ? new ceres::HuberLoss(options.huber_sigmas) : nullptr; };
  for (auto& p : *points) {
    if (!p.inlier) continue;
    double* point = p.far ? p.q.data() : p.p_world.data();
    for (const auto& o : p.previous) {
      const PinholeCamera& k = net.Intrinsics(o.camera);
      problem->AddResidualBlock(
          p.far ? internal::FixedCameraInverseDepth::Create(net.PreviousCamera(o).inverse() * p.world_from_anchor,
                                                            k.fx, k.fy, k.cx, k.cy, o.uv, o.sigma)
                : internal::FixedCameraReprojection::Create(net.PreviousCamera(o), k.fx, k.fy, k.cx, k.cy, o.uv,
                                                            o.sigma),
          loss(), point);
    }
    for (const auto& o : p.current) {
      const PinholeCamera& k = net.Intrinsics(o.camera);
      const Pose3& body_from_camera = net.BodyFromCurrentCamera(o);
      problem->AddResidualBlock(
          p.far ? internal::BodyCameraInverseDepth::Create(R0, body_from_camera, p.world_from_anchor, k.fx, k.fy,
                                                           k.cx, k.cy, o.uv, o.sigma)
                : internal::BodyCameraReprojection::Create(R0, body_from_camera, k.fx, k.fy, k.cx, k.cy, o.uv,
                                                           o.sigma),
          loss(), pose, point);
    }
    if (p.far) problem->SetParameterLowerBound(point, 2, 0.0);  // rho: at most at infinity
  }
}

// One Ceres solve over the inlier points; updates `world_from_current` and the points.
PassResult SolvePass(const Network& net, std::vector<BaPoint>* points, Pose3* world_from_current, bool robust,
                     const CrossSiteBaOptions& options) {
  const Eigen::Matrix3d R0 = world_from_current->linear();
  double pose[6] = {world_from_current->translation().x(), world_from_current->translation().y(),
                    world_from_current->translation().z(), 0, 0, 0};
  ceres::Problem problem;
  AddObservations(net, R0, robust, options, points, pose, &problem);
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_SCHUR;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.num_threads = options.num_threads;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  PassResult r;
  r.iterations = static_cast<int>(summary.iterations.size());
  r.converged = summary.termination_type == ceres::CONVERGENCE;
  r.message = summary.message;
  *world_from_current = internal::BodyPoseFromParameters(R0, pose);
  return r;
}

struct Residuals {
  double rms_px = 0;
  double normalised_rms = 0;
  double chi2 = 0;  // sum of squared normalised residuals
  int observations = 0;
  int points = 0;
};

Residuals ComputeResiduals(const Network& net, const std::vector<BaPoint>& points, const Pose3& world_from_current) {
  Residuals r;
  double sum_px = 0;
  for (const auto& p : points) {
    if (!p.inlier) continue;
    ++r.points;
    for (const auto* list : {&p.previous, &p.current}) {
      for (const auto& o : *list) {
        const Eigen::Vector2d e = net.Residual(o, p, world_from_current);
        sum_px += e.squaredNorm();
        r.chi2 += e.squaredNorm() / (o.sigma * o.sigma);
        ++r.observations;
      }
    }
  }
  if (r.observations > 0) {
    r.rms_px = std::sqrt(sum_px / (2.0 * r.observations));
    r.normalised_rms = std::sqrt(r.chi2 / (2.0 * r.observations));
  }
  return r;
}

// Marks points whose worst normalised residual is too large; returns how many.
int RejectOutliers(const Network& net, std::vector<BaPoint>* points, const Pose3& world_from_current,
                   const CrossSiteBaOptions& options) {
  std::vector<double> worst_of_point;
  std::vector<double> all;
  for (auto& p : *points) {
    if (!p.inlier) continue;
    double worst = 0;
    for (const auto* list : {&p.previous, &p.current}) {
      for (const auto& o : *list) {
        const double e = net.Residual(o, p, world_from_current).norm() / o.sigma;
        worst = std::max(worst, e);
        all.push_back(e);
      }
    }
    worst_of_point.push_back(worst);
  }
  if (all.empty()) return 0;
  std::nth_element(all.begin(), all.begin() + all.size() / 2, all.end());
  // Median of |e| for a 2-D unit Gaussian is sqrt(2 ln 2) = 1.1774.
  const double robust_scale = std::max(1.0, all[all.size() / 2] / 1.1774);
  const double threshold = options.outlier_sigmas * robust_scale;
  int rejected = 0, k = 0;
  for (auto& p : *points) {
    if (!p.inlier) continue;
    if (worst_of_point[k++] > threshold) {
      p.inlier = false;
      ++rejected;
    }
  }
  return rejected;
}

int CountInliers(const std::vector<BaPoint>& points) {
  return static_cast<int>(std::count_if(points.begin(), points.end(), [](const BaPoint& p) { return p.inlier; }));
}

// Covariance of the current site pose at `world_from_current` (dr = 0) by
// ceres::Covariance over a plain least-squares problem; false when singular.
bool PoseCovariance(const Network& net, std::vector<BaPoint> points, const Pose3& world_from_current,
                    const CrossSiteBaOptions& options, Matrix6d* covariance, std::string* why) {
  const Eigen::Matrix3d R0 = world_from_current.linear();
  double pose[6] = {world_from_current.translation().x(), world_from_current.translation().y(),
                    world_from_current.translation().z(), 0, 0, 0};
  ceres::Problem problem;
  AddObservations(net, R0, /*robust=*/false, options, &points, pose, &problem);
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::SPARSE_QR;
  co.num_threads = options.num_threads;
  ceres::Covariance cov(co);
  std::vector<std::pair<const double*, const double*>> blocks = {{pose, pose}};
  if (!cov.Compute(blocks, &problem)) {
    *why = "the adjustment's normal matrix is singular (rank deficient)";
    return false;
  }
  Eigen::Matrix<double, 6, 6, Eigen::RowMajor> c;
  cov.GetCovarianceBlock(pose, pose, c.data());
  *covariance = c;
  if (!covariance->allFinite()) {
    *why = "the pose covariance is not finite";
    return false;
  }
  return true;
}

// Why the input cannot be adjusted (one line), or "" when it can.
std::string InputError(const TiePointSet& set, const NavcamModel& navcam, const CrossSiteBaOptions& options) {
  std::string error;
  if (!options.Check(&error)) return "bad BA options: " + error;
  if (!navcam.Check(&error)) return "bad Navcam model: " + error;
  if (set.previous_site_id == set.current_site_id || set.previous_site_id < 0 || set.current_site_id < 0)
    return "previous site " + std::to_string(set.previous_site_id) + " and current site " +
           std::to_string(set.current_site_id) + " must be two different non-negative ids";
  if (!PoseIsValid(set.previous_site_pose.pose))
    return "previous site pose is not a finite rigid pose; check the tie-point message";
  if (!PoseIsValid(set.current_site_pose_dr.pose))
    return "dead-reckoning pose of the current site is not a finite rigid pose";
  if (set.previous_pointing.empty() || set.current_pointing.empty())
    return "no mast pointing for the previous or current site's pairs";
  for (const auto* list : {&set.previous_pointing, &set.current_pointing})
    for (const auto& p : *list)
      if (!(std::abs(p.pan) <= kMaxMastAngleRad) || !(std::abs(p.tilt) <= kMaxMastAngleRad))
        return "a mast pan/tilt is not finite or beyond 100 rad";
  return "";
}

// The previous site's cameras in the world, the current site's on the body.
Network MakeNetwork(const TiePointSet& set, const NavcamModel& navcam) {
  Network net;
  net.navcam = &navcam;
  SiteCameraPoses(set.previous_site_pose.pose, set.previous_pointing, navcam, &net.prev_left, &net.prev_right);
  for (const auto& p : set.current_pointing) {
    net.body_from_left.push_back(navcam.mast.BodyFromLeft(p.pan, p.tilt, navcam.rig));
    net.body_from_right.push_back(net.body_from_left.back() * navcam.rig.left_from_right);
  }
  return net;
}

// Only the left camera's observations of a far point: the stereo cannot
// range it (that is what made it far), so its right-image pixel adds a
// disparity below a pixel whose calibration bias would set the point's depth,
// and through it the site's scale (Devon: |t| 8 % longer with them).
void KeepLeftObservations(std::vector<TieObservation>* observations) {
  observations->erase(std::remove_if(observations->begin(), observations->end(),
                                     [](const TieObservation& o) { return o.camera != CameraSide::kLeft; }),
                      observations->end());
}

// A point whose previous-site rays are nearly parallel as an inverse depth
// in the left camera of its first previous observation: the ray from that
// pixel, rho from the intersection when it lies in front of that camera
// (else 0: at infinity); its left observations only (KeepLeftObservations).
// False when a site has no left observation of it.
bool MakeFarPoint(const Network& net, const std::vector<CameraView>& views, const std::vector<Eigen::Vector2d>& uv,
                  const std::vector<double>& sigma, BaPoint* bp) {
  KeepLeftObservations(&bp->previous);
  KeepLeftObservations(&bp->current);
  if (bp->previous.empty() || bp->current.empty()) return false;
  const TieObservation& anchor = bp->previous.front();
  const PinholeCamera& k = net.Intrinsics(anchor.camera);
  bp->far = true;
  bp->world_from_anchor = net.PreviousCamera(anchor);
  bp->q = Eigen::Vector3d((anchor.uv.x() - k.cx) / k.fx, (anchor.uv.y() - k.cy) / k.fy, 0.0);
  const IntersectionResult loose = IntersectPoint(views, uv, sigma, 0.0);
  if (loose.ok) {
    const double z = (bp->world_from_anchor.inverse() * loose.p_world).z();
    if (z > 0 && std::isfinite(z)) bp->q.z() = 1.0 / z;
  }
  return bp->q.allFinite();
}

// The tie points with valid observations, seen at least twice from the
// previous site and once from the current, intersected from the previous
// site; counts the bad observations and unusable points into `s`.
std::vector<BaPoint> IntersectFromPreviousSite(const TiePointSet& set, const Network& net,
                                               const CrossSiteBaOptions& options, CrossSiteBaSummary* s) {
  std::vector<BaPoint> points;
  for (const auto& tp : set.points) {
    BaPoint bp;
    bp.id = tp.id;
    for (const auto& o : tp.observations) {
      const size_t pairs = o.site == SiteRole::kPrevious ? set.previous_pointing.size() : set.current_pointing.size();
      if (o.pair_index < 0 || o.pair_index >= static_cast<int>(pairs) || !(o.sigma > 0) ||
          !(o.sigma <= kMaxObservationSigmaPx) || !(o.uv.cwiseAbs().maxCoeff() <= kMaxImageCoordinatePx)) {
        ++s->num_bad_observations;
        continue;
      }
      (o.site == SiteRole::kPrevious ? bp.previous : bp.current).push_back(o);
    }
    if (bp.previous.size() < 2 || bp.current.empty()) {
      ++s->num_tie_points_unusable;
      continue;
    }
    std::vector<CameraView> views;
    std::vector<Eigen::Vector2d> uv;
    std::vector<double> sigma;
    for (const auto& o : bp.previous) {
      views.push_back(CameraView::Make(net.PreviousCamera(o), net.Intrinsics(o.camera)));
      uv.push_back(o.uv);
      sigma.push_back(o.sigma);
    }
    const IntersectionResult ir = IntersectPoint(views, uv, sigma, options.min_intersection_parallax_rad);
    if (ir.ok) {
      bp.p_world = ir.p_world;
    } else if (!(options.far_points && ir.max_parallax_rad < options.min_intersection_parallax_rad &&
                 MakeFarPoint(net, views, uv, sigma, &bp))) {
      ++s->num_tie_points_unusable;
      continue;
    }
    points.push_back(bp);
  }
  return points;
}

// The current site's pose resected from the intersected points (dead
// reckoning when the resection fails); its iterations into `s`.
Pose3 ResectCurrentSite(const TiePointSet& set, const Network& net, const std::vector<BaPoint>& points,
                        const CrossSiteBaOptions& options, CrossSiteBaSummary* s) {
  std::vector<Pose3> body_from_camera;
  std::vector<PinholeCamera> intrinsics;
  for (size_t i = 0; i < net.body_from_left.size(); ++i) {
    body_from_camera.push_back(net.body_from_left[i]);
    intrinsics.push_back(net.navcam->rig.left);
    body_from_camera.push_back(net.body_from_right[i]);
    intrinsics.push_back(net.navcam->rig.right);
  }
  std::vector<ResectionObservation> robs;
  for (const auto& p : points) {
    if (p.far) continue;  // the resection takes the points in the world
    for (const auto& o : p.current) {
      ResectionObservation r;
      r.p_world = p.p_world;
      r.uv = o.uv;
      r.sigma_px = o.sigma;
      r.camera = 2 * o.pair_index + (o.camera == CameraSide::kLeft ? 0 : 1);
      robs.push_back(r);
    }
  }
  ResectionOptions ro;
  ro.huber_px = options.huber_sigmas;
  const ResectionResult rr = ResectBody(body_from_camera, intrinsics, robs, set.current_site_pose_dr.pose, ro);
  s->iterations += rr.iterations;
  return rr.ok ? rr.world_from_body : set.current_site_pose_dr.pose;
}

// Robust passes, each followed by the outlier rejection, until one rejects
// none (at most options.rejection_rounds): "" or why too few points are
// left.
std::string AdjustRejectingOutliers(const Network& net, const CrossSiteBaOptions& options,
                                    std::vector<BaPoint>* points, Pose3* world_from_current, CrossSiteBaSummary* s) {
  for (int round = 0; round < options.rejection_rounds; ++round) {
    const PassResult pr = SolvePass(net, points, world_from_current, /*robust=*/true, options);
    s->iterations += pr.iterations;
    const int rejected = RejectOutliers(net, points, *world_from_current, options);
    s->num_tie_points_rejected += rejected;
    if (CountInliers(*points) < options.min_tie_points) {
      return std::to_string(CountInliers(*points)) + " tie points left after rejecting " +
             std::to_string(s->num_tie_points_rejected) + " outliers, need " + std::to_string(options.min_tie_points);
    }
    if (rejected == 0) break;
  }
  return "";
}

// The pose covariance as reported (options.inflate_by_variance_factor,
// options.max_independent_points) and its condition number with the
// rotation scaled by the points' mean range (metres both).
struct ScaledCovariance {
  Matrix6d covariance;
  double variance_factor = 1;
  double condition_number = std::numeric_limits<double>::infinity();
};
ScaledCovariance ScaleCovariance(const Matrix6d& plain, const Residuals& res, const std::vector<BaPoint>& points,
                                 const Pose3& world_from_current, const CrossSiteBaOptions& options) {
  ScaledCovariance out;
  Matrix6d cov = plain;
  const int dof = 2 * res.observations - 6 - 3 * res.points;
  out.variance_factor = dof > 0 ? res.chi2 / dof : 1.0;
  if (options.inflate_by_variance_factor) cov *= std::max(1.0, out.variance_factor);
  if (options.max_independent_points > 0)
    cov *= std::max(1.0, static_cast<double>(res.points) / options.max_independent_points);
  double mean_range = 0;
  int near = 0;
  for (const auto& p : points)
    if (p.inlier && !p.far) mean_range += (p.p_world - world_from_current.translation()).norm(), ++near;
  mean_range /= std::max(1, near);
  Vector6d scale;
  scale << 1, 1, 1, mean_range, mean_range, mean_range;
  const Matrix6d scaled = scale.asDiagonal() * cov * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eig(scaled);
  const double lmin = eig.eigenvalues()(0), lmax = eig.eigenvalues()(5);
  out.condition_number = lmin > 0 ? lmax / lmin : std::numeric_limits<double>::infinity();
  out.covariance = cov;
  return out;
}

struct Verdict {
  CrossSiteBaStatus status;
  std::string message;
};

// Whether the adjusted pose may replace dead reckoning, and why.
Verdict Judge(const PassResult& final_pass, const Residuals& res, const ScaledCovariance& cov,
              const Pose3& world_from_current, const TiePointSet& set, const CrossSiteBaOptions& options) {
  std::ostringstream msg;
  if (!final_pass.converged) {
    msg << "adjustment did not converge: " << final_pass.message;
    return {CrossSiteBaStatus::kNotConverged, msg.str()};
  }
  if (res.normalised_rms > options.max_final_rms_sigmas) {
    msg << "final reprojection RMS " << res.normalised_rms << " sigmas exceeds " << options.max_final_rms_sigmas;
    return {CrossSiteBaStatus::kNotConverged, msg.str()};
  }
  const double correction = (world_from_current.translation() - set.current_site_pose_dr.pose.translation()).norm();
  if (correction > options.max_correction_m) {
    msg << "solution moved " << correction << " m from dead reckoning, more than " << options.max_correction_m;
    return {CrossSiteBaStatus::kNotConverged, msg.str()};
  }
  if (!(cov.condition_number <= options.max_condition_number)) {
    msg << "pose covariance condition number " << cov.condition_number << " exceeds " << options.max_condition_number
        << " (tie points too few, clustered or collinear)";
    return {CrossSiteBaStatus::kIllConditioned, msg.str()};
  }
  msg << "adjusted " << res.points << " tie points, moved " << correction << " m from dead reckoning, position sigma "
      << std::sqrt(cov.covariance.block<3, 3>(0, 0).trace()) << " m, variance factor " << cov.variance_factor;
  return {CrossSiteBaStatus::kOk, msg.str()};
}

// The summary's status and message, its relative pose and the cameras of
// both sites (dead reckoning's pose and covariance unless `status` is OK).
CrossSiteBaSummary Finish(const TiePointSet& set, const NavcamModel& navcam, std::chrono::steady_clock::time_point t0,
                          const Verdict& verdict, CrossSiteBaSummary s) {
  s.status = verdict.status;
  s.usable = verdict.status == CrossSiteBaStatus::kOk;
  s.message = verdict.message;
  if (!s.usable) s.world_from_current = set.current_site_pose_dr;
  s.world_from_current.utime = set.current_site_pose_dr.utime;
  const Pose3 previous_from_world = set.previous_site_pose.pose.inverse();
  s.previous_from_current.utime = s.world_from_current.utime;
  s.previous_from_current.pose = previous_from_world * s.world_from_current.pose;
  if (s.usable) {
    s.previous_from_current.covariance = ComposeCovariance(previous_from_world, Matrix6d::Zero(),
                                                           s.world_from_current.pose, s.world_from_current.covariance);
  } else {
    // Dead reckoning: the relative covariance is unknown here beyond the DR one.
    s.previous_from_current.covariance = s.world_from_current.covariance;
  }
  SiteCameraPoses(set.previous_site_pose.pose, set.previous_pointing, navcam, &s.world_from_left_previous,
                  &s.world_from_right_previous);
  SiteCameraPoses(s.world_from_current.pose, set.current_pointing, navcam, &s.world_from_left_current,
                  &s.world_from_right_current);
  s.solve_seconds = SecondsSince(t0);
  return s;
}

}  // namespace

// Wan et al. 2.3: the current site's pose (and the tie points) adjusted to
// both sites' observations, the previous site held fixed.
CrossSiteBaSummary SolveCrossSiteBa(const TiePointSet& set, const NavcamModel& navcam,
                                    const CrossSiteBaOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  CrossSiteBaSummary s;
  s.previous_site_id = set.previous_site_id;
  s.current_site_id = set.current_site_id;
  s.num_tie_points_in = static_cast<int>(set.points.size());
  s.world_from_current = set.current_site_pose_dr;
  s.world_from_current_initial = set.current_site_pose_dr.pose;
  auto finish = [&](CrossSiteBaStatus status, const std::string& message) {
    return Finish(set, navcam, t0, {status, message}, s);
  };
  const std::string bad_input = InputError(set, navcam, options);
  if (!bad_input.empty()) return finish(CrossSiteBaStatus::kBadInput, bad_input);

  const Network net = MakeNetwork(set, navcam);
  std::vector<BaPoint> points = IntersectFromPreviousSite(set, net, options, &s);
  const int usable = static_cast<int>(points.size());
  if (usable < options.min_tie_points) {
    return finish(CrossSiteBaStatus::kTooFewPoints,
                  std::to_string(usable) + " tie points seen from both sites and intersectable, need " +
                      std::to_string(options.min_tie_points));
  }
  Pose3 world_from_current = ResectCurrentSite(set, net, points, options, &s);
  s.world_from_current_initial = world_from_current;
  s.initial_rms_px = ComputeResiduals(net, points, world_from_current).rms_px;

  const std::string too_few = AdjustRejectingOutliers(net, options, &points, &world_from_current, &s);
  if (!too_few.empty()) return finish(CrossSiteBaStatus::kTooFewPoints, too_few);
  const PassResult final_pass = SolvePass(net, &points, &world_from_current, /*robust=*/false, options);
  s.iterations += final_pass.iterations;
  const Residuals res = ComputeResiduals(net, points, world_from_current);
  s.num_tie_points_used = res.points;
  s.num_far_points = static_cast<int>(
      std::count_if(points.begin(), points.end(), [](const BaPoint& p) { return p.inlier && p.far; }));
  s.num_observations = res.observations;
  s.final_rms_px = res.rms_px;
  s.final_normalised_rms = res.normalised_rms;
  s.world_from_current.pose = world_from_current;

  Matrix6d plain;
  std::string why;
  if (!PoseCovariance(net, points, world_from_current, options, &plain, &why)) {
    s.condition_number = std::numeric_limits<double>::infinity();
    return finish(CrossSiteBaStatus::kIllConditioned, why);
  }
  const ScaledCovariance cov = ScaleCovariance(plain, res, points, world_from_current, options);
  s.condition_number = cov.condition_number;
  s.world_from_current.covariance = cov.covariance;
  const Verdict verdict = Judge(final_pass, res, cov, world_from_current, set, options);
  return finish(verdict.status, verdict.message);
}

}  // namespace vloc
