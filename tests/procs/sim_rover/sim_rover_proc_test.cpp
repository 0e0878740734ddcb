// The sim_rover process: straight to an LCM log (channels, counts, order,
// decodable content), over real LCM in real time (port 7720), and a bad
// config. Uses a small world (60 m terrain, 256 x 256 Navcam, 3 pairs) to
// stay fast; the full-size defaults are exercised by the unit tests.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "vloc/features/texture_stats.h"
#include "vloc/imu_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/pose_t.hpp"
#include "vloc/site_event_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/stereo_image_t.hpp"
#include "vloc/testing/subprocess.h"
#include "vloc/wheel_odometry_t.hpp"

namespace vloc {
namespace {

using testing::BinPath;
using testing::Subprocess;

std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "/sim_rover_" + std::to_string(getpid()) + "_" + name;
}

// A small world: same models, smaller terrain and images.
std::string WriteSmallConfig() {
  const std::string path = TempPath("small.yaml");
  std::ofstream(path) << R"(
image_encoding: png
navcam:
  rig:
    left:  {width: 256, height: 256, fx: 297.25, fy: 297.25, cx: 127.5, cy: 127.5}
    right: {width: 256, height: 256, fx: 297.25, fy: 297.25, cx: 127.5, cy: 127.5}
    right_in_left_translation: [0.27, 0.0, 0.0]
  mast: {mast_head: [0.0, 0.0, 1.5]}
terrain: {size_m: 60.0, origin_x_m: -15.0, origin_y_m: -30.0}
traverse:
  plan: {num_sites: 5, spacing_min_m: 5.0, spacing_max_m: 6.0, margin_m: 5.0}
  panorama: {num_pairs: 3}
)";
  return path;
}

TEST(SimRoverProcess, LogHoldsEveryChannelInTimeOrder) {
  const std::string config = WriteSmallConfig();
  const std::string log = TempPath("traverse.lcmlog");
  Subprocess sim({BinPath("sim_rover"), "--config", config, "--log", log, "--sites", "2"});
  ASSERT_EQ(sim.WaitExit(180), 0) << sim.output();
  lcm::LogFile file(log, "r");
  ASSERT_TRUE(file.good());
  std::map<std::string, int> counts;
  std::vector<site_event_t> events;
  std::vector<site_pose_t> site_poses;
  int64_t last = -1;
  for (const lcm::LogEvent* e = file.readNextEvent(); e; e = file.readNextEvent()) {
    ++counts[e->channel];
    EXPECT_GE(e->timestamp, last) << e->channel;
    last = e->timestamp;
    if (e->channel == "NAVCAM_STEREO") {
      stereo_image_t msg;
      ASSERT_EQ(msg.decode(e->data, 0, e->datalen), e->datalen);
      EXPECT_EQ(msg.utime, e->timestamp);
      EXPECT_EQ(int{msg.left.encoding}, int{image_t::ENCODING_PNG});
      const StereoPair pair = StereoPairFromMessage(msg);
      EXPECT_EQ(pair.left.size(), cv::Size(256, 256));
      EXPECT_EQ(pair.right.size(), cv::Size(256, 256));
      EXPECT_EQ(pair.num_pairs, 3);
      // The middle pair looks straight ahead; pairs step 26 deg to the right.
      EXPECT_NEAR(pair.mast_pan, (1 - pair.pair_index) * 26.0 * M_PI / 180, 1e-9);
      EXPECT_NEAR(pair.mast_tilt, 25.0 * M_PI / 180, 1e-9);
      cv::Scalar mean, stddev;
      cv::meanStdDev(pair.left, mean, stddev);
      EXPECT_GT(mean[0], 40);   // terrain, not sky
      EXPECT_GT(stddev[0], 5);  // textured
    } else if (e->channel == "ROVER_SITE") {
      site_event_t msg;
      ASSERT_EQ(msg.decode(e->data, 0, e->datalen), e->datalen);
      EXPECT_EQ(msg.utime, e->timestamp);
      events.push_back(msg);
    } else if (e->channel == "SITE_POSE_GT") {
      site_pose_t msg;
      ASSERT_EQ(msg.decode(e->data, 0, e->datalen), e->datalen);
      site_poses.push_back(msg);
    } else if (e->channel == "GT_POSE") {
      pose_t msg;
      ASSERT_EQ(msg.decode(e->data, 0, e->datalen), e->datalen);
      EXPECT_EQ(msg.frame_id, "world");
      EXPECT_EQ(msg.child_frame_id, "body");
    } else if (e->channel == "IMU") {
      imu_t msg;
      ASSERT_EQ(msg.decode(e->data, 0, e->datalen), e->datalen);
      EXPECT_NEAR(msg.linear_acceleration[2], 1.62, 0.3);  // lunar gravity, nearly level
    } else if (e->channel == "WHEEL_ODOM") {
      wheel_odometry_t msg;
      ASSERT_EQ(msg.decode(e->data, 0, e->datalen), e->datalen);
    }
  }
  EXPECT_EQ(counts["NAVCAM_STEREO"], 2 * 3);
  ASSERT_EQ(events.size(), 5u);  // ARRIVED, IMAGING_DONE, DEPARTED, ARRIVED, IMAGING_DONE
  const int8_t expected[] = {site_event_t::EVENT_ARRIVED, site_event_t::EVENT_IMAGING_DONE,
                             site_event_t::EVENT_DEPARTED, site_event_t::EVENT_ARRIVED,
                             site_event_t::EVENT_IMAGING_DONE};
  for (size_t k = 0; k < events.size(); ++k) {
    EXPECT_EQ(int{events[k].event}, int{expected[k]}) << k;
    EXPECT_EQ(events[k].site_id, k < 3 ? 0 : 1) << k;
  }
  ASSERT_EQ(site_poses.size(), 2u);
  EXPECT_EQ(int{site_poses[0].source}, int{site_pose_t::SOURCE_GROUND_TRUTH});
  EXPECT_NEAR(site_poses[0].pose.position[0], 0.0, 1e-9);
  const double leg = std::hypot(site_poses[1].pose.position[0], site_poses[1].pose.position[1]);
  EXPECT_GT(leg, 4.5);
  EXPECT_LT(leg, 6.5);
  // Rates: IMU 100 Hz, wheels 20 Hz, GT 10 Hz over the same span.
  EXPECT_GT(counts["IMU"], 1000);
  EXPECT_NEAR(counts["WHEEL_ODOM"], counts["IMU"] / 5.0, 2.0);
  EXPECT_NEAR(counts["GT_POSE"], counts["IMU"] / 10.0, 2.0);
  std::filesystem::remove(log);
  std::filesystem::remove(config);
}

