// GIS products: the GeoTIFF's georeferencing read back with GDAL, the GeoJSON,
// and the route / height comparison against GPS.
#include <gtest/gtest.h>

#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <opencv2/imgproc.hpp>
#include <ogr_spatialref.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include "vloc/mosaic/gis_export.h"
#include "vloc/mosaic/survey_eval.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {
namespace {

constexpr double kLat0 = 30.1712, kLon0 = -98.0900;  // UTM zone 14 north

std::string TempPath(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / "vloc_gis_test";
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

TEST(GisExport, GeoTiffReadBackWithGdal) {
  // 300 x 200 px mosaic at 0.1 m/px, turned 20 deg from north-up; a red
  // square around pixel (220, 60).
  cv::Mat bgra(200, 300, CV_8UC4, cv::Scalar(90, 90, 90, 255));
  cv::rectangle(bgra, cv::Rect(210, 50, 21, 21), cv::Scalar(0, 0, 255, 255), cv::FILLED);
  const double res = 0.1, angle = 20 * M_PI / 180;
  auto enu_of = [&](const cv::Point2d& p) {
    const cv::Point2d v(p.x * res, -p.y * res);  // image y down = south
    return cv::Point2d(std::cos(angle) * v.x - std::sin(angle) * v.y, std::sin(angle) * v.x + std::cos(angle) * v.y);
  };
  auto lat_lon = [&](const cv::Point2d& p) {
    cv::Point2d ll;
    EnuToLatLon(enu_of(p), kLat0, kLon0, &ll.x, &ll.y);
    return ll;
  };
  const int epsg = UtmEpsg(kLat0, kLon0);
  ASSERT_EQ(epsg, 32614);
  const std::string path = TempPath("mosaic.tif");
  std::string error;
  ASSERT_TRUE(WriteGeoTiff(bgra, lat_lon, epsg, path, &error)) << error;

  GDALAllRegister();
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen(path.c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(ds->GetRasterCount(), 4);
  OGRSpatialReference srs(ds->GetProjectionRef());
  srs.AutoIdentifyEPSG();
  ASSERT_NE(srs.GetAuthorityCode(nullptr), nullptr);
  EXPECT_EQ(std::string(srs.GetAuthorityCode(nullptr)), "32614");
  double gt[6];
  ASSERT_EQ(ds->GetGeoTransform(gt), CE_None);
  // North-up, square pixels at the mosaic's ground resolution (UTM scale factor ~0.9996-1.0004 here).
  EXPECT_NEAR(gt[1], res, res * 2e-3);
  EXPECT_NEAR(gt[5], -res, res * 2e-3);
  EXPECT_EQ(gt[2], 0.0);
  EXPECT_EQ(gt[4], 0.0);
  // The red square's centre: its UTM coordinate from its lat/lon, then the
  // GeoTIFF pixel there must be red (within one pixel).
  std::vector<cv::Point2d> en;
  ASSERT_TRUE(LatLonToProjected(epsg, {lat_lon({220, 60})}, &en, &error)) << error;
  const int col = static_cast<int>(std::floor((en[0].x - gt[0]) / gt[1]));
  const int row = static_cast<int>(std::floor((en[0].y - gt[3]) / gt[5]));
  ASSERT_GE(col, 1);
  ASSERT_GE(row, 1);
  ASSERT_LT(col, ds->GetRasterXSize() - 1);
  ASSERT_LT(row, ds->GetRasterYSize() - 1);
  uint8_t rgba[4];
  for (int b = 0; b < 4; ++b)
    ASSERT_EQ(ds->GetRasterBand(b + 1)->RasterIO(GF_Read, col, row, 1, 1, &rgba[b], 1, 1, GDT_Byte, 0, 0), CE_None);
  EXPECT_GT(rgba[0], 200);
  EXPECT_LT(rgba[1], 60);
  EXPECT_LT(rgba[2], 60);
  EXPECT_EQ(rgba[3], 255);
  // A corner of the north-up raster lies outside the turned mosaic: transparent.
  uint8_t alpha = 1;
  ASSERT_EQ(ds->GetRasterBand(4)->RasterIO(GF_Read, 0, 0, 1, 1, &alpha, 1, 1, GDT_Byte, 0, 0), CE_None);
  EXPECT_EQ(alpha, 0);
  GDALClose(ds);
}

TEST(GisExport, GeoTiffRejectsBadInput) {
  std::string error;
  auto ll = [](const cv::Point2d&) { return cv::Point2d(kLat0, kLon0); };
  EXPECT_FALSE(WriteGeoTiff(cv::Mat(), ll, 32614, TempPath("empty.tif"), &error));
  EXPECT_FALSE(error.empty());
  error.clear();
  EXPECT_FALSE(WriteGeoTiff(cv::Mat(10, 10, CV_8UC4, cv::Scalar::all(255)), ll, 32614, TempPath("flat.tif"), &error));
  EXPECT_NE(error.find("degenerate"), std::string::npos) << error;
}

TEST(GisExport, RouteGeoJson) {
  std::vector<GeoFrame> frames(3);
  for (int i = 0; i < 3; ++i) {
    frames[i].name = "IMG_" + std::to_string(i) + ".jpg";
    frames[i].index = i;
    frames[i].latitude = kLat0 + i * 1e-4;
    frames[i].longitude = kLon0;
    frames[i].registered = i != 1;
    frames[i].status = i != 1 ? "TRACKING" : "LOST";
  }
  const std::string path = TempPath("route.geojson");
  std::string error;
  ASSERT_TRUE(WriteRouteGeoJson(frames, path, &error)) << error;
  // GDAL's GeoJSON driver reads it: one line layer feature + three points.
  GDALAllRegister();
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpenEx(path.c_str(), GDAL_OF_VECTOR, nullptr, nullptr, nullptr));
  ASSERT_NE(ds, nullptr);
  ASSERT_EQ(ds->GetLayerCount(), 1);
  OGRLayer* layer = ds->GetLayer(0);
  EXPECT_EQ(layer->GetFeatureCount(), 4);
  int lines = 0, points = 0, line_vertices = 0;
  for (auto& feature : *layer) {
    const OGRGeometry* g = feature->GetGeometryRef();
    ASSERT_NE(g, nullptr);
    if (wkbFlatten(g->getGeometryType()) == wkbLineString) {
      ++lines;
      line_vertices = g->toLineString()->getNumPoints();
    } else if (wkbFlatten(g->getGeometryType()) == wkbPoint) {
      ++points;
    }
  }
  EXPECT_EQ(lines, 1);
  EXPECT_EQ(points, 3);
  EXPECT_EQ(line_vertices, 2);  // the LOST frame is not on the route
  GDALClose(ds);
}

TEST(SurveyEval, RouteResidualAfterSimilarityFitMatchesTheNoise) {
  // GPS track: a lawnmower of 60 frames; the route is the same track in
  // mosaic px (turned, scaled, shifted, y down) plus 1.5 m of noise per axis.
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 1.5);
  std::vector<cv::Point2d> enu, route;
  const Similarity2 px_from_enu = Similarity2::FromScaleAngle(7.0, 0.4, 300, -120);
  for (int i = 0; i < 60; ++i) {
    const cv::Point2d e((i % 20) * 12.0 * ((i / 20) % 2 ? -1 : 1), (i / 20) * 40.0);
    enu.push_back(e);
    const cv::Point2d f = px_from_enu.Apply(e + cv::Point2d(noise(rng), noise(rng)));
    route.emplace_back(f.x, -f.y);
  }
  std::vector<bool> usable(60, true), in_fit(60, true);
  for (int i = 30; i < 36; ++i) in_fit[i] = false;  // a GPS drop-out
  usable[59] = false;
  const RouteComparison r = CompareRouteToGps(route, enu, usable, in_fit);
  ASSERT_TRUE(r.ok) << r.why;
  EXPECT_EQ(r.pairs, 53);
  EXPECT_EQ(r.held_out, 6);
  // 2-D noise of 1.5 m per axis: RMS distance 1.5 sqrt(2) = 2.1 m, less the 4 fitted parameters.
  EXPECT_NEAR(r.rms_m, 1.5 * std::sqrt(2.0), 0.5);
  EXPECT_LT(r.held_out_rms_m, 4.0);
  EXPECT_NEAR(r.enu_from_flipped.Scale(), 1.0 / 7.0, 0.01 / 7.0);
  EXPECT_GT(r.path_m, 600);
  EXPECT_TRUE(std::isnan(r.residual_m[59]));
}

TEST(SurveyEval, RobustRouteFitFlagsGpsJumpsAndKeepsTheNoiseFigure) {
  // The same lawnmower with 1.5 m of noise, and three fixes thrown 40-60 m
  // off (a consumer receiver's jumps): the robust fit names exactly those,
  // and its RMS over the rest matches the noise; least squares is pulled off.
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 1.5);
  std::vector<cv::Point2d> enu, route;
  const Similarity2 px_from_enu = Similarity2::FromScaleAngle(5.0, -1.1, -40, 75);
  for (int i = 0; i < 60; ++i) {
    const cv::Point2d e((i % 20) * 12.0 * ((i / 20) % 2 ? -1 : 1), (i / 20) * 40.0);
    const cv::Point2d f = px_from_enu.Apply(e + cv::Point2d(noise(rng), noise(rng)));
    route.emplace_back(f.x, -f.y);
    enu.push_back(e);
  }
  enu[12] += cv::Point2d(40, 0);
  enu[13] += cv::Point2d(0, -55);
  enu[41] += cv::Point2d(-42, 42);
  const std::vector<bool> all(60, true);
  RouteFitOptions plain;
  plain.robust = false;
  const RouteComparison ls = CompareRouteToGps(route, enu, all, all, plain);
  const RouteComparison robust = CompareRouteToGps(route, enu, all, all);
  ASSERT_TRUE(ls.ok && robust.ok);
  EXPECT_EQ(ls.gps_outliers, 0);
  EXPECT_EQ(robust.outlier_frames, (std::vector<int>{12, 13, 41}));
  EXPECT_NEAR(robust.inlier_rms_m, 1.5 * std::sqrt(2.0), 0.5);
  EXPECT_GT(ls.rms_m, 10.0);
  EXPECT_NEAR(robust.enu_from_flipped.Scale(), 1.0 / 5.0, 0.01 / 5.0);
  // Clean GPS: nothing is flagged (the 10 m floor is far above 1.5 m noise).
  std::vector<cv::Point2d> clean = enu;
  clean[12] -= cv::Point2d(40, 0);
  clean[13] -= cv::Point2d(0, -55);
  clean[41] -= cv::Point2d(-42, 42);
  EXPECT_EQ(CompareRouteToGps(route, clean, all, all).gps_outliers, 0);
}

