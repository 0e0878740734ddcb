// Manual tie points end to end on real LCM (port 7957): a simulated site
// pair whose automatic matching fails (the front end judges the ground too
// flat: min_region_std raised, as on a very difficult surface) stays at dead
// reckoning; an operator's clicks (MANUAL_TIE_POINTS, from the simulator's
// truth with a 1 px click error) are refined by the front end and solved by
// crosssite_ba: the site is localized, and far closer to the truth than
// dead reckoning. Clicks for a site whose images are gone get one clear
// FRONTEND_STATUS.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "true_clicks.h"
#include "vloc/frontend_status_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/process.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/localization_t.hpp"
#include "vloc/manual_tie_points_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

using testing::BinPath;
using testing::Subprocess;

constexpr const char* kSimConfig = "tests/procs/vloc_console/manual_tie_sim.yaml";

// The front end's config with the texture floor raised past any real ground.
std::string FlatGroundFrontendConfig(const std::filesystem::path& dir) {
  std::ifstream in("config/procs/feature_frontend.yaml");
  std::stringstream text;
  text << in.rdbuf();
  std::string yaml = text.str();
  const std::string navcam = "navcam: {include: ../navcam.yaml}";
  yaml.replace(yaml.find(navcam), navcam.size(),
               "navcam: {include: " + std::filesystem::absolute("config/navcam.yaml").string() + "}");
  const std::string frontend = "frontend:\n";
  yaml.replace(yaml.find(frontend), frontend.size(), "frontend:\n  min_region_std: 1000.0\n");
  const auto path = dir / "feature_frontend_flat.yaml";
  std::ofstream(path) << yaml;
  return path.string();
}

manual_tie_points_t TiesMessage(int previous, int current, const std::vector<ManualTie>& ties) {
  manual_tie_points_t m{};
  m.source = "manual_tie_proc_test";
  m.previous_site_id = previous;
  m.current_site_id = current;
  m.num_points = static_cast<int>(ties.size());
  for (const ManualTie& t : ties) {
    m.previous_pair.push_back(t.previous_pair);
    m.previous_u.push_back(t.previous_px.x());
    m.previous_v.push_back(t.previous_px.y());
    m.current_pair.push_back(t.current_pair);
    m.current_u.push_back(t.current_px.x());
    m.current_v.push_back(t.current_px.y());
  }
  return m;
}

struct Bus {
  std::map<int, site_pose_t> dr, truth;
  std::vector<frontend_status_t> statuses;
  std::vector<localization_t> localizations;
};

bool WaitFor(Transport& lcm, double seconds, const std::function<bool()>& done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < deadline) {
    lcm.Handle(100);
    if (done()) return true;
  }
  return false;
}

double PositionError(const pose_t& estimate, const site_pose_t& truth) {
  return (PoseFromMessage(estimate).pose.translation() - PoseFromMessage(truth.pose).pose.translation()).norm();
}

