// Map rasters: coordinates, GeoTIFF / PNG + world file input and output, resampling, cropping.
#include "vloc/maploc/map_raster.h"

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
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

// A map file before georeferencing: its bands (NaN = no data) in the file's
// pixel grid and the affine taking a pixel centre (col, row) to the file's
// coordinates (metres or degrees).
struct FileRaster {
  cv::Mat gray, height;
  cv::Matx23d file_from_pixel;
};

bool LoadGeoTiff(const std::string& path, FileRaster* raw, std::string* error) {
  RegisterGdal();
  CPLPushErrorHandler(CPLQuietErrorHandler);  // GDAL's own message goes into ours, not to stderr
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen(path.c_str(), GA_ReadOnly));
  const std::string gdal_message = CPLGetLastErrorMsg();
  CPLPopErrorHandler();
  if (!ds) return Fail(error, "map " + path + ": GDAL cannot open it as a GeoTIFF (" + gdal_message + ")");
  double gt[6];
  const bool geo = ds->GetGeoTransform(gt) == CE_None;
  const int bands = ds->GetRasterCount();
  bool ok = geo && bands >= 1;
  if (ok) {
    const bool colour = bands >= 3 && ds->GetRasterBand(1)->GetRasterDataType() == GDT_Byte;
    raw->gray = ReadBand(ds, 1);
    if (colour) {
      for (int b = 2; b <= 3; ++b) raw->gray += ReadBand(ds, b);
      raw->gray /= 3.0;
      if (bands >= 4) raw->gray.setTo(std::numeric_limits<float>::quiet_NaN(), ReadBand(ds, 4) == 0);  // alpha
    } else if (bands >= 2) {
      raw->height = ReadBand(ds, 2);
    }
    // The geotransform refers to the top-left corner of pixel (0, 0); its centre is half a cell in.
    raw->file_from_pixel = cv::Matx23d(gt[1], gt[2], gt[0] + 0.5 * (gt[1] + gt[2]),  //
                                       gt[4], gt[5], gt[3] + 0.5 * (gt[4] + gt[5]));
    ok = !raw->gray.empty() && (bands < 2 || colour || !raw->height.empty());
  }
  GDALClose(ds);
  if (!ok) return Fail(error, "map " + path + ": needs a geotransform and readable bands");
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

// World file lines A D B E C F: x = A col + B row + C, y = D col + E row + F
// at the centre of pixel (col, row).
bool ReadWorldFile(const std::string& image_path, cv::Matx23d* file_from_pixel, std::string* error) {
  for (const std::string& candidate : WorldFileCandidates(image_path)) {
    std::ifstream in(candidate);
    if (!in) continue;
    double v[6];
    for (int k = 0; k < 6; ++k)
      if (!(in >> v[k]) || !std::isfinite(v[k]))
        return Fail(error, "world file " + candidate + ": needs six finite numbers (A D B E C F)");
    if (!(std::abs(v[0] * v[3] - v[1] * v[2]) > 0))
      return Fail(error, "world file " + candidate + ": its cells have no area (A E - B D = 0)");
    *file_from_pixel = cv::Matx23d(v[0], v[2], v[4], v[1], v[3], v[5]);
    return true;
  }
  return Fail(error, "map " + image_path + ": no world file beside it (.pgw, .wld or <ext>w)");
}

