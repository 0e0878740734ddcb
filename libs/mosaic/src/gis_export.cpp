#include "vloc/mosaic/gis_export.h"

#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <memory>
#include <mutex>

namespace vloc::mosaic {

namespace {
void InitGdalOnce() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

std::string JsonEscape(const std::string& s) {
  std::string out;
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += ' ';
    } else {
      out += c;
    }
  }
  return out;
}
}  // namespace

int UtmEpsg(double latitude, double longitude) {
  const int zone = std::clamp(static_cast<int>(std::floor((longitude + 180.0) / 6.0)) + 1, 1, 60);
  return (latitude >= 0 ? 32600 : 32700) + zone;
}

bool LatLonToProjected(int epsg, const std::vector<cv::Point2d>& lat_lon, std::vector<cv::Point2d>* east_north,
                       std::string* error) {
  InitGdalOnce();
  OGRSpatialReference wgs, proj;
  wgs.importFromEPSG(4326);
  wgs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  if (proj.importFromEPSG(epsg) != OGRERR_NONE) {
    if (error) *error = "unknown EPSG code " + std::to_string(epsg);
    return false;
  }
  proj.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> t(OGRCreateCoordinateTransformation(&wgs, &proj));
  if (!t) {
    if (error) *error = "GDAL cannot transform WGS84 to EPSG:" + std::to_string(epsg);
    return false;
  }
  std::vector<double> x, y;
  for (const auto& p : lat_lon) {
    x.push_back(p.y);
    y.push_back(p.x);
  }
  if (!t->Transform(static_cast<int>(x.size()), x.data(), y.data())) {
    if (error) *error = "GDAL failed to transform coordinates to EPSG:" + std::to_string(epsg);
    return false;
  }
  east_north->clear();
  for (size_t i = 0; i < x.size(); ++i) east_north->emplace_back(x[i], y[i]);
  return true;
}

namespace {

// The mosaic resampled north up in the projected system at its own ground
// resolution, and that raster's GDAL geotransform.
struct NorthUpRaster {
  cv::Mat bgra;
  double geotransform[6] = {0, 0, 0, 0, 0, 0};
};

// `bgra` resampled north up from its corners' projected coordinates `en`
// (top left, top right, bottom left): false with *error when the
// georeferencing is degenerate or the output implausibly large.
bool NorthUp(const cv::Mat& bgra, const std::vector<cv::Point2d>& en, NorthUpRaster* out, std::string* error) {
  const cv::Point2d o = en[0], ax = (en[1] - en[0]) / bgra.cols, ay = (en[2] - en[0]) / bgra.rows;
  // en(c, r) = o + c ax + r ay. North-up output at the same ground resolution.
  const double res = std::sqrt(std::abs(ax.x * ay.y - ax.y * ay.x));
  if (!(res > 0)) {
    if (error) *error = "GeoTIFF: degenerate georeferencing";
    return false;
  }
  const cv::Point2d corners[4] = {o, o + ax * bgra.cols, o + ay * bgra.rows, o + ax * bgra.cols + ay * bgra.rows};
  double e0 = corners[0].x, e1 = e0, n0 = corners[0].y, n1 = n0;
  for (const auto& c : corners) {
    e0 = std::min(e0, c.x), e1 = std::max(e1, c.x), n0 = std::min(n0, c.y), n1 = std::max(n1, c.y);
  }
  const int W = static_cast<int>(std::ceil((e1 - e0) / res)), H = static_cast<int>(std::ceil((n1 - n0) / res));
  if (W <= 0 || H <= 0 || double(W) * H > 4e8) {
    if (error) *error = "GeoTIFF: implausible output size " + std::to_string(W) + " x " + std::to_string(H);
    return false;
  }
  // Output pixel (u, v) -> en = (e0 + u res, n1 - v res) -> input (c, r) solving o + c ax + r ay.
  const cv::Matx22d A(ax.x, ay.x, ax.y, ay.y);
  const cv::Matx22d Ai = A.inv();
  const cv::Vec2d t0 = Ai * cv::Vec2d(e0 - o.x, n1 - o.y);
  const cv::Matx23d input_from_output(Ai(0, 0) * res, -Ai(0, 1) * res, t0[0], Ai(1, 0) * res, -Ai(1, 1) * res, t0[1]);
  cv::warpAffine(bgra, out->bgra, input_from_output, cv::Size(W, H), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                 cv::BORDER_CONSTANT, cv::Scalar(0, 0, 0, 0));
  const double gt[6] = {e0, res, 0.0, n1, 0.0, -res};
  std::copy(gt, gt + 6, out->geotransform);
  return true;
}

// The raster as a tiled, deflated RGBA GeoTIFF in EPSG `epsg`.
bool WriteGdalRgba(const NorthUpRaster& raster, int epsg, const std::string& path, std::string* error) {
  std::error_code ec;
  const std::filesystem::path p(path);
  if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path(), ec);
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (!driver) {
    if (error) *error = "GDAL has no GTiff driver";
    return false;
  }
  char** create_options = nullptr;
  create_options = CSLSetNameValue(create_options, "COMPRESS", "DEFLATE");
  create_options = CSLSetNameValue(create_options, "TILED", "YES");
  create_options = CSLSetNameValue(create_options, "PHOTOMETRIC", "RGB");
  create_options = CSLSetNameValue(create_options, "ALPHA", "YES");
  const int W = raster.bgra.cols, H = raster.bgra.rows;
  GDALDataset* ds = driver->Create(path.c_str(), W, H, 4, GDT_Byte, create_options);
  CSLDestroy(create_options);
  if (!ds) {
    if (error) *error = "cannot create GeoTIFF " + path + " (folder writable?)";
    return false;
  }
  double gt[6];
  std::copy(raster.geotransform, raster.geotransform + 6, gt);
  ds->SetGeoTransform(gt);
  OGRSpatialReference srs;
  srs.importFromEPSG(epsg);
  char* wkt = nullptr;
  srs.exportToWkt(&wkt);
  ds->SetProjection(wkt);
  CPLFree(wkt);
  std::vector<cv::Mat> channels;
  cv::split(raster.bgra, channels);  // B G R A
  const int order[4] = {2, 1, 0, 3};
  bool ok = true;
  for (int b = 0; b < 4 && ok; ++b) {
    GDALRasterBand* band = ds->GetRasterBand(b + 1);
    ok = band->RasterIO(GF_Write, 0, 0, W, H, channels[order[b]].data, W, H, GDT_Byte, 0, 0) == CE_None;
    if (b == 3) band->SetColorInterpretation(GCI_AlphaBand);
  }
  GDALClose(ds);
  if (!ok && error) *error = "cannot write the pixels of GeoTIFF " + path;
  return ok;
}

}  // namespace