TEST(ManualTies, TurnAFailedSitePairIntoALocalizedOne) {
  const std::string url = testing::TestLcmUrl(7957);
  const auto dir = std::filesystem::temp_directory_path() / "vloc_manual_tie_proc_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::string error;
  auto lcm = MakeLcmTransport(url, &error);
  ASSERT_TRUE(lcm) << error;
  Bus bus;
  Subscribe<site_pose_t>(*lcm, "SITE_POSE_DR",
                         [&](const std::string&, const site_pose_t& m) { bus.dr[m.site_id] = m; });
  Subscribe<site_pose_t>(*lcm, "SITE_POSE_GT",
                         [&](const std::string&, const site_pose_t& m) { bus.truth[m.site_id] = m; });
  Subscribe<frontend_status_t>(*lcm, "FRONTEND_STATUS",
                               [&](const std::string&, const frontend_status_t& m) { bus.statuses.push_back(m); });
  Subscribe<localization_t>(*lcm, "SITE_POSE_VISUAL",
                            [&](const std::string&, const localization_t& m) { bus.localizations.push_back(m); });

  Subprocess dr({BinPath("dead_reckoning"), "--config", "config/procs/dead_reckoning.yaml", "--lcm-url", url});
  Subprocess frontend({BinPath("feature_frontend"), "--config", FlatGroundFrontendConfig(dir), "--lcm-url", url});
  Subprocess ba({BinPath("crosssite_ba"), "--config", "config/procs/crosssite_ba.yaml", "--lcm-url", url, "--state-dir",
                 dir.string()});
  for (Subprocess* p : {&dr, &frontend, &ba}) ASSERT_TRUE(p->WaitForOutput(kReadyLine, 20)) << p->output();
  Subprocess sim({BinPath("sim_rover"), "--config", kSimConfig, "--lcm-url", url, "--speed", "0"});
  // 1. The automatic pass fails: no tie points, no BA; the site stands at dead reckoning.
  ASSERT_TRUE(WaitFor(*lcm, 120, [&] { return !bus.statuses.empty(); })) << frontend.output();
  EXPECT_EQ(bus.statuses[0].current_site_id, 1);
  EXPECT_EQ(int(bus.statuses[0].status), int(frontend_status_t::STATUS_LOW_TEXTURE)) << bus.statuses[0].message;
  WaitFor(*lcm, 1.0, [] { return false; });
  EXPECT_TRUE(bus.localizations.empty());
  ASSERT_TRUE(bus.dr.count(1) && bus.truth.count(1));
  const double before = PositionError(bus.dr[1].pose, bus.truth[1]);

  // 2. The operator's clicks.
  const sim::RoverWorld world(testing::WorldOptionsOf(kSimConfig));
  const std::vector<ManualTie> ties = testing::TrueClicks(world, 0, 1, testing::ClickOptions());
  ASSERT_GE(ties.size(), 10u);
  ASSERT_TRUE(Publish(*lcm, "MANUAL_TIE_POINTS", TiesMessage(0, 1, ties)));
  ASSERT_TRUE(WaitFor(*lcm, 60, [&] { return !bus.localizations.empty(); })) << frontend.output() << ba.output();
  const localization_t& l = bus.localizations[0];
  EXPECT_EQ(l.site_id, 1);
  EXPECT_EQ(int(l.status), int(localization_t::STATUS_OK)) << l.message;
  const double after = PositionError(l.pose, bus.truth[1]);
  std::cout << "manual tie points: " << ties.size() << " clicks, BA used " << l.num_tie_points_used
            << "; site 1 position error before (dead reckoning) " << before << " m, after " << after << " m\n";
  EXPECT_LT(after, 0.05) << "12 clicks of 1 px refined by LSM localize a 10 m pair to a few cm";
  EXPECT_LT(after, before);
  // The front end publishes the tie points, then the status: on a loaded machine the BA's answer can come first.
  ASSERT_TRUE(WaitFor(*lcm, 10, [&] { return bus.statuses.size() >= 2; })) << frontend.output();
  EXPECT_NE(bus.statuses[1].message.find("manual:"), std::string::npos) << bus.statuses[1].message;
  std::cout << "front end: " << bus.statuses[1].message << "\n";


  // 3. Clicks for a site the front end no longer holds: one clear status, nothing solved.
  ASSERT_TRUE(Publish(*lcm, "MANUAL_TIE_POINTS", TiesMessage(7, 8, ties)));
  ASSERT_TRUE(WaitFor(*lcm, 10, [&] { return bus.statuses.size() >= 3; }));
  EXPECT_EQ(int(bus.statuses[2].status), int(frontend_status_t::STATUS_MISSING_INPUT));
  EXPECT_NE(bus.statuses[2].message.find("no longer kept"), std::string::npos) << bus.statuses[2].message;
  EXPECT_EQ(bus.localizations.size(), 1u);
}

}  // namespace
}  // namespace vloc
