// Row least-squares matching (step 3 of vloc::DenseStereo): one pixel
// (RowLeastSquaresMatch) or many at once (internal::RowLeastSquaresMatchBatch,
// 8 pixels per AVX2 register, the same results bit for bit). The sums and
// interpolations are fused multiply-adds: std::fma in the scalar code, FMA
// instructions in the lanes (fewer operations and shorter chains).
#include "row_lsm.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <vector>


#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define VLOC_ROW_LSM_AVX2 1
#endif
#if defined(__SSE2__) && !defined(__FMA__)
#define VLOC_ROW_LSM_SSE2 1  // FinishLsm's two chains in one register (no FMA to contract them into)
#endif

namespace vloc {

namespace {

constexpr int kMaxN = 41 * 41;  // largest window (half sizes <= 20)

// One pixel's Gauss-Newton state. The template T and the resampled window
// G of a pixel are stored every `stride` floats (1 alone, 8 in the lanes).
struct LsmState {
  int x = 0, y = 0;
  double initial_disparity = 0;
  double d = 0, gx = 0, gy = 0, r0 = 0, r1 = 1;  // disparity, its gradients, radiometry
  double tsum = 0;                              // sum of the template
  double gsum = 0;                              // sum of the resampled window G (last iteration)
  double nn[15] = {0}, bb[5] = {0}, ssr = 0;    // this iteration's normal equations (lower triangle)
  double chol[15] = {0}, inv_diag[5] = {0};     // their Cholesky factor (see Factor)
  int it = 0;                                   // Gauss-Newton iterations done
};

// The template window: false when it leaves the left image.
bool StartLsm(const cv::Mat& L, int x, int y, double initial_disparity, const DenseStereoOptions& o, LsmState* s,
              float* T, int stride) {
  const int h = o.lsm_half_window, hy = o.lsm_half_height;
  if (x - h < 0 || x + h >= L.cols || y - hy < 0 || y + hy >= L.rows) return false;
  *s = LsmState();
  s->x = x, s->y = y, s->initial_disparity = initial_disparity, s->d = initial_disparity;
  // The template's sum in two chains side by side (one chain's latency
  // was the cost), rows alternating.
  double sum[2] = {0, 0};
  for (int r = -hy, i = 0; r <= hy; ++r) {
    const float* row = L.ptr<float>(y + r);
    double rs = 0;
    for (int c = -h; c <= h; ++c, ++i) rs += T[i * stride] = row[x + c];
    sum[(r + hy) & 1] += rs;
  }
  s->tsum = sum[0] + sum[1];
  return true;
}

// Right x of the window corners (linear in c and r): all taps inside?
bool TapsInside(const LsmState& s, const DenseStereoOptions& o, int W) {
  const int h = o.lsm_half_window, hy = o.lsm_half_height;
  const double xmin = s.x - h - s.d - std::abs(s.gx) * h - std::abs(s.gy) * hy;
  const double xmax = s.x + h - s.d + std::abs(s.gx) * h + std::abs(s.gy) * hy;
  return !(xmin - 1 < 0 || xmax + 2 > W - 1);
}

// The kernel weights of cubic_kernels.h in fused multiply-adds (one
// rounding each) and 1/6 multiplied, as the vector lanes compute them.
inline void RowWeights(bool bspline, float t, float w[4], float dw[4]) {
  const float t2 = t * t, t3 = t2 * t;
  if (bspline) {
    const float u = 1.f - t, k6 = 1.f / 6.f;
    w[0] = u * u * u * k6;
    w[1] = std::fma(3.f, t3, std::fma(-6.f, t2, 4.f)) * k6;
    w[2] = std::fma(-3.f, t3, std::fma(3.f, t2, std::fma(3.f, t, 1.f))) * k6;
    w[3] = t3 * k6;
    dw[0] = -0.5f * u * u;
    dw[1] = std::fma(1.5f, t2, -2.f * t);
    dw[2] = std::fma(-1.5f, t2, t + 0.5f);
    dw[3] = 0.5f * t2;
  } else {
    w[0] = std::fma(-0.5f, t3, std::fma(-0.5f, t, t2));
    w[1] = std::fma(1.5f, t3, std::fma(-2.5f, t2, 1.f));
    w[2] = std::fma(-1.5f, t3, std::fma(2.f, t2, 0.5f * t));
    w[3] = std::fma(0.5f, t3, -0.5f * t2);
    dw[0] = std::fma(-1.5f, t2, std::fma(2.f, t, -0.5f));
    dw[1] = std::fma(4.5f, t2, -5.f * t);
    dw[2] = std::fma(-4.5f, t2, std::fma(4.f, t, 0.5f));
    dw[3] = std::fma(1.5f, t2, -t);
  }
}

// The right window's sample positions: x - d - gy r + (1 - gx) c, as the
// integer x - floor(d) + c plus the small offset u = -frac(d) - gy r - gx c
// in float (an offset of integral value can round to the next integer:
// PrepareRowLsmTarget's guard rows).
struct WindowShift {
  int base;              // x - floor(d) - 1: tap 0 at offset 0
  float frac, mgx, mgy;  // frac(d), -gx, -gy
};
WindowShift ShiftOf(const LsmState& s) {
  const double fd = std::floor(s.d);
  return {s.x - static_cast<int>(fd) - 1, static_cast<float>(s.d - fd), static_cast<float>(-s.gx),
          static_cast<float>(-s.gy)};
}

// Sums of one window row that build the normal equations: with the
// Jacobian j = (j0, j0 c, j0 r, 1, g) (j0 = -r1 dG/dx; without the plane
// (j0, 1, g)) the terms in c are summed per sample, those in r per row
// (WindowTotals): 14 sums instead of the 20 products of j.
enum RowSum { kA, kAc, kAcc, kJ, kJc, kQ, kQc, kG, kGg, kJe, kJec, kE, kGe, kEe, kRowSums };
constexpr int kWeighted[5] = {kA, kAc, kJ, kQ, kJe};  // the sums also needed weighted by r

// The window's totals of the row sums: plain, weighted by r (kWeighted)
// and by r^2 (kA), each row added in double in row order.
struct WindowTotals {
  double t[kRowSums] = {0}, rt[5] = {0}, rra = 0;
  void AddRow(const float* v, int r) {
    for (int k = 0; k < kRowSums; ++k) t[k] += v[k];
    for (int k = 0; k < 5; ++k) rt[k] += r * static_cast<double>(v[kWeighted[k]]);
    rra += static_cast<double>(r * r) * v[kA];
  }
};

// The normal equations (lower triangle nn, right side bb) and the sum of
// squared residuals from the window's totals.
void NormalEquations(const WindowTotals& w, int n, bool plane, LsmState* s) {
  const double* t = w.t;
  std::fill(s->nn, s->nn + 15, 0.0);
  std::fill(s->bb, s->bb + 5, 0.0);
  if (plane) {
    const double nn[15] = {t[kA],    t[kAc], t[kAcc], w.rt[0], w.rt[1], w.rra, t[kJ], t[kJc],
                           w.rt[2], static_cast<double>(n), t[kQ], t[kQc], w.rt[3], t[kG], t[kGg]};
    const double bb[5] = {t[kJe], t[kJec], w.rt[4], t[kE], t[kGe]};
    std::copy(nn, nn + 15, s->nn);
    std::copy(bb, bb + 5, s->bb);
  } else {
    const double nn[6] = {t[kA], t[kJ], static_cast<double>(n), t[kQ], t[kG], t[kGg]};
    std::copy(nn, nn + 6, s->nn);
    s->bb[0] = t[kJe], s->bb[1] = t[kE], s->bb[2] = t[kGe];
  }
  s->ssr = t[kEe];
  s->gsum = t[kG];
}

// One pixel's normal equations at its current state (s->nn, s->bb, s->ssr, G).
// Float sums per row, added in double: the terms are grey-level products,
// a row's sums stay well inside float range.
void AccumulateScalar(const cv::Mat& R, const DenseStereoOptions& o, const float* T, float* G, LsmState* s) {
  const int h = o.lsm_half_window, hy = o.lsm_half_height;
  const WindowShift ws = ShiftOf(*s);
  const float fr1 = static_cast<float>(s->r1), fr0 = static_cast<float>(s->r0);
  WindowTotals totals;
  float w[4], dw[4];
  for (int r = -hy, i = 0; r <= hy; ++r) {
    const float* row = R.ptr<float>(s->y + r) + ws.base;
    const float urow = ws.mgy * static_cast<float>(r) - ws.frac;
    float v[kRowSums] = {0};
    for (int c = -h; c <= h; ++c, ++i) {
      const float fc = static_cast<float>(c), fcc = static_cast<float>(c * c);
      const float u = std::fma(ws.mgx, fc, urow), fl = std::floor(u);
      RowWeights(o.lsm_bspline, u - fl, w, dw);
      const float* p = row + c + static_cast<int>(fl);
      // Fused multiply-adds (one rounding each), as the vector lanes do them.
      const float g = std::fma(w[3], p[3], std::fma(w[2], p[2], std::fma(w[1], p[1], w[0] * p[0])));
      const float j0 = -(fr1 * std::fma(dw[3], p[3], std::fma(dw[2], p[2], std::fma(dw[1], p[1], dw[0] * p[0]))));
      G[i] = g;
      const float e = T[i] - std::fma(fr1, g, fr0);
      const float a = j0 * j0, q = g * j0, je = j0 * e;
      v[kA] += a, v[kAc] = std::fma(a, fc, v[kAc]), v[kAcc] = std::fma(a, fcc, v[kAcc]);
      v[kJ] += j0, v[kJc] = std::fma(j0, fc, v[kJc]);
      v[kQ] += q, v[kQc] = std::fma(q, fc, v[kQc]);
      v[kG] += g, v[kGg] = std::fma(g, g, v[kGg]);
      v[kJe] += je, v[kJec] = std::fma(je, fc, v[kJec]);
      v[kE] += e, v[kGe] = std::fma(g, e, v[kGe]), v[kEe] = std::fma(e, e, v[kEe]);
    }
    totals.AddRow(v, r);
  }
  NormalEquations(totals, (2 * h + 1) * (2 * hy + 1), o.lsm_disparity_plane, s);
}

enum class LsmStep { kContinue, kConverged, kRejected };

// Packed lower-triangle index of (i, j), j <= i (the order of nn).
constexpr int Tri(int i, int j) { return i * (i + 1) / 2 + j; }

// The normal matrix as solved: the parameters that do not enter (the
// plane's without it, dd/dy with one window row) get a unit diagonal and
// stay 0.
void Regularise(const DenseStereoOptions& o, double nn[15]) {
  if (!o.lsm_disparity_plane) nn[Tri(3, 3)] += 1.0, nn[Tri(4, 4)] += 1.0;
  if (o.lsm_disparity_plane && o.lsm_half_height == 0) nn[Tri(2, 2)] = 1.0;
}

// Cholesky factor l (packed as nn) of the normal matrix and the
// reciprocals of its diagonal: false when it is not positive definite.
// FactorLanes repeats these operations in this order for 8 pixels.
bool Factor(const double nn[15], double l[15], double inv_diag[5]) {
  for (int j = 0; j < 5; ++j) {
    double d = nn[Tri(j, j)];
    for (int k = 0; k < j; ++k) d -= l[Tri(j, k)] * l[Tri(j, k)];
    if (!(d > 0)) return false;
    l[Tri(j, j)] = std::sqrt(d);
    inv_diag[j] = 1.0 / l[Tri(j, j)];
    for (int i = j + 1; i < 5; ++i) {
      double t = nn[Tri(i, j)];
      for (int k = 0; k < j; ++k) t -= l[Tri(i, k)] * l[Tri(j, k)];
      l[Tri(i, j)] = t * inv_diag[j];
    }
  }
  return true;
}

// Solves l l^T x = b with Factor's output.
void Solve(const double l[15], const double inv_diag[5], const double b[5], double x[5]) {
  double y[5];
  for (int i = 0; i < 5; ++i) {
    double t = b[i];
    for (int k = 0; k < i; ++k) t -= l[Tri(i, k)] * y[k];
    y[i] = t * inv_diag[i];
  }
  for (int i = 4; i >= 0; --i) {
    double t = y[i];
    for (int k = i + 1; k < 5; ++k) t -= l[Tri(k, i)] * x[k];
    x[i] = t * inv_diag[i];
  }
}

// This iteration's update from the normal equations: false when they are
// singular.
bool SolveNormalEquations(const DenseStereoOptions& o, LsmState* s, double dx[5]) {
  double nn[15];
  std::copy(s->nn, s->nn + 15, nn);
  Regularise(o, nn);
  if (!Factor(nn, s->chol, s->inv_diag)) return false;
  Solve(s->chol, s->inv_diag, s->bb, dx);
  return true;
}

// Moves the state by this iteration's update dx (false: singular).
LsmStep UpdateLsm(const DenseStereoOptions& o, bool solved, const double dx[5], LsmState* s) {
  const bool plane = o.lsm_disparity_plane;
  if (!solved || !std::all_of(dx, dx + 5, [](double v) { return std::isfinite(v); })) return LsmStep::kRejected;
  s->d += dx[0];
  if (plane) {
    s->gx += dx[1];
    s->gy += dx[2];
    s->r0 += dx[3];
    s->r1 += dx[4];
  } else {
    s->r0 += dx[1];
    s->r1 += dx[2];
  }
  if (std::abs(s->d - s->initial_disparity) > o.lsm_max_shift_px || std::abs(s->gx) > 0.5 || std::abs(s->gy) > 1.0 ||
      s->r1 < 0.2)
    return LsmStep::kRejected;
  ++s->it;
  return std::abs(dx[0]) < o.lsm_convergence_px ? LsmStep::kConverged : LsmStep::kContinue;
}

// Precision and window correlation of a converged pixel: accepted?
bool FinishLsm(const LsmState& s, const DenseStereoOptions& o, const float* T, const float* G, int stride,
               RowLsmResult* result) {
  const int n = (2 * o.lsm_half_window + 1) * (2 * o.lsm_half_height + 1);
  const int np = o.lsm_disparity_plane ? 5 : 3;  // d, [dd/dx, dd/dy], r0, r1
  const double sigma0_sq = s.ssr / std::max(1, n - np);
  const double e0[5] = {1, 0, 0, 0, 0};
  double ninv0[5];  // first column of the inverse normal matrix
  Solve(s.chol, s.inv_diag, e0, ninv0);
  const double sigma = std::sqrt(std::max(0.0, sigma0_sq * ninv0[0]));
  // Both windows about their means (the resampled window's from the last
  // accumulation's sum), two samples per step in separate chains (one
  // chain's latency was the cost).
  const double tm = s.tsum / n;
  const double gm = s.gsum / n;
  double stg0 = 0, stt0 = 0, sgg0 = 0, stg1 = 0, stt1 = 0, sgg1 = 0;
  int i = 0;
#ifdef VLOC_ROW_LSM_SSE2
  // The two chains in the two halves of an SSE2 register (x86-64's
  // baseline, no fused multiply-adds): the same operations.
  {
    const __m128d vtm = _mm_set1_pd(tm), vgm = _mm_set1_pd(gm);
    __m128d stg = _mm_setzero_pd(), stt = stg, sgg = stg;
    for (; i + 1 < n; i += 2) {
      const __m128d t = _mm_sub_pd(_mm_set_pd(T[(i + 1) * stride], T[i * stride]), vtm);
      const __m128d g = _mm_sub_pd(_mm_set_pd(G[(i + 1) * stride], G[i * stride]), vgm);
      stg = _mm_add_pd(stg, _mm_mul_pd(t, g));
      stt = _mm_add_pd(stt, _mm_mul_pd(t, t));
      sgg = _mm_add_pd(sgg, _mm_mul_pd(g, g));
    }
    alignas(16) double out[3][2];
    _mm_store_pd(out[0], stg), _mm_store_pd(out[1], stt), _mm_store_pd(out[2], sgg);
    stg0 = out[0][0], stg1 = out[0][1], stt0 = out[1][0], stt1 = out[1][1], sgg0 = out[2][0], sgg1 = out[2][1];
  }
#else
  for (; i + 1 < n; i += 2) {
    const double t0 = T[i * stride] - tm, g0 = G[i * stride] - gm;
    const double t1 = T[(i + 1) * stride] - tm, g1 = G[(i + 1) * stride] - gm;
    stg0 += t0 * g0, stt0 += t0 * t0, sgg0 += g0 * g0;
    stg1 += t1 * g1, stt1 += t1 * t1, sgg1 += g1 * g1;
  }
#endif
  if (i < n) {
    const double t0 = T[i * stride] - tm, g0 = G[i * stride] - gm;
    stg0 += t0 * g0, stt0 += t0 * t0, sgg0 += g0 * g0;
  }
  const double stg = stg0 + stg1, stt = stt0 + stt1, sgg = sgg0 + sgg1;
  const double corr = stg / std::sqrt(std::max(stt * sgg, 1e-12));
  if (result) {
    result->disparity = s.d;
    result->sigma_px = sigma;
    result->correlation = corr;
    result->iterations = s.it;
    result->disparity_dx = s.gx;
    result->disparity_dy = s.gy;
  }
  return corr >= o.lsm_min_correlation && sigma <= o.lsm_max_sigma_px;
}

}  // namespace

cv::Mat PrepareRowLsmTarget(const cv::Mat& right, const DenseStereoOptions& o) {
  // A guard row above and below: a tap position rounded in float (ShiftOf)
  // may reach one sample past the row ends that TapsInside allows.
  cv::Mat guarded(right.rows + 2, right.cols, CV_32F, cv::Scalar(0));
  cv::Mat out = guarded.rowRange(1, right.rows + 1);
  right.convertTo(out, CV_32F);
  if (!o.lsm_bspline) return out;
  // Cubic B-spline prefilter along the rows (Unser 1999; mirror boundary).
  const double z = std::sqrt(3.0) - 2.0;
  const int W = out.cols;
  const int horizon = std::min(W, 30);  // |z|^30 < 1e-17
  // Rows in parallel: each is filtered on its own.
#pragma omp parallel for schedule(static) num_threads(std::max(1, o.num_threads))
  for (int y = 0; y < out.rows; ++y) {
    std::vector<double> c(W);
    float* row = out.ptr<float>(y);
    for (int k = 0; k < W; ++k) c[k] = 6.0 * row[k];
    if (W > 1) {
      double sum = c[0], zk = z;
      for (int k = 1; k < horizon; ++k, zk *= z) sum += zk * c[k];
      c[0] = sum;
      for (int k = 1; k < W; ++k) c[k] += z * c[k - 1];
      c[W - 1] = (z / (z * z - 1.0)) * (c[W - 1] + z * c[W - 2]);
      for (int k = W - 2; k >= 0; --k) c[k] = z * (c[k + 1] - c[k]);
    }
    for (int k = 0; k < W; ++k) row[k] = static_cast<float>(c[k]);
  }
  return out;
}

bool RowLeastSquaresMatch(const cv::Mat& L, const cv::Mat& R, int x, int y, double initial_disparity,
                          const DenseStereoOptions& o, RowLsmResult* result) {
  float T[kMaxN], G[kMaxN];
  LsmState s;
  if (!StartLsm(L, x, y, initial_disparity, o, &s, T, 1)) return false;
  for (;;) {
    if (s.it >= o.lsm_max_iterations || !TapsInside(s, o, R.cols)) return false;
    AccumulateScalar(R, o, T, G, &s);
    double dx[5];
    const bool solved = SolveNormalEquations(o, &s, dx);
    const LsmStep step = UpdateLsm(o, solved, dx, &s);
    if (step == LsmStep::kRejected) return false;
    if (step == LsmStep::kConverged) break;
  }
  return FinishLsm(s, o, T, G, 1, result);
}

namespace internal {

#ifdef VLOC_ROW_LSM_AVX2
namespace {

constexpr int kLanes = 8;

#define VLOC_AVX2 __attribute__((target("avx2"), always_inline)) inline
VLOC_AVX2 __m256 Mul(float a, __m256 b) { return _mm256_mul_ps(_mm256_set1_ps(a), b); }
// acc (8 doubles in two registers) += v, converted to double.
VLOC_AVX2 void AddTo(__m256d acc[2], __m256 v) {
  acc[0] = _mm256_add_pd(acc[0], _mm256_cvtps_pd(_mm256_castps256_ps128(v)));
  acc[1] = _mm256_add_pd(acc[1], _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1)));
}
// acc += r * v (r: 4 equal doubles).
VLOC_AVX2 void AddTo(__m256d acc[2], __m256d r, __m256 v) {
  acc[0] = _mm256_add_pd(acc[0], _mm256_mul_pd(r, _mm256_cvtps_pd(_mm256_castps256_ps128(v))));
  acc[1] = _mm256_add_pd(acc[1], _mm256_mul_pd(r, _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1))));
}
VLOC_AVX2 void Store(const __m256d v[2], double* out) {
  _mm256_storeu_pd(out, v[0]);
  _mm256_storeu_pd(out + 4, v[1]);
}
#undef VLOC_AVX2
// A float in all lanes.
__attribute__((target("avx2"), always_inline)) inline __m256 S(float a) { return _mm256_set1_ps(a); }
// a * b + c, rounded once (std::fma in the scalar code).
__attribute__((target("avx2,fma"), always_inline)) inline __m256 Fma(__m256 a, __m256 b, __m256 c) {
  return _mm256_fmadd_ps(a, b, c);
}

