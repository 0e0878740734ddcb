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

// The centred template's dot product with the window at each of kBlock consecutive positions of one result
// row: out[l] = sum over (r, c) of templ[r][c] * image[r][c + l]. image: the padded window from the row and
// column of the first position, `step` floats a row.
__attribute__((target_clones("avx2", "default"))) void DotBlock(const float* image, size_t step, const float* templ,
                                                                int tw, int th, float* out) {
  Lanes a0 = {}, a1 = {}, a2 = {}, a3 = {};
  for (int r = 0; r < th; ++r) {
    const float* row = image + r * step;
    const float* t = templ + r * tw;
    for (int c = 0; c < tw; ++c) {
      const float w = t[c];
      const float* p = row + c;
      a0 += w * *reinterpret_cast<const UnalignedLanes*>(p);
      a1 += w * *reinterpret_cast<const UnalignedLanes*>(p + 8);
      a2 += w * *reinterpret_cast<const UnalignedLanes*>(p + 16);
      a3 += w * *reinterpret_cast<const UnalignedLanes*>(p + 24);
    }
  }
  std::memcpy(out, &a0, sizeof a0);
  std::memcpy(out + 8, &a1, sizeof a1);
  std::memcpy(out + 16, &a2, sizeof a2);
  std::memcpy(out + 24, &a3, sizeof a3);
}

// One result row normalised as OpenCV's common_matchTemplate does: the window's norm from its sums (s0, s1: the
// integral's rows above and below it; q0, q1: the squares') times the template's; |score| within 1.125 of 1
// clamped, beyond it 0 (a flat window). (sqrt of a value >= 0 needs no errno: the loop vectorises.)
__attribute__((target_clones("avx2", "default"), optimize("no-math-errno"))) void NormaliseRow(
    const float* dots, const double* s0, const double* s1, const double* q0, const double* q1, int tw, int cols,
    double inv_n, double templ_norm, float* out) {
  for (int x = 0; x < cols; ++x) {
    const double wsum = s1[x + tw] - s1[x] - s0[x + tw] + s0[x];
    const double wsq = q1[x + tw] - q1[x] - q0[x + tw] + q0[x];
    const double norm = std::sqrt(std::max(wsq - wsum * wsum * inv_n, 0.0)) * templ_norm;
    const double v = dots[x], a = std::abs(v), q = v / norm;
    out[x] = static_cast<float>(a < norm ? q : a < norm * 1.125 ? (v > 0 ? 1.0 : -1.0) : 0.0);
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
  std::vector<float> dots(((cols + kBlock - 1) / kBlock) * kBlock);
  for (int y = 0; y < rows; ++y) {
    for (int x0 = 0; x0 < cols; x0 += kBlock)
      DotBlock(padded.ptr<float>(y) + x0, step, centred.data(), tw, th, dots.data() + x0);
    NormaliseRow(dots.data(), sum.ptr<double>(y), sum.ptr<double>(y + th), sqsum.ptr<double>(y),
                 sqsum.ptr<double>(y + th), tw, cols, 1.0 / n, templ_norm, result->ptr<float>(y));
  }
}

}  // namespace vloc
