#include "vloc/features/dense_stereo.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <opencv2/core/hal/intrin.hpp>
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "median_test.h"
#include "row_lsm.h"
#include "vloc/common/options.h"

namespace vloc {

void DenseStereoOptions::Visit(OptionsReader& r) {
  r.Optional("min_disparity", &min_disparity, "px, smallest searched disparity (left x - right x)", NonNegative());
  r.Optional("max_disparity", &max_disparity, "px, largest searched disparity");
  r.Optional("step", &step, "px, grid spacing", AtLeast(1));
  r.Optional("zncc_window", &zncc_window, "px, ZNCC window side", Odd() && InRange(3, 41));
  r.Optional("min_score", &min_score, "minimum ZNCC of the best disparity", InOpen(-1, 1));
  r.Optional("min_peak_margin", &min_peak_margin, "best minus the next local maximum >= 3 px away", NonNegative());
  r.Optional("min_template_std", &min_template_std, "grey level, minimum left window std");
  r.Optional("left_right_check", &left_right_check, "require the right pixel's best disparity to agree");
  r.Optional("max_left_right_diff", &max_left_right_diff, "px, allowed left-right disagreement", NonNegative());
  r.Optional("median_radius", &median_radius, "grid cells, median window half side", NonNegative());
  r.Optional("median_stride", &median_stride, "grid cells, neighbour sampling step", AtLeast(1));
  r.Optional("median_min_neighbours", &median_min_neighbours, "fewer valid neighbours: dropped", NonNegative());
  r.Optional("median_abs_tolerance", &median_abs_tolerance, "px, allowed deviation from the median", NonNegative());
  r.Optional("median_rel_tolerance", &median_rel_tolerance, "fraction of the median added to the tolerance",
             NonNegative());
  r.Optional("lsm_enabled", &lsm_enabled, "refine by row least-squares matching");
  r.Optional("lsm_half_window", &lsm_half_window, "px, LSM window half width", InRange(2, 20));
  r.Optional("lsm_half_height", &lsm_half_height, "px, LSM window half height", InRange(0, 20));
  r.Optional("lsm_bspline", &lsm_bspline, "cubic B-spline resampling (false: Keys cubic convolution)");
  r.Optional("lsm_disparity_plane", &lsm_disparity_plane, "estimate the disparity gradients");
  r.Optional("lsm_max_iterations", &lsm_max_iterations, "Gauss-Newton iterations", AtLeast(1));
  r.Optional("lsm_convergence_px", &lsm_convergence_px, "px, disparity update that ends the iteration", Positive());
  r.Optional("lsm_max_shift_px", &lsm_max_shift_px, "px, largest accepted move from the ZNCC disparity", Positive());
  r.Optional("lsm_min_correlation", &lsm_min_correlation, "minimum window correlation at the solution");
  r.Optional("lsm_max_sigma_px", &lsm_max_sigma_px, "px, largest accepted 1-sigma disparity precision", Positive());
  r.Optional("lsm_back_check_px", &lsm_back_check_px, "px, LSM back from the right image must agree (0 = off)");
  r.Optional("lsm_median_tolerance", &lsm_median_tolerance, "px, median test again after LSM (0 = off)");
  r.Optional("lsm_lattice", &lsm_lattice, "grid points, LSM on this lattice, the points between from its planes",
             InRange(1, 8));
  r.Optional("lsm_lattice_min_corners", &lsm_lattice_min_corners, "accepted lattice corners a point between needs",
             InRange(1, 4));
  r.Optional("lsm_lattice_agree_px", &lsm_lattice_agree_px, "px, spread of the corners' predictions allowed",
             NonNegative());
  r.Optional("lsm_lattice_max_failed_corners", &lsm_lattice_max_failed_corners,
             "failed lattice corners (no ZNCC match, rejected, dropped) a point from the planes tolerates",
             InRange(0, 3));
  r.Optional("lsm_lattice_drop_failed_cells", &lsm_lattice_drop_failed_cells,
             "drop a point whose coarser cell's corners all failed, without LSM");
  r.Optional("num_threads", &num_threads, "OpenMP threads", AtLeast(1));
  r.Relation("max_disparity", max_disparity >= min_disparity + 1, "must exceed min_disparity by >= 1");
}

bool DenseStereoOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

std::string DenseStereoSummary::BriefReport() const {
  std::ostringstream s;
  s << (usable ? "usable" : "not usable") << " (" << message << "): grid " << grid_width << " x " << grid_height
    << ", points " << points << ", zncc " << zncc_matches << ", median " << after_median << ", lsm " << lsm_matches
    << ", " << total_seconds << " s (zncc " << zncc_seconds << ", median " << median_seconds << ", lsm "
    << lsm_seconds << ")";
  return s.str();
}

namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

bool HasAvx2() {
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
}

// One row of BoxStats' inverse standard deviations from the box means m
// and mean squares q: 1 / sqrt(max(0, q - m^2)) in double (m^2 is exact),
// 0 below min_std.
void InvStdRow(const float* m, const float* q, int cols, double min_std, float* out) {
  for (int x = 0; x < cols; ++x) {
    const double var = std::max(0.0, static_cast<double>(q[x]) - static_cast<double>(m[x]) * m[x]);
    const double sd = std::sqrt(var);
    out[x] = sd >= min_std ? static_cast<float>(1.0 / sd) : 0.f;
  }
}

// InvStdRow 4 columns at a time (AVX2): the same double operations, each
// correctly rounded, so the same floats; returns the first column left.
__attribute__((target("avx2"))) int InvStdRowAvx2(const float* m, const float* q, int cols, double min_std,
                                                  float* out) {
  const __m256d zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0), lo = _mm256_set1_pd(min_std);
  int x = 0;
  for (; x + 4 <= cols; x += 4) {
    const __m256d md = _mm256_cvtps_pd(_mm_loadu_ps(m + x)), qd = _mm256_cvtps_pd(_mm_loadu_ps(q + x));
    // max(var, 0) is var > 0 ? var : 0, as std::max(0.0, var) (NaN, -0 -> 0).
    const __m256d sd = _mm256_sqrt_pd(_mm256_max_pd(_mm256_sub_pd(qd, _mm256_mul_pd(md, md)), zero));
    const __m256d inv = _mm256_and_pd(_mm256_div_pd(one, sd), _mm256_cmp_pd(sd, lo, _CMP_GE_OQ));
    _mm_storeu_ps(out + x, _mm256_cvtpd_ps(inv));
  }
  return x;
}

// Box mean and inverse standard deviation (0 where the std is below
// min_std) of a float image over a square window.
void BoxStats(const cv::Mat& img, int window, double min_std, cv::Mat* mean, cv::Mat* inv_std) {
  cv::Mat sq;
  cv::multiply(img, img, sq);
  cv::Mat m2;
  cv::boxFilter(img, *mean, CV_32F, cv::Size(window, window), cv::Point(-1, -1), true, cv::BORDER_REFLECT);
  cv::boxFilter(sq, m2, CV_32F, cv::Size(window, window), cv::Point(-1, -1), true, cv::BORDER_REFLECT);
  *inv_std = cv::Mat(img.size(), CV_32F);
  const bool avx2 = HasAvx2();
  for (int y = 0; y < img.rows; ++y) {
    const float* m = mean->ptr<float>(y);
    const float* q = m2.ptr<float>(y);
    float* o = inv_std->ptr<float>(y);
    const int done = avx2 ? InvStdRowAvx2(m, q, img.cols, min_std, o) : 0;
    InvStdRow(m + done, q + done, img.cols - done, min_std, o + done);
  }
}