#define VLOC_LANES __attribute__((target("avx2,fma"), optimize("fp-contract=off"), always_inline)) inline

// WindowTotals of 8 lanes.
struct LaneTotals {
  __m256d t[kRowSums][2], rt[5][2], rra[2];
};
VLOC_LANES void ZeroTotals(LaneTotals* w) {
  for (auto& v : w->t) v[0] = v[1] = _mm256_setzero_pd();
  for (auto& v : w->rt) v[0] = v[1] = _mm256_setzero_pd();
  w->rra[0] = w->rra[1] = _mm256_setzero_pd();
}
// WindowTotals::AddRow, 8 lanes at a time.
VLOC_LANES void AddRowTotals(const __m256* v, int r, LaneTotals* w) {
  const __m256d rd = _mm256_set1_pd(r), rrd = _mm256_set1_pd(static_cast<double>(r * r));
  for (int k = 0; k < kRowSums; ++k) AddTo(w->t[k], v[k]);
  for (int k = 0; k < 5; ++k) AddTo(w->rt[k], rd, v[kWeighted[k]]);
  AddTo(w->rra, rrd, v[kA]);
}
// The 8 lanes' normal equations (with the disparity plane, which the lanes
// need), lane k of entry q at nn[q][k]: NormalEquations' entries and
// Regularise's unit diagonal, without the round trip through LsmState.
struct LaneSystems {
  alignas(32) double nn[15][kLanes];
  alignas(32) double bb[5][kLanes];
};
// The lanes' normal equations from their totals; each lane's sum of
// squared residuals and of G into its state.
VLOC_LANES void ExportTotals(const LaneTotals& w, int n, const DenseStereoOptions& o, LsmState* const* lanes,
                             LaneSystems* sys) {
  const __m256d* nn[15] = {w.t[kA], w.t[kAc], w.t[kAcc], w.rt[0], w.rt[1], w.rra,  w.t[kJ], w.t[kJc],
                           w.rt[2], nullptr,  w.t[kQ],   w.t[kQc], w.rt[3], w.t[kG], w.t[kGg]};
  const __m256d* bb[5] = {w.t[kJe], w.t[kJec], w.rt[4], w.t[kE], w.t[kGe]};
  for (int q = 0; q < 15; ++q) {
    if (nn[q]) {
      Store(nn[q], sys->nn[q]);
    } else {
      std::fill(sys->nn[q], sys->nn[q] + kLanes, static_cast<double>(n));
    }
  }
  for (int q = 0; q < 5; ++q) Store(bb[q], sys->bb[q]);
  if (o.lsm_half_height == 0) std::fill(sys->nn[Tri(2, 2)], sys->nn[Tri(2, 2)] + kLanes, 1.0);  // Regularise
  alignas(32) double ssr[kLanes], gsum[kLanes];
  Store(w.t[kEe], ssr);
  Store(w.t[kG], gsum);
  for (int l = 0; l < kLanes; ++l) lanes[l]->ssr = ssr[l], lanes[l]->gsum = gsum[l];
}
// One tap's terms added to the row sums v (AccumulateScalar's order):
// resampled value g, Jacobian j0, residual e, column c and c^2.
VLOC_LANES void AddTap(__m256 g, __m256 j0, __m256 e, __m256 fc, __m256 fcc, __m256* v) {
  const __m256 a = _mm256_mul_ps(j0, j0), q = _mm256_mul_ps(g, j0), je = _mm256_mul_ps(j0, e);
  v[kA] = _mm256_add_ps(v[kA], a), v[kAc] = Fma(a, fc, v[kAc]), v[kAcc] = Fma(a, fcc, v[kAcc]);
  v[kJ] = _mm256_add_ps(v[kJ], j0), v[kJc] = Fma(j0, fc, v[kJc]);
  v[kQ] = _mm256_add_ps(v[kQ], q), v[kQc] = Fma(q, fc, v[kQc]);
  v[kG] = _mm256_add_ps(v[kG], g), v[kGg] = Fma(g, g, v[kGg]);
  v[kJe] = _mm256_add_ps(v[kJe], je), v[kJec] = Fma(je, fc, v[kJec]);
  v[kE] = _mm256_add_ps(v[kE], e), v[kGe] = Fma(g, e, v[kGe]), v[kEe] = Fma(e, e, v[kEe]);
}

