// The uav_mosaicker process over real LCM (ports 7801-7802): fed by sim_uav,
// it publishes UAV_STATE for the frames with heights that follow UAV_GT, a
// UAV_MOSAIC preview, and writes the mosaic on SIGUSR1; a misspelt key stops it.
#include <gtest/gtest.h>
#include <iterator>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include "vloc/image_t.hpp"
#include "vloc/lcm_io/process.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/pose_t.hpp"
#include "vloc/testing/subprocess.h"
#include "vloc/uav_state_t.hpp"

namespace vloc {
namespace {

using testing::BinPath;
using testing::Subprocess;

std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "/uav_mosaicker_" + std::to_string(getpid()) + "_" + name;
}

TEST(UavMosaickerProcess, TracksSimulatedFlightOverRealLcm) {
  const std::string url = testing::TestLcmUrl(7801);
  const std::string mosaic = TempPath("mosaic.png");
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  std::map<int64_t, double> truth_height;  // utime -> z
  std::vector<uav_state_t> states;
  int previews = 0;
  cv::Size preview_size;
  auto s1 = Subscribe<pose_t>(*transport, "UAV_GT", [&](const std::string&, const pose_t& m) {
    truth_height[m.utime] = m.position[2];
  }, 200);
  auto s2 = Subscribe<uav_state_t>(*transport, "UAV_STATE", [&](const std::string&, const uav_state_t& m) {
    states.push_back(m);
  }, 200);
  auto s3 = Subscribe<image_t>(*transport, "UAV_MOSAIC", [&](const std::string&, const image_t& m) {
    ++previews;
    preview_size = ImageFromMessage(m).size();
  }, 10);
  // The flight's config with every frame kept (camera_queue 1000, not 8): this test checks tracking and height, and
  // a mosaicker starved of CPU (a loaded machine) would otherwise drop frames as it does in real time and lose the
  // track across the gap (found at load 10: 16 LOST, "too few matches").
  const std::string config = TempPath("uav_mosaicker.yaml");
  {
    std::ifstream in("config/procs/uav_mosaicker.yaml");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (size_t at = text.find("include: ../"); at != std::string::npos; at = text.find("include: ../", at))
      text.replace(at, 12, "include: " + std::filesystem::absolute("config").string() + "/");
    const size_t q = text.find("camera_queue: 8");
    ASSERT_NE(q, std::string::npos);
    text.replace(q, 15, "camera_queue: 1000");
    std::ofstream(config) << text;
  }
  Subprocess mosaicker({BinPath("uav_mosaicker"), "--config", config, "--lcm-url", url, "--output", mosaic});
  // Frames published before the mosaicker has subscribed would be lost.
  ASSERT_TRUE(mosaicker.WaitForOutput(kReadyLine, 60)) << mosaicker.output();
  std::filesystem::remove(config);  // read at start
  Subprocess sim({BinPath("sim_uav"), "--config", "config/procs/sim_uav.yaml", "--lcm-url", url, "--duration", "9",
                  "--fps", "10", "--speed", "0.5"});
  std::optional<int> sim_code;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(150);
  size_t settled = 0, last = 0;
  auto since = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() < deadline) {
    transport->Handle(50);
    if (!sim_code) sim_code = sim.WaitExit(0.0);
    if (sim_code && *sim_code != 0) break;
    if (mosaicker.WaitExit(0.0)) break;
    // After the sim ends, wait until no state has arrived for a while (the queue is drained).
    if (sim_code) {
      if (states.size() != last) {
        last = states.size();
        since = std::chrono::steady_clock::now();
      } else if (std::chrono::steady_clock::now() - since > std::chrono::seconds(5)) {
        settled = last;
        break;
      }
    }
  }
  ASSERT_TRUE(sim_code.has_value()) << sim.output();
  ASSERT_EQ(*sim_code, 0) << sim.output();
  EXPECT_GT(settled, 0u);
  // 91 frames published; real-time processing may drop some (camera_queue), most arrive.
  ASSERT_GT(states.size(), 40u) << mosaicker.output();
  int tracked = 0, checked = 0, lost = 0, well_matched = 0;
  std::string lost_why;  // the first LOST frames' reasons
  double worst = 0;
  for (const auto& s : states) {
    if (s.status == uav_state_t::STATUS_LOST && ++lost <= 5)
      lost_why += "frame " + std::to_string(s.frame_index) + ": " + s.message + "\n";
    if (s.status != uav_state_t::STATUS_TRACKING && s.status != uav_state_t::STATUS_RECOVERED) continue;
    ++tracked;
    auto it = truth_height.find(s.utime);
    if (it == truth_height.end()) continue;
    ++checked;
    worst = std::max(worst, std::abs(s.height - it->second) / it->second);
    if (s.num_inliers > 25) ++well_matched;  // all but the frame that starts the mosaic
  }
  EXPECT_EQ(lost, 0) << lost_why;
  EXPECT_GT(tracked, 30);
  EXPECT_EQ(well_matched, tracked - 1);
  EXPECT_GT(checked, 30);
  // Marker + known focal calibration (~0.5 %) and the scale chain over 9 s: well inside 2 %.
  EXPECT_LT(worst, 0.02) << "worst relative height error";
  EXPECT_GE(previews, 1);
  EXPECT_GT(preview_size.area(), 0);
  // SIGUSR1 writes the mosaic now.
  std::filesystem::remove(mosaic);
  mosaicker.Signal(SIGUSR1);
  const auto wait_file = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  const auto world_file = std::filesystem::path(mosaic).replace_extension(".pgw");
  // The PNG is written first, then the world file: wait for both.
  while (!(std::filesystem::exists(mosaic) && std::filesystem::exists(world_file)) &&
         std::chrono::steady_clock::now() < wait_file)
    transport->Handle(100);
  EXPECT_TRUE(std::filesystem::exists(mosaic)) << mosaicker.output();
  EXPECT_TRUE(std::filesystem::exists(world_file))
      << "tied to GPS: world file expected";
  mosaicker.Signal(SIGTERM);
  const auto code = mosaicker.WaitExit(60);
  ASSERT_TRUE(code.has_value());
  EXPECT_EQ(*code, 0) << mosaicker.output();
  std::filesystem::remove(mosaic);
  std::filesystem::remove(std::filesystem::path(mosaic).replace_extension(".pgw"));
}

TEST(UavMosaickerProcess, MisspelledConfigKeyStopsWithOneLine) {
  const std::string config = TempPath("bad.yaml");
  std::ofstream(config) << "mosaicker:\n  matcher:\n    foreground_roh: 2.0\n";
  Subprocess p({BinPath("uav_mosaicker"), "--config", config, "--lcm-url", testing::TestLcmUrl(7802)});
  EXPECT_EQ(p.WaitExit(60), 1);
  EXPECT_NE(p.output().find("foreground_roh"), std::string::npos) << p.output();
  std::filesystem::remove(config);
}

}  // namespace
}  // namespace vloc
