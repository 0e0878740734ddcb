#include "vloc/features/template_ncc.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <vector>
#include <opencv2/imgproc.hpp>

namespace vloc {

namespace {

constexpr int kBlock = 32;  // result columns summed together: four AVX2 registers of partial sums
typedef float Lanes __attribute__((vector_size(32)));
typedef float UnalignedLanes __attribute__((vector_size(32), aligned(4), may_alias));

// The centred template's dot product with the window at each of 8 kRegs consecutive positions of kRows
// consecutive result rows: out[y][l] = sum over (r, c) of templ[r][c] * image[y + r][c + l] (out: `out_step`
// floats a row). image: the padded window from the row and column of the first position, `step` floats a
// row. Each position's sum runs in the same order whatever kRegs and kRows (two rows: twice the independent
// sums, which the adds' latency bounds).
template <int kRegs, int kRows>
__attribute__((always_inline)) inline void DotBlockBody(const float* image, size_t step, const float* templ, int tw,
                                                        int th, float* out, size_t out_step) {
  Lanes a[kRows][kRegs] = {};
  for (int r = 0; r < th; ++r) {
    const float* t = templ + r * tw;
    for (int c = 0; c < tw; ++c) {
      const float w = t[c];
      for (int y = 0; y < kRows; ++y) {
        const float* p = image + (r + y) * step + c;
        for (int k = 0; k < kRegs; ++k) a[y][k] += w * *reinterpret_cast<const UnalignedLanes*>(p + 8 * k);
      }
    }
  }
  for (int y = 0; y < kRows; ++y) std::memcpy(out + y * out_step, a[y], sizeof a[y]);
}
#define VLOC_DOT_BLOCK(N, ROWS)                                                                                \
  __attribute__((target_clones("avx2", "default"))) void DotBlock##N##x##ROWS(                                 \
      const float* image, size_t step, const float* templ, int tw, int th, float* out, size_t out_step) {   \
    DotBlockBody<N, ROWS>(image, step, templ, tw, th, out, out_step);                                          \
  }
VLOC_DOT_BLOCK(1, 1)
VLOC_DOT_BLOCK(2, 1)
VLOC_DOT_BLOCK(3, 1)
VLOC_DOT_BLOCK(4, 1)
VLOC_DOT_BLOCK(1, 2)
VLOC_DOT_BLOCK(2, 2)
VLOC_DOT_BLOCK(3, 2)
VLOC_DOT_BLOCK(4, 2)
#undef VLOC_DOT_BLOCK

// DotBlockBody for the positions [0, width) of a block (width <= kBlock) on `rows` (1 or 2) result rows:
// whole registers only (a 7-wide search sums 8 positions, not 32).
void DotBlock(const float* image, size_t step, const float* templ, int tw, int th, int width, int rows, float* out,
              size_t out_step) {
  using Dot = void (*)(const float*, size_t, const float*, int, int, float*, size_t);
  static constexpr Dot kDot[2][4] = {{DotBlock1x1, DotBlock2x1, DotBlock3x1, DotBlock4x1},
                                     {DotBlock1x2, DotBlock2x2, DotBlock3x2, DotBlock4x2}};
  kDot[rows - 1][(std::min(width, kBlock) + 7) / 8 - 1](image, step, templ, tw, th, out, out_step);
}

// One result row normalised as OpenCV's common_matchTemplate does: the window's norm from its sums (s0, s1: the
// integral's rows above and below it; q0, q1: the squares') times the template's; |score| within 1.125 of 1
// clamped, beyond it 0 (a flat window). Selections, not branches: with this file built without math errno
// and traps (CMakeLists.txt) the loop runs 4 positions a register.
__attribute__((target_clones("avx2", "default"))) void NormaliseRow(
    const float* dots, const double* s0, const double* s1, const double* q0, const double* q1, int tw, int cols,
    double inv_n, double templ_norm, float* out) {
  for (int x = 0; x < cols; ++x) {
    const double wsum = s1[x + tw] - s1[x] - s0[x + tw] + s0[x];
    const double wsq = q1[x + tw] - q1[x] - q0[x + tw] + q0[x];
    const double norm = std::sqrt(std::max(wsq - wsum * wsum * inv_n, 0.0)) * templ_norm;
    const double v = dots[x], a = std::abs(v), q = v / norm;
    // (v = 0 never reaches the sign: its a = 0 is below a norm > 0, and at norm 0 not below 1.125 norm.)
    const double clamped = a < norm * 1.125 ? std::copysign(1.0, v) : 0.0;
    out[x] = static_cast<float>(a < norm ? q : clamped);
  }
}

// `image` as float, its width padded with zeros to a whole number of blocks of positions.
cv::Mat PaddedFloat(const cv::Mat& image, int positions_wide, int templ_cols) {
  const int blocks = (positions_wide + kBlock - 1) / kBlock;
  cv::Mat out(image.rows, blocks * kBlock + templ_cols - 1, CV_32FC1, cv::Scalar(0));
  cv::Mat part = out(cv::Rect(0, 0, image.cols, image.rows));
  image.convertTo(part, CV_32F);
  return out;
}

}  // namespace

void MatchTemplateNcc(const cv::Mat& image, const cv::Mat& templ, cv::Mat* result) {
  CV_Assert((image.type() == CV_8UC1 || image.type() == CV_32FC1) && templ.type() == image.type());
  CV_Assert(templ.cols <= image.cols && templ.rows <= image.rows && !templ.empty());
  const int tw = templ.cols, th = templ.rows, n = tw * th;
  const int cols = image.cols - tw + 1, rows = image.rows - th + 1;
  result->create(rows, cols, CV_32FC1);
  // The template centred (sum T' I = sum T I - mean(T) sum I, OpenCV's numerator), and its norm.
  cv::Mat t;
  templ.convertTo(t, CV_32F);
  cv::Scalar mean, sdv;
  cv::meanStdDev(t, mean, sdv);
  const double templ_var = sdv[0] * sdv[0];
  if (templ_var < DBL_EPSILON) {
    result->setTo(1);
    return;
  }
  const double templ_norm = std::sqrt(templ_var * n);
  std::vector<float> centred(n);
  for (int r = 0; r < th; ++r)
    for (int c = 0; c < tw; ++c) centred[r * tw + c] = static_cast<float>(t.at<float>(r, c) - mean[0]);
  const cv::Mat padded = PaddedFloat(image, cols, tw);
  cv::Mat sum, sqsum;
  cv::integral(image, sum, sqsum, CV_64F, CV_64F);
  const size_t step = padded.step1();
  const size_t dots_step = ((cols + kBlock - 1) / kBlock) * kBlock;
  std::vector<float> dots(2 * dots_step);
  for (int y = 0; y < rows; y += 2) {
    const int pair = std::min(2, rows - y);  // result rows y (and y + 1)
    for (int x0 = 0; x0 < cols; x0 += kBlock)
      DotBlock(padded.ptr<float>(y) + x0, step, centred.data(), tw, th, cols - x0, pair, dots.data() + x0, dots_step);
    for (int k = 0; k < pair; ++k)
      NormaliseRow(dots.data() + k * dots_step, sum.ptr<double>(y + k), sum.ptr<double>(y + k + th),
                   sqsum.ptr<double>(y + k), sqsum.ptr<double>(y + k + th), tw, cols, 1.0 / n, templ_norm,
                   result->ptr<float>(y + k));
  }
}

}  // namespace vloc
