#pragma once
// Dense stereo of a rectified pair by the paper's method (Wan et al. 2.2):
// ZNCC along the row, a median filter of the disparities against their
// neighbours, least-squares matching to sub-pixel precision. Built for
// whole images:
//   1. ZNCC for every grid pixel and integer disparity from running box
//      sums (cost independent of the window size), OpenMP over row blocks;
//      the best peak must be unique (margin over the next local maximum) and
//      agree with the right-to-left best of the same scores (left-right check).
//      Near the left edge the search stops at the largest disparity whose
//      window fits the right image (a best score at that cut is no peak).
//   2. Median test on the disparity grid: a disparity far from the median of
//      its neighbours is dropped.
//   3. Row LSM: the left window matched into the right image along the row
//      with a disparity plane (d, dd/dx, dd/dy) and a linear radiometric
//      model; 1-D cubic B-spline resampling along the rows (rows stay
//      integer: the pair is rectified). Keys' cubic convolution instead
//      biases the disparity by up to +-0.02 px with its sub-pixel phase.
//      8 pixels at a time in the lanes of AVX2 registers where the CPU has
//      them and FMA (row_lsm.cpp: the scalar code's operations in its
//      order, the same disparities bit for bit; row_lsm_test). With
//      lsm_lattice > 1 LSM runs on a lattice of the grid first, and the
//      points of finer lattices take the disparity planes of the refined
//      points around them where those agree (a window overlaps its
//      neighbours' by most of its area), running LSM themselves only where
//      they do not (depth edges).
// Options default to the paper's pipeline; lsm_median_tolerance and
// lsm_back_check_px add filters after LSM (off by default: each trades
// matched pixels for fewer > 1 px errors). config/stereo_photo.yaml holds
// the settings for photographs with depth edges (7 x 7 LSM window, the LSM
// median test), config/stereo_jpeg.yaml those for compressed, weakly
// textured ones (15 x 15); windows shifted along the row (shiftable
// windows) were tried: more pixels matched, the same share of > 1 px
// errors.

#include <opencv2/core.hpp>
#include <string>