// One tap of the 8 lanes: its sub-pixel phase t and its 4 samples.
struct LaneTap {
  __m256 t, p[4];
};
// The tap at column fc (float) whose row index without the phase's whole
// part is rowc, for window row offset urow.
VLOC_LANES LaneTap LoadTap(const float* base, __m256 vmgx, __m256 urow, __m256 fc, __m256i rowc) {
  const __m256 u = Fma(vmgx, fc, urow), fl = _mm256_floor_ps(u);
  LaneTap tap;
  tap.t = _mm256_sub_ps(u, fl);
  const __m256i idx = _mm256_add_epi32(rowc, _mm256_cvttps_epi32(fl));
  // The 4 taps of each lane are adjacent: one 4-float load per lane,
  // lanes k and k + 4 in the halves of one register, and a 4 x 4
  // transpose within the halves (fewer loads than 4 gathers, fewer
  // shuffles than two 128-bit transposes and their joins).
  alignas(32) int at[kLanes];
  _mm256_store_si256(reinterpret_cast<__m256i*>(at), idx);
  // Read back from memory: 8 loads are fewer instructions than the 8
  // extracts and sign extensions the compiler makes of them otherwise.
  asm volatile("" : : "m"(at) : "memory");
  __m256 q4[4];
  for (int k = 0; k < 4; ++k)
    q4[k] = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(base + at[k])), _mm_loadu_ps(base + at[k + 4]), 1);
  const __m256 lo01 = _mm256_unpacklo_ps(q4[0], q4[1]), lo23 = _mm256_unpacklo_ps(q4[2], q4[3]);
  const __m256 hi01 = _mm256_unpackhi_ps(q4[0], q4[1]), hi23 = _mm256_unpackhi_ps(q4[2], q4[3]);
  tap.p[0] = _mm256_shuffle_ps(lo01, lo23, 0x44), tap.p[1] = _mm256_shuffle_ps(lo01, lo23, 0xEE);
  tap.p[2] = _mm256_shuffle_ps(hi01, hi23, 0x44), tap.p[3] = _mm256_shuffle_ps(hi01, hi23, 0xEE);
  return tap;
}

