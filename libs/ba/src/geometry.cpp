#include "vloc/ba/geometry.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "reprojection.h"

namespace vloc {

CameraView CameraView::Make(const Pose3& world_from_camera, const PinholeCamera& camera) {
  CameraView v;
  v.world_from_camera = world_from_camera;
  v.fx = camera.fx;
  v.fy = camera.fy;
  v.cx = camera.cx;
  v.cy = camera.cy;
  return v;
}

std::optional<Eigen::Vector2d> CameraView::Project(const Eigen::Vector3d& p_world) const {
  const Eigen::Vector3d pc = world_from_camera.inverse() * p_world;
  if (pc.z() <= 1e-9) return std::nullopt;
  return Eigen::Vector2d(fx * pc.x() / pc.z() + cx, fy * pc.y() / pc.z() + cy);
}

namespace {

// The largest angle between two of the views' rays through their pixels.
double MaxParallax(const std::vector<CameraView>& views, const std::vector<Eigen::Vector2d>& uv) {
  const size_t n = views.size();
  std::vector<Eigen::Vector3d> rays(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d ray_c((uv[i].x() - views[i].cx) / views[i].fx, (uv[i].y() - views[i].cy) / views[i].fy, 1.0);
    rays[i] = (views[i].world_from_camera.linear() * ray_c).normalized();
  }
  double max_parallax = 0;
  for (size_t i = 0; i < n; ++i)
    for (size_t j = i + 1; j < n; ++j)
      max_parallax = std::max(max_parallax, std::acos(std::clamp(rays[i].dot(rays[j]), -1.0, 1.0)));
  return max_parallax;
}

// Linear solution: for each view, (x r3 - r1) p = t1 - x t3 and
// (y r3 - r2) p = t2 - y t3 with (R, t) = camera_from_world and (x, y)
// normalised coordinates.
Eigen::Vector3d LinearIntersection(const std::vector<CameraView>& views, const std::vector<Eigen::Vector2d>& uv,
                                   const std::vector<Pose3>& camera_from_world) {
  const size_t n = views.size();
  Eigen::MatrixXd A(2 * n, 3);
  Eigen::VectorXd b(2 * n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Matrix3d R = camera_from_world[i].linear();
    const Eigen::Vector3d t = camera_from_world[i].translation();
    const double x = (uv[i].x() - views[i].cx) / views[i].fx;
    const double y = (uv[i].y() - views[i].cy) / views[i].fy;
    A.row(2 * i) = x * R.row(2) - R.row(0);
    A.row(2 * i + 1) = y * R.row(2) - R.row(1);
    b(2 * i) = t.x() - x * t.z();
    b(2 * i + 1) = t.y() - y * t.z();
  }
  return A.colPivHouseholderQr().solve(b);
}

// Gauss-Newton on the reprojection error weighted by 1 / sigma^2 (unit
// weights without sigmas), from p.
void RefineIntersection(const std::vector<CameraView>& views, const std::vector<Eigen::Vector2d>& uv,
                        const std::vector<double>& sigma_px, const std::vector<Pose3>& camera_from_world,
                        Eigen::Vector3d* p) {
  const size_t n = views.size();
  for (int iter = 0; iter < 10; ++iter) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d pc = camera_from_world[i] * *p;
      if (pc.z() <= 1e-6) break;
      const double w = sigma_px.empty() ? 1.0 : 1.0 / (sigma_px[i] * sigma_px[i]);
      Eigen::Matrix<double, 2, 3> J;
      J << views[i].fx / pc.z(), 0, -views[i].fx * pc.x() / (pc.z() * pc.z()), 0, views[i].fy / pc.z(),
          -views[i].fy * pc.y() / (pc.z() * pc.z());
      J = J * camera_from_world[i].linear();
      const Eigen::Vector2d r(views[i].fx * pc.x() / pc.z() + views[i].cx - uv[i].x(),
                              views[i].fy * pc.y() / pc.z() + views[i].cy - uv[i].y());
      H += w * J.transpose() * J;
      g += w * J.transpose() * r;
    }
    const Eigen::Vector3d step = H.ldlt().solve(-g);
    if (!step.allFinite()) break;
    *p += step;
    if (step.norm() < 1e-10 * (1.0 + p->norm())) break;
  }
}

}  // namespace