TEST(SurveyEval, HeightsWithAndWithoutAFittedGround) {
  std::vector<double> h = {40, 50, 60, std::nan("")}, gps = {340.4, 349.6, 360.0, 380};
  const HeightComparison a = CompareHeights(h, gps, true);
  ASSERT_TRUE(a.ok);
  EXPECT_EQ(a.pairs, 3);
  EXPECT_NEAR(a.offset_m, 300.0, 1e-9);
  EXPECT_NEAR(a.rms_m, std::sqrt((0.16 + 0.16 + 0) / 3), 1e-9);
  const HeightComparison b = CompareHeights(h, {41, 49, 60, 1}, false);
  EXPECT_NEAR(b.rms_m, std::sqrt(2.0 / 3), 1e-9);
  EXPECT_NEAR(b.rms_percent, 100 * std::sqrt(2.0 / 3) / 50.0, 1e-9);  // mean reference 50 m
}

// Another tool's heights (scripts/survey_reference.py's TSV): comments
// skipped, the columns found by name; each kind of bad file refused in one
// line naming the file and the problem, nothing kept.
TEST(SurveyEval, ReferenceHeightsReadByColumnNameAndRefusedInOneLine) {
  auto write = [](const std::string& name, const std::string& text) {
    const std::string path = TempPath(name);
    std::ofstream(path) << text;
    return path;
  };
  std::map<std::string, double> heights;
  std::string error;
  const std::string good = write("good.tsv", "# made by a tool\nname\theight_m\teast_m\nA.jpg\t63.5\t1\nB.jpg\t64.25\t2\n");
  ASSERT_TRUE(ReadReferenceHeights(good, &heights, &error)) << error;
  ASSERT_EQ(heights.size(), 2u);
  EXPECT_EQ(heights.at("A.jpg"), 63.5);
  EXPECT_EQ(heights.at("B.jpg"), 64.25);
  const std::string swapped = write("swapped.tsv", "height_m\tname\n70\tC.jpg\n");
  ASSERT_TRUE(ReadReferenceHeights(swapped, &heights, &error)) << error;
  EXPECT_EQ(heights.at("C.jpg"), 70);
  // Written on Windows: a byte-order mark, CRLF line ends, a trailing empty field.
  const std::string crlf = write("crlf.tsv", "\xEF\xBB\xBFname\theight_m\tnote\r\nD.jpg\t71.5\t\r\n");
  ASSERT_TRUE(ReadReferenceHeights(crlf, &heights, &error)) << error;
  EXPECT_EQ(heights.at("D.jpg"), 71.5);

  const std::vector<std::pair<std::string, std::string>> bad = {
      {"no_columns.tsv", "name\theight\nA.jpg\t63\n"},
      {"word.tsv", "name\theight_m\nA.jpg\thigh\n"},
      {"negative.tsv", "name\theight_m\nA.jpg\t-3\n"},
      {"short.tsv", "name\theight_m\teast_m\nA.jpg\t63\n"},
      {"twice.tsv", "name\theight_m\nA.jpg\t63\nA.jpg\t64\n"},
      {"no_name.tsv", "name\theight_m\n\t63\n"},
      {"long.tsv", "name\theight_m\nA.jpg\t" + std::string(100000, '9') + "\x01\n"},
      {"empty.tsv", "# nothing\n"},
      {"header_only.tsv", "name\theight_m\n"}};
  const std::vector<std::string> why = {"columns name and height_m", "is not a height", "is not a height",
                                        "fields, the header 3", "twice", "no photo name", "\"9999", "no tab-separated header",
                                        "no photo"};
  for (size_t k = 0; k < bad.size(); ++k) {
    const std::string path = write(bad[k].first, bad[k].second);
    heights = {{"kept?", 1.0}};
    EXPECT_FALSE(ReadReferenceHeights(path, &heights, &error)) << bad[k].first;
    EXPECT_TRUE(heights.empty()) << bad[k].first;
    EXPECT_EQ(error.find("height reference " + path + ": "), 0u) << error;
    EXPECT_NE(error.find(why[k]), std::string::npos) << bad[k].first << ": " << error;
    EXPECT_EQ(error.find('\n'), std::string::npos) << error;
    EXPECT_LT(error.size(), 200 + path.size()) << "a hostile field is quoted short";
  }
  EXPECT_FALSE(ReadReferenceHeights(TempPath("no_such.tsv"), &heights, &error));
  EXPECT_NE(error.find("cannot be read"), std::string::npos) << error;
}

}  // namespace
}  // namespace vloc::mosaic