struct ZnccStage {
  cv::Mat disparity;  // grid, CV_32F, NaN = none
  long points = 0, matches = 0;
};

// The products of ZNCC's window sums are of integer grey levels centred on
// 0 (|L|, |R| <= 128): the column sums V and the window sums S are exact
// integers, in int32 (a 41 x 41 window's sum stays under 2^25).
//
// Two window rows a, b entering (sign +1) or leaving (-1) the column sums
// of grid row y, for the 16-bit pair products of AddRowPairProducts:
// lpair[x] packs (sign_a L(a, x), sign_b L(b, x)) into one int32 (a
// missing row b: 0), rpair[2k], rpair[2k + 1] = R(a, W - 1 - k), R(b, W - 1 - k)
// (the right rows reversed, so that x - d runs forward with di).
struct RowPair {
  std::vector<int32_t> lpair;
  std::vector<int16_t> rpair;
};

// Adds L(a, x) R(a, x - d) +- L(b, x) R(b, x - d) (the pair's signs) to
// V[x * nd + di] (d = dlo + di, x - d >= 0) for x in [xa, xb): 8
// disparities per multiply-add of 16-bit pairs (AVX2), else the scalar loop.
__attribute__((target("avx2"))) void AddRowPairProductsAvx2(const RowPair& p, int W, int dlo, int nd, int xa, int xb,
                                                            int32_t* V) {
  for (int x = std::max(xa, dlo); x < xb; ++x) {
    const int m = std::min(nd - 1, x - dlo);
    int32_t* v = V + static_cast<size_t>(x) * nd;
    const __m256i lp = _mm256_set1_epi32(p.lpair[x]);
    const int16_t* rp = p.rpair.data() + 2 * (W - 1 - x + dlo);  // rp[2 di], rp[2 di + 1]: R(a | b, x - d)
    int di = 0;
    for (; di + 8 <= m + 1; di += 8) {
      const __m256i r = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(rp + 2 * di));
      __m256i* out = reinterpret_cast<__m256i*>(v + di);
      _mm256_storeu_si256(out, _mm256_add_epi32(_mm256_loadu_si256(out), _mm256_madd_epi16(lp, r)));
    }
    const int16_t la = static_cast<int16_t>(p.lpair[x] & 0xffff), lb = static_cast<int16_t>(p.lpair[x] >> 16);
    for (; di <= m; ++di) v[di] += la * rp[2 * di] + lb * rp[2 * di + 1];
  }
}

void AddRowPairProducts(const RowPair& p, int W, int dlo, int nd, int xa, int xb, int32_t* V) {
  if (HasAvx2()) return AddRowPairProductsAvx2(p, W, dlo, nd, xa, xb, V);
  for (int x = std::max(xa, dlo); x < xb; ++x) {
    const int m = std::min(nd - 1, x - dlo);
    int32_t* v = V + static_cast<size_t>(x) * nd;
    const int16_t la = static_cast<int16_t>(p.lpair[x] & 0xffff), lb = static_cast<int16_t>(p.lpair[x] >> 16);
    const int16_t* rp = p.rpair.data() + 2 * (W - 1 - x + dlo);
    for (int di = 0; di <= m; ++di) v[di] += la * rp[2 * di] + lb * rp[2 * di + 1];
  }
}

// A column's best score and its disparity index (the first of equal
// scores; -2 / -1: none), as RowScores finds them.
struct ColumnBest {
  float score = -2.f;
  int index = -1;
};

// RowScores' scores for di in [0, active) 8 at a time, the same float
// operations in each lane, and their best (each lane keeps its first best,
// the lanes' first of the best is the column's); returns the first di left
// to the scalar loop. The left window is not flat (il > 0: RowScores skips
// those).
__attribute__((target("avx2"))) int ScoresAvx2(const int32_t* S, double inv_n, float ml, float il, const float* mr,
                                               const float* ir, int active, float* c, float* br, int* brd,
                                               ColumnBest* best) {
  const __m256d vinv = _mm256_set1_pd(inv_n);
  const __m256 vml = _mm256_set1_ps(ml), vil = _mm256_set1_ps(il), undefined = _mm256_set1_ps(-2.f);
  const __m256 zero = _mm256_setzero_ps();
  __m256i vdi = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  __m256 vbest = undefined;
  __m256i vbi = _mm256_set1_epi32(-1);
  int di = 0;
  for (; di + 8 <= active; di += 8, vdi = _mm256_add_epi32(vdi, _mm256_set1_epi32(8))) {
    const __m256i si = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(S + di));
    const __m128 s0 = _mm256_cvtpd_ps(_mm256_mul_pd(_mm256_cvtepi32_pd(_mm256_castsi256_si128(si)), vinv));
    const __m128 s1 = _mm256_cvtpd_ps(_mm256_mul_pd(_mm256_cvtepi32_pd(_mm256_extracti128_si256(si, 1)), vinv));
    const __m256 vir = _mm256_loadu_ps(ir + di);
    const __m256 cov = _mm256_sub_ps(_mm256_set_m128(s1, s0), _mm256_mul_ps(vml, _mm256_loadu_ps(mr + di)));
    const __m256 ok = _mm256_cmp_ps(vir, zero, _CMP_GT_OQ);
    const __m256 z = _mm256_blendv_ps(undefined, _mm256_mul_ps(_mm256_mul_ps(cov, vil), vir), ok);
    _mm256_storeu_ps(c + di, z);
    const __m256 better = _mm256_cmp_ps(z, vbest, _CMP_GT_OQ);
    vbest = _mm256_blendv_ps(vbest, z, better);
    vbi = _mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(vbi), _mm256_castsi256_ps(vdi), better));
    const __m256 old = _mm256_loadu_ps(br + di);
    const __m256 up = _mm256_cmp_ps(z, old, _CMP_GT_OQ);
    _mm256_storeu_ps(br + di, _mm256_blendv_ps(old, z, up));
    const __m256i oldd = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(brd + di));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(brd + di),
                        _mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(oldd), _mm256_castsi256_ps(vdi), up)));
  }
  // The lanes' best (max across halves, then within), and the first index
  // among the lanes that hold it; none when every score is -2.
  __m256 m = _mm256_max_ps(vbest, _mm256_permute2f128_ps(vbest, vbest, 1));
  m = _mm256_max_ps(m, _mm256_permute_ps(m, 0x4E));
  m = _mm256_max_ps(m, _mm256_permute_ps(m, 0xB1));
  const float score = _mm_cvtss_f32(_mm256_castps256_ps128(m));
  if (score > best->score) {
    const __m256i at_best = _mm256_castps_si256(_mm256_cmp_ps(vbest, m, _CMP_EQ_OQ));
    __m256i i = _mm256_blendv_epi8(_mm256_set1_epi32(INT32_MAX), vbi, at_best);
    i = _mm256_min_epi32(i, _mm256_permute2x128_si256(i, i, 1));
    i = _mm256_min_epi32(i, _mm256_shuffle_epi32(i, 0x4E));
    i = _mm256_min_epi32(i, _mm256_shuffle_epi32(i, 0xB1));
    best->score = score;
    best->index = _mm_cvtsi128_si32(_mm256_castsi256_si128(i));
  }
  return di;
}