// The window sums of 8 pixels (one per lane) at their current states:
// AccumulateScalar's operations in its order, 8 at a time. T and G hold
// window sample i of lane k at [i * 8 + k].
template <bool kBspline>
__attribute__((target("avx2,fma"), optimize("fp-contract=off"), always_inline)) inline void AccumulateLanesBody(
    const cv::Mat& R, const DenseStereoOptions& o, LsmState* const* lanes, const float* T, float* G, LaneSystems* sys) {
  const int h = o.lsm_half_window, hy = o.lsm_half_height;
  const int stride = static_cast<int>(R.step1());
  const float* base = R.ptr<float>(0);
  alignas(32) float frac[kLanes], mgx[kLanes], mgy[kLanes], r0_f[kLanes], r1_f[kLanes];
  alignas(32) int row0[kLanes];
  for (int k = 0; k < kLanes; ++k) {
    const LsmState& s = *lanes[k];
    const WindowShift ws = ShiftOf(s);
    frac[k] = ws.frac, mgx[k] = ws.mgx, mgy[k] = ws.mgy;
    r0_f[k] = static_cast<float>(s.r0);
    r1_f[k] = static_cast<float>(s.r1);
    row0[k] = s.y * stride + ws.base;
  }
  const __m256 vfrac = _mm256_load_ps(frac), vmgx = _mm256_load_ps(mgx), vmgy = _mm256_load_ps(mgy);
  const __m256 fr0 = _mm256_load_ps(r0_f), fr1 = _mm256_load_ps(r1_f);
  const __m256i rows = _mm256_load_si256(reinterpret_cast<const __m256i*>(row0));
  const __m256 sign = _mm256_set1_ps(-0.f);
  const __m256i one = _mm256_set1_epi32(1);
  LaneTotals totals;
  ZeroTotals(&totals);
  for (int r = -hy, i = 0; r <= hy; ++r) {
    const __m256 rf = _mm256_set1_ps(static_cast<float>(r));
    const __m256 urow = _mm256_sub_ps(_mm256_mul_ps(vmgy, rf), vfrac);
    const __m256i row = _mm256_add_epi32(rows, _mm256_set1_epi32(r * stride));
    __m256 v[kRowSums];
    for (auto& x : v) x = _mm256_setzero_ps();
    // c as a float and the row's index at c counted up (exact: small integers).
    __m256 fc = _mm256_set1_ps(static_cast<float>(-h));
    __m256i rowc = _mm256_add_epi32(row, _mm256_set1_epi32(-h));
    // Each tap's phase and samples are read one tap ahead (software
    // pipelining: the next tap's loads start before this tap's sums).
    LaneTap next = LoadTap(base, vmgx, urow, fc, rowc);
    for (int c = -h; c <= h; ++c, ++i, fc = _mm256_add_ps(fc, S(1.f)), rowc = _mm256_add_epi32(rowc, one)) {
      const LaneTap tap = next;
      if (c < h) next = LoadTap(base, vmgx, urow, _mm256_add_ps(fc, S(1.f)), _mm256_add_epi32(rowc, one));
      const __m256 fcc = _mm256_mul_ps(fc, fc);
      const __m256 t = tap.t, p0 = tap.p[0], p1 = tap.p[1], p2 = tap.p[2], p3 = tap.p[3];
      const __m256 t2 = _mm256_mul_ps(t, t), t3 = _mm256_mul_ps(t2, t);
      __m256 w0, w1, w2, w3, dw0, dw1, dw2, dw3;
      // RowWeights, 8 phases at a time.
      const __m256 k1 = _mm256_set1_ps(1.f);
      if (kBspline) {
        const __m256 u = _mm256_sub_ps(k1, t), k6 = _mm256_set1_ps(1.f / 6.f);
        w0 = _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(u, u), u), k6);
        w1 = _mm256_mul_ps(Fma(S(3.f), t3, Fma(S(-6.f), t2, S(4.f))), k6);
        w2 = _mm256_mul_ps(Fma(S(-3.f), t3, Fma(S(3.f), t2, Fma(S(3.f), t, k1))), k6);
        w3 = _mm256_mul_ps(t3, k6);
        dw0 = _mm256_mul_ps(Mul(-0.5f, u), u);
        dw1 = Fma(S(1.5f), t2, Mul(-2.f, t));
        dw2 = Fma(S(-1.5f), t2, _mm256_add_ps(t, S(0.5f)));
        dw3 = Mul(0.5f, t2);
      } else {
        w0 = Fma(S(-0.5f), t3, Fma(S(-0.5f), t, t2));
        w1 = Fma(S(1.5f), t3, Fma(S(-2.5f), t2, k1));
        w2 = Fma(S(-1.5f), t3, Fma(S(2.f), t2, Mul(0.5f, t)));
        w3 = Fma(S(0.5f), t3, Mul(-0.5f, t2));
        dw0 = Fma(S(-1.5f), t2, Fma(S(2.f), t, S(-0.5f)));
        dw1 = Fma(S(4.5f), t2, Mul(-5.f, t));
        dw2 = Fma(S(-4.5f), t2, Fma(S(4.f), t, S(0.5f)));
        dw3 = Fma(S(1.5f), t2, _mm256_xor_ps(t, sign));
      }
      const __m256 g = Fma(w3, p3, Fma(w2, p2, Fma(w1, p1, _mm256_mul_ps(w0, p0))));
      const __m256 dg = _mm256_mul_ps(fr1, Fma(dw3, p3, Fma(dw2, p2, Fma(dw1, p1, _mm256_mul_ps(dw0, p0)))));
      _mm256_storeu_ps(G + i * kLanes, g);
      const __m256 e = _mm256_sub_ps(_mm256_loadu_ps(T + i * kLanes), Fma(fr1, g, fr0));
      AddTap(g, _mm256_xor_ps(dg, sign), e, fc, fcc, v);
    }
    AddRowTotals(v, r, &totals);
  }
  ExportTotals(totals, (2 * h + 1) * (2 * hy + 1), o, lanes, sys);
}

