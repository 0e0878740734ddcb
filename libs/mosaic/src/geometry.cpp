#include "vloc/mosaic/geometry.h"

#include <opencv2/imgproc.hpp>

#include <cmath>

namespace vloc::mosaic {

Similarity2 Similarity2::FromScaleAngle(double scale, double angle, double tx, double ty) {
  return {scale * std::cos(angle), scale * std::sin(angle), tx, ty};
}
double Similarity2::Scale() const { return std::hypot(a, b); }
double Similarity2::Angle() const { return std::atan2(b, a); }
cv::Point2d Similarity2::Apply(const cv::Point2d& p) const {
  return {a * p.x - b * p.y + tx, b * p.x + a * p.y + ty};
}
Similarity2 Similarity2::Inverse() const {
  const double s2 = a * a + b * b;
  const double ia = a / s2, ib = -b / s2;
  return {ia, ib, -(ia * tx - ib * ty), -(ib * tx + ia * ty)};
}
cv::Matx23d Similarity2::ToMatx() const { return {a, -b, tx, b, a, ty}; }
Similarity2 Similarity2::operator*(const Similarity2& o) const {
  Similarity2 r;
  r.a = a * o.a - b * o.b;
  r.b = b * o.a + a * o.b;
  const cv::Point2d t = Apply({o.tx, o.ty});
  r.tx = t.x;
  r.ty = t.y;
  return r;
}

AxisScaleFit FitAxisScale(const std::vector<cv::Point2f>& from, const std::vector<cv::Point2f>& to) {
  AxisScaleFit fit;
  const size_t n = std::min(from.size(), to.size());
  if (n < 3) return fit;
  // Two independent 1-D regressions x' = lx x + tx, y' = ly y + ty.
  auto regress = [&](bool use_x, double* slope, double* offset) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (size_t i = 0; i < n; ++i) {
      const double u = use_x ? from[i].x : from[i].y;
      const double v = use_x ? to[i].x : to[i].y;
      sx += u; sy += v; sxx += u * u; sxy += u * v;
    }
    const double den = n * sxx - sx * sx;
    if (std::abs(den) < 1e-9) return false;
    *slope = (n * sxy - sx * sy) / den;
    *offset = (sy - *slope * sx) / n;
    return true;
  };
  if (!regress(true, &fit.lambda_x, &fit.tau_x) || !regress(false, &fit.lambda_y, &fit.tau_y)) return fit;
  double ss = 0;
  for (size_t i = 0; i < n; ++i) {
    const double ex = fit.lambda_x * from[i].x + fit.tau_x - to[i].x;
    const double ey = fit.lambda_y * from[i].y + fit.tau_y - to[i].y;
    ss += ex * ex + ey * ey;
  }
  fit.rms = std::sqrt(ss / n);
  fit.ok = true;
  return fit;
}

namespace {
template <class P>
bool FitSimilarityImpl(const std::vector<P>& from, const std::vector<P>& to, Similarity2* out, double* rms) {
  const size_t n = std::min(from.size(), to.size());
  if (n < 2) return false;
  double mx = 0, my = 0, nx = 0, ny = 0;
  for (size_t i = 0; i < n; ++i) {
    mx += from[i].x; my += from[i].y; nx += to[i].x; ny += to[i].y;
  }
  mx /= n; my /= n; nx /= n; ny /= n;
  double sxx = 0, sab = 0, sba = 0;
  for (size_t i = 0; i < n; ++i) {
    const double ux = from[i].x - mx, uy = from[i].y - my;
    const double vx = to[i].x - nx, vy = to[i].y - ny;
    sxx += ux * ux + uy * uy;
    sab += ux * vx + uy * vy;
    sba += ux * vy - uy * vx;
  }
  if (sxx < 1e-12) return false;
  Similarity2 s;
  s.a = sab / sxx;
  s.b = sba / sxx;
  s.tx = nx - (s.a * mx - s.b * my);
  s.ty = ny - (s.b * mx + s.a * my);
  if (rms) {
    double ss = 0;
    for (size_t i = 0; i < n; ++i) {
      const cv::Point2d p = s.Apply({double(from[i].x), double(from[i].y)});
      ss += (p.x - to[i].x) * (p.x - to[i].x) + (p.y - to[i].y) * (p.y - to[i].y);
    }
    *rms = std::sqrt(ss / n);
  }
  *out = s;
  return true;
}
}  // namespace

bool FitSimilarity(const std::vector<cv::Point2f>& from, const std::vector<cv::Point2f>& to,
                   Similarity2* result, double* rms) {
  return FitSimilarityImpl(from, to, result, rms);
}
bool FitSimilarity(const std::vector<cv::Point2d>& from, const std::vector<cv::Point2d>& to,
                   Similarity2* result, double* rms) {
  return FitSimilarityImpl(from, to, result, rms);
}

bool FitAffine(const std::vector<cv::Point2f>& from, const std::vector<cv::Point2f>& to, cv::Matx23d* result,
               double* rms) {
  const int n = static_cast<int>(std::min(from.size(), to.size()));
  if (n < 3) return false;
  cv::Mat A(n, 3, CV_64F), bx(n, 1, CV_64F), by(n, 1, CV_64F);
  for (int i = 0; i < n; ++i) {
    A.at<double>(i, 0) = from[i].x;
    A.at<double>(i, 1) = from[i].y;
    A.at<double>(i, 2) = 1.0;
    bx.at<double>(i) = to[i].x;
    by.at<double>(i) = to[i].y;
  }
  cv::Mat px, py;
  if (!cv::solve(A, bx, px, cv::DECOMP_SVD) || !cv::solve(A, by, py, cv::DECOMP_SVD)) return false;
  *result = cv::Matx23d(px.at<double>(0), px.at<double>(1), px.at<double>(2), py.at<double>(0),
                        py.at<double>(1), py.at<double>(2));
  if (rms) {
    double ss = 0;
    for (int i = 0; i < n; ++i) {
      const cv::Vec2d p = (*result) * cv::Vec3d(from[i].x, from[i].y, 1.0);
      ss += (p[0] - to[i].x) * (p[0] - to[i].x) + (p[1] - to[i].y) * (p[1] - to[i].y);
    }
    *rms = std::sqrt(ss / n);
  }
  return true;
}

cv::Mat ToGray(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat gray;
  cv::cvtColor(image, gray, image.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  return gray;
}

double OverlapFraction(const Similarity2& other_to_this, cv::Size size) {
  const std::vector<cv::Point2f> rect = {
      {0, 0}, {float(size.width), 0}, {float(size.width), float(size.height)}, {0, float(size.height)}};
  std::vector<cv::Point2f> quad, inter;
  for (const auto& p : rect) quad.push_back(other_to_this.Apply(p));
  const float area = cv::intersectConvexConvex(rect, quad, inter, true);
  return area / (static_cast<double>(size.area()) + 1e-9);
}

}  // namespace vloc::mosaic
