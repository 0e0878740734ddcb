#pragma once
// 2-D transforms between a nadir frame and the mosaic, and the least-squares
// fits of section 2.2 (equation 3) used for the scale change.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace vloc::mosaic {

// p' = [a -b; b a] p + t : rotation + isotropic scale + translation.
struct Similarity2 {
  double a = 1.0, b = 0.0, tx = 0.0, ty = 0.0;

  static Similarity2 FromScaleAngle(double scale, double angle, double tx, double ty);
  double Scale() const;   // lambda
  double Angle() const;   // rad
  cv::Point2d Apply(const cv::Point2d& p) const;
  Similarity2 Inverse() const;
  cv::Matx23d ToMatx() const;
  // (this * other)(p) = this(other(p))
  Similarity2 operator*(const Similarity2& other) const;
};

// Equation 3 as printed, fitted by least squares to every match:
// x' = lambda_x x + tau_x, y' = lambda_y y + tau_y (no rotation).
struct AxisScaleFit {
  bool ok = false;
  double lambda_x = 1.0, lambda_y = 1.0, tau_x = 0.0, tau_y = 0.0;
  double rms = 0.0;  // px, residual
};
AxisScaleFit FitAxisScale(const std::vector<cv::Point2f>& from, const std::vector<cv::Point2f>& to);

// Fraction of a frame of `size` that another frame of the same size covers,
// `other_to_this` mapping the other's px to this frame's px.
double OverlapFraction(const Similarity2& other_to_this, cv::Size size);

// Least-squares similarity (closed form, Umeyama without reflection).
// rms receives the residual in px when not null. ok=false for < 2 points.
bool FitSimilarity(const std::vector<cv::Point2f>& from, const std::vector<cv::Point2f>& to,
                   Similarity2* result, double* rms = nullptr);

// Least-squares full affine; its scale is sqrt(|det|).
bool FitAffine(const std::vector<cv::Point2f>& from, const std::vector<cv::Point2f>& to,
               cv::Matx23d* result, double* rms = nullptr);

// Weighted 2-D similarity between double points (used for the GPS tie).
bool FitSimilarity(const std::vector<cv::Point2d>& from, const std::vector<cv::Point2d>& to,
                   Similarity2* result, double* rms = nullptr);

// 8-bit grey from grey, BGR or BGRA (grey is returned as is, not copied).
cv::Mat ToGray(const cv::Mat& image);

}  // namespace vloc::mosaic