// Columns k of the 8 x 8 block r[0..7] (r[k] = row k): r[j] = column j.
VLOC_LANES void Transpose8(__m256 r[8]) {
  __m256 t[8], u[8];
  for (int k = 0; k < 8; k += 2) {
    t[k] = _mm256_unpacklo_ps(r[k], r[k + 1]);
    t[k + 1] = _mm256_unpackhi_ps(r[k], r[k + 1]);
  }
  for (int k = 0; k < 8; k += 4) {
    u[k] = _mm256_shuffle_ps(t[k], t[k + 2], 0x44), u[k + 1] = _mm256_shuffle_ps(t[k], t[k + 2], 0xEE);
    u[k + 2] = _mm256_shuffle_ps(t[k + 1], t[k + 3], 0x44), u[k + 3] = _mm256_shuffle_ps(t[k + 1], t[k + 3], 0xEE);
  }
  for (int k = 0; k < 4; ++k) {
    r[k] = _mm256_permute2f128_ps(u[k], u[k + 4], 0x20);
    r[k + 4] = _mm256_permute2f128_ps(u[k], u[k + 4], 0x31);
  }
}

// A lane's first iteration: with no disparity gradients every tap has the
// same sub-pixel phase (the kernel's u = -frac(d), or 0), so its weights
// are computed once and the window row is resampled along the row.
struct FirstLane {
  const float* row;  // the right image at tap (r = 0, c = 0), p0
  float w[4], dw[4], r0, r1;
};
FirstLane FirstLaneOf(const cv::Mat& R, const LsmState& s, bool bspline) {
  const WindowShift ws = ShiftOf(s);
  FirstLane f;
  const float u = ws.frac == 0.f ? 0.f : -ws.frac, fl = std::floor(u);
  RowWeights(bspline, u - fl, f.w, f.dw);
  f.row = R.ptr<float>(s.y) + ws.base + static_cast<int>(fl);
  f.r0 = static_cast<float>(s.r0), f.r1 = static_cast<float>(s.r1);
  return f;
}