IntersectionResult IntersectPoint(const std::vector<CameraView>& views, const std::vector<Eigen::Vector2d>& uv,
                                  const std::vector<double>& sigma_px, double min_parallax_rad) {
  IntersectionResult res;
  const size_t n = views.size();
  if (n < 2 || uv.size() != n || (!sigma_px.empty() && sigma_px.size() != n)) {
    res.message = "intersection needs at least two views with one pixel each";
    return res;
  }
  res.max_parallax_rad = MaxParallax(views, uv);
  if (res.max_parallax_rad < min_parallax_rad) {
    res.message = "rays are (nearly) parallel: no intersection";
    return res;
  }
  std::vector<Pose3> camera_from_world(n);
  for (size_t i = 0; i < n; ++i) camera_from_world[i] = views[i].world_from_camera.inverse();
  Eigen::Vector3d p = LinearIntersection(views, uv, camera_from_world);
  RefineIntersection(views, uv, sigma_px, camera_from_world, &p);
  double sum2 = 0;
  for (size_t i = 0; i < n; ++i) {
    const auto px = views[i].Project(p);
    if (!px) {
      res.message = "intersected point lies behind a camera";
      return res;
    }
    sum2 += (*px - uv[i]).squaredNorm();
  }
  if (!p.allFinite()) {
    res.message = "intersection is not finite";
    return res;
  }
  res.p_world = p;
  res.rms_px = std::sqrt(sum2 / n);
  res.ok = true;
  return res;
}