TEST(SimRoverProcess, PublishesOverRealLcmInRealTime) {
  const std::string url = testing::TestLcmUrl(7720);
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  int stereo = 0, imu = 0, wheel = 0, gt = 0, site_pose = 0;
  std::vector<int> events;
  auto s1 = Subscribe<stereo_image_t>(*transport, "NAVCAM_STEREO", [&](const std::string&, const stereo_image_t&) { ++stereo; }, 1000);
  auto s2 = Subscribe<site_event_t>(*transport, "ROVER_SITE", [&](const std::string&, const site_event_t& m) { events.push_back(m.event); }, 1000);
  auto s3 = Subscribe<imu_t>(*transport, "IMU", [&](const std::string&, const imu_t&) { ++imu; }, 10000);
  auto s4 = Subscribe<wheel_odometry_t>(*transport, "WHEEL_ODOM", [&](const std::string&, const wheel_odometry_t&) { ++wheel; }, 10000);
  auto s5 = Subscribe<pose_t>(*transport, "GT_POSE", [&](const std::string&, const pose_t&) { ++gt; }, 10000);
  auto s6 = Subscribe<site_pose_t>(*transport, "SITE_POSE_GT", [&](const std::string&, const site_pose_t&) { ++site_pose; }, 100);
  const std::string config = WriteSmallConfig();
  Subprocess sim({BinPath("sim_rover"), "--config", config, "--lcm-url", url, "--sites", "1", "--speed", "10"});
  std::optional<int> code;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (std::chrono::steady_clock::now() < deadline) {
    transport->Handle(50);
    if (!code) code = sim.WaitExit(0.0);
    if (code) break;
  }
  // Drain what is in flight: until nothing arrives for 0.5 s (bounded).
  for (int quiet = 0, i = 0; quiet < 10 && i < 100000; ++i) quiet = transport->Handle(50) > 0 ? 0 : quiet + 1;
  ASSERT_TRUE(code.has_value()) << sim.output();
  EXPECT_EQ(*code, 0) << sim.output();
  EXPECT_EQ(stereo, 3);
  EXPECT_EQ(site_pose, 1);
  ASSERT_EQ(events.size(), 2u);  // one site: ARRIVED, IMAGING_DONE
  EXPECT_EQ(events[0], int{site_event_t::EVENT_ARRIVED});
  EXPECT_EQ(events[1], int{site_event_t::EVENT_IMAGING_DONE});
  EXPECT_GT(imu, 500);
  EXPECT_GT(wheel, 100);
  EXPECT_GT(gt, 50);
  std::filesystem::remove(config);
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Same seed, same bytes; --seed 2 (another traverse seed) a different log;
// --seed -1 keeps the config's seed.
TEST(SimRoverProcess, SameSeedSameLogBytes) {
  const std::string config = WriteSmallConfig();
  const std::string a = TempPath("a.lcmlog"), b = TempPath("b.lcmlog"), c = TempPath("c.lcmlog");
  const std::vector<std::pair<std::string, std::string>> runs{{a, "-1"}, {b, "1"}, {c, "2"}};  // config seed: 1
  for (const auto& [log, seed] : runs) {
    Subprocess sim({BinPath("sim_rover"), "--config", config, "--log", log, "--sites", "1", "--seed", seed});
    ASSERT_EQ(sim.WaitExit(120), 0) << sim.output();
  }
  const std::string bytes_a = ReadFile(a), bytes_b = ReadFile(b), bytes_c = ReadFile(c);
  EXPECT_GT(bytes_a.size(), 100000u);
  EXPECT_TRUE(bytes_a == bytes_b) << "two runs with the same seed wrote different logs";
  EXPECT_FALSE(bytes_a == bytes_c) << "--seed 2 wrote the same log as seed 1";
  for (const std::string& f : {a, b, c, config}) std::filesystem::remove(f);
}

TEST(SimRoverProcess, RenderSampleWritesTheNavcamPairAsPng) {
  const std::string config = WriteSmallConfig();
  const std::string dir = TempPath("samples");
  Subprocess sim({BinPath("sim_rover"), "--config", config, "--render-sample", dir});
  ASSERT_EQ(sim.WaitExit(120), 0) << sim.output();
  for (const std::string name : {"navcam_left.png", "navcam_right.png"}) {
    const cv::Mat image = cv::imread(dir + "/" + name, cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(image.empty()) << name;
    EXPECT_EQ(image.type(), CV_8UC1);
    EXPECT_EQ(image.size(), cv::Size(256, 256));
  }
  EXPECT_FALSE(cv::imread(dir + "/terrain_ortho.png").empty());
  std::filesystem::remove_all(dir);
  std::filesystem::remove(config);
}

// The profiles' texture against real Curiosity Navcam images
// (../shared/data/real/mars_navcam): the hard profile must not flatter the
// front end, so its near-field feature density stays below every real
// image's; and the simulated terrain's spectrum (the default profile) falls
// off like the real ground's. Measured (vloc_texture_stats): SIFT keypoints
// per 10,000 px in the bottom third, default 47, hard 8.5, real 48-128;
// spectrum slope default -2.80, real -2.42 to -2.82.
TEST(SimRoverProcess, ProfilesTextureAgainstRealNavcamImages) {
  const std::string real_dir = "../shared/data/real/mars_navcam";
  if (!std::filesystem::is_directory(real_dir))
    GTEST_SKIP() << real_dir << " absent (real data lives beside the repo, see ../shared/data/README.md): skipped";
  std::vector<TextureStats> real;
  for (const auto& e : std::filesystem::directory_iterator(real_dir)) {
    const std::string ext = e.path().extension().string();
    if (ext != ".png" && ext != ".jpeg") continue;
    real.push_back(ComputeTextureStats(cv::imread(e.path().string(), cv::IMREAD_GRAYSCALE)));
  }
  ASSERT_GE(real.size(), 4u);
  auto render = [](const std::string& config) {
    const std::string dir = TempPath("texture");
    Subprocess sim({BinPath("sim_rover"), "--config", config, "--render-sample", dir});
    EXPECT_EQ(sim.WaitExit(120), 0) << sim.output();
    const TextureStats s = ComputeTextureStats(cv::imread(dir + "/navcam_left.png", cv::IMREAD_GRAYSCALE));
    std::filesystem::remove_all(dir);
    return s;
  };
  const TextureStats def = render("config/procs/sim_rover.yaml"), hard = render("config/procs/sim_rover_hard.yaml");
  double least_features = 1e9, slope_lo = 0, slope_hi = -1e9;
  for (const auto& r : real) {
    least_features = std::min(least_features, r.features_per_10kpx[2]);
    slope_lo = std::min(slope_lo, r.spectrum_slope);
    slope_hi = std::max(slope_hi, r.spectrum_slope);
  }
  std::cout << "bottom-third SIFT per 10 kpx: default " << def.features_per_10kpx[2] << ", hard "
            << hard.features_per_10kpx[2] << ", real >= " << least_features << "; spectrum slope default "
            << def.spectrum_slope << ", real " << slope_lo << " .. " << slope_hi << "\n";
  EXPECT_LT(hard.features_per_10kpx[2], least_features);
  EXPECT_LT(hard.features_per_10kpx[2], def.features_per_10kpx[2]);
  EXPECT_GT(def.spectrum_slope, slope_lo - 0.3);
  EXPECT_LT(def.spectrum_slope, slope_hi + 0.3);
}

TEST(SimRoverProcess, MisspelledConfigKeyStopsWithOneLine) {
  const std::string config = TempPath("bad.yaml");
  std::ofstream(config) << "traverse:\n  panorama:\n    num_pair: 5\n";
  Subprocess sim({BinPath("sim_rover"), "--config", config, "--log", TempPath("never.lcmlog")});
  EXPECT_EQ(sim.WaitExit(60), 1);
  EXPECT_NE(sim.output().find("num_pair"), std::string::npos) << sim.output();
  std::filesystem::remove(config);
}

}  // namespace
}  // namespace vloc