// AccumulateLanesBody for 8 lanes in their first iteration (gx = gy = 0):
// the same operations per tap. Each lane resamples 8 taps of its window
// row at a time (g, the Jacobian's dG/dx and the residual), transposed
// into the lanes for the sums. T[k], G[k]: lane k's window, row by row,
// readable 8 floats past its end.
VLOC_LANES void FirstIterationBody(const cv::Mat& R, const DenseStereoOptions& o, LsmState* const* lanes,
                                   const float* const* T, float* const* G, LaneSystems* sys) {
  const int h = o.lsm_half_window, hy = o.lsm_half_height, wc = 2 * h + 1;
  const int stride = static_cast<int>(R.step1());
  FirstLane f[kLanes];
  for (int k = 0; k < kLanes; ++k) f[k] = FirstLaneOf(R, *lanes[k], o.lsm_bspline);
  const __m256 sign = _mm256_set1_ps(-0.f);
  LaneTotals totals;
  ZeroTotals(&totals);
  for (int r = -hy; r <= hy; ++r) {
    __m256 v[kRowSums];
    for (auto& x : v) x = _mm256_setzero_ps();
    const int i0 = (r + hy) * wc;  // window index of tap (r, -h)
    for (int c0 = -h; c0 <= h; c0 += 8) {
      __m256 g[kLanes], dg[kLanes], e[kLanes];
      for (int k = 0; k < kLanes; ++k) {
        const float* p = f[k].row + r * stride + c0;
        const __m256 p0 = _mm256_loadu_ps(p), p1 = _mm256_loadu_ps(p + 1), p2 = _mm256_loadu_ps(p + 2),
                     p3 = _mm256_loadu_ps(p + 3);
        const float *w = f[k].w, *dw = f[k].dw;
        g[k] = Fma(S(w[3]), p3, Fma(S(w[2]), p2, Fma(S(w[1]), p1, _mm256_mul_ps(S(w[0]), p0))));
        const __m256 dp = Fma(S(dw[3]), p3, Fma(S(dw[2]), p2, Fma(S(dw[1]), p1, _mm256_mul_ps(S(dw[0]), p0))));
        dg[k] = _mm256_mul_ps(S(f[k].r1), dp);
        _mm256_storeu_ps(G[k] + i0 + c0 + h, g[k]);
        e[k] = _mm256_sub_ps(_mm256_loadu_ps(T[k] + i0 + c0 + h), Fma(S(f[k].r1), g[k], S(f[k].r0)));
      }
      Transpose8(g), Transpose8(dg), Transpose8(e);
      for (int j = 0; j < 8 && c0 + j <= h; ++j) {
        const int c = c0 + j;
        AddTap(g[j], _mm256_xor_ps(dg[j], sign), e[j], S(static_cast<float>(c)), S(static_cast<float>(c * c)), v);
      }
    }
    AddRowTotals(v, r, &totals);
  }
  ExportTotals(totals, wc * (2 * hy + 1), o, lanes, sys);
}

