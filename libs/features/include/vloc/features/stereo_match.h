#pragma once
// Stereo matching of feature points at one site: ZNCC along the epipolar
// segment of a disparity (range) interval, then a median filter that drops
// points whose disparity disagrees with their neighbours (Wan et al. 2.2,
// Di et al. 2008).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace vloc {

class OptionsReader;

struct ZnccOptions {
  int window = 11;                  // px, side of the square correlation window (odd)
  double min_score = 0.7;           // ZNCC of the best candidate must reach this
  double min_peak_margin = 0.02;    // best minus the best candidate >= 3 steps away must reach this
  double min_template_std = 2.0;    // grey level: flatter templates are rejected (no texture)
  double step = 1.0;                // px, sampling step along the epipolar segment

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct ZnccMatch {
  bool ok = false;
  Eigen::Vector2d right = Eigen::Vector2d::Zero();  // px, sub-pixel (parabola) position on the segment
  double score = -1;                                // ZNCC at the peak
  const char* why = "";                             // reason when !ok
};

// Searches `right` (CV_32FC1) along the segment from seg_start to seg_end
// (right-image px) for the window around left_px in `left` (CV_32FC1).
ZnccMatch ZnccAlongSegment(const cv::Mat& left, const cv::Mat& right, const Eigen::Vector2d& left_px,
                           const Eigen::Vector2d& seg_start, const Eigen::Vector2d& seg_end,
                           const ZnccOptions& options);

struct MedianFilterOptions {
  double radius = 50.0;           // px, neighbours are the points within this distance in the left image
  int min_neighbours = 3;         // fewer neighbours: the point is kept (cannot be judged)
  double abs_tolerance = 2.0;     // px, allowed |d - median(neighbours)|, plus ...
  double rel_tolerance = 0.15;    // ... this fraction of the median disparity

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// keep[i] = disparity i agrees with the median disparity of its neighbours.
std::vector<bool> MedianDisparityFilter(const std::vector<Eigen::Vector2d>& left_points,
                                        const std::vector<double>& disparities,
                                        const MedianFilterOptions& options);

}  // namespace vloc
