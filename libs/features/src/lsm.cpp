#include "vloc/features/lsm.h"

#include <algorithm>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>
#include <cstring>
#include <vector>

#include "cubic_kernels.h"
#include "vloc/common/options.h"
#include "vloc/features/stereo_match.h"

namespace vloc {

void LsmOptions::Visit(OptionsReader& r) {
  r.Optional("half_window", &half_window, "px, template half size", InRange(2, 30));
  r.Optional("half_height", &half_height, "px, template half height (0 = half_window: square)",
             Is(0) || InRange(2, 30));
  r.Optional("max_iterations", &max_iterations, "Gauss-Newton iterations", AtLeast(1));
  r.Optional("convergence_px", &convergence_px, "px, shift update that ends the iteration", Positive());
  r.Optional("max_shift_px", &max_shift_px, "px, largest accepted move from the initial position", Positive());
  r.Optional("min_template_std", &min_template_std, "grey level, minimum template std");
  r.Optional("max_sigma_px", &max_sigma_px, "px, largest accepted 1-sigma precision", Positive());
  r.Optional("max_sigma_axis_px", &max_sigma_axis_px, "px, largest accepted sigma along the worst direction (0 = off)");
  r.Optional("min_correlation", &min_correlation, "minimum correlation at the solution");
  r.Optional("estimate_affine", &estimate_affine, "estimate the 4 affine shape parameters");
  r.Optional("bspline", &bspline, "cubic B-spline resampling (false: Keys cubic convolution)");
}

bool LsmOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

cv::Mat BSplineCoefficients(const cv::Mat& gray) {
  CV_Assert(gray.type() == CV_32FC1);
  // Causal then anti-causal recursion with pole z (gain 6), mirror boundary;
  // rows one by one, then the columns all at once row after row (cache order).
  const float z = static_cast<float>(std::sqrt(3.0) - 2.0);
  const float last = z / (z * z - 1.f);
  cv::Mat c = gray * 36.0;  // gain 6 per dimension
  const int W = c.cols, H = c.rows;
  const int hx = std::min(W, 30), hy = std::min(H, 30);  // |z|^30 < 1e-17
  if (W > 1) {
    for (int y = 0; y < H; ++y) {
      float* r = c.ptr<float>(y);
      float sum = r[0], zk = z;
      for (int k = 1; k < hx; ++k, zk *= z) sum += zk * r[k];
      r[0] = sum;
      for (int k = 1; k < W; ++k) r[k] += z * r[k - 1];
      r[W - 1] = last * (r[W - 1] + z * r[W - 2]);
      for (int k = W - 2; k >= 0; --k) r[k] = z * (r[k + 1] - r[k]);
    }
  }
  if (H > 1) {
    std::vector<float> sum(c.ptr<float>(0), c.ptr<float>(0) + W);
    float zk = z;
    for (int k = 1; k < hy; ++k, zk *= z) {
      const float* r = c.ptr<float>(k);
      for (int x = 0; x < W; ++x) sum[x] += zk * r[x];
    }
    std::copy(sum.begin(), sum.end(), c.ptr<float>(0));
    for (int y = 1; y < H; ++y) {
      float* r = c.ptr<float>(y);
      const float* p = c.ptr<float>(y - 1);
      for (int x = 0; x < W; ++x) r[x] += z * p[x];
    }
    {
      float* r = c.ptr<float>(H - 1);
      const float* p = c.ptr<float>(H - 2);
      for (int x = 0; x < W; ++x) r[x] = last * (r[x] + z * p[x]);
    }
    for (int y = H - 2; y >= 0; --y) {
      float* r = c.ptr<float>(y);
      const float* n = c.ptr<float>(y + 1);
      for (int x = 0; x < W; ++x) r[x] = z * (n[x] - r[x]);
    }
  }
  return c;
}

LsmImage MakeLsmImage(const cv::Mat& gray, bool bspline_coefficients) {
  LsmImage out;
  if (gray.type() == CV_32FC1) {
    out.gray = gray;
  } else {
    CV_Assert(gray.type() == CV_8UC1);
    gray.convertTo(out.gray, CV_32F);
  }
  if (bspline_coefficients) out.bspline = BSplineCoefficients(out.gray);
  return out;
}

namespace {

using internal::BSplineWeights;
using internal::CubicWeights;

bool Inside(const cv::Mat& m, const Eigen::Vector2d& p, double margin_x, double margin_y) {
  return p.x() >= margin_x && p.y() >= margin_y && p.x() <= m.cols - 1 - margin_x && p.y() <= m.rows - 1 - margin_y;
}

// A template window resampled about its centre, row by row, with its mean and standard deviation.
struct Template {
  std::vector<float> T;
  double mean = 0, std = 0;
};

// The 8 parameters: the window centre t (2), the affine shape A (4,
// row-major) and the radiometry r0 + r1 g. Without affine estimation the 4
// shape parameters get zero Jacobians and a unit diagonal, so their update
// is zero.
constexpr int kParams = 8;
using Mat8 = Eigen::Matrix<double, kParams, kParams>;
using Vec8 = Eigen::Matrix<double, kParams, 1>;
struct WindowParams {
  Eigen::Vector2d t;
  Eigen::Matrix2d A;
  double r0 = 0, r1 = 1;
};

// The normal equations N dx = b at `p` (N's lower triangle) and the sum of
// squared residuals; G: the resampled target window.
struct NormalEquations {
  Mat8 N;
  Vec8 b;
  double ssr = 0;
  std::vector<float> G;
};
// N's columns in 4-double lanes: lo[l] rows 0-3 of column l (l < 4), hi[l] rows 4-7 of column l, and b.
// Each lane sums its own N(k, l) += J(l) J(k) over the taps in the scalar order (no FMA: the same products
// and sums): bit for bit the scalar loop's lower triangle, a quarter of its instructions with AVX2.
typedef double Lanes4 __attribute__((vector_size(32)));
struct NormalLanes {
  Lanes4 lo[4] = {}, hi[kParams] = {}, b_lo = {}, b_hi = {};
};

// Four floats (one tap a lane) and a 4 x 4 transpose of them.
typedef float Floats4 __attribute__((vector_size(16)));
typedef int Ints4 __attribute__((vector_size(16)));
__attribute__((always_inline)) inline void Transpose4(Floats4 q[4]) {
  const Ints4 lo{0, 4, 1, 5}, hi{2, 6, 3, 7};
  const Floats4 t0 = __builtin_shuffle(q[0], q[1], lo), t1 = __builtin_shuffle(q[0], q[1], hi);
  const Floats4 t2 = __builtin_shuffle(q[2], q[3], lo), t3 = __builtin_shuffle(q[2], q[3], hi);
  q[0] = __builtin_shuffle(t0, t2, Ints4{0, 1, 4, 5}), q[1] = __builtin_shuffle(t0, t2, Ints4{2, 3, 6, 7});
  q[2] = __builtin_shuffle(t1, t3, Ints4{0, 1, 4, 5}), q[3] = __builtin_shuffle(t1, t3, Ints4{2, 3, 6, 7});
}

// The target image's samples: its first row and row step (read once per linearisation).
struct Samples {
  const float* data;
  size_t step;
};

// Bicubic value and gradient (cubic_kernels.h; bspline: `img` holds B-spline coefficients) at 4 window taps,
// columns c[k] and rows r[k] about the window centre mapped by `p`, one tap a lane: in each lane the float
// operations of one tap, the kernels' then the rows' and columns' sums left to right. The caller keeps the
// taps at least 2 px inside the image.
__attribute__((always_inline)) inline void SampleCubic4(const Samples& img, const WindowParams& p, const int c[4],
                                                        const int r[4], bool bspline, double g[4], double gx[4],
                                                        double gy[4]) {
  const size_t step = img.step;
  alignas(16) float tx[4], ty[4];
  const float* base[4];
  for (int k = 0; k < 4; ++k) {
    const double x = p.t.x() + p.A(0, 0) * c[k] + p.A(0, 1) * r[k];
    const double y = p.t.y() + p.A(1, 0) * c[k] + p.A(1, 1) * r[k];
    const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
    tx[k] = static_cast<float>(x - x0), ty[k] = static_cast<float>(y - y0);
    base[k] = img.data + static_cast<ptrdiff_t>(y0 - 1) * static_cast<ptrdiff_t>(step) + (x0 - 1);
  }
  Floats4 wx[4], dwx[4], wy[4], dwy[4], t;
  std::memcpy(&t, tx, sizeof t);
  if (bspline) BSplineWeights(t, wx, dwx); else CubicWeights(t, wx, dwx);
  std::memcpy(&t, ty, sizeof t);
  if (bspline) BSplineWeights(t, wy, dwy); else CubicWeights(t, wy, dwy);
  Floats4 v = {}, vx = {}, vy = {};
  for (int i = 0; i < 4; ++i) {
    Floats4 q[4];  // row i of each tap's 4 x 4 neighbourhood, then its columns
    for (int k = 0; k < 4; ++k) std::memcpy(&q[k], base[k] + i * step, sizeof q[k]);
    Transpose4(q);
    const Floats4 rv = wx[0] * q[0] + wx[1] * q[1] + wx[2] * q[2] + wx[3] * q[3];
    const Floats4 rdx = dwx[0] * q[0] + dwx[1] * q[1] + dwx[2] * q[2] + dwx[3] * q[3];
    v += wy[i] * rv;
    vx += wy[i] * rdx;
    vy += dwy[i] * rv;
  }
  for (int k = 0; k < 4; ++k) g[k] = v[k], gx[k] = vx[k], gy[k] = vy[k];
}

// The window's taps in row-major order, 4 at a time (past the last one the last again): columns c and rows r
// about the window centre.
struct TapWalk {
  int h, hy, c, r;
  TapWalk(int h_, int hy_) : h(h_), hy(hy_), c(-h_), r(-hy_) {}
  void Next4(int cs[4], int rs[4]) {
    for (int k = 0; k < 4; ++k) {
      cs[k] = c, rs[k] = r;
      if (c < h) ++c;
      else if (r < hy) c = -h, ++r;
    }
  }
};

// The template window resampled about its centre, row by row, with its mean and standard deviation (the
// identity shape's tap positions centre + (c, r), exactly).
Template SampleTemplate(const cv::Mat& img, const Eigen::Vector2d& centre, int h, int hy, bool bspline) {
  Template tpl;
  const int n = (2 * h + 1) * (2 * hy + 1);
  tpl.T.resize(n);
  const Samples samples{img.ptr<float>(0), img.step1()};
  WindowParams at;
  at.t = centre, at.A.setIdentity();
  TapWalk walk(h, hy);
  double sum = 0, sum2 = 0;
  for (int i0 = 0; i0 < n; i0 += 4) {
    int cs[4], rs[4];
    double v[4], unused_x[4], unused_y[4];
    walk.Next4(cs, rs);
    SampleCubic4(samples, at, cs, rs, bspline, v, unused_x, unused_y);
    for (int i = i0; i < std::min(n, i0 + 4); ++i) {
      tpl.T[i] = static_cast<float>(v[i - i0]);
      sum += tpl.T[i];
      sum2 += static_cast<double>(tpl.T[i]) * tpl.T[i];
    }
  }
  tpl.mean = sum / n;
  tpl.std = std::sqrt(std::max(sum2 / n - tpl.mean * tpl.mean, 0.0));
  return tpl;
}

// The normal equations at `p`: N's lower triangle, b, the sum of squared residuals and the resampled window.
// The window is resampled 4 taps at a time (SampleCubic4), the sums taken tap by tap.
__attribute__((target_clones("avx2", "default"))) void Linearise(const cv::Mat& target_img, const Template& tpl,
                                                               const WindowParams& p, int h, int hy,
                                                               const LsmOptions& o, NormalEquations* eq) {
  NormalLanes acc;
  double ssr = 0;
  const Samples img{target_img.ptr<float>(0), target_img.step1()};
  const int n = (2 * h + 1) * (2 * hy + 1);
  TapWalk walk(h, hy);
  for (int i0 = 0; i0 < n; i0 += 4) {
    int cs[4], rs[4];
    double gs[4], gxs[4], gys[4];
    walk.Next4(cs, rs);
    SampleCubic4(img, p, cs, rs, o.bspline, gs, gxs, gys);
    for (int i = i0; i < std::min(n, i0 + 4); ++i) {
      const int c = cs[i - i0], r = rs[i - i0];
      const double g = gs[i - i0];
      const double gx = gxs[i - i0] * p.r1, gy = gys[i - i0] * p.r1;
      eq->G[i] = static_cast<float>(g);
      const double resid = tpl.T[i] - (p.r0 + p.r1 * g);
      ssr += resid * resid;
      // Without affine estimation the shape Jacobians stay 0 (then their products are 0 or -0: N unchanged).
      const Lanes4 j_lo = o.estimate_affine ? Lanes4{gx, gy, gx * c, gx * r} : Lanes4{gx, gy, 0.0, 0.0};
      const Lanes4 j_hi = o.estimate_affine ? Lanes4{gy * c, gy * r, 1.0, g} : Lanes4{0.0, 0.0, 1.0, g};
      const double j[kParams] = {j_lo[0], j_lo[1], j_lo[2], j_lo[3], j_hi[0], j_hi[1], j_hi[2], j_hi[3]};
      for (int l = 0; l < 4; ++l) acc.lo[l] += j[l] * j_lo;
      for (int l = 0; l < kParams; ++l) acc.hi[l] += j[l] * j_hi;
      acc.b_lo += j_lo * resid;
      acc.b_hi += j_hi * resid;
    }
  }
  eq->ssr = ssr;
  eq->N.setZero();
  for (int l = 0; l < kParams; ++l) {
    for (int k = l; k < 4; ++k) eq->N(k, l) = acc.lo[l][k];
    for (int k = std::max(l, 4); k < kParams; ++k) eq->N(k, l) = acc.hi[l][k - 4];
  }
  for (int k = 0; k < 4; ++k) {
    eq->b(k) = acc.b_lo[k];
    eq->b(k + 4) = acc.b_hi[k];
  }
}

// The update dx from eq (N made whole and, without affine estimation, its
// shape block regularised, as the precision then uses it): false when
// singular.
bool SolveNormalEquations(const LsmOptions& o, NormalEquations* eq, Vec8* dx) {
  Mat8& N = eq->N;
  N.triangularView<Eigen::StrictlyUpper>() = N.transpose();
  if (!o.estimate_affine) N.block<4, 4>(2, 2).diagonal().array() += 1.0;
  Eigen::LDLT<Mat8> ldlt(N);
  if (ldlt.info() != Eigen::Success) return false;
  *dx = ldlt.solve(eq->b);
  return dx->allFinite();
}

// Moves `p` by dx: why the match fails there, or nullptr.
const char* Update(const Vec8& dx, const Eigen::Vector2d& initial_target, const LsmOptions& o, WindowParams* p) {
  p->t += dx.head<2>();
  if (o.estimate_affine) {
    p->A(0, 0) += dx(2);
    p->A(0, 1) += dx(3);
    p->A(1, 0) += dx(4);
    p->A(1, 1) += dx(5);
  }
  p->r0 += dx(kParams - 2);
  p->r1 += dx(kParams - 1);
  if ((p->t - initial_target).norm() > o.max_shift_px) return "moved beyond max_shift_px";
  const double det = p->A.determinant();
  if (!(det > 0.01 && det < 100) || p->r1 <= 0.05) return "degenerate shape or radiometry";
  return nullptr;
}

// Precision from the last linearisation (at the previous step's values,
// a negligible difference at convergence).
void Precision(const NormalEquations& eq, int n, int n_estimated, LsmResult* res) {
  const double sigma0_sq = eq.ssr / std::max(1, n - n_estimated);
  const Mat8 Ninv = Eigen::LDLT<Mat8>(eq.N).solve(Mat8::Identity());
  res->sigma0 = std::sqrt(sigma0_sq);
  res->sigma_px = std::sqrt(sigma0_sq * 0.5 * (Ninv(0, 0) + Ninv(1, 1)));
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(sigma0_sq * Ninv.block<2, 2>(0, 0));
  res->sigma_max_px = std::sqrt(std::max(es.eigenvalues()(1), 0.0));
}

// Correlation of the template and the last resampled window.
double WindowCorrelation(const Template& tpl, const std::vector<float>& G) {
  const int n = static_cast<int>(G.size());
  double gm = 0;
  for (float v : G) gm += v;
  gm /= n;
  double stg = 0, sgg = 0, stt = 0;
  for (int i = 0; i < n; ++i) {
    stg += (tpl.T[i] - tpl.mean) * (G[i] - gm);
    sgg += (G[i] - gm) * (G[i] - gm);
    stt += (tpl.T[i] - tpl.mean) * (tpl.T[i] - tpl.mean);
  }
  return stg / std::sqrt(std::max(sgg * stt, 1e-12));
}

}  // namespace

LsmResult LeastSquaresMatch(const LsmImage& templ, const Eigen::Vector2d& template_px, const LsmImage& target,
                            const Eigen::Vector2d& initial_target, const Eigen::Matrix2d& initial_affine,
                            const LsmOptions& o) {
  LsmResult res;
  const int h = o.half_window, hy = o.half_height > 0 ? o.half_height : h;
  const int n = (2 * h + 1) * (2 * hy + 1);
  if (!Inside(templ.gray, template_px, h + 3, hy + 3)) {
    res.why = "template outside its image";
    return res;
  }
  const bool bs = o.bspline;
  if (bs && (templ.bspline.empty() || target.bspline.empty())) {
    res.why = "lsm.bspline needs images made by MakeLsmImage(gray, true)";
    return res;
  }
  const Template tpl = SampleTemplate(bs ? templ.bspline : templ.gray, template_px, h, hy, bs);
  if (tpl.std < o.min_template_std) {
    res.why = "too little texture";
    return res;
  }
  const cv::Mat& target_img = bs ? target.bspline : target.gray;
  WindowParams p{initial_target, initial_affine};
  NormalEquations eq;
  eq.G.resize(n);
  bool converged = false;
  int it = 0;
  for (; it < o.max_iterations; ++it) {
    // Bounding margin of the warped window.
    const double reach_x = h * std::abs(p.A(0, 0)) + hy * std::abs(p.A(0, 1)) + 3;
    const double reach_y = h * std::abs(p.A(1, 0)) + hy * std::abs(p.A(1, 1)) + 3;
    if (!Inside(target.gray, p.t, reach_x, reach_y)) {
      res.why = "window left the target image";
      return res;
    }
    Linearise(target_img, tpl, p, h, hy, o, &eq);
    Vec8 dx;
    if (!SolveNormalEquations(o, &eq, &dx)) {
      res.why = "singular normal equations";
      return res;
    }
    if (const char* why = Update(dx, initial_target, o, &p)) {
      res.why = why;
      return res;
    }
    if (dx.head<2>().norm() < o.convergence_px) {
      converged = true;
      ++it;
      break;
    }
  }
  res.iterations = it;
  if (!converged) {
    res.why = "did not converge";
    return res;
  }
  Precision(eq, n, o.estimate_affine ? 8 : 4, &res);
  res.correlation = WindowCorrelation(tpl, eq.G);
  res.target = p.t;
  res.affine = p.A;
  res.r0 = p.r0;
  res.r1 = p.r1;
  if (res.correlation < o.min_correlation) {
    res.why = "correlation below min_correlation";
    return res;
  }
  if (!(res.sigma_px <= o.max_sigma_px) || (o.max_sigma_axis_px > 0 && !(res.sigma_max_px <= o.max_sigma_axis_px))) {
    res.why = "precision worse than max_sigma_px";
    return res;
  }
  res.ok = true;
  return res;
}

}  // namespace vloc
