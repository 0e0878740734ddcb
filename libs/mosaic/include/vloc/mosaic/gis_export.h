#pragma once
// GIS products of a georeferenced mosaic: a north-up GeoTIFF in the UTM zone
// of the flight (GDAL), and the route and frame centres as GeoJSON (WGS84
// lon/lat). Both open in QGIS.

#include <opencv2/core.hpp>
#include <functional>
#include <string>
#include <vector>

namespace vloc::mosaic {

// EPSG code of the WGS84 / UTM zone holding (lat, lon): 326zz north, 327zz south.
int UtmEpsg(double latitude, double longitude);

// WGS84 lat/lon (deg) -> easting/northing (m) in `epsg`; false when GDAL
// cannot transform.
bool LatLonToProjected(int epsg, const std::vector<cv::Point2d>& lat_lon, std::vector<cv::Point2d>* east_north,
                       std::string* error);

// Writes `bgra` (CV_8UC4, alpha = covered) as a north-up GeoTIFF (RGBA,
// deflate, tiled) in `epsg`. `lat_lon_of_pixel` maps a pixel (col, row) of
// `bgra` to WGS84 (lat, lon); it is sampled at three corners to build the
// affine pixel -> projected map, and the image is resampled north-up at
// the same ground resolution. False with one line in *error.
bool WriteGeoTiff(const cv::Mat& bgra, const std::function<cv::Point2d(const cv::Point2d&)>& lat_lon_of_pixel,
                  int epsg, const std::string& path, std::string* error);

// One frame of a flight, for the GeoJSON.
struct GeoFrame {
  std::string name;                 // e.g. the file name
  int index = 0;                    // frame index
  double latitude = 0, longitude = 0;  // deg, WGS84: the frame centre on the ground (estimated)
  std::string status;               // TRACKING, RECOVERED, LOST, ...
  double height = 0;                // m, estimated flight height
  bool registered = false;          // placed by image registration
};

// A FeatureCollection: one LineString "route" through the registered frames
// and one Point per frame (properties: name, index, status, height_m, registered).
bool WriteRouteGeoJson(const std::vector<GeoFrame>& frames, const std::string& path, std::string* error);

}  // namespace vloc::mosaic
