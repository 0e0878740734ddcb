#pragma once
// Coarse registration of two images of the same ground by correlation of
// tiles: each tile of `moving` is searched in `fixed` within a radius of its
// own position (normalised cross-correlation on a reduced-resolution copy of
// both images). Used to turn a dead-reckoning prediction that is off by up
// to a few hundred pixels into one good to a few pixels before feature
// matching, using all the texture rather than the few features whose
// descriptors survive a large change of viewing distance.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace vloc {

class OptionsReader;

struct TileRegistrationOptions {
  int reduction = 4;               // both images are reduced by this factor (area average) before correlation
  int tile_px = 48;                // width of a tile in reduced px
  int tile_height_px = 4;           // height of a tile in reduced px (0 = tile_px); short, wide tiles suit a
                                   // grazing view, whose offsets change fast from row to row
  double min_coverage = 0.95;      // fraction of a tile's pixels that `moving_mask` must cover
  double min_tile_std = 2.0;       // grey level (reduced image): flatter tiles are not searched
  double min_ncc = 0.2;            // correlation peak needed
  double min_peak_margin = 0.03;   // peak minus the best score >= 3 reduced px away must reach this

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct TileMatch {
  Eigen::Vector2d moving_px = Eigen::Vector2d::Zero();  // full-resolution px, tile centre in `moving`
  Eigen::Vector2d fixed_px = Eigen::Vector2d::Zero();   // full-resolution px, where it lies in `fixed`
  double ncc = 0;                                       // correlation at the (integer) peak
  double margin = 0;                                    // peak minus the best score away from it
};

// Tiles of `moving` (CV_8UC1) whose correlation peak in `fixed` (CV_8UC1)
// within `search_radius_px` (full-resolution px) is clear. `moving_mask`
// (CV_8UC1, may be empty) marks valid pixels of `moving`. The peak is
// refined to sub-pixel (reduced grid) by a parabola fit in x and y.
std::vector<TileMatch> RegisterTiles(const cv::Mat& moving, const cv::Mat& moving_mask, const cv::Mat& fixed,
                                     double search_radius_px, const TileRegistrationOptions& options);

}  // namespace vloc
