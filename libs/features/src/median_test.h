#pragma once
// Dense stereo's median test (step 2 of dense_stereo.h) and median, for their tests.

#include <opencv2/core.hpp>

#include "vloc/features/dense_stereo.h"

namespace vloc::internal {

// Drops the disparities of `disp` (a grid, CV_32F, NaN = none) farther
// than abs_tolerance + rel_tolerance |median| from the median of their
// grid neighbours (median_radius, median_stride, median_min_neighbours of
// `options`); returns the disparities kept.
long MedianTest(const DenseStereoOptions& options, double abs_tolerance, double rel_tolerance, cv::Mat* disp);

// The median (the (n / 2)-th smallest) of the finite values of a CV_32F
// grid into *median, unchanged when there are none (the LSM sigmas').
void MedianOfFinite(const cv::Mat& grid, double* median);

}  // namespace vloc::internal
