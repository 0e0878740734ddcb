#pragma once
// Row LSM of many pixels at once (private to libs/features): the same
// Gauss-Newton steps as vloc::RowLeastSquaresMatch, pixel for pixel, with
// the window sums of 8 pixels in the 8 lanes of an AVX2 register (each
// lane runs the scalar code's float and double operations in the scalar
// code's order, its fused multiply-adds as FMA instructions, so the
// results are bit for bit those of RowLeastSquaresMatch; row_lsm_test
// checks it). A pixel's first iteration, where every tap has the same
// sub-pixel phase, runs 8 pixels at a time before the lanes take it (the
// window rows resampled 8 taps at a time). Without AVX2 and FMA, or without
// the disparity plane, it loops over RowLeastSquaresMatch.

#include <opencv2/core.hpp>

#include "vloc/features/dense_stereo.h"

namespace vloc::internal {

struct RowLsmTask {
  int x = 0, y = 0;                // left pixel
  double initial_disparity = 0;    // px
};

// results[k], accepted[k] (1 = RowLeastSquaresMatch returned true) for
// tasks[k]; `left32`, `right32` as for RowLeastSquaresMatch.
void RowLeastSquaresMatchBatch(const cv::Mat& left32, const cv::Mat& right32, const RowLsmTask* tasks, int count,
                               const DenseStereoOptions& options, RowLsmResult* results, unsigned char* accepted);

// Whether RowLeastSquaresMatchBatch runs its AVX2 lanes for `options` on this CPU.
bool RowLsmBatchVectorised(const DenseStereoOptions& options);

// Whether the lanes' kernel is its AVX-512VL build (the same instructions
// with 32 registers: the same results), which they use where the CPU has
// it unless AllowRowLsmAvx512(false) (tests: the AVX2 build on such a CPU).
bool RowLsmBatchUsesAvx512(const DenseStereoOptions& options);
void AllowRowLsmAvx512(bool allowed);

}  // namespace vloc::internal
