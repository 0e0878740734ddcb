// feature_frontend's revisits over real LCM (port 7786): six sites whose
// dead reckoning brings site 5 back within 0.5 m of site 1 (4 ids back). The
// front end must, besides the adjacent pairs, match site 5 against site 1,
// whose images it has by then moved to the site cache (max_sites_in_memory 1),
// and say so in FRONTEND_STATUS (previous_site_id 1). Textureless images keep
// it fast: every pair ends LOW_TEXTURE, which is still answered.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>

#include "vloc/testing/rover_inputs.h"
#include "vloc/frontend_status_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

TEST(RevisitFrontendProcess, NewSiteNearAnEarlierOneIsAlsoMatchedAgainstIt) {
  const std::string url = testing::TestLcmUrl(7786);
  const auto dir = std::filesystem::temp_directory_path() / "vloc_revisit_frontend_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string config = (dir / "feature_frontend.yaml").string(), cache = (dir / "sites").string();
  {  // The shipped config, calibration included by absolute path, one site in memory.
    std::ifstream in("config/procs/feature_frontend.yaml");
    std::ofstream out(config);
    for (std::string line; std::getline(in, line);) {
      if (line.rfind("navcam:", 0) == 0) line = "navcam: {include: " VLOC_SOURCE_DIR "/config/navcam.yaml}";
      if (line.rfind("max_sites_in_memory:", 0) == 0) line = "max_sites_in_memory: 1";
      out << line << "\n";
    }
  }
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  std::set<std::pair<int, int>> pairs;
  Subscribe<frontend_status_t>(*transport, "FRONTEND_STATUS", [&](const std::string&, const frontend_status_t& m) {
    pairs.emplace(m.previous_site_id, m.current_site_id);
  });
  testing::Subprocess proc(
      {testing::BinPath("feature_frontend"), "--config", config, "--lcm-url", url, "--site-cache", cache});
  ASSERT_TRUE(proc.WaitForOutput("feature_frontend: waiting for", 30)) << proc.output();
  // A loop: east along y = 0, north, back west, and down to site 1's place.
  const double xy[6][2] = {{0, 0}, {8, 0}, {16, 0}, {16, 8}, {8, 8}, {8.3, 0.4}};
  for (int site = 0; site < 6; ++site) {
    PoseWithCovariance pose;
    pose.pose = MakePose(xy[site][0], xy[site][1], 0, 0, 0, site == 5 ? 0.1 : 0.0);
    pose.covariance = (0.01 + 0.1 * site) * Matrix6d::Identity();
    Publish(*transport, "SITE_POSE_DR", SitePoseToMessage(site, site_pose_t::SOURCE_DEAD_RECKONING, pose));
    for (int k = 0; k < 3; ++k) {
      Publish(*transport, "NAVCAM_STEREO", StereoPairToMessage(testing::TexturelessPair(site, k), ImageEncoding::kPng));
      transport->Handle(20);
    }
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(90);
  while (!pairs.count({1, 5}) && std::chrono::steady_clock::now() < deadline) transport->Handle(100);
  EXPECT_TRUE(pairs.count({1, 5})) << proc.output();
  for (int site = 1; site < 6; ++site) EXPECT_TRUE(pairs.count({site - 1, site})) << site;
  EXPECT_EQ(pairs.size(), 6u);  // no other earlier site is within 6 m of a site 3 ids later
  EXPECT_TRUE(std::filesystem::exists(cache + "/site1_pair0_left.png"));
  EXPECT_TRUE(proc.WaitForOutput("revisit of site 1", 10)) << proc.output();
  proc.Signal(SIGTERM);
  EXPECT_EQ(proc.WaitExit(20), 0) << proc.output();
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vloc