// ZNCC C[(x - xa) * nd + di] of one row from the column sums V, for x in
// [xa, xb) within [d + h, W - h - 1] (calls in x order), and each column's
// best (best[x - xa]): the window sum S[di] starts at x = d + h and slides
// with x; the best score of each right pixel x - d in bestRrev / bestRdrev
// (reversed: index W - 1 - (x - d); the first of equal scores in d order).
// mRrev, iRrev: the right row's window mean and inverse std, reversed.
__attribute__((target_clones("avx2", "default"))) void RowScores(const int32_t* V, int W, int nd, int dlo, int h,
                                                                  int n, int xa, int xb, const float* mL,
                                                                  const float* iL, const float* mRrev,
                                                                  const float* iRrev, int32_t* S, float* C,
                                                                  float* bestRrev, int* bestRdrev, ColumnBest* best) {
  for (int x = std::max(xa, dlo + h); x < std::min(xb, W - h); ++x) {
    const int started = x - dlo - h;  // disparities below this slide; this one starts at x
    const int32_t* va = V + static_cast<size_t>(x + h) * nd;
    const int32_t* vb = V + static_cast<size_t>(x - h - 1) * nd;
    const int slide = std::min(nd, started);
    for (int di = 0; di < slide; ++di) S[di] += va[di] - vb[di];
    if (started < nd) {
      int32_t s = 0;
      for (int k = x - h; k <= x + h; ++k) s += V[static_cast<size_t>(k) * nd + started];
      S[started] = s;
    }
    const int active = std::min(nd, started + 1);
    const double inv_n = 1.0 / n;  // a multiply, not a division per score
    float* c = C + static_cast<size_t>(x - xa) * nd;
    const float ml = mL[x], il = iL[x];
    const int k0 = W - 1 - x + dlo;  // reversed index of x - dlo
    const float* mr = mRrev + k0;
    const float* ir = iRrev + k0;
    float* br = bestRrev + k0;
    int* brd = bestRdrev + k0;
    ColumnBest& b = best[x - xa];
    b = ColumnBest();
    if (!(il > 0)) {  // a flat left window: no score (and none beats a right pixel's best)
      std::fill(c, c + nd, -2.f);
      continue;
    }
    const int first = HasAvx2() ? ScoresAvx2(S, inv_n, ml, il, mr, ir, active, c, br, brd, &b) : 0;
    for (int di = first; di < active; ++di) {
      const float cov = static_cast<float>(static_cast<double>(S[di]) * inv_n) - ml * mr[di];
      const float z = ir[di] > 0 ? cov * il * ir[di] : -2.f;
      c[di] = z;
      if (z > b.score) b.score = z, b.index = di;
      const bool up = z > br[di];
      br[di] = up ? z : br[di];
      brd[di] = up ? di : brd[di];
    }
    for (int di = active; di < nd; ++di) c[di] = -2.f;
  }
}

// The best local maximum of c[0, nd) at least 3 disparities from the best
// score's index bi (-2 = none): maxima of exact values, 4 at a time.
float SecondPeak(const float* c, int nd, int bi) {
  // A disparity d qualifies when |d - bi| >= 3 and c[d] >= its neighbours.
  auto qualifies = [&](int d) {
    return std::abs(d - bi) >= 3 && (d == 0 || c[d] >= c[d - 1]) && (d + 1 == nd || c[d] >= c[d + 1]);
  };
  float second = -2.f;
  if (qualifies(0)) second = std::max(second, c[0]);
  cv::v_float32x4 vsec = cv::v_setall_f32(-2.f);
  const cv::v_int32x4 lo = cv::v_setall_s32(bi - 2), hi = cv::v_setall_s32(bi + 2), four = cv::v_setall_s32(4);
  cv::v_int32x4 idx(1, 2, 3, 4);
  int di = 1;
  for (; di + 5 <= nd; di += 4, idx += four) {  // d = di .. di + 3, all with both neighbours
    const cv::v_float32x4 cur = cv::v_load(c + di);
    const cv::v_float32x4 peak = (cur >= cv::v_load(c + di - 1)) & (cur >= cv::v_load(c + di + 1));
    const cv::v_float32x4 far = cv::v_reinterpret_as_f32((idx < lo) | (idx > hi));
    vsec = cv::v_max(vsec, cv::v_select(peak & far, cur, cv::v_setall_f32(-2.f)));
  }
  second = std::max(second, cv::v_reduce_max(vsec));
  for (; di < nd; ++di)
    if (qualifies(di)) second = std::max(second, c[di]);
  return second;
}

// SecondPeak 8 disparities at a time (AVX2): the same maximum (a maximum
// does not depend on the order).
__attribute__((target("avx2"))) float SecondPeakAvx2(const float* c, int nd, int bi) {
  auto qualifies = [&](int d) {
    return std::abs(d - bi) >= 3 && (d == 0 || c[d] >= c[d - 1]) && (d + 1 == nd || c[d] >= c[d + 1]);
  };
  float second = -2.f;
  if (qualifies(0)) second = std::max(second, c[0]);
  __m256 vsec = _mm256_set1_ps(-2.f);
  const __m256i lo = _mm256_set1_epi32(bi - 2), hi = _mm256_set1_epi32(bi + 2), eight = _mm256_set1_epi32(8);
  __m256i idx = _mm256_setr_epi32(1, 2, 3, 4, 5, 6, 7, 8);
  int di = 1;
  for (; di + 9 <= nd; di += 8, idx = _mm256_add_epi32(idx, eight)) {  // d = di .. di + 7, all with both neighbours
    const __m256 cur = _mm256_loadu_ps(c + di);
    const __m256 peak = _mm256_and_ps(_mm256_cmp_ps(cur, _mm256_loadu_ps(c + di - 1), _CMP_GE_OQ),
                                      _mm256_cmp_ps(cur, _mm256_loadu_ps(c + di + 1), _CMP_GE_OQ));
    const __m256 far = _mm256_castsi256_ps(_mm256_or_si256(_mm256_cmpgt_epi32(lo, idx), _mm256_cmpgt_epi32(idx, hi)));
    vsec = _mm256_max_ps(vsec, _mm256_blendv_ps(_mm256_set1_ps(-2.f), cur, _mm256_and_ps(peak, far)));
  }
  alignas(32) float lanes[8];
  _mm256_store_ps(lanes, vsec);
  for (float v : lanes) second = std::max(second, v);
  for (; di < nd; ++di)
    if (qualifies(di)) second = std::max(second, c[di]);
  return second;
}

// The best of c[0, nd) at least 3 disparities from bi (-2 = none), 8 at a
// time (AVX2); NaN scores never enter it. It bounds SecondPeak (a maximum
// over fewer of the same values).
__attribute__((target("avx2"))) float FarBestAvx2(const float* c, int nd, int bi) {
  __m256 vbest = _mm256_set1_ps(-2.f);
  const __m256i lo = _mm256_set1_epi32(bi - 2), hi = _mm256_set1_epi32(bi + 2), eight = _mm256_set1_epi32(8);
  __m256i idx = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  int d = 0;
  for (; d + 8 <= nd; d += 8, idx = _mm256_add_epi32(idx, eight)) {
    const __m256 far = _mm256_castsi256_ps(_mm256_or_si256(_mm256_cmpgt_epi32(lo, idx), _mm256_cmpgt_epi32(idx, hi)));
    // max(x, best) keeps best where x is NaN.
    vbest = _mm256_max_ps(_mm256_blendv_ps(_mm256_set1_ps(-2.f), _mm256_loadu_ps(c + d), far), vbest);
  }
  alignas(32) float lanes[8];
  _mm256_store_ps(lanes, vbest);
  float best = -2.f;
  for (float v : lanes) best = std::max(best, v);
  for (; d < nd; ++d)
    if (std::abs(d - bi) >= 3 && c[d] > best) best = c[d];
  return best;
}

