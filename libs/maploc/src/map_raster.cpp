// Map rasters: coordinates, GeoTIFF / PNG + world file input and output, resampling, cropping.
#include "vloc/maploc/map_raster.h"

#include <gdal_priv.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "vloc/common/options.h"

namespace vloc::maploc {

Eigen::Vector2d MapRaster::WorldOfPixel(double col, double row) const {
  return {x_min + (col + 0.5) * m_per_px, y_max - (row + 0.5) * m_per_px};
}

Eigen::Vector2d MapRaster::PixelOfWorld(const Eigen::Vector2d& xy) const {
  return {(xy.x() - x_min) / m_per_px - 0.5, (y_max - xy.y()) / m_per_px - 0.5};
}

bool MapRaster::Check(std::string* error) const {
  if (gray.empty() || gray.type() != CV_32F) return Fail(error, "raster grey band missing or not float");
  if (valid.size() != gray.size() || valid.type() != CV_8U) return Fail(error, "raster valid mask missing or mis-sized");
  if (!height.empty() && (height.size() != gray.size() || height.type() != CV_32F))
    return Fail(error, "raster height band mis-sized or not float");
  if (!(m_per_px > 0) || !std::isfinite(m_per_px) || !std::isfinite(x_min) || !std::isfinite(y_max))
    return Fail(error, "raster geometry not finite or cell size not positive");
  return true;
}

namespace {

void RegisterGdal() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Invalid where a band is NaN or the grey is exactly `nodata`.
void MarkNoData(MapRaster* map) {
  map->valid = cv::Mat(map->gray.size(), CV_8U, cv::Scalar(255));
  for (int r = 0; r < map->gray.rows; ++r)
    for (int c = 0; c < map->gray.cols; ++c) {
      float& g = map->gray.at<float>(r, c);
      const bool bad_height = map->has_height() && !std::isfinite(map->height.at<float>(r, c));
      if (!std::isfinite(g) || bad_height) {
        map->valid.at<uint8_t>(r, c) = 0;
        g = 0;
        if (map->has_height()) map->height.at<float>(r, c) = 0;
      }
    }
}

cv::Mat ReadBand(GDALDataset* ds, int band) {
  cv::Mat m(ds->GetRasterYSize(), ds->GetRasterXSize(), CV_32F);
  GDALRasterBand* b = ds->GetRasterBand(band);
  if (b->RasterIO(GF_Read, 0, 0, m.cols, m.rows, m.data, m.cols, m.rows, GDT_Float32, 0, 0) != CE_None) return {};
  int has_nodata = 0;
  const double nodata = b->GetNoDataValue(&has_nodata);
  if (has_nodata) m.setTo(std::numeric_limits<float>::quiet_NaN(), m == static_cast<float>(nodata));
  return m;
}

bool LoadGeoTiff(const std::string& path, MapRaster* map, std::string* error) {
  RegisterGdal();
  CPLPushErrorHandler(CPLQuietErrorHandler);  // GDAL's own message goes into ours, not to stderr
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen(path.c_str(), GA_ReadOnly));
  const std::string gdal_message = CPLGetLastErrorMsg();
  CPLPopErrorHandler();
  if (!ds) return Fail(error, "map " + path + ": GDAL cannot open it as a GeoTIFF (" + gdal_message + ")");
  double gt[6];
  const bool geo = ds->GetGeoTransform(gt) == CE_None;
  const int bands = ds->GetRasterCount();
  bool ok = geo && gt[2] == 0 && gt[4] == 0 && gt[1] > 0 && std::abs(gt[1] + gt[5]) < 1e-9 * gt[1] && bands >= 1;
  if (ok) {
    const bool colour = bands >= 3 && ds->GetRasterBand(1)->GetRasterDataType() == GDT_Byte;
    map->gray = ReadBand(ds, 1);
    if (colour) {
      for (int b = 2; b <= 3; ++b) map->gray += ReadBand(ds, b);
      map->gray /= 3.0;
    } else if (bands >= 2) {
      map->height = ReadBand(ds, 2);
    }
    map->x_min = gt[0];
    map->y_max = gt[3];
    map->m_per_px = gt[1];
    ok = !map->gray.empty() && (bands < 2 || colour || !map->height.empty());
  }
  GDALClose(ds);
  if (!ok) return Fail(error, "map " + path + ": needs a north-up geotransform with square cells and readable bands");
  MarkNoData(map);
  return true;
}

std::vector<std::string> WorldFileCandidates(const std::string& path) {
  std::filesystem::path p(path);
  const std::string ext = Lower(p.extension().string());
  std::vector<std::string> out;
  for (const char* e : {".pgw", ".pngw", ".jgw", ".jpgw", ".wld"}) out.push_back(p.replace_extension(e).string());
  if (ext.size() >= 3) out.push_back(path.substr(0, path.size() - ext.size()) + ext.substr(0, 2) + ext.back() + "w");
  out.push_back(path + "w");
  return out;
}

bool ReadWorldFile(const std::string& image_path, double v[6], std::string* error) {
  for (const std::string& candidate : WorldFileCandidates(image_path)) {
    std::ifstream in(candidate);
    if (!in) continue;
    for (int k = 0; k < 6; ++k)
      if (!(in >> v[k]) || !std::isfinite(v[k]))
        return Fail(error, "world file " + candidate + ": needs six numbers (A D B E C F)");
    if (v[1] != 0 || v[2] != 0 || !(v[0] > 0) || std::abs(v[0] + v[3]) > 1e-9 * v[0])
      return Fail(error, "world file " + candidate + ": only north-up square cells are supported (D = B = 0, E = -A)");
    return true;
  }
  return Fail(error, "map " + image_path + ": no world file beside it (.pgw, .wld or <ext>w)");
}

bool LoadImageWithWorldFile(const std::string& path, MapRaster* map, std::string* error) {
  const cv::Mat image = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (image.empty() || image.depth() != CV_8U) return Fail(error, "map " + path + ": cannot read it as an 8-bit image");
  double v[6];
  if (!ReadWorldFile(path, v, error)) return false;
  cv::Mat gray, alpha;
  if (image.channels() == 4) cv::extractChannel(image, alpha, 3);
  if (image.channels() >= 3) cv::cvtColor(image, gray, image.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  else gray = image;
  gray.convertTo(map->gray, CV_32F);
  map->gray.setTo(std::numeric_limits<float>::quiet_NaN(), alpha.empty() ? (gray == 0) : (alpha == 0));
  map->height.release();
  map->m_per_px = v[0];
  map->x_min = v[4] - 0.5 * v[0];
  map->y_max = v[5] + 0.5 * v[0];
  MarkNoData(map);
  return true;
}

}  // namespace

bool LoadMapRaster(const std::string& path, MapRaster* map, std::string* error, const Eigen::Vector2d& offset_xy) {
  if (!std::filesystem::is_regular_file(path)) return Fail(error, "map " + path + ": no such file");
  const std::string ext = Lower(std::filesystem::path(path).extension().string());
  MapRaster loaded;
  const bool ok = (ext == ".tif" || ext == ".tiff") ? LoadGeoTiff(path, &loaded, error)
                                                    : LoadImageWithWorldFile(path, &loaded, error);
  if (!ok) return false;
  loaded.x_min -= offset_xy.x();
  loaded.y_max -= offset_xy.y();
  if (cv::countNonZero(loaded.valid) == 0) return Fail(error, "map " + path + ": every cell is no-data");
  if (!loaded.Check(error)) return Fail(error, "map " + path + ": " + *error);
  *map = std::move(loaded);
  return true;
}

bool WriteMapGeoTiff(const MapRaster& map, const std::string& path, std::string* error) {
  if (!map.Check(error)) return false;
  RegisterGdal();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (!driver) return Fail(error, "GDAL has no GTiff driver");
  const int bands = map.has_height() ? 2 : 1;
  GDALDataset* ds = driver->Create(path.c_str(), map.gray.cols, map.gray.rows, bands, GDT_Float32, nullptr);
  if (!ds) return Fail(error, "cannot create " + path);
  double gt[6] = {map.x_min, map.m_per_px, 0, map.y_max, 0, -map.m_per_px};
  ds->SetGeoTransform(gt);
  bool ok = true;
  for (int b = 0; b < bands; ++b) {
    cv::Mat band = (b == 0 ? map.gray : map.height).clone();
    band.setTo(std::numeric_limits<float>::quiet_NaN(), map.valid == 0);
    ok = ok && ds->GetRasterBand(b + 1)->RasterIO(GF_Write, 0, 0, band.cols, band.rows, band.data, band.cols,
                                                  band.rows, GDT_Float32, 0, 0) == CE_None;
  }
  GDALClose(ds);
  return ok || Fail(error, "cannot write " + path);
}

bool WriteMapPngWorld(const MapRaster& map, const std::string& path, std::string* error) {
  if (!map.Check(error)) return false;
  cv::Mat out;
  map.gray.convertTo(out, CV_8U);
  out.setTo(1, (out == 0) & (map.valid != 0));
  out.setTo(0, map.valid == 0);
  if (!cv::imwrite(path, out)) return Fail(error, "cannot write " + path);
  std::ofstream w(std::filesystem::path(path).replace_extension(".pgw"));
  w.precision(12);
  w << map.m_per_px << "\n0\n0\n" << -map.m_per_px << "\n"
    << map.x_min + 0.5 * map.m_per_px << "\n" << map.y_max - 0.5 * map.m_per_px << "\n";
  return w.good() || Fail(error, "cannot write the world file of " + path);
}

namespace {

// Masked area average of `band` into `size`: sum(band * valid) / sum(valid).
cv::Mat AreaAverage(const cv::Mat& band, const cv::Mat& weight, const cv::Mat& weight_small, cv::Size size) {
  cv::Mat weighted = band.mul(weight), small;
  cv::resize(weighted, small, size, 0, 0, cv::INTER_AREA);
  return small / cv::max(weight_small, 1e-6);
}

}  // namespace

MapRaster ResampleRaster(const MapRaster& raster, double m_per_px, double min_valid_fraction) {
  if (std::abs(m_per_px - raster.m_per_px) < 1e-9 * m_per_px) return raster;
  const double scale = raster.m_per_px / m_per_px;
  const cv::Size size(std::max(1, static_cast<int>(std::lround(raster.gray.cols * scale))),
                      std::max(1, static_cast<int>(std::lround(raster.gray.rows * scale))));
  cv::Mat weight, weight_small;
  raster.valid.convertTo(weight, CV_32F, 1.0 / 255);
  const int interpolation = scale < 1 ? cv::INTER_AREA : cv::INTER_LINEAR;
  cv::resize(weight, weight_small, size, 0, 0, interpolation);
  MapRaster out;
  out.m_per_px = raster.m_per_px * raster.gray.cols / size.width;
  const double cx = raster.x_min + 0.5 * raster.gray.cols * raster.m_per_px;
  const double cy = raster.y_max - 0.5 * raster.gray.rows * raster.m_per_px;
  out.x_min = cx - 0.5 * size.width * out.m_per_px;
  out.y_max = cy + 0.5 * size.height * out.m_per_px;
  out.gray = AreaAverage(raster.gray, weight, weight_small, size);
  if (raster.has_height()) out.height = AreaAverage(raster.height, weight, weight_small, size);
  out.valid = weight_small >= min_valid_fraction;
  return out;
}

MapRaster CropRaster(const MapRaster& raster, const Eigen::Vector2d& centre, double half_m) {
  const Eigen::Vector2d px = raster.PixelOfWorld(centre);
  const int half = static_cast<int>(std::ceil(half_m / raster.m_per_px));
  const int c0 = static_cast<int>(std::lround(px.x())) - half, r0 = static_cast<int>(std::lround(px.y())) - half;
  const cv::Rect want(c0, r0, 2 * half + 1, 2 * half + 1);
  const cv::Rect have = want & cv::Rect(0, 0, raster.gray.cols, raster.gray.rows);
  MapRaster out;
  out.m_per_px = raster.m_per_px;
  out.x_min = raster.x_min + c0 * raster.m_per_px;
  out.y_max = raster.y_max - r0 * raster.m_per_px;
  out.gray = cv::Mat::zeros(want.size(), CV_32F);
  out.valid = cv::Mat::zeros(want.size(), CV_8U);
  if (raster.has_height()) out.height = cv::Mat::zeros(want.size(), CV_32F);
  if (have.empty()) return out;
  const cv::Rect dst(have.x - c0, have.y - r0, have.width, have.height);
  raster.gray(have).copyTo(out.gray(dst));
  raster.valid(have).copyTo(out.valid(dst));
  if (raster.has_height()) raster.height(have).copyTo(out.height(dst));
  return out;
}

}  // namespace vloc::maploc