bool LoadImageWithWorldFile(const std::string& path, FileRaster* raw, std::string* error) {
  const cv::Mat image = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (image.empty() || image.depth() != CV_8U) return Fail(error, "map " + path + ": cannot read it as an 8-bit image");
  if (!ReadWorldFile(path, &raw->file_from_pixel, error)) return false;
  cv::Mat gray, alpha;
  if (image.channels() == 4) cv::extractChannel(image, alpha, 3);
  if (image.channels() >= 3) cv::cvtColor(image, gray, image.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  else gray = image;
  gray.convertTo(raw->gray, CV_32F);
  raw->gray.setTo(std::numeric_limits<float>::quiet_NaN(), alpha.empty() ? (gray == 0) : (alpha == 0));
  raw->height.release();
  return true;
}

cv::Point2d Apply(const cv::Matx23d& m, const cv::Point2d& p) {
  return {m(0, 0) * p.x + m(0, 1) * p.y + m(0, 2), m(1, 0) * p.x + m(1, 1) * p.y + m(1, 2)};
}

// The affine taking file coordinates in WGS84 degrees to metres east / north of
// the origin: GDAL's transverse Mercator on the WGS84 ellipsoid centred there
// (the local tangent plane to < 1 cm within a few km), sampled at three corners.
bool DegreesToMetres(const cv::Matx23d& deg_from_pixel, cv::Size size, const MapGeoreference& geo,
                     const std::string& path, cv::Matx23d* metres_from_pixel, std::string* error) {
  const cv::Point2d corners[3] = {{0, 0}, {static_cast<double>(size.width), 0}, {0, static_cast<double>(size.height)}};
  double lon[3], lat[3];
  for (int k = 0; k < 3; ++k) {
    const cv::Point2d p = Apply(deg_from_pixel, corners[k]);
    lon[k] = p.x;
    lat[k] = p.y;
    if (!(std::abs(p.x) <= 180 && std::abs(p.y) <= 90))
      return Fail(error, "map " + path + ": coordinates (" + std::to_string(p.x) + ", " + std::to_string(p.y) +
                             ") are not longitude / latitude degrees; drop map_geographic_origin for a map in metres");
  }
  const double cell_deg = std::sqrt(std::abs(deg_from_pixel(0, 0) * deg_from_pixel(1, 1) -
                                             deg_from_pixel(0, 1) * deg_from_pixel(1, 0)));
  if (cell_deg > 0.01)
    return Fail(error, "map " + path + ": cells of " + std::to_string(cell_deg) +
                           " deg are not a local map (> 1 km); is the world file in degrees?");
  RegisterGdal();
  OGRSpatialReference wgs, local;
  wgs.importFromEPSG(4326);
  wgs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  local.SetWellKnownGeogCS("WGS84");
  local.SetTM(geo.origin_latitude, geo.origin_longitude, 1.0, 0.0, 0.0);
  local.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> t(OGRCreateCoordinateTransformation(&wgs, &local));
  if (!t || !t->Transform(3, lon, lat))
    return Fail(error, "map " + path + ": GDAL cannot turn its degrees into metres around the origin");
  const cv::Point2d e0(lon[0], lat[0]), ex = (cv::Point2d(lon[1], lat[1]) - e0) / size.width,
      ey = (cv::Point2d(lon[2], lat[2]) - e0) / size.height;
  *metres_from_pixel = cv::Matx23d(ex.x, ey.x, e0.x, ex.y, ey.y, e0.y);
  return true;
}

// A projected world file whose cells are below 0.1 mm and whose coordinates
// fit longitude / latitude is almost surely in degrees.
bool LooksLikeDegrees(const cv::Matx23d& m) {
  const double cell = std::max({std::abs(m(0, 0)), std::abs(m(0, 1)), std::abs(m(1, 0)), std::abs(m(1, 1))});
  return cell < 1e-4 && std::abs(m(0, 2)) <= 180 && std::abs(m(1, 2)) <= 90;
}

// Bands resampled north-up with square cells of `m_per_px` covering the
// footprint of `world_from_pixel`; cells reaching outside the source or onto
// its no-data are no-data.
MapRaster WarpNorthUp(const FileRaster& raw, const cv::Matx23d& world_from_pixel, double m_per_px) {
  double x_lo = 1e300, x_hi = -1e300, y_lo = 1e300, y_hi = -1e300;
  for (const cv::Point2d c : {cv::Point2d(-0.5, -0.5), cv::Point2d(raw.gray.cols - 0.5, -0.5),
                              cv::Point2d(-0.5, raw.gray.rows - 0.5), cv::Point2d(raw.gray.cols - 0.5, raw.gray.rows - 0.5)}) {
    const cv::Point2d w = Apply(world_from_pixel, c);
    x_lo = std::min(x_lo, w.x), x_hi = std::max(x_hi, w.x), y_lo = std::min(y_lo, w.y), y_hi = std::max(y_hi, w.y);
  }
  MapRaster out;
  out.m_per_px = m_per_px;
  out.x_min = x_lo;
  out.y_max = y_hi;
  const cv::Size size(std::max(1, static_cast<int>(std::ceil((x_hi - x_lo) / m_per_px))),
                      std::max(1, static_cast<int>(std::ceil((y_hi - y_lo) / m_per_px))));
  // Output cell (c, r) -> world -> source pixel.
  const cv::Matx33d world_from_out(m_per_px, 0, x_lo + 0.5 * m_per_px, 0, -m_per_px, y_hi - 0.5 * m_per_px, 0, 0, 1);
  const cv::Matx33d world_from_src(world_from_pixel(0, 0), world_from_pixel(0, 1), world_from_pixel(0, 2),
                                   world_from_pixel(1, 0), world_from_pixel(1, 1), world_from_pixel(1, 2), 0, 0, 1);
  const cv::Matx33d src_from_out = world_from_src.inv() * world_from_out;
  const cv::Matx23d warp = src_from_out.get_minor<2, 3>(0, 0);
  cv::Mat finite = raw.gray == raw.gray;  // false on NaN
  if (!raw.height.empty()) finite &= raw.height == raw.height;
  cv::Mat weight;
  finite.convertTo(weight, CV_32F, 1.0 / 255);
  auto warp_band = [&](const cv::Mat& band) {
    cv::Mat clean = band.clone(), warped;
    clean.setTo(0, ~finite);
    cv::warpAffine(clean, warped, warp, size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, 0);
    return warped;
  };
  const cv::Mat w = warp_band(weight);
  out.valid = w > 0.999f;  // every source pixel under the bilinear footprint observed
  out.gray = warp_band(raw.gray);
  out.gray.setTo(0, ~out.valid);
  if (!raw.height.empty()) {
    out.height = warp_band(raw.height);
    out.height.setTo(0, ~out.valid);
  }
  return out;
}

// The file's raster in the world frame: degrees -> metres, offset, north-up, cell size.
bool Georeference(FileRaster raw, const MapGeoreference& geo, const std::string& path, MapRaster* map,
                  std::string* error) {
  cv::Matx23d world_from_pixel = raw.file_from_pixel;
  if (geo.geographic) {
    if (!DegreesToMetres(raw.file_from_pixel, raw.gray.size(), geo, path, &world_from_pixel, error)) return false;
  } else if (LooksLikeDegrees(raw.file_from_pixel)) {
    return Fail(error, "map " + path + ": its coordinates look like longitude / latitude degrees; set "
                       "map_geographic_origin [lat, lon] (the world frame's origin) to read them");
  }
  world_from_pixel(0, 2) -= geo.offset_xy.x();
  world_from_pixel(1, 2) -= geo.offset_xy.y();
  const cv::Matx23d& m = world_from_pixel;
  const double cell = std::sqrt(std::abs(m(0, 0) * m(1, 1) - m(0, 1) * m(1, 0)));
  const double tolerance = 1e-9 * cell;
  const bool north_up = m(0, 0) > 0 && std::abs(m(0, 1)) <= tolerance && std::abs(m(1, 0)) <= tolerance &&
                        std::abs(m(0, 0) + m(1, 1)) <= tolerance;
  MapRaster out;
  if (north_up) {
    out.gray = raw.gray;
    out.height = raw.height;
    out.m_per_px = m(0, 0);
    out.x_min = m(0, 2) - 0.5 * m(0, 0);
    out.y_max = m(1, 2) + 0.5 * m(0, 0);
    MarkNoData(&out);
  } else {
    out = WarpNorthUp(raw, world_from_pixel, cell);
  }
  if (geo.m_per_px > 0) out = ResampleRaster(out, geo.m_per_px);
  *map = std::move(out);
  return true;
}

}  // namespace