// A grid pixel's ZNCC peak before the left-right check.
struct ZnccPeak {
  int gx, bi;     // grid column, best disparity index
  double offset;  // sub-pixel parabola offset
};

// The ZNCC peak of grid column x from its scores c[0, nd) and their best:
// false when the best score is too low, not unique enough, or at the
// search limit.
bool PeakOfColumn(const float* c, const ColumnBest& b, int x, int nd, int dlo, int h, const DenseStereoOptions& o,
                  int* bi_out, double* offset_out) {
  const int bi = b.index;
  const float best = b.score;
  if (bi < 0 || best < o.min_score) return false;  // compared in double
  // With AVX2 the local maxima are looked for only when the best score
  // away from the peak is within the margin (best - second >= best - far).
  if (HasAvx2()) {
    if (!(best - FarBestAvx2(c, nd, bi) >= o.min_peak_margin) && best - SecondPeakAvx2(c, nd, bi) < o.min_peak_margin)
      return false;
  } else if (best - SecondPeak(c, nd, bi) < o.min_peak_margin) {
    return false;
  }
  // Near the left edge the search stops at the largest disparity whose
  // window fits the right image; a best score at that limit may still be
  // rising, so it is no peak.
  const int last = std::min(nd - 1, x - h - dlo);
  if (last < nd - 1 && bi == last) return false;
  double offset = 0;
  if (bi > 0 && bi + 1 < nd) {
    const double a = c[bi - 1], bb = best, cc = c[bi + 1];
    const double den = a - 2 * bb + cc;
    if (a > -2 && cc > -2 && den < -1e-9) offset = std::clamp(0.5 * (a - cc) / den, -0.5, 0.5);
  }
  *bi_out = bi;
  *offset_out = offset;
  return true;
}

// One thread's buffers for ZnccRows. Disparity-major per x: V[x * nd + di];
// the scores of a chunk of kChunk columns C[(x - x0) * nd + di] (the chunk
// stays in the first-level cache) and their best. The right image's rows
// and statistics are read reversed, so that x - d runs forward with di;
// bestR / bestRd are kept reversed too.
struct ZnccScratch {
  static constexpr int kChunk = 16;
  ZnccScratch(int W, int nd)
      : V(static_cast<size_t>(nd) * W), S(nd), C(static_cast<size_t>(nd) * kChunk), best(kChunk), mRrev(W), iRrev(W),
        bestRrev(W), bestRdrev(W) {}
  std::vector<int32_t> V, S;
  std::vector<float> C;
  std::vector<ColumnBest> best;
  std::vector<float> mRrev, iRrev, bestRrev;
  std::vector<int> bestRdrev;
  std::vector<RowPair> pairs;  // the window rows added / subtracted this grid row, two at a time
  std::vector<ZnccPeak> peaks;
  int prev_y = -(1 << 20);
};

// The window rows that enter (sign +1) and leave (-1) V for grid row y
// (V cleared when the windows do not overlap), two at a time in z->pairs;
// L8, R8: the 8-bit images.
void RowsToAdd(const cv::Mat& L8, const cv::Mat& R8, int y, int h, int window, ZnccScratch* z) {
  std::vector<std::pair<int, int>> rows;
  if (y - z->prev_y < window) {
    for (int r = z->prev_y + h + 1, o = z->prev_y - h; r <= y + h; ++r, ++o) {
      rows.emplace_back(r, 1);
      if (o < y - h) rows.emplace_back(o, -1);
    }
  } else {
    std::fill(z->V.begin(), z->V.end(), 0);
    for (int r = y - h; r <= y + h; ++r) rows.emplace_back(r, 1);
  }
  z->prev_y = y;
  const int W = L8.cols;
  z->pairs.resize((rows.size() + 1) / 2);
  for (size_t k = 0; k < z->pairs.size(); ++k) {
    RowPair& p = z->pairs[k];
    p.lpair.assign(W, 0);
    p.rpair.assign(2 * static_cast<size_t>(W), 0);
    for (size_t e = 0; e < 2 && 2 * k + e < rows.size(); ++e) {
      const auto [r, sign] = rows[2 * k + e];
      const uchar* l = L8.ptr<uchar>(r);
      const uchar* rr = R8.ptr<uchar>(r);
      for (int x = 0; x < W; ++x) {
        const auto lv = static_cast<uint16_t>(static_cast<int16_t>(sign * (l[x] - 128)));
        p.lpair[x] |= static_cast<int32_t>(static_cast<uint32_t>(lv) << (16 * e));
        p.rpair[2 * static_cast<size_t>(W - 1 - x) + e] = static_cast<int16_t>(rr[x] - 128);
      }
    }
  }
}

// One grid row of step 1, chunk by chunk of columns: the column sums V
// (rows in, then rows out), the scores and the peaks of the grid columns;
// then the left-right check (the right pixels' best disparities are
// complete only after the row). Returns the grid points searched.
long ZnccRow(const cv::Mat& L8, const cv::Mat& R8, const cv::Mat& muL, const cv::Mat& isdL, const cv::Mat& muR,
             const cv::Mat& isdR, int y, const DenseStereoOptions& o, ZnccScratch* z, float* out_row, long* matches) {
  const int W = L8.cols, h = o.zncc_window / 2, n = o.zncc_window * o.zncc_window;
  const int dlo = static_cast<int>(std::ceil(o.min_disparity)), dhi = static_cast<int>(std::floor(o.max_disparity));
  const int nd = dhi - dlo + 1;
  RowsToAdd(L8, R8, y, h, o.zncc_window, z);
  std::fill(z->bestRrev.begin(), z->bestRrev.end(), -2.f);
  std::fill(z->bestRdrev.begin(), z->bestRdrev.end(), -1);
  const float* mR = muR.ptr<float>(y);
  const float* iR = isdR.ptr<float>(y);
  std::reverse_copy(mR, mR + W, z->mRrev.begin());
  std::reverse_copy(iR, iR + W, z->iRrev.begin());
  z->peaks.clear();
  long points = 0;
  // Scores at x need V up to column x + h.
  for (int x0 = dlo + h, vdone = 0; x0 < W - h; x0 += ZnccScratch::kChunk) {
    const int x1 = std::min(W - h, x0 + ZnccScratch::kChunk);
    for (const RowPair& p : z->pairs) AddRowPairProducts(p, W, dlo, nd, vdone, x1 + h, z->V.data());
    vdone = x1 + h;
    RowScores(z->V.data(), W, nd, dlo, h, n, x0, x1, muL.ptr<float>(y), isdL.ptr<float>(y), z->mRrev.data(),
              z->iRrev.data(), z->S.data(), z->C.data(), z->bestRrev.data(), z->bestRdrev.data(), z->best.data());
    for (int x = (x0 + o.step - 1) / o.step * o.step; x < x1; x += o.step) {
      ++points;
      ZnccPeak p;
      p.gx = x / o.step;
      if (PeakOfColumn(z->C.data() + static_cast<size_t>(x - x0) * nd, z->best[x - x0], x, nd, dlo, h, o, &p.bi,
                       &p.offset))
        z->peaks.push_back(p);
    }
  }
  for (const ZnccPeak& p : z->peaks) {
    const int xr = p.gx * o.step - (dlo + p.bi);
    if (o.left_right_check && std::abs(z->bestRdrev[W - 1 - xr] - p.bi) > o.max_left_right_diff) continue;
    out_row[p.gx] = static_cast<float>(dlo + p.bi + p.offset);
    ++*matches;
  }
  return points;
}