bool WriteGeoTiff(const cv::Mat& bgra, const std::function<cv::Point2d(const cv::Point2d&)>& lat_lon_of_pixel, int epsg,
                  const std::string& path, std::string* error) {
  InitGdalOnce();
  if (bgra.empty() || bgra.type() != CV_8UC4) {
    if (error) *error = "GeoTIFF: the mosaic must be a non-empty BGRA image";
    return false;
  }
  // Affine pixel -> projected from three corners (exact for a similarity over a small area).
  const std::vector<cv::Point2d> px = {{0, 0}, {double(bgra.cols), 0}, {0, double(bgra.rows)}};
  std::vector<cv::Point2d> ll, en;
  for (const auto& p : px) ll.push_back(lat_lon_of_pixel(p));
  if (!LatLonToProjected(epsg, ll, &en, error)) return false;
  NorthUpRaster raster;
  return NorthUp(bgra, en, &raster, error) && WriteGdalRgba(raster, epsg, path, error);
}

bool WriteRouteGeoJson(const std::vector<GeoFrame>& frames, const std::string& path, std::string* error) {
  std::error_code ec;
  const std::filesystem::path p(path);
  if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path(), ec);
  std::ofstream out(path);
  if (!out) {
    if (error) *error = "cannot write GeoJSON " + path + " (folder writable?)";
    return false;
  }
  out << std::setprecision(10);
  out << "{\"type\": \"FeatureCollection\",\n \"features\": [\n";
  out << "  {\"type\": \"Feature\", \"properties\": {\"name\": \"route\"}, \"geometry\": {\"type\": \"LineString\", "
         "\"coordinates\": [";
  // JSON has no inf or nan: a height that is not finite is null, a position
  // that is not a position (not finite, outside WGS84) has no geometry.
  auto located = [](const GeoFrame& f) {
    return std::isfinite(f.latitude) && std::isfinite(f.longitude) && std::abs(f.latitude) <= 90 &&
           std::abs(f.longitude) <= 180;
  };
  bool first = true;
  for (const auto& f : frames) {
    if (!f.registered || !located(f)) continue;
    out << (first ? "" : ", ") << "[" << f.longitude << ", " << f.latitude << "]";
    first = false;
  }
  out << "]}}";
  for (const auto& f : frames) {
    out << ",\n  {\"type\": \"Feature\", \"properties\": {\"name\": \"" << JsonEscape(f.name) << "\", \"index\": " << f.index
        << ", \"status\": \"" << JsonEscape(f.status) << "\", \"height_m\": ";
    if (std::isfinite(f.height)) out << f.height;
    else out << "null";
    out << ", \"registered\": " << (f.registered ? "true" : "false") << "}, \"geometry\": ";
    if (located(f)) out << "{\"type\": \"Point\", \"coordinates\": [" << f.longitude << ", " << f.latitude << "]}}";
    else out << "null}";
  }
  out << "\n ]}\n";
  if (!out && error) *error = "cannot write GeoJSON " + path;
  return static_cast<bool>(out);
}

}  // namespace vloc::mosaic