bool LoadMapRaster(const std::string& path, MapRaster* map, std::string* error, const MapGeoreference& georeference) {
  if (!std::filesystem::is_regular_file(path)) return Fail(error, "map " + path + ": no such file");
  if (georeference.geographic &&
      !(std::abs(georeference.origin_latitude) <= 90 && std::abs(georeference.origin_longitude) <= 180))
    return Fail(error, "map " + path + ": the geographic origin must be [latitude, longitude] in degrees");
  if (!(georeference.m_per_px >= 0) || !std::isfinite(georeference.m_per_px))
    return Fail(error, "map " + path + ": the requested cell size must be >= 0 m (0 = the file's)");
  const std::string ext = Lower(std::filesystem::path(path).extension().string());
  FileRaster raw;
  const bool ok = (ext == ".tif" || ext == ".tiff") ? LoadGeoTiff(path, &raw, error)
                                                    : LoadImageWithWorldFile(path, &raw, error);
  MapRaster loaded;
  if (!ok || !Georeference(std::move(raw), georeference, path, &loaded, error)) return false;
  if (cv::countNonZero(loaded.valid) == 0) return Fail(error, "map " + path + ": every cell is no-data");
  if (!loaded.Check(error)) return Fail(error, "map " + path + ": " + *error);
  *map = std::move(loaded);
  return true;
}

bool LoadMapRaster(const std::string& path, MapRaster* map, std::string* error, const Eigen::Vector2d& offset_xy) {
  MapGeoreference georeference;
  georeference.offset_xy = offset_xy;
  return LoadMapRaster(path, map, error, georeference);
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