// Step 1: ZNCC for every grid pixel and integer disparity.
ZnccStage ZnccRows(const cv::Mat& left8, const cv::Mat& right8, const DenseStereoOptions& o) {
  const int W = left8.cols, H = left8.rows, h = o.zncc_window / 2;
  const int dlo = static_cast<int>(std::ceil(o.min_disparity)), dhi = static_cast<int>(std::floor(o.max_disparity));
  const int nd = dhi - dlo + 1;
  const int gw = (W + o.step - 1) / o.step, gh = (H + o.step - 1) / o.step;
  cv::Mat L, R;
  // Centred grey levels for the window statistics (the sums of products
  // centre them too: RowsToAdd).
  left8.convertTo(L, CV_32F, 1.0, -128.0);
  right8.convertTo(R, CV_32F, 1.0, -128.0);
  cv::Mat muL, isdL, muR, isdR;
  // The two images side by side (OpenCV's box filters run on one thread).
#pragma omp parallel sections num_threads(std::min(2, o.num_threads))
  {
#pragma omp section
    BoxStats(L, o.zncc_window, o.min_template_std, &muL, &isdL);
#pragma omp section
    BoxStats(R, o.zncc_window, 1e-3, &muR, &isdR);
  }
  ZnccStage out;
  out.disparity = cv::Mat(gh, gw, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  const int block = 16;  // grid rows per task: the column sums carry over within a block
  const int nblocks = (gh + block - 1) / block;
  long points = 0, matches = 0;
#pragma omp parallel num_threads(o.num_threads) reduction(+ : points, matches)
  {
    ZnccScratch z(W, nd);
#pragma omp for schedule(dynamic, 1)
    for (int b = 0; b < nblocks; ++b) {
      z.prev_y = -(1 << 20);
      for (int gy = b * block; gy < std::min(gh, (b + 1) * block); ++gy) {
        const int y = gy * o.step;
        if (y - h < 0 || y + h >= H) continue;
        points += ZnccRow(left8, right8, muL, isdL, muR, isdR, y, o, &z, out.disparity.ptr<float>(gy), &matches);
      }
    }
  }
  out.points = points;
  out.matches = matches;
  return out;
}

// Whether disparity d at grid cell (x, y) of `in` passes the median test:
// within abs_tolerance + rel_tolerance |median| of its valid neighbours'
// median. `neigh`: scratch.
bool KeepByMedian(const cv::Mat& in, int x, int y, float d, const DenseStereoOptions& o, double abs_tolerance,
                  double rel_tolerance, std::vector<float>* neigh) {
  const int r = o.median_radius, s = o.median_stride;
  // Without the relative term the median is within the tolerance unless
  // k + 1 neighbours lie below the tolerated interval around d (the median
  // among them) or size - k above it: counted in the same pass, without
  // sorting (the interval is contiguous: |d - v| rounds monotonically in v).
  const bool count_only = rel_tolerance == 0;
  size_t n = 0, below = 0, above = 0;
  neigh->clear();
  for (int dy = -(r / s) * s; dy <= r; dy += s) {
    const int yy = y + dy;
    if (yy < 0 || yy >= in.rows) continue;
    const float* row = in.ptr<float>(yy);
    for (int dx = -(r / s) * s; dx <= r; dx += s) {
      const int xx = x + dx;
      if (xx < 0 || xx >= in.cols || (dx == 0 && dy == 0) || !std::isfinite(row[xx])) continue;
      const float v = row[xx];
      ++n;
      if (!count_only) {
        neigh->push_back(v);
      } else if (std::abs(d - static_cast<double>(v)) > abs_tolerance) {
        ++(v < d ? below : above);
      }
    }
  }
  if (static_cast<int>(n) < std::max(1, o.median_min_neighbours)) return o.median_min_neighbours == 0;
  const size_t k = n / 2;  // the median is the k-th smallest
  if (count_only) return below <= k && above < n - k;
  std::nth_element(neigh->begin(), neigh->begin() + k, neigh->end());
  const double med = (*neigh)[k];
  return std::abs(d - med) <= abs_tolerance + rel_tolerance * std::abs(med);
}

// KeepByMedian's verdict for 8 cells from their counts of valid
// neighbours and of those beyond the tolerance below and above.
__attribute__((target("avx2"))) void KeepFromCounts(__m256i n, __m256i below, __m256i above,
                                                    const DenseStereoOptions& o, unsigned char* keep) {
  alignas(32) int nn[8], bb[8], aa[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(nn), n);
  _mm256_store_si256(reinterpret_cast<__m256i*>(bb), below);
  _mm256_store_si256(reinterpret_cast<__m256i*>(aa), above);
  for (int k = 0; k < 8; ++k) {
    if (nn[k] < std::max(1, o.median_min_neighbours)) {
      keep[k] = o.median_min_neighbours == 0;
    } else {
      const int half = nn[k] / 2;
      keep[k] = bb[k] <= half && aa[k] < nn[k] - half;
    }
  }
}

// KeepByMedian without the relative term for the cells of grid row y
// (keep[x] = 1: passes; cells without a disparity are not looked at), 8
// cells at a time: the same counts, the differences in double as there.
__attribute__((target("avx2"))) void KeepRowByMedianAvx2(const cv::Mat& in, int y, const DenseStereoOptions& o,
                                                         double abs_tolerance, unsigned char* keep) {
  const int r = o.median_radius, s = o.median_stride, cols = in.cols;
  const float* row = in.ptr<float>(y);
  const __m256d tol = _mm256_set1_pd(abs_tolerance), abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(~(1LL << 63)));
  const __m256 fmax = _mm256_set1_ps(std::numeric_limits<float>::max());
  const __m256 fabs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256i pack = _mm256_setr_epi32(1, 3, 5, 7, 0, 0, 0, 0);  // the high halves of 4 64-bit masks
  const int kmin = -(r / s) * s;
  int x = 0;
  for (; x + 8 <= cols; x += 8) {
    const __m256 d = _mm256_loadu_ps(row + x);
    const __m256d d0 = _mm256_cvtps_pd(_mm256_castps256_ps128(d)), d1 = _mm256_cvtps_pd(_mm256_extractf128_ps(d, 1));
    __m256i n = _mm256_setzero_si256(), below = n, above = n;
    const __m256i lane = _mm256_add_epi32(_mm256_set1_epi32(x), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    for (int dy = kmin; dy <= r; dy += s) {
      const int yy = y + dy;
      if (yy < 0 || yy >= in.rows) continue;
      const float* nrow = in.ptr<float>(yy);
      for (int dx = kmin; dx <= r; dx += s) {
        if (dx == 0 && dy == 0) continue;
        // Lanes whose neighbour column lies outside the grid load nothing.
        const __m256i xx = _mm256_add_epi32(lane, _mm256_set1_epi32(dx));
        const __m256i outside = _mm256_or_si256(_mm256_cmpgt_epi32(_mm256_setzero_si256(), xx),
                                                _mm256_cmpgt_epi32(xx, _mm256_set1_epi32(cols - 1)));
        const __m256i inside = _mm256_andnot_si256(outside, _mm256_set1_epi32(-1));
        const __m256 v = _mm256_maskload_ps(nrow + x + dx, inside);
        const __m256 finite = _mm256_cmp_ps(_mm256_and_ps(v, fabs_mask), fmax, _CMP_LE_OQ);
        const __m256i valid = _mm256_and_si256(inside, _mm256_castps_si256(finite));
        const __m256d v0 = _mm256_cvtps_pd(_mm256_castps256_ps128(v));
        const __m256d v1 = _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1));
        const __m256d far0 = _mm256_cmp_pd(_mm256_and_pd(_mm256_sub_pd(d0, v0), abs_mask), tol, _CMP_GT_OQ);
        const __m256d far1 = _mm256_cmp_pd(_mm256_and_pd(_mm256_sub_pd(d1, v1), abs_mask), tol, _CMP_GT_OQ);
        const __m256i far = _mm256_and_si256(_mm256_setr_m128i(
            _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(_mm256_castpd_si256(far0), pack)),
            _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(_mm256_castpd_si256(far1), pack))), valid);
        const __m256i lower = _mm256_castps_si256(_mm256_cmp_ps(v, d, _CMP_LT_OQ));
        n = _mm256_sub_epi32(n, valid);
        below = _mm256_sub_epi32(below, _mm256_and_si256(far, lower));
        above = _mm256_sub_epi32(above, _mm256_andnot_si256(lower, far));
      }
    }
    KeepFromCounts(n, below, above, o, keep + x);
  }
  std::vector<float> neigh;
  for (; x < cols; ++x)
    keep[x] = std::isfinite(row[x]) && KeepByMedian(in, x, y, row[x], o, abs_tolerance, 0.0, &neigh);
}

