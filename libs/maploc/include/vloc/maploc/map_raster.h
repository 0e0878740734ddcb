#pragma once
// A north-up raster over a level frame: the aerial map (world frame, x east,
// y north) or the rover's ground orthophoto (a site's level frame, x forward,
// y left). Column c, row r is the cell whose centre is at
//   x = x_min + (c + 0.5) * m_per_px,   y = y_max - (r + 0.5) * m_per_px.
//
//   vloc::maploc::MapRaster map;
//   if (!vloc::maploc::LoadMapRaster("map.tif", &map, &error)) ...   // GeoTIFF, or PNG + world file
//   Eigen::Vector2d xy = map.WorldOfPixel(col, row);

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>

namespace vloc::maploc {

struct MapRaster {
  cv::Mat gray;          // CV_32F, grey level (any gain: matching is gain-invariant)
  cv::Mat height;        // CV_32F, m, up; empty when the raster has no height
  cv::Mat valid;         // CV_8U, 255 = observed, 0 = unseen / no data
  double x_min = 0;      // m, x of the west (left) edge of column 0
  double y_max = 0;      // m, y of the north (top) edge of row 0
  double m_per_px = 0;   // m, cell size

  bool empty() const { return gray.empty(); }
  bool has_height() const { return !height.empty(); }
  Eigen::Vector2d WorldOfPixel(double col, double row) const;
  Eigen::Vector2d PixelOfWorld(const Eigen::Vector2d& xy) const;  // (col, row), fractional
  // Sizes and types agree, m_per_px > 0 and finite; false with *error naming what is wrong.
  bool Check(std::string* error) const;
};

// Reads a map. GeoTIFF (.tif/.tiff, via GDAL): band 1 = grey (several
// colour bands are averaged when there is no height band), a float band 2
// (when band 1 is not the first of 3-4 colour bands) = height in m; the
// geotransform must be north-up without rotation. Other images (PNG, JPEG)
// need a world file beside them (.pgw, .pngw, .jgw, .wld or <file>w);
// grey 0 (or alpha 0) marks no data. `offset_xy` is subtracted from the
// file's coordinates (projected map coordinates -> the world frame).
// False with *error naming the file and the fix.
bool LoadMapRaster(const std::string& path, MapRaster* map, std::string* error,
                   const Eigen::Vector2d& offset_xy = Eigen::Vector2d::Zero());

// Writes a GeoTIFF with band 1 = grey, band 2 = height (when present),
// float32, no-data cells NaN; LoadMapRaster reads it back.
bool WriteMapGeoTiff(const MapRaster& map, const std::string& path, std::string* error);
// Writes the grey band as an 8-bit PNG (no data = 0, data 1..255) and its world file (<path minus .png>.pgw).
bool WriteMapPngWorld(const MapRaster& map, const std::string& path, std::string* error);

// The raster resampled to `m_per_px` by masked area averaging (a cell of the
// result is valid when at least `min_valid_fraction` of it was valid). The
// extent keeps its centre.
MapRaster ResampleRaster(const MapRaster& raster, double m_per_px, double min_valid_fraction = 0.3);

// A sub-raster covering the square of half side `half_m` around `centre`
// (cells outside the source are invalid).
MapRaster CropRaster(const MapRaster& raster, const Eigen::Vector2d& centre, double half_m);

}  // namespace vloc::maploc
