// The sim_uav process: straight to an LCM log, over real LCM in real time
// (port 7730), and a bad config.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>

#include "vloc/image_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/pose_t.hpp"
#include "vloc/testing/subprocess.h"
#include "vloc/uav_gps_t.hpp"

namespace vloc {
namespace {

using testing::BinPath;
using testing::Subprocess;

std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "/sim_uav_" + std::to_string(getpid()) + "_" + name;
}

TEST(SimUavProcess, LogHoldsFramesGpsAndTruthInTimeOrder) {
  const std::string log = TempPath("flight.lcmlog");
  Subprocess sim({BinPath("sim_uav"), "--config", "config/procs/sim_uav.yaml", "--log", log, "--duration", "2",
                  "--fps", "10"});
  ASSERT_EQ(sim.WaitExit(120), 0) << sim.output();
  lcm::LogFile file(log, "r");
  ASSERT_TRUE(file.good());
  std::map<std::string, int> counts;
  int64_t last = -1;
  bool checked_image = false, checked_gt = false, checked_gps = false;
  for (const lcm::LogEvent* e = file.readNextEvent(); e; e = file.readNextEvent()) {
    ++counts[e->channel];
    EXPECT_GE(e->timestamp, last);
    last = e->timestamp;
    if (e->channel == "UAV_CAMERA" && !checked_image) {
      image_t msg;
      ASSERT_EQ(msg.decode(e->data, 0, e->datalen), e->datalen);
      EXPECT_EQ(msg.utime, e->timestamp);
      EXPECT_EQ(msg.frame_id, "uav_nadir");
      EXPECT_EQ(int{msg.encoding}, int{image_t::ENCODING_JPEG});
      const cv::Mat image = ImageFromMessage(msg);
      EXPECT_EQ(image.cols, 1280);
      EXPECT_EQ(image.rows, 720);
      checked_image = true;
    } else if (e->channel == "UAV_GT" && !checked_gt) {
      pose_t msg;
      ASSERT_EQ(msg.decode(e->data, 0, e->datalen), e->datalen);
      EXPECT_EQ(msg.frame_id, "world");
      EXPECT_EQ(msg.child_frame_id, "uav_body");
      EXPECT_NEAR(msg.position[2], 15.0, 1e-6);  // calibration hover height
      checked_gt = true;
    } else if (e->channel == "UAV_GPS" && !checked_gps) {
      uav_gps_t msg;
      ASSERT_EQ(msg.decode(e->data, 0, e->datalen), e->datalen);
      EXPECT_EQ(int{msg.fix}, int{uav_gps_t::FIX_3D});
      EXPECT_NEAR(msg.latitude, 45.4642, 1e-3);  // within ~100 m of the configured origin
      EXPECT_NEAR(msg.height_above_ground, 15.0, 3.0);
      checked_gps = true;
    }
  }
  EXPECT_EQ(counts["UAV_CAMERA"], 21);  // t = 0, 0.1, ..., 2.0
  EXPECT_EQ(counts["UAV_GT"], 21);
  EXPECT_EQ(counts["UAV_GPS"], 11);     // 5 Hz
  EXPECT_TRUE(checked_image && checked_gt && checked_gps);
  std::filesystem::remove(log);
}

TEST(SimUavProcess, PublishesOverRealLcmInRealTime) {
  const std::string url = testing::TestLcmUrl(7730);
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  int frames = 0, gps = 0, gt = 0;
  cv::Size size;
  auto s1 = Subscribe<image_t>(*transport, "UAV_CAMERA", [&](const std::string&, const image_t& m) {
    ++frames;
    size = ImageFromMessage(m).size();
  }, 100);
  auto s2 = Subscribe<uav_gps_t>(*transport, "UAV_GPS", [&](const std::string&, const uav_gps_t&) { ++gps; }, 100);
  auto s3 = Subscribe<pose_t>(*transport, "UAV_GT", [&](const std::string&, const pose_t&) { ++gt; }, 100);
  Subprocess sim({BinPath("sim_uav"), "--config", "config/procs/sim_uav.yaml", "--lcm-url", url, "--duration", "1.0",
                  "--fps", "5", "--speed", "1"});
  std::optional<int> code;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (std::chrono::steady_clock::now() < deadline) {
    transport->Handle(50);
    if (!code) code = sim.WaitExit(0.0);
    if (code && frames >= 6 && gps >= 6 && gt >= 6) break;
    if (code && *code != 0) break;
  }
  // Drain what is still in flight.
  for (int i = 0; i < 10; ++i) transport->Handle(20);
  ASSERT_TRUE(code.has_value()) << sim.output();
  EXPECT_EQ(*code, 0) << sim.output();
  EXPECT_EQ(frames, 6);  // t = 0, 0.2, ..., 1.0
  EXPECT_EQ(gt, 6);
  EXPECT_EQ(gps, 6);
  EXPECT_EQ(size, cv::Size(1280, 720));
}

TEST(SimUavProcess, MisspelledConfigKeyStopsWithOneLine) {
  const std::string config = TempPath("bad.yaml");
  std::ofstream(config) << "world:\n  flight:\n    calibration_heigth: 12\n";
  Subprocess sim({BinPath("sim_uav"), "--config", config, "--log", TempPath("never.lcmlog")});
  EXPECT_EQ(sim.WaitExit(60), 1);
  EXPECT_NE(sim.output().find("calibration_heigth: unknown key; did you mean 'calibration_height'?"), std::string::npos) << sim.output();
  std::filesystem::remove(config);
}

}  // namespace
}  // namespace vloc