// Whether KeepRowByThresholdsAvx2's float thresholds decide as
// KeepByMedian's double differences do: the tolerance a multiple of 2^-10
// up to 256 px, every disparity 0 or NaN or of magnitude in [2^-20, 4096].
// Then d - tol, d + tol and, wherever it is near the tolerance, d - v are
// exact in double (at most 53 bits from the highest to the lowest), so
// |d - v| > tol is v < d - tol or v > d + tol, exactly.
bool ThresholdsAreExact(const cv::Mat& in, double tol) {
  const double scaled = std::ldexp(tol, 10);
  if (!(tol >= 0 && tol <= 256 && scaled == std::floor(scaled))) return false;
  const float tiny = std::ldexp(1.f, -20);
  for (int y = 0; y < in.rows; ++y) {
    const float* row = in.ptr<float>(y);
    for (int x = 0; x < in.cols; ++x) {
      const float a = std::abs(row[x]);
      if (std::isnan(a) || a == 0.f) continue;
      if (!(a >= tiny && a <= 4096.f)) return false;
    }
  }
  return true;
}

// KeepRowByMedianAvx2 when ThresholdsAreExact: each cell's neighbours
// compared in float with the smallest float not below d - tol and the
// largest not above d + tol. `padded`: the grid with median_radius NaN
// columns on either side.
__attribute__((target("avx2"))) void KeepRowByThresholdsAvx2(const cv::Mat& padded, int y, const DenseStereoOptions& o,
                                                             double tol, unsigned char* keep) {
  const int r = o.median_radius, s = o.median_stride, cols = padded.cols - 2 * r;
  const float* row = padded.ptr<float>(y) + r;
  std::vector<float> lo(cols), hi(cols);
  for (int x = 0; x < cols; ++x) {
    const double l = static_cast<double>(row[x]) - tol, u = static_cast<double>(row[x]) + tol;
    float lf = static_cast<float>(l), uf = static_cast<float>(u);
    if (static_cast<double>(lf) < l) lf = std::nextafter(lf, std::numeric_limits<float>::infinity());
    if (static_cast<double>(uf) > u) uf = std::nextafter(uf, -std::numeric_limits<float>::infinity());
    lo[x] = lf, hi[x] = uf;
  }
  const int kmin = -(r / s) * s;
  int x = 0;
  for (; x + 8 <= cols; x += 8) {
    const __m256 vlo = _mm256_loadu_ps(lo.data() + x), vhi = _mm256_loadu_ps(hi.data() + x);
    __m256i n = _mm256_setzero_si256(), below = n, above = n;
    for (int dy = kmin; dy <= r; dy += s) {
      const int yy = y + dy;
      if (yy < 0 || yy >= padded.rows) continue;
      const float* nrow = padded.ptr<float>(yy) + r;
      for (int dx = kmin; dx <= r; dx += s) {
        if (dx == 0 && dy == 0) continue;
        const __m256 v = _mm256_loadu_ps(nrow + x + dx);  // NaN past the grid's sides
        n = _mm256_sub_epi32(n, _mm256_castps_si256(_mm256_cmp_ps(v, v, _CMP_ORD_Q)));
        below = _mm256_sub_epi32(below, _mm256_castps_si256(_mm256_cmp_ps(v, vlo, _CMP_LT_OQ)));
        above = _mm256_sub_epi32(above, _mm256_castps_si256(_mm256_cmp_ps(v, vhi, _CMP_GT_OQ)));
      }
    }
    KeepFromCounts(n, below, above, o, keep + x);
  }
  if (x < cols) {
    const cv::Mat in = padded.colRange(r, r + cols);
    std::vector<float> neigh;
    for (; x < cols; ++x)
      keep[x] = std::isfinite(row[x]) && KeepByMedian(in, x, y, row[x], o, tol, 0.0, &neigh);
  }
}

}  // namespace

