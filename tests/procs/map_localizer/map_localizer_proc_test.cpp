// map_localizer over real LCM (ports 7897, 7835): a rendered aerial map (GeoTIFF,
// 20 cm/px, another sun) on disk, a simulated site's dead-reckoning prior and
// Navcam panorama in; SITE_POSE_FIX out within 0.2 m of the truth. Garbage on
// its channels and an implausible pair leave it running; a site that came
// before the map file waits for it; a bad map file stops it with one error
// line naming the file.
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

// map_localizer started on `url` with the configs in `dir`, and the fixes it publishes.
struct Running {
  std::unique_ptr<Transport> transport;
  std::vector<site_pose_t> fixes;
  std::unique_ptr<testing::Subprocess> proc;
};
void Start(const std::string& url, const std::filesystem::path& dir, Running* r) {
  std::string error;
  r->transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(r->transport) << error;
  Subscribe<site_pose_t>(*r->transport, "SITE_POSE_FIX",
                         [r](const std::string&, const site_pose_t& m) { r->fixes.push_back(m); });
  r->proc = std::make_unique<testing::Subprocess>(std::vector<std::string>{
      testing::BinPath("map_localizer"), "--config", (dir / "map_localizer.yaml").string(), "--lcm-url", url});
  ASSERT_TRUE(r->proc->WaitForOutput(kReadyLine, 30)) << r->proc->output();
}

// The world both fix tests drive in: sites at (0, 0) and (8, 2) m.
testing::MaplocScenarioOptions TwoSites() {
  testing::MaplocScenarioOptions s;
  s.sites_xy = {0, 0, 8, 2};
  return s;
}

// Site `site`'s dead-reckoning prior (0.7 m, 2 deg off the truth) and its panorama on the bus; returns the prior.
PoseWithCovariance PublishSite(Transport& transport, const sim::RoverWorld& world, int site) {
  std::mt19937 rng(5);
  PoseWithCovariance prior = testing::NoisyPrior(world.traverse().sites[site].world_from_body, 0.7, 2 * kDeg, &rng);
  prior.utime = world.traverse().sites[site].arrived_utime;
  Publish(transport, "SITE_POSE_DR", SitePoseToMessage(site, site_pose_t::SOURCE_DEAD_RECKONING, prior));
  for (const StereoPair& pair : world.RenderSite(site)) {
    Publish(transport, "NAVCAM_STEREO", StereoPairToMessage(pair, ImageEncoding::kPng));
    transport.Handle(50);
  }
  return prior;
}

// Handles `transport` until `fixes` holds one or `seconds` pass.
void WaitForAFix(Transport& transport, testing::Subprocess& proc, const std::vector<site_pose_t>& fixes,
                 double seconds) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (fixes.empty() && std::chrono::steady_clock::now() < deadline) {
    transport.Handle(100);
    proc.Drain();
  }
}

