#pragma once
// Applying a plane-to-plane homography (3x3, OpenCV's Matx33d) to points.

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace vloc {

// H * (p, 1), dehomogenised.
inline Eigen::Vector2d ApplyHomography(const cv::Matx33d& H, const Eigen::Vector2d& p) {
  const double w = H(2, 0) * p.x() + H(2, 1) * p.y() + H(2, 2);
  return {(H(0, 0) * p.x() + H(0, 1) * p.y() + H(0, 2)) / w, (H(1, 0) * p.x() + H(1, 1) * p.y() + H(1, 2)) / w};
}

// The local affine of H at p (d H(p) / d p), by central differences over 1 px.
inline Eigen::Matrix2d HomographyJacobian(const cv::Matx33d& H, const Eigen::Vector2d& p) {
  Eigen::Matrix2d J;
  J.col(0) = ApplyHomography(H, p + Eigen::Vector2d(0.5, 0)) - ApplyHomography(H, p - Eigen::Vector2d(0.5, 0));
  J.col(1) = ApplyHomography(H, p + Eigen::Vector2d(0, 0.5)) - ApplyHomography(H, p - Eigen::Vector2d(0, 0.5));
  return J;
}

}  // namespace vloc
