// map_localizer over real LCM (port 7897): a rendered aerial map (GeoTIFF,
// 20 cm/px, another sun) on disk, a simulated site's dead-reckoning prior and
// Navcam panorama in; SITE_POSE_FIX out within 0.2 m of the truth. Garbage on
// its channels and an implausible pair leave it running; a bad map file
// stops it with one error line naming the file.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>

#include "map_localizer_test_config.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/process.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/maploc/map_raster.h"
#include "vloc/site_pose_t.hpp"
#include "vloc/testing/maploc_scenario.h"
#include "vloc/testing/rover_inputs.h"
#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

constexpr double kDeg = M_PI / 180.0;

std::filesystem::path TempDir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("vloc_map_localizer_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

void WriteConfigs(const std::filesystem::path& dir, const std::string& map_path) {
  testing::WriteMapLocalizerConfigs(dir, map_path);
}

TEST(MapLocalizerProcess, PublishesAFixOfASimulatedSiteAndSurvivesGarbage) {
  const std::string url = testing::TestLcmUrl(7897);
  const auto dir = TempDir("fix");
  testing::MaplocScenarioOptions s;
  s.sites_xy = {0, 0, 8, 2};
  const sim::RoverWorld world(testing::MaplocWorldOptions(s));
  std::string error;
  ASSERT_TRUE(maploc::WriteMapGeoTiff(testing::RenderMapOf(world.options().terrain, s), (dir / "map.tif").string(),
                                      &error))
      << error;
  WriteConfigs(dir, (dir / "map.tif").string());
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  std::vector<site_pose_t> fixes;
  Subscribe<site_pose_t>(*transport, "SITE_POSE_FIX",
                         [&](const std::string&, const site_pose_t& m) { fixes.push_back(m); });
  testing::Subprocess proc({testing::BinPath("map_localizer"), "--config", (dir / "map_localizer.yaml").string(),
                            "--lcm-url", url});
  ASSERT_TRUE(proc.WaitForOutput(kReadyLine, 30)) << proc.output();
  // Garbage first: bytes that are no message, and a pair with an implausible count.
  const std::vector<uint8_t> junk(100, 0xab);
  transport->Publish("NAVCAM_STEREO", junk.data(), junk.size());
  transport->Publish("TRAVERSE", junk.data(), junk.size());
  StereoPair bad = testing::TexturelessPair(1, 0);
  bad.num_pairs = 1000;
  Publish(*transport, "NAVCAM_STEREO", StereoPairToMessage(bad, ImageEncoding::kPng));
  // Site 1: its dead-reckoning prior (0.7 m, 2 deg off) and its panorama.
  const Pose3 truth = world.traverse().sites[1].world_from_body;
  std::mt19937 rng(5);
  PoseWithCovariance prior = testing::NoisyPrior(truth, 0.7, 2 * kDeg, &rng);
  prior.utime = world.traverse().sites[1].arrived_utime;
  Publish(*transport, "SITE_POSE_DR", SitePoseToMessage(1, site_pose_t::SOURCE_DEAD_RECKONING, prior));
  for (const StereoPair& pair : world.RenderSite(1)) {
    Publish(*transport, "NAVCAM_STEREO", StereoPairToMessage(pair, ImageEncoding::kPng));
    transport->Handle(50);
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(40);
  while (fixes.empty() && std::chrono::steady_clock::now() < deadline) {
    transport->Handle(100);
    proc.Drain();
  }
  ASSERT_EQ(fixes.size(), 1u) << proc.output();
  EXPECT_EQ(fixes[0].site_id, 1);
  EXPECT_EQ(fixes[0].source, 4);
  const PoseWithCovariance fix = PoseFromMessage(fixes[0].pose);
  EXPECT_LT((fix.pose.translation() - truth.translation()).head<2>().norm(), 0.2);
  EXPECT_LT(std::abs(WrapAngle(Heading(fix.pose) - Heading(truth))), 1.0 * kDeg);
  EXPECT_LT(std::abs(fix.pose.translation().z() - truth.translation().z()), 0.1);  // from the map's heights
  EXPECT_GT(fix.covariance(0, 0), 0.0);
  EXPECT_LT(fix.covariance(0, 0), 0.04);  // sigma below 0.2 m
  EXPECT_EQ(fixes[0].utime, prior.utime);
  proc.Signal(SIGTERM);
  EXPECT_EQ(proc.WaitExit(20), 0) << proc.output();
  EXPECT_NE(proc.output().find("implausible site 1"), std::string::npos) << proc.output();
  EXPECT_NE(proc.output().find("1 fixes"), std::string::npos) << proc.output();
  std::filesystem::remove_all(dir);
}

TEST(MapLocalizerProcess, BadMapFileStopsWithOneErrorLine) {
  const auto dir = TempDir("bad");
  std::ofstream(dir / "map.tif") << "not a map";
  WriteConfigs(dir, (dir / "map.tif").string());
  testing::Subprocess proc({testing::BinPath("map_localizer"), "--config", (dir / "map_localizer.yaml").string(),
                            "--lcm-url", "memq://"});
  EXPECT_EQ(proc.WaitExit(20), 1) << proc.output();
  // The error lines: not glog's (the option echo), not GDAL's own.
  std::vector<std::string> lines;
  for (const std::string& line : testing::ErrorLines(proc.output()))
    if (line.rfind("map_localizer: ", 0) == 0 || line.find("ERROR") != std::string::npos) lines.push_back(line);
  ASSERT_EQ(lines.size(), 1u) << proc.output();
  EXPECT_NE(lines[0].find("map.tif"), std::string::npos) << lines[0];
  // The shipped config parses; the bad map (given by --map) still stops it at once.
  testing::Subprocess shipped({testing::BinPath("map_localizer"), "--config", "config/procs/map_localizer.yaml",
                               "--map", (dir / "map.tif").string(), "--lcm-url", "memq://"});
  EXPECT_EQ(shipped.WaitExit(20), 1) << shipped.output();
  EXPECT_NE(shipped.output().find("map_localizer: map " + (dir / "map.tif").string()), std::string::npos)
      << shipped.output();
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vloc