namespace internal {

// Step 2: drops disparities far from the median of their grid neighbours.
long MedianTest(const DenseStereoOptions& o, double abs_tolerance, double rel_tolerance, cv::Mat* disp) {
  const cv::Mat in = disp->clone();
  long kept = 0;
  const bool vector_rows = rel_tolerance == 0 && HasAvx2();
  const bool thresholds = vector_rows && ThresholdsAreExact(in, abs_tolerance);
  cv::Mat padded;
  if (thresholds)
    cv::copyMakeBorder(in, padded, 0, 0, o.median_radius, o.median_radius, cv::BORDER_CONSTANT,
                       cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
#pragma omp parallel for schedule(dynamic, 8) num_threads(o.num_threads) reduction(+ : kept)
  for (int y = 0; y < in.rows; ++y) {
    std::vector<float> neigh;
    std::vector<unsigned char> keep;
    const float* row = in.ptr<float>(y);
    float* out = disp->ptr<float>(y);
    if (vector_rows) {
      keep.resize(in.cols);
      if (thresholds) {
        KeepRowByThresholdsAvx2(padded, y, o, abs_tolerance, keep.data());
      } else {
        KeepRowByMedianAvx2(in, y, o, abs_tolerance, keep.data());
      }
    }
    for (int x = 0; x < in.cols; ++x) {
      if (!std::isfinite(row[x])) continue;
      if (vector_rows ? keep[x] != 0 : KeepByMedian(in, x, y, row[x], o, abs_tolerance, rel_tolerance, &neigh)) {
        ++kept;
      } else {
        out[x] = std::numeric_limits<float>::quiet_NaN();
      }
    }
  }
  return kept;
}

// The median (the (n / 2)-th smallest) of the finite values of a CV_32F
// grid into *median, unchanged when there are none. Non-negative floats
// order as their bits: a histogram of the top 16 bits finds the median's
// bin, and only that bin's values are partly sorted (a negative value:
// all of them are).
void MedianOfFinite(const cv::Mat& grid, double* median) {
  std::vector<uint32_t> bins(1 << 16, 0);
  size_t n = 0;
  bool negative = false;
  auto bits = [](float v) {
    uint32_t b;
    std::memcpy(&b, &v, sizeof b);
    return b;
  };
  for (int y = 0; y < grid.rows; ++y) {
    const float* row = grid.ptr<float>(y);
    for (int x = 0; x < grid.cols; ++x) {
      if (!std::isfinite(row[x])) continue;
      const uint32_t b = bits(row[x]);
      negative |= (b >> 31) != 0;
      ++bins[b >> 16];
      ++n;
    }
  }
  if (n == 0) return;
  const size_t k = n / 2;
  size_t below = 0;
  uint32_t bin = 0;
  while (!negative && below + bins[bin] <= k) below += bins[bin++];
  std::vector<float> values;
  values.reserve(negative ? n : bins[bin]);
  for (int y = 0; y < grid.rows; ++y) {
    const float* row = grid.ptr<float>(y);
    for (int x = 0; x < grid.cols; ++x)
      if (std::isfinite(row[x]) && (negative || bits(row[x]) >> 16 == bin)) values.push_back(row[x]);
  }
  const size_t at = negative ? k : k - below;
  std::nth_element(values.begin(), values.begin() + at, values.end());
  *median = values[at];
}

}  // namespace internal

namespace {

// Step 3's images: the left grey levels, the right image's row
// interpolation coefficients and, for the back check, the reverse pair.
struct LsmImages {
  LsmImages(const cv::Mat& left, const cv::Mat& right, const DenseStereoOptions& o) {
    left.convertTo(L, CV_32F);
    R = PrepareRowLsmTarget(right, o);
    if (o.lsm_back_check_px > 0) {
      right.convertTo(Rraw, CV_32F);
      Lcoef = PrepareRowLsmTarget(left, o);
    }
  }
  cv::Mat L, R, Rraw, Lcoef;
};

// Step 3 for the grid points of `tasks`: row LSM of each left pixel from
// its ZNCC disparity (8 at a time, internal::RowLeastSquaresMatchBatch),
// then the optional back check of those LSM accepted.
void RefinePixels(const LsmImages& im, const DenseStereoOptions& o, const std::vector<internal::RowLsmTask>& tasks,
                  std::vector<RowLsmResult>* results, std::vector<unsigned char>* accepted) {
  results->resize(tasks.size());
  accepted->resize(tasks.size());
  internal::RowLeastSquaresMatchBatch(im.L, im.R, tasks.data(), static_cast<int>(tasks.size()), o, results->data(),
                                      accepted->data());
  if (o.lsm_back_check_px <= 0) return;
  for (size_t k = 0; k < tasks.size(); ++k) {
    if (!(*accepted)[k]) continue;
    // Back from the nearest right pixel into the left image (disparity
    // negated: the left point is to the right of the right point).
    const RowLsmResult& out = (*results)[k];
    RowLsmResult back;
    const int xr = static_cast<int>(std::lround(tasks[k].x - out.disparity));
    (*accepted)[k] = RowLeastSquaresMatch(im.Rraw, im.Lcoef, xr, tasks[k].y, -out.disparity, o, &back) &&
                     std::abs(-back.disparity - out.disparity) <= o.lsm_back_check_px;
  }
}

struct LsmPassCounts {
  long matched = 0, iterations = 0, from_lattice = 0, dropped = 0;
};

// The lattice's strides, coarse to fine: lsm_lattice, halved while even,
// then 1 (4: 4, 2, 1; 3: 3, 1; 1: 1). Level 0 runs LSM on its lattice;
// level i takes the points of its lattice not on level i - 1's from the
// corners of level i - 1's cells.
std::vector<int> LatticeStrides(int k) {
  std::vector<int> strides{k};
  while (strides.back() > 1) strides.push_back(strides.back() % 2 == 0 ? strides.back() / 2 : 1);
  return strides;
}

// a mod k for a >= 0, k >= 1 (a mask for the usual powers of two: an
// integer division per grid point and level was a few percent of LSM).
inline int Mod(int a, int k) { return (k & (k - 1)) == 0 ? a & (k - 1) : a % k; }

// The levels' results so far: disparity and sigma (NaN = rejected), the
// disparity plane's gradients, and whether the point was refined (by LSM
// or from its corners).
struct LatticeResults {
  cv::Mat d, sigma, ddx, ddy, done;  // grid-sized; done: CV_8U
  // Refined and kept: not failed (no ZNCC match, rejected by LSM, dropped).
  bool Accepted(int x, int y) const { return done.at<uchar>(y, x) && std::isfinite(d.at<float>(y, x)); }
};

// A point's disparity, sigma and plane (written into `lattice`, the point
// then refined) from the planes of the refined points at the corners of its
// cell of side `k` (tent weights: the nearer a corner, the more it counts):
// false when more than lsm_lattice_max_failed_corners corners inside the
// grid failed (no ZNCC match, rejected by LSM or dropped with their failed
// cell; the others count), when
// fewer than lsm_lattice_min_corners were accepted (the grid's
// last row and column lack some), or when their predictions spread wider
// than lsm_lattice_agree_px or leave lsm_max_shift_px of the point's ZNCC
// disparity.
bool FromLattice(const DenseStereoOptions& o, int k, int gx, int gy, float zncc, LatticeResults* lattice) {
  LatticeResults& lat = *lattice;
  const int x0 = gx - Mod(gx, k), y0 = gy - Mod(gy, k);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo, sum = 0, weights = 0, sdx = 0, sdy = 0;
  float worst = 0;
  int used = 0, failed = 0;
  for (const int cy : {y0, y0 + k}) {
    for (const int cx : {x0, x0 + k}) {
      if (cx >= lat.d.cols || cy >= lat.d.rows) continue;  // past the grid's last row or column
      // No ZNCC match there (an occlusion, no texture) or rejected by LSM (an edge).
      if (!lat.Accepted(cx, cy)) {
        if (++failed > o.lsm_lattice_max_failed_corners) return false;
        continue;
      }
      const float dc = lat.d.at<float>(cy, cx);
      const double ddx = lat.ddx.at<float>(cy, cx), ddy = lat.ddy.at<float>(cy, cx);
      const double p = dc + (ddx * (gx - cx) + ddy * (gy - cy)) * o.step;
      const double w = (k - std::abs(gx - cx) + 0.5) * (k - std::abs(gy - cy) + 0.5);  // tent, never 0
      lo = std::min(lo, p), hi = std::max(hi, p), sum += w * p, weights += w, ++used;
      sdx += w * ddx, sdy += w * ddy;
      worst = std::max(worst, lat.sigma.at<float>(cy, cx));
    }
  }
  if (used < o.lsm_lattice_min_corners || hi - lo > o.lsm_lattice_agree_px) return false;
  const double mean = sum / weights;
  if (std::abs(mean - zncc) > o.lsm_max_shift_px) return false;
  lat.d.at<float>(gy, gx) = static_cast<float>(mean);
  lat.sigma.at<float>(gy, gx) = worst;
  lat.ddx.at<float>(gy, gx) = static_cast<float>(sdx / weights);
  lat.ddy.at<float>(gy, gx) = static_cast<float>(sdy / weights);
  lat.done.at<uchar>(gy, gx) = 1;
  return true;
}

// Whether every corner inside the grid of point (gx, gy)'s cell of side k
// failed: rejected by LSM or without a ZNCC match.
bool CellFailed(int k, int gx, int gy, const LatticeResults& lat) {
  const int x0 = gx - Mod(gx, k), y0 = gy - Mod(gy, k);
  for (const int cy : {y0, y0 + k})
    for (const int cx : {x0, x0 + k})
      if (cx < lat.d.cols && cy < lat.d.rows && lat.Accepted(cx, cy)) return false;
  return true;
}

// Step 3 over the grid (`disp`: the ZNCC disparities in, the LSM ones out,
// NaN = rejected; `sigma` out): LSM on every point, or level by level of
// the lattice (lsm_lattice > 1, LatticeStrides). OpenMP over blocks of 8
// grid rows; a level reads only the levels before it.
LsmPassCounts RefineDisparities(const LsmImages& images, const DenseStereoOptions& o, cv::Mat* disp, cv::Mat* sigma) {
  LsmPassCounts total;
  const std::vector<int> strides = LatticeStrides(std::max(1, o.lsm_lattice));
  const cv::Mat zncc = disp->clone();
  LatticeResults lat;
  const cv::Scalar nan(std::numeric_limits<float>::quiet_NaN());
  lat.d = cv::Mat(disp->size(), CV_32F, nan), lat.sigma = lat.d.clone();
  lat.ddx = cv::Mat(disp->size(), CV_32F, cv::Scalar(0)), lat.ddy = lat.ddx.clone();
  lat.done = cv::Mat(disp->size(), CV_8U, cv::Scalar(0));
  for (size_t level = 0; level < strides.size(); ++level) {
    const int stride = strides[level], coarser = level > 0 ? strides[level - 1] : 0;
    const int block = 8;  // grid rows per task
    const int nblocks = (disp->rows + block - 1) / block;
    long matched = 0, iterations = 0, from_lattice = 0, dropped = 0;
#pragma omp parallel num_threads(o.num_threads) reduction(+ : matched, iterations, from_lattice, dropped)
    {
      std::vector<internal::RowLsmTask> tasks;
      std::vector<cv::Point> cells;
      std::vector<RowLsmResult> results;
      std::vector<unsigned char> accepted;
#pragma omp for schedule(dynamic, 1)
      for (int b = 0; b < nblocks; ++b) {
        tasks.clear();
        cells.clear();
        for (int gy = b * block; gy < std::min(disp->rows, (b + 1) * block); ++gy) {
          if (Mod(gy, stride) != 0) continue;  // only this level's lattice points, in grid order
          const bool coarser_row = level > 0 && Mod(gy, coarser) == 0;
          const float* row = zncc.ptr<float>(gy);
          for (int gx = 0; gx < disp->cols; gx += stride) {
            if (!std::isfinite(row[gx])) continue;
            if (level > 0) {
              if (coarser_row && Mod(gx, coarser) == 0) continue;  // refined on a coarser level
              if (FromLattice(o, coarser, gx, gy, row[gx], &lat)) {
                ++matched, ++from_lattice;
                continue;
              }
              if (o.lsm_lattice_drop_failed_cells && CellFailed(coarser, gx, gy, lat)) {
                lat.done.at<uchar>(gy, gx) = 1;
                ++dropped;
                continue;
              }
            }
            internal::RowLsmTask t;
            t.x = gx * o.step, t.y = gy * o.step, t.initial_disparity = row[gx];
            tasks.push_back(t);
            cells.emplace_back(gx, gy);
          }
        }
        RefinePixels(images, o, tasks, &results, &accepted);
        for (size_t k = 0; k < tasks.size(); ++k) {
          lat.done.at<uchar>(cells[k]) = 1;
          if (!accepted[k]) continue;
          lat.d.at<float>(cells[k]) = static_cast<float>(results[k].disparity);
          lat.sigma.at<float>(cells[k]) = static_cast<float>(results[k].sigma_px);
          lat.ddx.at<float>(cells[k]) = static_cast<float>(results[k].disparity_dx);
          lat.ddy.at<float>(cells[k]) = static_cast<float>(results[k].disparity_dy);
          ++matched;
          iterations += results[k].iterations;
        }
      }
    }
    total.matched += matched, total.iterations += iterations, total.from_lattice += from_lattice;
    total.dropped += dropped;
  }
  lat.d.copyTo(*disp);
  lat.sigma.copyTo(*sigma);
  return total;
}

}  // namespace

cv::Mat DenseStereo(const cv::Mat& left, const cv::Mat& right, const DenseStereoOptions& o,
                    DenseStereoSummary* summary) {
  std::string error;
  if (!o.Check(&error)) throw std::invalid_argument(error);
  if (left.type() != CV_8UC1 || right.type() != CV_8UC1 || left.size() != right.size() || left.empty())
    throw std::invalid_argument("DenseStereo needs two 8-bit grey images of the same size");
  DenseStereoSummary local;
  DenseStereoSummary& s = summary ? *summary : local;
  s = DenseStereoSummary();
  const auto t0 = Clock::now();
  ZnccStage z = ZnccRows(left, right, o);
  s.grid_width = z.disparity.cols;
  s.grid_height = z.disparity.rows;
  s.points = z.points;
  s.zncc_matches = z.matches;
  s.zncc_seconds = Since(t0);
  const auto t1 = Clock::now();
  cv::Mat disp = z.disparity;
  s.after_median = internal::MedianTest(o, o.median_abs_tolerance, o.median_rel_tolerance, &disp);
  s.median_seconds = Since(t1);
  const auto t2 = Clock::now();
  if (o.lsm_enabled) {
    const LsmImages images(left, right, o);
    cv::Mat sigma(disp.size(), CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
    const LsmPassCounts counts = RefineDisparities(images, o, &disp, &sigma);
    const long matched = counts.matched, iterations = counts.iterations;
    s.lsm_from_lattice = counts.from_lattice;
    s.lsm_dropped = counts.dropped;
    s.lsm_matches = matched;
    const long refined = matched - counts.from_lattice;
    s.lsm_mean_iterations = refined ? static_cast<double>(iterations) / refined : 0.0;
    if (o.lsm_median_tolerance > 0) s.lsm_matches = internal::MedianTest(o, o.lsm_median_tolerance, 0.0, &disp);
    internal::MedianOfFinite(sigma, &s.median_sigma_px);
  } else {
    s.lsm_matches = s.after_median;
  }
  s.lsm_seconds = Since(t2);
  s.total_seconds = Since(t0);
  const long out = o.lsm_enabled ? s.lsm_matches : s.after_median;
  s.usable = out > 0;
  s.message = s.usable ? "ok" : (s.zncc_matches == 0 ? "no unique ZNCC match (texture, disparity range?)" : "every match rejected");
  return disp;
}

}  // namespace vloc
