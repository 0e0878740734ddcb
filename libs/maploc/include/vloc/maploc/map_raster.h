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

// How a map file's coordinates become world metres (x east, y north).
struct MapGeoreference {
  Eigen::Vector2d offset_xy = Eigen::Vector2d::Zero();  // m, subtracted from projected map coordinates
  bool geographic = false;         // the file's coordinates are WGS84 degrees (x = longitude, y = latitude),
                                   // e.g. the UAV mosaicker's world file; they become metres east / north of
                                   // the origin below (transverse Mercator on the WGS84 ellipsoid, via GDAL)
  double origin_latitude = 0;      // deg, WGS84 latitude of the world frame's origin (geographic)
  double origin_longitude = 0;     // deg, WGS84 longitude of the world frame's origin (geographic)
  double m_per_px = 0;             // m, cell size of the loaded raster; 0 = the file's (a rotated or non-square
                                   // file: the side of a square of the same area)
};

// Reads a map. GeoTIFF (.tif/.tiff, via GDAL): band 1 = grey (several
// colour bands are averaged when there is no height band), a float band 2
// (when band 1 is not the first of 3-4 colour bands) = height in m. Other
// images (PNG, JPEG) need a world file beside them (.pgw, .pngw, .jgw, .wld
// or <file>w); grey 0 (or alpha 0, e.g. the mosaic's uncovered pixels)
// marks no data. A rotated or sheared geotransform / world file (B, D != 0)
// or non-square cells are resampled north-up (no-data outside the image).
// False with *error (one line) naming the file and the fix.
bool LoadMapRaster(const std::string& path, MapRaster* map, std::string* error, const MapGeoreference& georeference);
// The same for projected coordinates in metres: `offset_xy` is subtracted
// from the file's coordinates (projected map coordinates -> the world frame).
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
