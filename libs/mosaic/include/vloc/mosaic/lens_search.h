#pragma once
// The lens's radial distortion self-calibrated from a survey's height ties
// (height_graph.h). A compact camera on a survey aircraft rarely comes with a
// calibration, and an unmodelled barrel bends the ground plane each photo
// pair sees: the height ratio of a pair that overlaps along the track and of
// one across the strips are bent differently, so the ties disagree with the
// registration chain. The matched points of every link and tie of one run
// are kept (the matching is not repeated); for each candidate k1 they are
// re-undistorted, each pair's plane homography fitted and decomposed again,
// and the height graph solved; the k1 whose ties agree best (smallest
// residual in their sigmas) is the lens's. No GPS is used.
//
//   mosaicker.KeepHeightObservations();  ... every photo registered ...
//   LensSearch s = SearchRadialDistortion(*mosaicker.height_observations(), camera, options.height_graph);
//   camera.k1 = s.k1;                    // then run the survey again with it
#include <opencv2/core.hpp>

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/mosaic/height_graph.h"

namespace vloc::mosaic {

struct PlaneRatio {
  double height_ratio = 1;       // h_to / h_from
  cv::Vec3d normal{0, 0, 1};     // the ground normal in the `to` camera
};

// The ground plane of homography H (`from` frame px -> `to` frame px, both
// undistorted, camera matrix K): H = K (R + t n^T / d) K^-1. Of the
// decompositions facing the camera whose normal lies within 60 degrees of
// from_normal (the `from` frame's ground normal), the nearest; none when no
// decomposition is plausible (height ratio outside 0.2 ... 5).
std::optional<PlaneRatio> PlaneFromHomography(const cv::Matx33d& H, const cv::Matx33d& K, const cv::Vec3d& from_normal);

// One height ratio of a run: a registration link or a tie.
struct HeightObservation {
  int from = -1, to = -1;                   // frame indexes
  double log_ratio = 0;                     // log(h_to / h_from) as the run measured it
  int support = 0;                          // matches behind it (its sigma: HeightGraphOptions::sigma at 100)
  cv::Vec3d from_normal{0, 0, 1};           // the `from` frame's ground normal (which decomposition)
  std::vector<cv::Point2f> from_px, to_px;  // the matched points, undistorted px of the run's camera; none = the
                                            // ratio came from a similarity fit and is kept as measured
};

struct HeightObservations {
  std::vector<std::pair<int, double>> frames;  // frame index, chained log scale (HeightGraph::AddFrame order)
  std::vector<HeightObservation> pairs;        // links and ties in the order the run added them
};

struct LensSearchOptions {
  double k1_min = -0.12;         // candidates k1_min ... k1_max in steps of k1_step (the run's camera's other
  double k1_max = 0.12;          // coefficients kept)
  double k1_step = 0.01;
  int min_ties = 20;             // pairs with points needed for a search
};

struct LensSearch {
  bool ok = false;
  std::string why;               // when !ok
  double k1 = 0;                 // the smallest residual (parabola through the best step and its neighbours)
  double residual = 0;           // tie residual RMS in sigmas at the best step
  double residual_as_run = 0;    // at the run camera's own k1
  std::vector<cv::Point2d> curve;  // (k1, residual) per candidate
  int pairs = 0;                 // pairs with points re-measured
  int dropped = 0;               // pairs the run's own solution rejects, left out of every candidate
};

// Points of `run_camera` (undistorted by it) are taken back to raw pixels
// and undistorted with each candidate k1. The ties the solution at the run's
// camera drops are left out of every candidate, so that each is scored on
// the same ties.
LensSearch SearchRadialDistortion(const HeightObservations& observations, const PinholeCamera& run_camera,
                                  const HeightGraphOptions& graph, const LensSearchOptions& options = {});

}  // namespace vloc::mosaic
