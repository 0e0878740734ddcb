#pragma once
// Dense stereo's median test (step 2 of dense_stereo.h), for its tests.

#include <opencv2/core.hpp>

#include "vloc/features/dense_stereo.h"

namespace vloc::internal {

// Drops the disparities of `disp` (a grid, CV_32F, NaN = none) farther
// than abs_tolerance + rel_tolerance |median| from the median of their
// grid neighbours (median_radius, median_stride, median_min_neighbours of
// `options`); returns the disparities kept.
long MedianTest(const DenseStereoOptions& options, double abs_tolerance, double rel_tolerance, cv::Mat* disp);

}  // namespace vloc::internal