namespace vloc {

class OptionsReader;

struct DenseStereoOptions {
  double min_disparity = 0;        // px, searched disparities are [min, max] (left x - right x)
  double max_disparity = 128;      // px
  int step = 1;                    // px, grid spacing: every step-th pixel of every step-th row
  int zncc_window = 11;            // px, side of the ZNCC window (odd)
  double min_score = 0.7;          // ZNCC of the best disparity must reach this
  double min_peak_margin = 0.02;   // best minus the best other local maximum (>= 3 px away)
  double min_template_std = 2.0;   // grey level, flatter left windows are skipped
  bool left_right_check = true;    // the right pixel's best disparity must agree ...
  int max_left_right_diff = 1;     // ... within this many px
  int median_radius = 6;           // grid cells, half side of the median filter's window
  int median_stride = 2;           // grid cells, neighbours sampled every this many cells
  int median_min_neighbours = 8;   // fewer valid neighbours: the disparity is dropped
  double median_abs_tolerance = 1.0;  // px, allowed |d - median|, plus ...
  double median_rel_tolerance = 0.0;  // ... this fraction of the median
  bool lsm_enabled = true;         // false: ZNCC parabola disparities
  int lsm_half_window = 5;         // px, LSM window half width ...
  int lsm_half_height = 5;         // px, ... and half height
  bool lsm_disparity_plane = true; // estimate dd/dx and dd/dy (slanted surfaces)
  bool lsm_bspline = true;         // resample the right image with cubic B-splines (false: Keys' cubic
                                   // convolution, biased by up to +-0.02 px with the sub-pixel phase)
  int lsm_max_iterations = 10;     // Gauss-Newton iterations
  double lsm_convergence_px = 0.002;  // px, stop when the disparity update is below this
  double lsm_max_shift_px = 1.0;   // px, reject LSM moving further from the ZNCC disparity
  double lsm_min_correlation = 0.8;   // correlation of the windows at the solution
  double lsm_max_sigma_px = 0.2;   // px, reject disparities less precise than this (1 sigma)
  double lsm_median_tolerance = 0; // px, the median test again on the LSM disparities (0 = off)
  double lsm_back_check_px = 0;    // px, LSM from the right image back into the left must agree (0 = off)
  // LSM on a coarser lattice (grid points): every lsm_lattice-th point of
  // every lsm_lattice-th row is refined; then, level by level (the stride
  // halved while even, then 1), a point of the finer lattice takes the
  // mean of the disparity planes of its coarser cell's refined corners,
  // weighted by nearness (the nearest LSM windows hold most of its own),
  // when enough were accepted, at most lsm_lattice_max_failed_corners were
  // rejected by LSM or had no ZNCC match, and their predictions agree; else
  // it runs LSM itself (depth edges, occlusions). A point from the planes
  // skips lsm_back_check_px and takes its corners' largest sigma. 1 = every
  // point (the paper's).
  int lsm_lattice = 1;
  int lsm_lattice_min_corners = 3;    // accepted corners a point from the planes needs (of 4)
  double lsm_lattice_agree_px = 0.2;  // px, largest spread of the corners' predictions
  int lsm_lattice_max_failed_corners = 0;  // failed corners (no ZNCC match, rejected, dropped) a point tolerates
  // A point whose coarser cell has every corner failed (rejected by LSM or
  // without a ZNCC match) is dropped without LSM (true) instead of running
  // it: about 1 in 10 of them is accepted then, each after the most
  // iterations (README, issue 36).
  bool lsm_lattice_drop_failed_cells = false;
  int num_threads = 2;             // OpenMP threads over rows

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct DenseStereoSummary {
  bool usable = false;
  std::string message;            // why not usable, or "ok"
  int grid_width = 0, grid_height = 0;
  long points = 0;                // grid points whose window and search range fit the images
  long zncc_matches = 0;          // unique ZNCC peaks passing the left-right check
  long after_median = 0;          // ... and the median test
  long lsm_matches = 0;           // ... and LSM (the output when lsm_enabled)
  long lsm_from_lattice = 0;      // points taken from the lattice's planes (lsm_lattice > 1), before
                                  // the LSM median test (lsm_median_tolerance)
  long lsm_dropped = 0;           // points dropped without LSM (lsm_lattice_drop_failed_cells)
  double median_sigma_px = 0;     // median LSM 1-sigma disparity precision
  double lsm_mean_iterations = 0; // Gauss-Newton iterations per accepted LSM match
  double zncc_seconds = 0, median_seconds = 0, lsm_seconds = 0, total_seconds = 0;

  std::string BriefReport() const;
};

// Disparity (left x - right x, px) of every grid point, CV_32FC1 of
// ceil(H / step) x ceil(W / step); NaN = no match. `left`, `right`: CV_8UC1,
// same size, rectified (corresponding points on the same row). Throws
// std::invalid_argument on bad input or options.
cv::Mat DenseStereo(const cv::Mat& left, const cv::Mat& right, const DenseStereoOptions& options,
                    DenseStereoSummary* summary = nullptr);

// The right image as row LSM resamples it: CV_32F grey levels, or their
// B-spline coefficients along the rows when options.lsm_bspline.
cv::Mat PrepareRowLsmTarget(const cv::Mat& right, const DenseStereoOptions& options);

// Row LSM of one left pixel (integer x, y) from an initial disparity;
// `left32`: CV_32F grey levels, `right32`: PrepareRowLsmTarget(right).
// Returns false when rejected. For tests and tools.
struct RowLsmResult {
  double disparity = 0;   // px
  double sigma_px = 0;    // px, 1-sigma
  double correlation = 0;
  int iterations = 0;
  double disparity_dx = 0, disparity_dy = 0;  // the disparity plane's gradients, px per px
};
bool RowLeastSquaresMatch(const cv::Mat& left32, const cv::Mat& right32, int x, int y, double initial_disparity,
                          const DenseStereoOptions& options, RowLsmResult* result);

}  // namespace vloc
