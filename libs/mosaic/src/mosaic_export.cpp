// The mosaicker's products: preview, PNG + world file, GeoTIFF (uav_mosaicker.h).
#include <glog/logging.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>

#include "vloc/mosaic/gis_export.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {

namespace {
constexpr double kEarthRadius = 6378137.0;
constexpr double kDeg = M_PI / 180.0;
}  // namespace

cv::Mat UavMosaicker::Preview(int max_side, bool draw_route) const {
  double scale = 1;
  cv::Point2d origin;
  cv::Mat preview = blender_.Preview(max_side, &scale, &origin);
  if (preview.empty() || !draw_route || route_.size() < 2) return preview;
  preview = preview.clone();
  const size_t step = std::max<size_t>(1, route_.size() / 2000);
  for (size_t i = step; i < route_.size(); i += step) {
    const cv::Point2d a = (route_[i - step] - origin) * scale, b = (route_[i] - origin) * scale;
    cv::line(preview, a, b, cv::Scalar(0, 0, 255), 1, cv::LINE_AA);
  }
  cv::circle(preview, (route_.back() - origin) * scale, 3, cv::Scalar(0, 255, 255), -1);
  return preview;
}

bool UavMosaicker::WriteMosaic(const std::string& png_path, std::string* error) {
  cv::Mat bgra;
  double scale = 1;
  cv::Point2d origin;
  if (!blender_.Export(&bgra, &scale, &origin, error)) return false;
  std::error_code ec;
  const std::filesystem::path path(png_path);
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path(), ec);
  // Written under temporary names, then renamed world file first, image last:
  // a reader watching the image (map_localizer) never sees half a file or an
  // image with another export's world file.
  std::filesystem::path world = path, tmp_png = path, tmp_world;
  world.replace_extension(".pgw");
  tmp_png.replace_filename("." + path.stem().string() + ".writing" + path.extension().string());
  tmp_world = tmp_png;
  tmp_world.replace_extension(".pgw");
  bool written = false;
  try {
    written = cv::imwrite(tmp_png.string(), bgra);
  } catch (const cv::Exception& e) {
    written = false;
  }
  if (!written) {
    std::filesystem::remove(tmp_png, ec);
    if (error) *error = "cannot write " + png_path + " (folder writable? name ends in .png?)";
    return false;
  }
  const std::optional<Similarity2>& enu_from_flipped = gps_.enu_from_flipped();
  if (enu_from_flipped && gps_.origin()) {
    // pixel (col,row) -> mosaic px origin + (col,row)/scale -> (x,-y) -> ENU -> lon/lat.
    const Similarity2& T = *enu_from_flipped;
    const double lat0 = gps_.origin()->latitude, lon0 = gps_.origin()->longitude;
    const double ke = 1.0 / (kEarthRadius * std::cos(lat0 * kDeg)) / kDeg, kn = 1.0 / kEarthRadius / kDeg;
    const double a = T.a, b = T.b, s = scale, ox = origin.x, oy = origin.y;
    std::ofstream out(tmp_world);
    out << std::setprecision(12) << ke * a / s << "\n"
        << kn * b / s << "\n"
        << ke * b / s << "\n"
        << -kn * a / s << "\n"
        << lon0 + ke * (a * ox + b * oy + T.tx) << "\n"
        << lat0 + kn * (b * ox - a * oy + T.ty) << "\n";
    out.close();
    if (!out) {
      std::filesystem::remove(tmp_world, ec);
      if (error) *error = "mosaic written but not its world file " + world.string();
    } else {
      std::filesystem::rename(tmp_world, world, ec);
    }
  } else {
    std::filesystem::remove(world, ec);
  }
  std::filesystem::rename(tmp_png, path, ec);
  if (ec) {
    if (error) *error = "cannot rename " + tmp_png.string() + " to " + png_path + ": " + ec.message();
    return false;
  }
  LOG(INFO) << "mosaic written: " << png_path << " (" << bgra.cols << "x" << bgra.rows << ", "
            << metres_per_pixel_ / scale << " m/px" << (enu_from_flipped ? ", world file " + world.string() : "")
            << ")";
  return true;
}

bool UavMosaicker::MosaicToLatLon(const cv::Point2d& mosaic_px, cv::Point2d* lat_lon) const {
  return gps_.MosaicToLatLon(mosaic_px, lat_lon);
}

bool UavMosaicker::WriteGeoTiff(const std::string& tif_path, std::string* error) {
  if (!blender_.started() || !gps_.tied() || !gps_.origin()) {
    if (error) *error = "no GeoTIFF for " + tif_path + ": the mosaic is not tied to GPS (no geotags or too few)";
    return false;
  }
  cv::Mat bgra;
  double scale = 1;
  cv::Point2d origin;
  if (!blender_.Export(&bgra, &scale, &origin, error)) return false;
  auto lat_lon_of_pixel = [&](const cv::Point2d& p) {
    cv::Point2d ll;
    MosaicToLatLon(origin + p * (1.0 / scale), &ll);
    return ll;
  };
  const int epsg = UtmEpsg(gps_.origin()->latitude, gps_.origin()->longitude);
  if (!vloc::mosaic::WriteGeoTiff(bgra, lat_lon_of_pixel, epsg, tif_path, error)) return false;
  LOG(INFO) << "GeoTIFF written: " << tif_path << " (EPSG:" << epsg << ")";
  return true;
}

}  // namespace vloc::mosaic