TEST(MapLocalizerProcess, PublishesAFixOfASimulatedSiteAndSurvivesGarbage) {
  const std::string url = testing::TestLcmUrl(7897);
  const auto dir = TempDir("fix");
  const testing::MaplocScenarioOptions s = TwoSites();
  const sim::RoverWorld world(testing::MaplocWorldOptions(s));
  std::string error;
  ASSERT_TRUE(maploc::WriteMapGeoTiff(testing::RenderMapOf(world.options().terrain, s), (dir / "map.tif").string(),
                                      &error))
      << error;
  WriteConfigs(dir, (dir / "map.tif").string());
  Running r;
  ASSERT_NO_FATAL_FAILURE(Start(url, dir, &r));
  Transport* transport = r.transport.get();
  const std::vector<site_pose_t>& fixes = r.fixes;
  testing::Subprocess& proc = *r.proc;
  // Garbage first: bytes that are no message, and a pair with an implausible count.
  const std::vector<uint8_t> junk(100, 0xab);
  transport->Publish("NAVCAM_STEREO", junk.data(), junk.size());
  transport->Publish("TRAVERSE", junk.data(), junk.size());
  StereoPair bad = testing::TexturelessPair(1, 0);
  bad.num_pairs = 1000;
  Publish(*transport, "NAVCAM_STEREO", StereoPairToMessage(bad, ImageEncoding::kPng));
  // Site 1: its dead-reckoning prior and its panorama.
  const Pose3 truth = world.traverse().sites[1].world_from_body;
  const PoseWithCovariance prior = PublishSite(*transport, world, 1);
  WaitForAFix(*transport, proc, fixes, 40);
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

// The map is not there when the rover's site arrives (a UAV mosaic still
// being flown, wait_for_map_s): the site waits for the map file; the first
// map does not reach it (no fix), the next, rewritten in its place, does:
// the site is tried again and localised (each written elsewhere and renamed
// into place, as the mosaicker does).
TEST(MapLocalizerProcess, ASiteThatCameBeforeTheMapIsLocalisedOnceAMapReachesIt) {
  const std::string url = testing::TestLcmUrl(7835);
  const auto dir = TempDir("late_map");
  const testing::MaplocScenarioOptions s = TwoSites();
  const sim::RoverWorld world(testing::MaplocWorldOptions(s));
  WriteConfigs(dir, (dir / "map.tif").string());
  std::ofstream(dir / "map_localizer.yaml", std::ios::app) << "wait_for_map_s: 60\n";
  Running r;
  ASSERT_NO_FATAL_FAILURE(Start(url, dir, &r));
  PublishSite(*r.transport, world, 1);
  WaitForAFix(*r.transport, *r.proc, r.fixes, 2);
  EXPECT_TRUE(r.fixes.empty()) << "a fix without a map";
  maploc::MapRaster map = testing::RenderMapOf(world.options().terrain, s);
  const auto put_map = [&](const maploc::MapRaster& m) {
    std::string error;
    ASSERT_TRUE(maploc::WriteMapGeoTiff(m, (dir / "map.part").string(), &error)) << error;
    std::filesystem::rename(dir / "map.part", dir / "map.tif");
  };
  map.x_min += 500;  // 500 m east of the site
  put_map(map);
  WaitForAFix(*r.transport, *r.proc, r.fixes, 5);
  EXPECT_TRUE(r.fixes.empty()) << "a fix on a map that does not cover the site";
  map.x_min -= 500;
  put_map(map);
  WaitForAFix(*r.transport, *r.proc, r.fixes, 40);
  const std::string& output = r.proc->output();
  ASSERT_EQ(r.fixes.size(), 1u) << output;
  EXPECT_EQ(r.fixes[0].site_id, 1);
  const Pose3 truth = world.traverse().sites[1].world_from_body;
  EXPECT_LT((PoseFromMessage(r.fixes[0].pose).pose.translation() - truth.translation()).head<2>().norm(), 0.2);
  r.proc->Signal(SIGTERM);
  EXPECT_EQ(r.proc->WaitExit(20), 0) << output;
  EXPECT_NE(output.find("1 sites waited for it"), std::string::npos) << output;
  EXPECT_NE(output.find("site 1: tried again on the new map"), std::string::npos) << output;
  EXPECT_NE(output.find("1 fixes, 0 sites without a fix"), std::string::npos) << output;
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
  // A map that never comes: one line once wait_for_map_s has passed.
  WriteConfigs(dir, (dir / "never.tif").string());
  std::ofstream(dir / "map_localizer.yaml", std::ios::app) << "wait_for_map_s: 0.5\n";
  testing::Subprocess never({testing::BinPath("map_localizer"), "--config", (dir / "map_localizer.yaml").string(),
                             "--lcm-url", "memq://"});
  EXPECT_EQ(never.WaitExit(20), 1) << never.output();
  EXPECT_NE(never.output().find("did not appear within wait_for_map_s 0.5 s"), std::string::npos) << never.output();
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vloc