__attribute__((target("avx2,fma"), optimize("fp-contract=off"))) void FirstIteration(
    const cv::Mat& R, const DenseStereoOptions& o, LsmState* const* lanes, const float* const* T, float* const* G,
    LaneSystems* sys) {
  FirstIterationBody(R, o, lanes, T, G, sys);
}
__attribute__((target("avx2,fma,avx512f,avx512vl"), optimize("fp-contract=off"))) void FirstIteration32(
    const cv::Mat& R, const DenseStereoOptions& o, LsmState* const* lanes, const float* const* T, float* const* G,
    LaneSystems* sys) {
  FirstIterationBody(R, o, lanes, T, G, sys);
}

// AccumulateLanesBody for AVX2 + FMA (16 vector registers) and, the same
// instructions, for a CPU with AVX-512VL, whose 32 registers hold the 13
// row sums without spilling them.
template <bool kBspline>
__attribute__((target("avx2,fma"), optimize("fp-contract=off"))) void AccumulateLanes(
    const cv::Mat& R, const DenseStereoOptions& o, LsmState* const* lanes, const float* T, float* G, LaneSystems* sys) {
  AccumulateLanesBody<kBspline>(R, o, lanes, T, G, sys);
}
template <bool kBspline>
__attribute__((target("avx2,fma,avx512f,avx512vl"), optimize("fp-contract=off"))) void AccumulateLanes32(
    const cv::Mat& R, const DenseStereoOptions& o, LsmState* const* lanes, const float* T, float* G, LaneSystems* sys) {
  AccumulateLanesBody<kBspline>(R, o, lanes, T, G, sys);
}

// SolveNormalEquations of 8 pixels (one per lane; 4 doubles a register):
// Factor's and Solve's operations in their order on the lanes' regularised
// systems. A lane whose matrix is not positive definite gets solved[k] =
// false (its numbers are NaN).
__attribute__((target("avx2"), optimize("fp-contract=off"))) void SolveLanes(const LaneSystems& sys,
                                                                             LsmState* const* lanes,
                                                                             bool solved[kLanes],
                                                                             double dx[kLanes][5]) {
  const auto& nn = sys.nn;
  const auto& bb = sys.bb;
  alignas(32) double l_out[15][kLanes], inv_out[5][kLanes], x_out[5][kLanes];
  alignas(32) double ok_out[kLanes];
  const __m256d zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0);
  for (int half = 0; half < kLanes; half += 4) {
    auto ld = [&](const double* row) { return _mm256_load_pd(row + half); };
    __m256d l[15], inv[5], y[5], x[5], ok = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    for (int j = 0; j < 5; ++j) {
      __m256d d = ld(nn[Tri(j, j)]);
      for (int k = 0; k < j; ++k) d = _mm256_sub_pd(d, _mm256_mul_pd(l[Tri(j, k)], l[Tri(j, k)]));
      ok = _mm256_and_pd(ok, _mm256_cmp_pd(d, zero, _CMP_GT_OQ));
      l[Tri(j, j)] = _mm256_sqrt_pd(d);
      inv[j] = _mm256_div_pd(one, l[Tri(j, j)]);
      for (int i = j + 1; i < 5; ++i) {
        __m256d t = ld(nn[Tri(i, j)]);
        for (int k = 0; k < j; ++k) t = _mm256_sub_pd(t, _mm256_mul_pd(l[Tri(i, k)], l[Tri(j, k)]));
        l[Tri(i, j)] = _mm256_mul_pd(t, inv[j]);
      }
    }
    for (int i = 0; i < 5; ++i) {
      __m256d t = ld(bb[i]);
      for (int k = 0; k < i; ++k) t = _mm256_sub_pd(t, _mm256_mul_pd(l[Tri(i, k)], y[k]));
      y[i] = _mm256_mul_pd(t, inv[i]);
    }
    for (int i = 4; i >= 0; --i) {
      __m256d t = y[i];
      for (int k = i + 1; k < 5; ++k) t = _mm256_sub_pd(t, _mm256_mul_pd(l[Tri(k, i)], x[k]));
      x[i] = _mm256_mul_pd(t, inv[i]);
    }
    for (int q = 0; q < 15; ++q) _mm256_store_pd(l_out[q] + half, l[q]);
    for (int q = 0; q < 5; ++q) _mm256_store_pd(inv_out[q] + half, inv[q]), _mm256_store_pd(x_out[q] + half, x[q]);
    _mm256_store_pd(ok_out + half, ok);
  }
  for (int k = 0; k < kLanes; ++k) {
    for (int q = 0; q < 15; ++q) lanes[k]->chol[q] = l_out[q][k];
    for (int q = 0; q < 5; ++q) lanes[k]->inv_diag[q] = inv_out[q][k], dx[k][q] = x_out[q][k];
    solved[k] = std::signbit(ok_out[k]);  // all ones: a NaN with the sign bit set
  }
}

std::atomic<bool> avx512_allowed{true};  // AllowRowLsmAvx512

bool HasAvx512Vl() {
  static const bool has = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl");
  return has && avx512_allowed.load(std::memory_order_relaxed);
}

bool HasAvx2Fma() {
  static const bool has = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return has;
}

// The first iteration of the tasks, 8 at a time (FirstIteration): the
// pixels it rejects or finishes get their result here, the others wait in
// `ready` for a lane of the later iterations, their templates in `T_`.
class FirstIterations {
 public:
  FirstIterations(const cv::Mat& L, const cv::Mat& R, const RowLsmTask* tasks, int count, const DenseStereoOptions& o,
                  RowLsmResult* results, unsigned char* accepted)
      : L_(L), R_(R), tasks_(tasks), count_(count), o_(o), results_(results), accepted_(accepted),
        n_((2 * o.lsm_half_window + 1) * (2 * o.lsm_half_height + 1)),
        T_(static_cast<size_t>(n_ + 8) * (kLanes + 1), 0.f), G_(T_.size(), 0.f) {}

  // The next pixel past its first iteration: its state, its template into
  // T[i * stride] (i < n); its task, or -1 when none is left.
  int Next(LsmState* s, float* T, int stride) {
    while (ready_next_ == ready_count_)
      if (!RunGroup()) return -1;
    const int k = ready_[ready_next_++];
    *s = state_[k];
    const float* from = T_.data() + static_cast<size_t>(k) * (n_ + 8);
    for (int i = 0; i < n_; ++i) T[i * stride] = from[i];
    return task_[k];
  }