namespace {

struct RefinedStart {
  bool ok = false;
  Pose3 pose;
  double cost = std::numeric_limits<double>::infinity();
  int iterations = 0;
};

RefinedStart RefineResection(const std::vector<Pose3>& body_from_camera, const std::vector<PinholeCamera>& intrinsics,
                             const std::vector<ResectionObservation>& obs, const Pose3& start,
                             const ResectionOptions& options) {
  RefinedStart out;
  const Eigen::Matrix3d R0 = start.linear();
  double pose[6] = {start.translation().x(), start.translation().y(), start.translation().z(), 0, 0, 0};
  std::vector<Eigen::Vector3d> points(obs.size());
  ceres::Problem problem;
  for (size_t i = 0; i < obs.size(); ++i) {
    const auto& o = obs[i];
    const PinholeCamera& k = intrinsics[o.camera];
    points[i] = o.p_world;
    problem.AddResidualBlock(internal::BodyCameraReprojection::Create(R0, body_from_camera[o.camera], k.fx, k.fy,
                                                                      k.cx, k.cy, o.uv, o.sigma_px),
                             new ceres::HuberLoss(options.huber_px), pose, points[i].data());
    problem.SetParameterBlockConstant(points[i].data());
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  out.ok = summary.IsSolutionUsable();
  out.pose = internal::BodyPoseFromParameters(R0, pose);
  out.cost = summary.final_cost;
  out.iterations = static_cast<int>(summary.iterations.size());
  // A start that leaves points behind the cameras is not a solution.
  for (const auto& o : obs) {
    const Eigen::Vector3d pc = (out.pose * body_from_camera[o.camera]).inverse() * o.p_world;
    if (pc.z() <= 0) {
      out.ok = false;
      break;
    }
  }
  return out;
}

}  // namespace

namespace {

// Why the resection's input is unusable ("" when it is), and the number of
// observations per camera.
std::string ResectionInputError(const std::vector<Pose3>& body_from_camera,
                                const std::vector<PinholeCamera>& intrinsics,
                                const std::vector<ResectionObservation>& observations, const ResectionOptions& options,
                                std::vector<int>* per_camera) {
  if (body_from_camera.size() != intrinsics.size()) return "resection: one intrinsics entry per camera needed";
  per_camera->assign(body_from_camera.size(), 0);
  for (const auto& o : observations) {
    if (o.camera < 0 || o.camera >= static_cast<int>(body_from_camera.size()) || !(o.sigma_px > 0) ||
        !o.uv.allFinite() || !o.p_world.allFinite())
      return "resection: an observation has a bad camera index, sigma or value";
    ++(*per_camera)[o.camera];
  }
  if (static_cast<int>(observations.size()) < std::max(3, options.min_observations))
    return "resection: " + std::to_string(observations.size()) + " observations, need " +
           std::to_string(std::max(3, options.min_observations));
  return "";
}

// The body pose from solvePnP (SQPnP) on the camera with the most
// observations (at least 4), or nullopt.
std::optional<Pose3> PnpStart(const std::vector<Pose3>& body_from_camera, const std::vector<PinholeCamera>& intrinsics,
                              const std::vector<ResectionObservation>& observations, const std::vector<int>& per_camera) {
  const int best = static_cast<int>(std::max_element(per_camera.begin(), per_camera.end()) - per_camera.begin());
  if (per_camera[best] < 4) return std::nullopt;
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  for (const auto& o : observations) {
    if (o.camera != best) continue;
    object.emplace_back(o.p_world.x(), o.p_world.y(), o.p_world.z());
    image.emplace_back(o.uv.x(), o.uv.y());
  }
  cv::Mat rvec, tvec;
  bool ok = false;
  try {
    ok = cv::solvePnP(object, image, cv::Mat(intrinsics[best].K()), cv::Mat(), rvec, tvec, false, cv::SOLVEPNP_SQPNP);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) return std::nullopt;
  cv::Mat Rcv;
  cv::Rodrigues(rvec, Rcv);
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  cv::cv2eigen(Rcv, R);
  cv::cv2eigen(tvec, t);
  const Pose3 world_from_camera = MakePose(R, t).inverse();
  return world_from_camera * body_from_camera[best].inverse();
}

}  // namespace

ResectionResult ResectBody(const std::vector<Pose3>& body_from_camera, const std::vector<PinholeCamera>& intrinsics,
                           const std::vector<ResectionObservation>& observations,
                           const Pose3& initial_world_from_body, const ResectionOptions& options) {
  ResectionResult res;
  std::vector<int> per_camera;
  res.message = ResectionInputError(body_from_camera, intrinsics, observations, options, &per_camera);
  if (!res.message.empty()) return res;
  std::vector<std::pair<Pose3, bool>> starts = {{initial_world_from_body, false}};
  if (options.try_pnp)
    if (const auto pnp = PnpStart(body_from_camera, intrinsics, observations, per_camera)) starts.emplace_back(*pnp, true);
  RefinedStart best;
  for (const auto& [start, from_pnp] : starts) {
    RefinedStart r = RefineResection(body_from_camera, intrinsics, observations, start, options);
    res.iterations += r.iterations;
    if (r.ok && r.cost < best.cost) {
      best = r;
      res.used_pnp_start = from_pnp;
    }
  }
  if (!best.ok) {
    res.message = "resection did not converge from the initial pose or from solvePnP";
    return res;
  }
  res.world_from_body = best.pose;
  double sum2 = 0;
  for (const auto& o : observations) {
    const CameraView view = CameraView::Make(best.pose * body_from_camera[o.camera], intrinsics[o.camera]);
    const auto px = view.Project(o.p_world);
    sum2 += px ? (*px - o.uv).squaredNorm() : 1e6;
  }
  res.rms_px = std::sqrt(sum2 / observations.size());
  res.ok = true;
  return res;
}

}  // namespace vloc
