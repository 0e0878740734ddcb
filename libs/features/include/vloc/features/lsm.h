#pragma once
// Least-squares matching (Gruen 1985, adaptive least squares correlation):
// the template window T(x) around a point of one image is matched to the
// other image G with an affine geometric model and a linear radiometric
// model,  T(x) = r0 + r1 * G(A x + t),  x = offset from the template centre,
// solved by Gauss-Newton to sub-pixel precision. The precision of t comes
// from the a-posteriori variance of unit weight and the normal matrix.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>

namespace vloc {

class OptionsReader;

struct LsmOptions {
  int half_window = 7;             // px, template is (2 h + 1)^2 ...
  int half_height = 0;             // px, ... or (2 h + 1) wide and (2 half_height + 1) high (0: square)
  int max_iterations = 20;         // Gauss-Newton iterations
  double convergence_px = 0.005;   // px, stop when the shift update is below this
  double max_shift_px = 3.0;       // px, reject when t moves further from its initial value
  double min_template_std = 2.0;   // grey level, flatter templates are rejected
  double max_sigma_px = 0.3;       // px, reject results less precise than this (mean of x and y)
  double max_sigma_axis_px = 0;    // px, reject when the least precise direction is worse than this (0 = off)
  double min_correlation = 0.8;    // correlation of template and resampled window at the solution
  bool estimate_affine = true;     // false: shift + radiometry only
  bool bspline = false;            // resample with cubic B-splines (both images made by
                                   // MakeLsmImage(gray, true)); false: Keys' cubic convolution,
                                   // whose smoothing changes with the sub-pixel phase and pulls
                                   // matches towards phase 0.5 by up to 0.02 px

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// An image prepared for LSM: float grey levels (LSM takes its gradients from
// the cubic it resamples with, not from gradient images).
struct LsmImage {
  cv::Mat gray;     // CV_32FC1
  cv::Mat bspline;  // CV_32FC1, cubic B-spline coefficients of gray (empty unless asked for)
};
// Accepts CV_8UC1 or CV_32FC1.
LsmImage MakeLsmImage(const cv::Mat& gray, bool bspline_coefficients = false);

// Cubic B-spline interpolation coefficients of a CV_32FC1 image (separable
// recursive prefilter, mirror boundary; Unser 1999).
cv::Mat BSplineCoefficients(const cv::Mat& gray);

struct LsmResult {
  bool ok = false;
  const char* why = "";
  Eigen::Vector2d target = Eigen::Vector2d::Zero();    // px, matched position of the template centre
  Eigen::Matrix2d affine = Eigen::Matrix2d::Identity();  // d target / d template offset
  double r0 = 0, r1 = 1;                               // radiometric offset and gain
  double sigma_px = 0;                                 // px, 1-sigma precision of `target` (mean of x, y)
  double sigma_max_px = 0;                             // px, 1-sigma along the least precise direction
  double sigma0 = 0;                                   // grey level, a-posteriori std of the residuals
  double correlation = 0;                              // at the solution
  int iterations = 0;
};

// Matches the window centred on template_px (sub-pixel allowed) of
// `templ` into `target`, starting from initial_target / initial_affine.
LsmResult LeastSquaresMatch(const LsmImage& templ, const Eigen::Vector2d& template_px, const LsmImage& target,
                            const Eigen::Vector2d& initial_target, const Eigen::Matrix2d& initial_affine,
                            const LsmOptions& options);

}  // namespace vloc
