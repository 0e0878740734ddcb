#pragma once
// The ground texture the simulated UAV looks at: a north-up orthomap of the
// plane z = 0 (procedural, deterministic from a seed, or a user image with
// its metres per pixel), with an image pyramid for alias-free rendering at
// any height, plus a fine periodic "detail" texture that keeps the ground
// textured when the UAV flies low (20 m: ~2 cm per pixel).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace vloc {

class OptionsReader;

struct OrthomapOptions {
  int seed = 7;                     // procedural map seed (same seed, same bytes)
  double size = 420.0;              // m, side of the square procedural map
  double metres_per_pixel = 0.1;    // m/px of the procedural map (or of `image`)
  Eigen::Vector2d centre = Eigen::Vector2d(30.0, 85.0);  // m, world x/y of the map centre
  std::string image;                // path of a user orthomap (north up, BGR); empty = procedural
  double field_size = 40.0;         // m, typical side of a field
  int num_roads = 4;                // roads crossing the map (cars drive on them)
  int num_buildings = 60;           // rectangular roofs
  double tree_density = 0.012;      // trees per m^2 outside forests
  double detail_amplitude = 28.0;   // grey levels (1-sigma) of the fine detail texture; 0 = off
  double detail_metres_per_pixel = 0.01;  // m/px of the detail texture
  int detail_tile = 2048;           // px, side of the periodic detail tile (power of two)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// A polyline on the ground (world metres), e.g. a road centre line.
using GroundPath = std::vector<Eigen::Vector2d>;

class Orthomap {
 public:
  // Builds the procedural map or loads `image`. Throws std::runtime_error
  // with one line when the image cannot be read.
  explicit Orthomap(const OrthomapOptions& options);

  int NumLevels() const { return static_cast<int>(levels_.size()); }
  const cv::Mat& Level(int level) const { return levels_[level]; }  // CV_8UC3, BGR
  // Homogeneous world (x, y, 1) metres -> (col, row, 1) pixel of `level`.
  cv::Matx33d PixelFromWorld(int level) const;
  double metres_per_pixel() const { return mpp_; }
  // World rectangle covered: x in [min_x, max_x], y in [min_y, max_y], m.
  Eigen::Vector2d min_corner() const { return min_; }
  Eigen::Vector2d max_corner() const { return max_; }

  // Detail texture pyramid (CV_8UC1, mean 128, periodic) and its mapping.
  int NumDetailLevels() const { return static_cast<int>(detail_.size()); }
  const cv::Mat& DetailLevel(int level) const { return detail_[level]; }
  cv::Matx33d DetailPixelFromWorld(int level) const;
  double detail_metres_per_pixel() const { return options_.detail_metres_per_pixel; }

  // Road centre lines of the procedural map (empty for a user image).
  const std::vector<GroundPath>& roads() const { return roads_; }

 private:
  void BuildProcedural();
  void BuildDetail();

  OrthomapOptions options_;
  double mpp_ = 0.1;
  Eigen::Vector2d min_, max_;
  std::vector<cv::Mat> levels_;
  std::vector<cv::Mat> detail_;
  std::vector<GroundPath> roads_;
};

}  // namespace vloc