 private:
  // The first iteration of the next (up to) 8 tasks whose template and
  // window fit: false when no task is left.
  bool RunGroup() {
    ready_next_ = ready_count_ = 0;
    int m = 0;
    while (m < kLanes && next_ < count_) {
      const int t = next_++;
      results_[t] = RowLsmResult();
      accepted_[t] = 0;
      float* T = T_.data() + static_cast<size_t>(m) * (n_ + 8);
      if (!StartLsm(L_, tasks_[t].x, tasks_[t].y, tasks_[t].initial_disparity, o_, &state_[m], T, 1)) continue;
      if (state_[m].it >= o_.lsm_max_iterations || !TapsInside(state_[m], o_, R_.cols)) continue;
      task_[m++] = t;
    }
    if (m == 0) return false;
    // Idle lanes repeat lane 0 into a spare window (their sums are ignored).
    LsmState idle = state_[0];
    LsmState* lanes[kLanes];
    const float* T[kLanes];
    float* G[kLanes];
    for (int k = 0; k < kLanes; ++k) {
      const size_t at = static_cast<size_t>(k < m ? k : kLanes) * (n_ + 8);
      lanes[k] = k < m ? &state_[k] : &idle;
      T[k] = k < m ? T_.data() + at : T_.data();
      G[k] = G_.data() + at;
    }
    LaneSystems sys;
    if (HasAvx512Vl()) {
      FirstIteration32(R_, o_, lanes, T, G, &sys);
    } else {
      FirstIteration(R_, o_, lanes, T, G, &sys);
    }
    bool solved[kLanes];
    double dx[kLanes][5];
    SolveLanes(sys, lanes, solved, dx);
    for (int k = 0; k < m; ++k) {
      const LsmStep step = UpdateLsm(o_, solved[k], dx[k], &state_[k]);
      if (step == LsmStep::kContinue) ready_[ready_count_++] = k;
      if (step == LsmStep::kConverged)
        accepted_[task_[k]] = FinishLsm(state_[k], o_, T[k], G[k], 1, &results_[task_[k]]);
    }
    return true;
  }

  const cv::Mat &L_, &R_;
  const RowLsmTask* tasks_;
  const int count_;
  const DenseStereoOptions& o_;
  RowLsmResult* results_;
  unsigned char* accepted_;
  const int n_;
  std::vector<float> T_, G_;  // lane k's window at k * (n + 8) (a spare one for idle lanes)
  LsmState state_[kLanes];
  int task_[kLanes] = {0}, ready_[kLanes] = {0};
  int ready_next_ = 0, ready_count_ = 0, next_ = 0;
};

}  // namespace
#endif

void AllowRowLsmAvx512(bool allowed) {
#ifdef VLOC_ROW_LSM_AVX2
  avx512_allowed = allowed;
#else
  (void)allowed;
#endif
}

bool RowLsmBatchUsesAvx512(const DenseStereoOptions& o) {
#ifdef VLOC_ROW_LSM_AVX2
  return RowLsmBatchVectorised(o) && HasAvx512Vl();
#else
  (void)o;
  return false;
#endif
}

bool RowLsmBatchVectorised(const DenseStereoOptions& o) {
#ifdef VLOC_ROW_LSM_AVX2
  return HasAvx2Fma() && o.lsm_disparity_plane;
#else
  (void)o;
  return false;
#endif
}

void RowLeastSquaresMatchBatch(const cv::Mat& L, const cv::Mat& R, const RowLsmTask* tasks, int count,
                               const DenseStereoOptions& o, RowLsmResult* results, unsigned char* accepted) {
  if (!RowLsmBatchVectorised(o)) {
    for (int k = 0; k < count; ++k) {
      results[k] = RowLsmResult();
      accepted[k] = RowLeastSquaresMatch(L, R, tasks[k].x, tasks[k].y, tasks[k].initial_disparity, o, &results[k]);
    }
    return;
  }
#ifdef VLOC_ROW_LSM_AVX2
  const int n = (2 * o.lsm_half_window + 1) * (2 * o.lsm_half_height + 1);
  std::vector<float> T(static_cast<size_t>(n) * kLanes, 0.f), G(static_cast<size_t>(n) * kLanes, 0.f);
  FirstIterations first(L, R, tasks, count, o, results, accepted);
  LsmState state[kLanes];
  int task_of[kLanes];
  // Lane k takes the next pixel past its first iteration (false: none left).
  auto start = [&](int k) {
    task_of[k] = first.Next(&state[k], T.data() + k, kLanes);
    return task_of[k] >= 0;
  };
  for (int k = 0; k < kLanes; ++k) start(k);
  LsmState* lanes[kLanes];
  for (;;) {
    // The iteration's bounds check; a lane that fails takes the next task.
    int live = -1;
    for (int k = 0; k < kLanes; ++k) {
      while (task_of[k] >= 0 && (state[k].it >= o.lsm_max_iterations || !TapsInside(state[k], o, R.cols))) start(k);
      if (task_of[k] >= 0) live = k;
    }
    if (live < 0) break;
    // Idle lanes repeat a live one (their sums are ignored).
    LsmState idle = state[live];
    for (int k = 0; k < kLanes; ++k) lanes[k] = task_of[k] >= 0 ? &state[k] : &idle;
    LaneSystems sys;
    if (HasAvx512Vl()) {
      if (o.lsm_bspline) {
        AccumulateLanes32<true>(R, o, lanes, T.data(), G.data(), &sys);
      } else {
        AccumulateLanes32<false>(R, o, lanes, T.data(), G.data(), &sys);
      }
    } else if (o.lsm_bspline) {
      AccumulateLanes<true>(R, o, lanes, T.data(), G.data(), &sys);
    } else {
      AccumulateLanes<false>(R, o, lanes, T.data(), G.data(), &sys);
    }
    bool solved[kLanes];
    double dx[kLanes][5];
    SolveLanes(sys, lanes, solved, dx);
    for (int k = 0; k < kLanes; ++k) {
      if (task_of[k] < 0) continue;
      const LsmStep step = UpdateLsm(o, solved[k], dx[k], &state[k]);
      if (step == LsmStep::kContinue) continue;
      const int t = task_of[k];
      if (step == LsmStep::kConverged)
        accepted[t] = FinishLsm(state[k], o, T.data() + k, G.data() + k, kLanes, &results[t]);
      start(k);
    }
  }
#endif
}

}  // namespace internal

}  // namespace vloc
