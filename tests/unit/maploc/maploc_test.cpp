// libs/maploc: map files, masked correlation, the rover's ground
// orthophoto against terrain truth, fixes against a rendered aerial map
// (accuracy and covariance against ground truth), and the honest failures:
// featureless sand, a wrong map, an older map with other rocks.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "../../../libs/maploc/src/masked_correlation.h"
#include "vloc/maploc/ground_ortho.h"
#include "vloc/maploc/map_registration.h"
#include "vloc/sim/uav_geo.h"
#include "vloc/testing/maploc_scenario.h"

namespace vloc::maploc {
namespace {

constexpr double kDeg = M_PI / 180.0;

MapRaster NoiseRaster(int rows, int cols, uint64_t seed) {
  MapRaster m;
  m.gray.create(rows, cols, CV_32F);
  cv::RNG rng(seed);
  rng.fill(m.gray, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(m.gray, m.gray, cv::Size(), 1.5);
  m.height = m.gray / 100.0;
  m.valid = cv::Mat(rows, cols, CV_8U, cv::Scalar(255));
  m.valid(cv::Rect(0, 0, 5, 5)).setTo(0);
  m.x_min = 100.0;
  m.y_max = 50.0;
  m.m_per_px = 0.25;
  return m;
}

std::filesystem::path TempDir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("vloc_maploc_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

TEST(MapRaster, GeoTiffAndPngWorldFileRoundTripWithTheirGeometry) {
  const auto dir = TempDir("files");
  const MapRaster m = NoiseRaster(40, 60, 1);
  std::string error;
  ASSERT_TRUE(WriteMapGeoTiff(m, (dir / "map.tif").string(), &error)) << error;
  MapRaster tif;
  ASSERT_TRUE(LoadMapRaster((dir / "map.tif").string(), &tif, &error, Eigen::Vector2d(100, 0))) << error;
  EXPECT_NEAR(tif.x_min, 0.0, 1e-9);  // offset subtracted
  EXPECT_NEAR(tif.y_max, 50.0, 1e-9);
  EXPECT_NEAR(tif.m_per_px, 0.25, 1e-12);
  ASSERT_TRUE(tif.has_height());
  EXPECT_LT(cv::norm(tif.gray, m.gray, cv::NORM_INF, m.valid), 1e-3);
  EXPECT_LT(cv::norm(tif.height, m.height, cv::NORM_INF, m.valid), 1e-6);
  EXPECT_EQ(cv::countNonZero(tif.valid != m.valid), 0);  // no-data kept as no-data
  ASSERT_TRUE(WriteMapPngWorld(m, (dir / "map.png").string(), &error)) << error;
  MapRaster png;
  ASSERT_TRUE(LoadMapRaster((dir / "map.png").string(), &png, &error)) << error;
  EXPECT_NEAR(png.x_min, 100.0, 1e-9);
  EXPECT_NEAR(png.y_max, 50.0, 1e-9);
  EXPECT_FALSE(png.has_height());
  EXPECT_LT(cv::norm(png.gray, m.gray, cv::NORM_INF, m.valid), 1.0);  // 8-bit
  const Eigen::Vector2d px = png.PixelOfWorld(png.WorldOfPixel(12.5, 7.25));
  EXPECT_NEAR(px.x(), 12.5, 1e-9);
  EXPECT_NEAR(px.y(), 7.25, 1e-9);
  std::filesystem::remove_all(dir);
}

TEST(MapRaster, BadFilesGiveOneLineNamingTheFile) {
  const auto dir = TempDir("bad");
  MapRaster m;
  std::string error;
  EXPECT_FALSE(LoadMapRaster((dir / "none.tif").string(), &m, &error));
  EXPECT_NE(error.find("no such file"), std::string::npos) << error;
  std::ofstream((dir / "junk.tif").string()) << "not a tiff";
  EXPECT_FALSE(LoadMapRaster((dir / "junk.tif").string(), &m, &error));
  EXPECT_NE(error.find("junk.tif"), std::string::npos) << error;
  cv::Mat img(10, 10, CV_8U, cv::Scalar(7));
  ASSERT_TRUE(cv::imwrite((dir / "noworld.png").string(), img));
  EXPECT_FALSE(LoadMapRaster((dir / "noworld.png").string(), &m, &error));
  EXPECT_NE(error.find("world file"), std::string::npos) << error;
  std::ofstream((dir / "noworld.pgw").string()) << "0.2\n0.1\n0.4\n0.2\n5\n5\n";  // A E - B D = 0
  EXPECT_FALSE(LoadMapRaster((dir / "noworld.png").string(), &m, &error));
  EXPECT_NE(error.find("no area"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);
  std::ofstream((dir / "noworld.pgw").string()) << "2e-6\n0\n0\n-2e-6\n9.19\n45.46\n";  // degrees
  EXPECT_FALSE(LoadMapRaster((dir / "noworld.png").string(), &m, &error));
  EXPECT_NE(error.find("map_geographic_origin"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);
  MapGeoreference geographic;
  geographic.geographic = true;
  geographic.origin_latitude = 45.46;
  geographic.origin_longitude = 9.19;
  std::ofstream((dir / "noworld.pgw").string()) << "0.2\n0\n0\n-0.2\n500100\n5040000\n";  // UTM metres
  EXPECT_FALSE(LoadMapRaster((dir / "noworld.png").string(), &m, &error, geographic));
  EXPECT_NE(error.find("not longitude / latitude"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);
  std::filesystem::remove_all(dir);
}

// A smooth pattern of the world position (period ~4 m: 5 cm of misplacement
// changes it by ~5 grey levels), for checking where a loaded map puts its cells.
double Pattern(const Eigen::Vector2d& xy) {
  return 128 + 50 * std::sin(1.6 * xy.x() + 0.3 * xy.y()) * std::cos(1.3 * xy.y() - 0.2 * xy.x());
}

// An 8-bit BGRA image whose pixel (c, r) shows Pattern at world_from_pixel(c, r);
// alpha 0 (no data) in its top-left corner block.
cv::Mat PatternImage(cv::Size size, const std::function<Eigen::Vector2d(double, double)>& world_from_pixel) {
  cv::Mat image(size, CV_8UC4);
  for (int r = 0; r < size.height; ++r)
    for (int c = 0; c < size.width; ++c) {
      const uint8_t g = cv::saturate_cast<uint8_t>(Pattern(world_from_pixel(c, r)));
      image.at<cv::Vec4b>(r, c) = cv::Vec4b(g, g, g, (r < 40 && c < 40) ? 0 : 255);
    }
  return image;
}

// Largest |loaded grey - Pattern| over valid cells; counts valid cells.
double PatternError(const MapRaster& map, int* valid_cells) {
  double worst = 0;
  *valid_cells = 0;
  for (int r = 0; r < map.gray.rows; ++r)
    for (int c = 0; c < map.gray.cols; ++c) {
      if (!map.valid.at<uint8_t>(r, c)) continue;
      ++*valid_cells;
      worst = std::max(worst, std::abs(map.gray.at<float>(r, c) - Pattern(map.WorldOfPixel(c, r))));
    }
  return worst;
}

TEST(MapRaster, RotatedWorldFileIsResampledNorthUpWithItsNoDataMasked) {
  const auto dir = TempDir("rotated");
  // 0.1 m cells turned 30 deg: x = A c + B r + C, y = D c + E r + F.
  const double s = 0.1, angle = 30 * kDeg;
  const double A = s * std::cos(angle), D = s * std::sin(angle), B = s * std::sin(angle), E = -s * std::cos(angle);
  const double C = 40.0, F = -12.0;
  const cv::Mat image = PatternImage(cv::Size(300, 200), [&](double c, double r) {
    return Eigen::Vector2d(A * c + B * r + C, D * c + E * r + F);
  });
  ASSERT_TRUE(cv::imwrite((dir / "rot.png").string(), image));
  std::ofstream((dir / "rot.pgw").string()) << A << "\n" << D << "\n" << B << "\n" << E << "\n" << C << "\n" << F << "\n";
  MapRaster map;
  std::string error;
  ASSERT_TRUE(LoadMapRaster((dir / "rot.png").string(), &map, &error)) << error;
  EXPECT_NEAR(map.m_per_px, s, 1e-6);  // same cell area (world file to 6 digits)
  // Footprint: the bounding box of the turned 30 x 20 m image.
  EXPECT_NEAR(map.gray.cols * s, 30 * std::cos(angle) + 20 * std::sin(angle), 2 * s);
  EXPECT_NEAR(map.gray.rows * s, 30 * std::sin(angle) + 20 * std::cos(angle), 2 * s);
  int valid = 0;
  EXPECT_LT(PatternError(map, &valid), 6.0);  // bilinear resampling + 8 bits; 5 cm off would give ~5 more
  EXPECT_NEAR(valid, 300 * 200 - 40 * 40, 0.03 * 300 * 200);  // the image's area less its alpha-0 corner
  // The alpha-0 corner (around pixel (20, 20) of the image) is no-data in the map.
  const Eigen::Vector2d corner = map.PixelOfWorld({A * 20 + B * 20 + C, D * 20 + E * 20 + F});
  EXPECT_EQ(map.valid.at<uint8_t>(static_cast<int>(std::lround(corner.y())), static_cast<int>(std::lround(corner.x()))), 0);
  // Resampled to a requested cell size on load.
  MapGeoreference coarse;
  coarse.m_per_px = 0.2;
  ASSERT_TRUE(LoadMapRaster((dir / "rot.png").string(), &map, &error, coarse)) << error;
  EXPECT_NEAR(map.m_per_px, 0.2, 2e-3);
  std::filesystem::remove_all(dir);
}

TEST(MapRaster, WorldFileInDegreesBecomesMetresAroundTheGeographicOrigin) {
  // A mosaic-like world file: lon / lat degrees, turned 15 deg, 8 cm cells, placed
  // 120 m east and 80 m north of the world origin (the UAV simulator's GPS origin).
  const LocalTangentPlane plane(45.4642, 9.19, 120.0);
  const double s = 0.08, angle = 15 * kDeg;
  auto metres_of_pixel = [&](double c, double r) {
    return Eigen::Vector2d(120 + s * (std::cos(angle) * c + std::sin(angle) * r),
                           80 + s * (std::sin(angle) * c - std::cos(angle) * r));
  };
  auto degrees_of_pixel = [&](double c, double r) {
    const Eigen::Vector2d m = metres_of_pixel(c, r);
    double lat, lon, alt;
    plane.ToGeodetic(m.x(), m.y(), 0, &lat, &lon, &alt);
    return Eigen::Vector2d(lon, lat);
  };
  const Eigen::Vector2d o = degrees_of_pixel(0, 0), dc = degrees_of_pixel(1, 0) - o, dr = degrees_of_pixel(0, 1) - o;
  const auto dir = TempDir("degrees");
  ASSERT_TRUE(cv::imwrite((dir / "mosaic.png").string(), PatternImage(cv::Size(320, 240), metres_of_pixel)));
  std::ofstream w((dir / "mosaic.pgw").string());
  w.precision(15);
  w << dc.x() << "\n" << dc.y() << "\n" << dr.x() << "\n" << dr.y() << "\n" << o.x() << "\n" << o.y() << "\n";
  w.close();
  MapGeoreference geo;
  geo.geographic = true;
  geo.origin_latitude = 45.4642;
  geo.origin_longitude = 9.19;
  MapRaster map;
  std::string error;
  ASSERT_TRUE(LoadMapRaster((dir / "mosaic.png").string(), &map, &error, geo)) << error;
  EXPECT_NEAR(map.m_per_px, s, 1e-4);
  int valid = 0;
  EXPECT_LT(PatternError(map, &valid), 6.0);
  EXPECT_GT(valid, 0.9 * (320 * 240 - 40 * 40));
  // The image's centre lands where it was drawn (to well under a cell).
  const Eigen::Vector2d centre = metres_of_pixel(159.5, 119.5);
  const Eigen::Vector2d mid = map.WorldOfPixel(0.5 * map.gray.cols - 0.5, 0.5 * map.gray.rows - 0.5);
  EXPECT_LT((mid - centre).norm(), 0.5 * s + 0.02);
  std::filesystem::remove_all(dir);
}

TEST(MaskedCorrelation, FindsAKnownShiftAndIgnoresMaskedCells) {
  const MapRaster m = NoiseRaster(80, 80, 2);
  const cv::Rect at(23, 31, 25, 25);
  cv::Mat templ = m.gray(at).clone(), mask(templ.size(), CV_32F, cv::Scalar(1));
  mask(cv::Rect(0, 0, 12, 25)).setTo(0);
  templ(cv::Rect(0, 0, 12, 25)).setTo(999);  // garbage under the mask
  cv::Mat valid(m.gray.size(), CV_32F, cv::Scalar(1));
  const cv::Mat score = internal::MaskedZncc(m.gray, valid, templ, mask, 0.9);
  double best;
  cv::Point where;
  cv::minMaxLoc(score, nullptr, &best, nullptr, &where);
  EXPECT_EQ(where, at.tl());
  EXPECT_NEAR(best, 1.0, 1e-4);
  // Rotation about a centre: a point 10 px east of it, turned by +90 deg (counter-clockwise), lands 10 px north.
  cv::Mat dot = cv::Mat::zeros(41, 41, CV_32F);
  dot.at<float>(20, 30) = 1;
  cv::Point peak;
  cv::minMaxLoc(internal::RotateAbout(dot, M_PI / 2, {20, 20}, cv::INTER_LINEAR), nullptr, nullptr, nullptr, &peak);
  EXPECT_EQ(peak, cv::Point(20, 10));
}

TEST(MaplocOptions, DefaultsPassTheirChecks) {
  std::string error;
  EXPECT_TRUE(RegistrationOptions().Check(&error)) << error;
  EXPECT_TRUE(GroundOrthoOptions().Check(&error)) << error;
  RegistrationOptions bad;
  bad.max_peak_ratio = 0;
  EXPECT_FALSE(bad.Check(&error));
}

// One scenario: world, map (maybe of another terrain), fixes of some sites.
struct SiteResult {
  MapFix fix;
  Pose3 truth;
  GroundOrthoSummary ortho;
};

std::vector<SiteResult> LocaliseSites(const testing::MaplocScenarioOptions& s, const std::vector<int>& sites,
                                      const sim::TerrainOptions* map_terrain = nullptr,
                                      const sim::TerrainOptions* world_terrain = nullptr, double sigma_xy = 1.0,
                                      MapRaster* ortho_out = nullptr, std::unique_ptr<sim::RoverWorld>* world_out = nullptr,
                                      int downsample = 2) {
  sim::RoverWorldOptions wo = testing::MaplocWorldOptions(s);
  if (world_terrain) wo.terrain = *world_terrain;
  auto world = std::make_unique<sim::RoverWorld>(wo);
  const MapRaster map = testing::RenderMapOf(map_terrain ? *map_terrain : wo.terrain, s);
  GroundOrthoOptions oo;
  oo.m_per_px = s.map_m_per_px;
  oo.downsample = downsample;
  std::mt19937 rng(s.seed);
  std::vector<SiteResult> out;
  for (int id : sites) {
    SiteResult r;
    r.truth = world->traverse().sites[id].world_from_body;
    const PoseWithCovariance prior = testing::NoisyPrior(r.truth, sigma_xy, 2 * kDeg, &rng);
    const Eigen::Vector3d rpy = RollPitchYawFromRotation(r.truth.linear());
    const MapRaster ortho = BuildGroundOrtho(world->RenderSite(id), wo.navcam, rpy.x(), rpy.y(), oo, &r.ortho);
    r.fix = RegisterToMap(ortho, map, SitePriorFromPose(prior), RegistrationOptions());
    if (ortho_out) *ortho_out = ortho;
    out.push_back(r);
  }
  if (world_out) *world_out = std::move(world);
  return out;
}

Eigen::Vector3d FixError(const SiteResult& r) {
  return {r.fix.xyh.x() - r.truth.translation().x(), r.fix.xyh.y() - r.truth.translation().y(),
          WrapAngle(r.fix.xyh.z() - Heading(r.truth))};
}

// Two sites of a 6-site traverse (512 px images at full size: the shipped
// 1024 px Navcam at map_localizer's downsample 2), map at 20 cm/px under another sun, prior
// 1 m / 2 deg off: every site fixed within 0.2 m and 0.5 deg of the truth, and
// within the 99.9 % ellipse of its covariance (16 sites: bench_maploc_sites), its height from
// the map's heights within 2 sigma. The orthophoto's heights agree
// with the terrain. (The NEES mean over many sites: bench_maploc_sites.)
TEST(MapLocalization, SitesFixedAgainstA20cmMapUnderAnotherSun) {
  testing::MaplocScenarioOptions s;
  MapRaster ortho;
  std::unique_ptr<sim::RoverWorld> world;
  const auto results = LocaliseSites(s, {1, 5}, nullptr, nullptr, 1.0, &ortho, &world, /*downsample=*/1);
  for (const SiteResult& r : results) {
    ASSERT_TRUE(r.fix.usable) << r.fix.BriefReport();
    const Eigen::Vector3d e = FixError(r);
    EXPECT_LT(e.head<2>().norm(), 0.2) << r.fix.BriefReport();
    EXPECT_LT(std::abs(e.z()), 0.5 * kDeg) << r.fix.BriefReport();
    const double nees = e.head<2>().dot(r.fix.covariance.topLeftCorner<2, 2>().inverse() * e.head<2>());
    EXPECT_LT(nees, 13.8) << "outside the 99.9 % ellipse: " << r.fix.BriefReport();
    EXPECT_GT(r.ortho.valid_cells, 2000);
    // The body's height from the map's heights, within its sigma (its floor: 5 cm).
    ASSERT_TRUE(r.fix.has_z);
    EXPECT_LT(std::abs(r.fix.z - r.truth.translation().z()), 2 * r.fix.z_sigma) << r.fix.BriefReport();
  }
  // The last site's orthophoto: cell heights vs the terrain under them (level frame -> world).
  const Pose3& truth = results.back().truth;
  const double h = Heading(truth);
  std::vector<double> dz;
  for (int r = 0; r < ortho.gray.rows; ++r)
    for (int c = 0; c < ortho.gray.cols; ++c) {
      if (!ortho.valid.at<uint8_t>(r, c)) continue;
      const Eigen::Vector2d p = ortho.WorldOfPixel(c, r);
      const Eigen::Vector2d w = truth.translation().head<2>() + Eigen::Rotation2Dd(h) * p;
      dz.push_back(ortho.height.at<float>(r, c) + truth.translation().z() - world->terrain().Height(w.x(), w.y()));
    }
  std::nth_element(dz.begin(), dz.begin() + dz.size() / 2, dz.end());
  EXPECT_LT(std::abs(dz[dz.size() / 2]), 0.05) << "median height difference, m";
}

// Featureless sand: no albedo texture, no rocks, no craters, no micro-relief.
// Stereo finds nothing to match: no fix, and the reason says why.
TEST(MapLocalization, FeaturelessSandGivesNoFixWithTheReason) {
  testing::MaplocScenarioOptions s;
  s.sites_xy = {0, 0, 8, 0};
  sim::TerrainOptions sand = testing::MaplocWorldOptions(s).terrain;
  sand.albedo_contrast = 0.0;
  sand.rock_density = 0.0;
  sand.crater_density = 0.0;
  sand.micro_slope = 0.0;
  sand.relief_amplitude_m = 0.05;
  const auto results = LocaliseSites(s, {1}, &sand, &sand);
  EXPECT_FALSE(results[0].fix.usable) << results[0].fix.BriefReport();
  EXPECT_NE(results[0].fix.message.find("featureless"), std::string::npos) << results[0].fix.message;
  std::printf("featureless sand: %s\n", results[0].fix.BriefReport().c_str());
}

// The wrong map (another terrain): no fix.
TEST(MapLocalization, WrongMapGivesNoFix) {
  testing::MaplocScenarioOptions s;
  s.sites_xy = {0, 0, 8, 2, 16, 0};
  sim::TerrainOptions other = testing::MaplocWorldOptions(s).terrain;
  other.seed = 99;
  const auto results = LocaliseSites(s, {1, 2}, &other);
  for (const SiteResult& r : results) {
    EXPECT_FALSE(r.fix.usable) << r.fix.BriefReport();
    EXPECT_TRUE(r.fix.message.find("weak correlation") != std::string::npos ||
                r.fix.message.find("ambiguous") != std::string::npos)
        << r.fix.message;
    std::printf("wrong map: %s\n", r.fix.BriefReport().c_str());
  }
}

// A map older than the rover's view: the rocks are different (another rock
// field over the same relief and craters). The fix may survive or fail, but
// a fix that survives must be right (within its 99.9 % ellipse).
TEST(MapLocalization, OlderMapWithOtherRocksGivesARightFixOrNone) {
  testing::MaplocScenarioOptions s;
  s.sites_xy = {0, 0, 8, 2, 16, 0};
  const sim::TerrainOptions now = testing::MaplocWorldOptions(s).terrain;
  sim::TerrainOptions older = now;
  older.rock_density = 2.0 * now.rock_density;  // a different rock field
  const auto results = LocaliseSites(s, {1, 2}, &older);
  for (const SiteResult& r : results) {
    std::printf("older map: %s\n", r.fix.BriefReport().c_str());
    if (!r.fix.usable) continue;
    const Eigen::Vector3d e = FixError(r);
    EXPECT_LT(e.head<2>().dot(r.fix.covariance.topLeftCorner<2, 2>().inverse() * e.head<2>()), 13.8)
        << r.fix.BriefReport();
  }
}

}  // namespace
}  // namespace vloc::maploc
