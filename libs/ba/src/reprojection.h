#pragma once
// Ceres residuals shared by the resection and the bundle adjustment
// (internal header). A body pose parameter block is [t (3), dr (3)]:
// world_from_body = (Exp(dr) * R0, t), so its covariance is directly in
// vloc's convention [x y z rx ry rz] (world-frame position and rotation
// errors) when evaluated at dr = 0.

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Core>

#include "vloc/common/pose.h"

namespace vloc::internal {

// A pinhole observation (pixel and sigma): the normalised residual of a
// point in camera coordinates (any positive multiple of them).
struct PinholeObservation {
  double fx, fy, cx, cy, u, v, inv_sigma;

  template <class T>
  bool Residual(T* pc, T* residual) const {
    if (pc[2] < T(1e-6)) pc[2] = T(1e-6);  // behind the camera: keep finite, huge residual
    residual[0] = (fx * pc[0] / pc[2] + cx - u) * inv_sigma;
    residual[1] = (fy * pc[1] / pc[2] + cy - v) * inv_sigma;
    return true;
  }
};

// An observation by a camera rigidly attached to a moving body.
// Parameters: body pose [t, dr] (6), point in world (3). Residual: 2, in sigmas.
struct BodyCameraReprojection {
  BodyCameraReprojection(const Eigen::Matrix3d& R0, const Pose3& body_from_camera, double fx, double fy, double cx,
                         double cy, const Eigen::Vector2d& uv, double sigma)
      : obs{fx, fy, cx, cy, uv.x(), uv.y(), 1.0 / sigma} {
    const Pose3 camera_from_body = body_from_camera.inverse();
    M = camera_from_body.linear() * R0.transpose();
    t_cb = camera_from_body.translation();
  }

  template <class T>
  bool operator()(const T* pose, const T* point, T* residual) const {
    const T d[3] = {point[0] - pose[0], point[1] - pose[1], point[2] - pose[2]};
    const T minus_dr[3] = {-pose[3], -pose[4], -pose[5]};
    T w[3];
    ceres::AngleAxisRotatePoint(minus_dr, d, w);  // Exp(dr)^T (p - t)
    T pc[3];
    for (int i = 0; i < 3; ++i) pc[i] = M(i, 0) * w[0] + M(i, 1) * w[1] + M(i, 2) * w[2] + t_cb[i];
    return obs.Residual(pc, residual);
  }

  static ceres::CostFunction* Create(const Eigen::Matrix3d& R0, const Pose3& body_from_camera, double fx, double fy,
                                     double cx, double cy, const Eigen::Vector2d& uv, double sigma) {
    return new ceres::AutoDiffCostFunction<BodyCameraReprojection, 2, 6, 3>(
        new BodyCameraReprojection(R0, body_from_camera, fx, fy, cx, cy, uv, sigma));
  }

  Eigen::Matrix3d M;
  Eigen::Vector3d t_cb;
  PinholeObservation obs;
};

// An observation by a camera whose pose is fixed. Parameters: point (3).
struct FixedCameraReprojection {
  FixedCameraReprojection(const Pose3& world_from_camera, double fx, double fy, double cx, double cy,
                          const Eigen::Vector2d& uv, double sigma)
      : obs{fx, fy, cx, cy, uv.x(), uv.y(), 1.0 / sigma} {
    const Pose3 camera_from_world = world_from_camera.inverse();
    R = camera_from_world.linear();
    t = camera_from_world.translation();
  }

  template <class T>
  bool operator()(const T* point, T* residual) const {
    T pc[3];
    for (int i = 0; i < 3; ++i) pc[i] = R(i, 0) * point[0] + R(i, 1) * point[1] + R(i, 2) * point[2] + t[i];
    return obs.Residual(pc, residual);
  }

  static ceres::CostFunction* Create(const Pose3& world_from_camera, double fx, double fy, double cx, double cy,
                                     const Eigen::Vector2d& uv, double sigma) {
    return new ceres::AutoDiffCostFunction<FixedCameraReprojection, 2, 3>(
        new FixedCameraReprojection(world_from_camera, fx, fy, cx, cy, uv, sigma));
  }

  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  PinholeObservation obs;
};

// A far point as an inverse depth in its anchor camera: parameters
// q = [a, b, rho] with p_anchor = (a, b, 1) / rho. Both functors project
// rho times the point's camera coordinates, which stays defined at rho = 0
// (a point at infinity: the direction alone, which still fixes rotation).

// An observation of an inverse-depth point by a fixed camera. Parameters: q (3).
struct FixedCameraInverseDepth {
  FixedCameraInverseDepth(const Pose3& camera_from_anchor, double fx, double fy, double cx, double cy,
                          const Eigen::Vector2d& uv, double sigma)
      : R(camera_from_anchor.linear()), t(camera_from_anchor.translation()),
        obs{fx, fy, cx, cy, uv.x(), uv.y(), 1.0 / sigma} {}

  template <class T>
  bool operator()(const T* q, T* residual) const {
    T pc[3];
    for (int i = 0; i < 3; ++i) pc[i] = R(i, 0) * q[0] + R(i, 1) * q[1] + R(i, 2) + q[2] * t[i];
    return obs.Residual(pc, residual);
  }

  static ceres::CostFunction* Create(const Pose3& camera_from_anchor, double fx, double fy, double cx, double cy,
                                     const Eigen::Vector2d& uv, double sigma) {
    return new ceres::AutoDiffCostFunction<FixedCameraInverseDepth, 2, 3>(
        new FixedCameraInverseDepth(camera_from_anchor, fx, fy, cx, cy, uv, sigma));
  }

  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  PinholeObservation obs;
};

// An observation of an inverse-depth point by a camera on the moving body.
// Parameters: body pose [t, dr] (6), q (3). BodyCameraReprojection times rho.
struct BodyCameraInverseDepth {
  BodyCameraInverseDepth(const Eigen::Matrix3d& R0, const Pose3& body_from_camera, const Pose3& world_from_anchor,
                         double fx, double fy, double cx, double cy, const Eigen::Vector2d& uv, double sigma)
      : R_wa(world_from_anchor.linear()), t_wa(world_from_anchor.translation()),
        obs{fx, fy, cx, cy, uv.x(), uv.y(), 1.0 / sigma} {
    const Pose3 camera_from_body = body_from_camera.inverse();
    M = camera_from_body.linear() * R0.transpose();
    t_cb = camera_from_body.translation();
  }

  template <class T>
  bool operator()(const T* pose, const T* q, T* residual) const {
    T h[3];  // rho (p - t)
    for (int i = 0; i < 3; ++i) h[i] = R_wa(i, 0) * q[0] + R_wa(i, 1) * q[1] + R_wa(i, 2) + q[2] * (t_wa[i] - pose[i]);
    const T minus_dr[3] = {-pose[3], -pose[4], -pose[5]};
    T w[3];
    ceres::AngleAxisRotatePoint(minus_dr, h, w);
    T pc[3];
    for (int i = 0; i < 3; ++i) pc[i] = M(i, 0) * w[0] + M(i, 1) * w[1] + M(i, 2) * w[2] + q[2] * t_cb[i];
    return obs.Residual(pc, residual);
  }

  static ceres::CostFunction* Create(const Eigen::Matrix3d& R0, const Pose3& body_from_camera,
                                     const Pose3& world_from_anchor, double fx, double fy, double cx, double cy,
                                     const Eigen::Vector2d& uv, double sigma) {
    return new ceres::AutoDiffCostFunction<BodyCameraInverseDepth, 2, 6, 3>(
        new BodyCameraInverseDepth(R0, body_from_camera, world_from_anchor, fx, fy, cx, cy, uv, sigma));
  }

  Eigen::Matrix3d M, R_wa;
  Eigen::Vector3d t_cb, t_wa;
  PinholeObservation obs;
};

// world_from_body from a linearisation rotation and a parameter block.
inline Pose3 BodyPoseFromParameters(const Eigen::Matrix3d& R0, const double* pose) {
  return MakePose(ExpSO3(Eigen::Vector3d(pose[3], pose[4], pose[5])) * R0, Eigen::Vector3d(pose[0], pose[1], pose[2]));
}

}  // namespace vloc::internal
