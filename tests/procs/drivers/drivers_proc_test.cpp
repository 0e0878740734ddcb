// The three drivers as processes: they publish what their input holds (read
// back from an LCM log written through a file:// URL, or received over real
// LCM on port 7731), and name every bad input in one line while carrying on.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>

#include "driver_fixtures.h"
#include "pds_fixtures.h"
#include "vloc/imu_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/site_event_t.hpp"
#include "vloc/stereo_image_t.hpp"
#include "vloc/testing/subprocess.h"
#include "vloc/uav_gps_t.hpp"
#include "vloc/wheel_odometry_t.hpp"

namespace vloc {
namespace {

using testing::BinPath;
using testing::CountOccurrences;
using testing::Subprocess;

// The messages of an LCM log, per channel, in order.
std::map<std::string, std::vector<std::vector<uint8_t>>> ReadLog(const std::string& path) {
  std::map<std::string, std::vector<std::vector<uint8_t>>> out;
  lcm::LogFile log(path, "r");
  if (!log.good()) return out;
  for (const lcm::LogEvent* e = log.readNextEvent(); e; e = log.readNextEvent()) {
    const auto* data = static_cast<const uint8_t*>(e->data);
    out[e->channel].emplace_back(data, data + e->datalen);
  }
  return out;
}

template <class Msg>
Msg DecodeOrFail(const std::vector<uint8_t>& bytes) {
  Msg msg;
  EXPECT_TRUE(Decode(bytes.data(), bytes.size(), &msg));
  return msg;
}

std::string FileUrl(const std::string& log) { return "file://" + log + "?mode=w"; }

// Handles `transport` until the driver has exited and `received()` holds (or
// it failed, or 60 s passed), then drains what is in flight; its exit code.
template <class Received>
std::optional<int> ReceiveUntilExit(Transport& transport, Subprocess& driver, Received received) {
  std::optional<int> code;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline && !(code && received())) {
    transport.Handle(50);
    if (!code) code = driver.WaitExit(0.0);
    if (code && *code != 0) break;
  }
  for (int i = 0; i < 5; ++i) transport.Handle(20);
  return code;
}

TEST(NavcamDriver, PublishesTheGoodPairsWithSiteEventsAndNamesTheBadRows) {
  const std::string dir = testing::MakeFixtureDir("navcam_proc");
  const std::string manifest = testing::WriteNavcamFixture(dir);
  const std::string log = dir + "/out.lcmlog";
  Subprocess driver({BinPath("navcam_driver"), "--config", "config/procs/navcam_driver.yaml", "--manifest", manifest,
                     "--speed", "0", "--lcm-url", FileUrl(log)});
  ASSERT_EQ(driver.WaitExit(60), 0) << driver.output();
  const std::string& out = driver.output();
  EXPECT_EQ(CountOccurrences(out, "tilt 120.000000 out of range"), 1) << out;
  EXPECT_EQ(CountOccurrences(out, "site1/R2.png missing; row skipped"), 1) << out;
  EXPECT_EQ(CountOccurrences(out, "row 7: missing 'time'"), 1) << out;
  EXPECT_EQ(CountOccurrences(out, "site 0 pair 2: left image"), 1) << out;
  EXPECT_NE(out.find("2 sites, 3 pairs published, 4 skipped"), std::string::npos) << out;

  auto messages = ReadLog(log);
  ASSERT_EQ(messages["NAVCAM_STEREO"].size(), 3u);
  const int expected_site[] = {0, 0, 1}, expected_pair[] = {0, 1, 0}, level[] = {10, 20, 40};
  const double expected_pan[] = {30, 0, 30}, expected_tilt[] = {20, 20, 25};
  const int64_t expected_utime[] = {100000000, 100500000, 160000000};
  for (size_t i = 0; i < 3; ++i) {
    const StereoPair pair = StereoPairFromMessage(DecodeOrFail<stereo_image_t>(messages["NAVCAM_STEREO"][i]));
    EXPECT_EQ(pair.site_id, expected_site[i]);
    EXPECT_EQ(pair.pair_index, expected_pair[i]);
    EXPECT_EQ(pair.utime, expected_utime[i]);
    EXPECT_NEAR(pair.mast_pan, expected_pan[i] * M_PI / 180, 1e-12);
    EXPECT_NEAR(pair.mast_tilt, expected_tilt[i] * M_PI / 180, 1e-12);
    EXPECT_EQ(cv::norm(pair.left, testing::FixtureImage(level[i]), cv::NORM_INF), 0.0) << "pair " << i;
    EXPECT_EQ(cv::norm(pair.right, testing::FixtureImage(level[i] + 1), cv::NORM_INF), 0.0) << "pair " << i;
  }
  ASSERT_EQ(messages["ROVER_SITE"].size(), 4u);
  const SiteEvent a0 = SiteEventFromMessage(DecodeOrFail<site_event_t>(messages["ROVER_SITE"][0]));
  const SiteEvent d0 = SiteEventFromMessage(DecodeOrFail<site_event_t>(messages["ROVER_SITE"][1]));
  const SiteEvent a1 = SiteEventFromMessage(DecodeOrFail<site_event_t>(messages["ROVER_SITE"][2]));
  EXPECT_EQ(a0.event, SiteEventType::kArrived);
  EXPECT_EQ(a0.site_id, 0);
  EXPECT_EQ(a0.num_pairs, 3);
  EXPECT_EQ(d0.event, SiteEventType::kImagingDone);
  EXPECT_EQ(d0.num_pairs, 2);
  EXPECT_EQ(a1.site_id, 1);
  std::filesystem::remove_all(dir);
}

// Injecting a logged run: a process reading a log (file:// provider) handles
// every message and exits cleanly at its end, not with a transport error.
TEST(NavcamDriver, ItsLogReplayedIntoTheFrontEndEndsCleanly) {
  const std::string dir = testing::MakeFixtureDir("navcam_replay");
  const std::string manifest = testing::WriteNavcamFixture(dir);
  const std::string log = dir + "/out.lcmlog";
  Subprocess driver({BinPath("navcam_driver"), "--config", "config/procs/navcam_driver.yaml", "--manifest", manifest,
                     "--speed", "0", "--lcm-url", FileUrl(log)});
  ASSERT_EQ(driver.WaitExit(60), 0) << driver.output();
  Subprocess frontend({BinPath("feature_frontend"), "--config", "config/procs/feature_frontend.yaml", "--lcm-url",
                       "file://" + log + "?speed=0"});
  EXPECT_EQ(frontend.WaitExit(60), 0) << frontend.output();
  EXPECT_NE(frontend.output().find("end of the log being read"), std::string::npos) << frontend.output();
  EXPECT_EQ(frontend.output().find("transport error"), std::string::npos) << frontend.output();
  EXPECT_NE(frontend.output().find("rejected 0"), std::string::npos) << frontend.output();
}

// Issue 30: a manifest's pair 99 of a site of 6 rows was published as "pair 99 of
// num_pairs 6", which every consumer rejects. Now the row is refused in one
// line naming its line in the manifest, and the site goes out as 5 pairs.
TEST(NavcamDriver, APairIndexBeyondTheSiteIsRefusedNamingItsManifestLine) {
  const std::string dir = testing::MakeFixtureDir("navcam_pair99");
  cv::imwrite(dir + "/L.png", testing::FixtureImage(10));
  cv::imwrite(dir + "/R.png", testing::FixtureImage(11));
  {
    std::ofstream f(dir + "/manifest.yaml");
    f << "pairs:\n";
    for (int pair : {0, 1, 2, 3, 4, 99})
      f << "  - {site: 0, pair: " << pair << ", pan: 0, tilt: 0.3, time: " << 10 + pair << ", left: L.png, right: R.png}\n";
  }
  const std::string log = dir + "/out.lcmlog";
  Subprocess driver({BinPath("navcam_driver"), "--manifest", dir + "/manifest.yaml", "--speed", "0", "--lcm-url",
                     FileUrl(log)});
  ASSERT_EQ(driver.WaitExit(60), 0) << driver.output();
  EXPECT_EQ(CountOccurrences(driver.output(), "manifest.yaml line 7, row 6 (site 0 pair 99): pair index 99 is not below "
                                        "num_pairs 6"),
            1)
      << driver.output();
  auto messages = ReadLog(log);
  ASSERT_EQ(messages["NAVCAM_STEREO"].size(), 5u) << driver.output();
  for (size_t i = 0; i < 5; ++i) {
    const StereoPair pair = StereoPairFromMessage(DecodeOrFail<stereo_image_t>(messages["NAVCAM_STEREO"][i]));
    EXPECT_EQ(pair.pair_index, static_cast<int>(i));
    EXPECT_EQ(pair.num_pairs, 5);  // every consumer accepts it: below num_pairs
  }
  std::filesystem::remove_all(dir);
}

TEST(NavcamDriver, MissingManifestStopsWithOneLine) {
  Subprocess driver({BinPath("navcam_driver"), "--manifest", "/nonexistent/m.yaml", "--lcm-url", "memq://"});
  EXPECT_EQ(driver.WaitExit(30), 1);
  EXPECT_EQ(CountOccurrences(driver.output(), "/nonexistent/m.yaml cannot be read"), 1) << driver.output();
}

// Issue 33: a folder of PDS3 products, no manifest (procs/navcam_driver/
// navcam_pds.h; fixture tests/unit/drivers/pds_fixtures.h): two sites of two
// pairs, received over real LCM with their times, pointing and pixels (the
// colour pair in colour); each of the nine bad products one line.
TEST(NavcamDriver, PdsFolderWithoutManifestOverRealLcm) {
  const std::string dir = testing::MakeFixtureDir("navcam_pds_proc");
  const std::string folder = testing::WritePdsFixture(dir);
  const std::string url = testing::TestLcmUrl(7731);
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  std::vector<stereo_image_t> stereo;
  std::vector<SiteEvent> events;
  auto s1 = Subscribe<stereo_image_t>(*transport, "NAVCAM_STEREO", [&](const std::string&, const stereo_image_t& m) {
    stereo.push_back(m);
  }, 100);
  auto s2 = Subscribe<site_event_t>(*transport, "ROVER_SITE", [&](const std::string&, const site_event_t& m) {
    events.push_back(SiteEventFromMessage(m));
  }, 100);
  Subprocess driver({BinPath("navcam_driver"), "--config", "config/procs/navcam_driver.yaml", "--pds", folder,
                     "--speed", "0", "--lcm-url", url});
  const std::optional<int> code =
      ReceiveUntilExit(*transport, driver, [&] { return stereo.size() >= 4 && events.size() >= 4; });
  ASSERT_TRUE(code.has_value()) << driver.output();
  ASSERT_EQ(*code, 0) << driver.output();
  const std::string& out = driver.output();
  for (const std::string& problem : testing::kPdsFixtureProblems) EXPECT_EQ(CountOccurrences(out, problem), 1) << problem << "\n" << out;
  EXPECT_EQ(CountOccurrences(out, "PDS site 0: SITE 3 DRIVE 10 (sol 100): 2 stereo pair(s) of 5 frame(s)"), 1) << out;
  EXPECT_NE(out.find("2 sites, 4 pairs published, 9 skipped"), std::string::npos) << out;

  ASSERT_EQ(stereo.size(), 4u) << out;
  const int site[] = {0, 0, 1, 1}, pair[] = {0, 1, 0, 1}, level[] = {10, 20, 40, 60};
  const int64_t t0 = 1577836800000000;  // 2020-01-01T00:00:00 UTC
  const int64_t utime[] = {t0 + 10000000, t0 + 30000000, t0 + 110000000, t0 + 120000000};
  const double pan_deg[] = {-30, 15, 0, -90}, tilt_deg[] = {20, 25, 0, 0};
  for (size_t i = 0; i < 4; ++i) {
    const stereo_image_t& m = stereo[i];
    EXPECT_EQ(m.site_id, site[i]);
    EXPECT_EQ(m.pair_index, pair[i]);
    EXPECT_EQ(m.num_pairs, 2);
    EXPECT_EQ(m.utime, utime[i]);
    if (i != 2) {  // pair 2's pointing comes from the model's axis (navcam_pds_test checks it)
      EXPECT_NEAR(m.mast_pan, pan_deg[i] * M_PI / 180, 1e-9) << i;
      EXPECT_NEAR(m.mast_tilt, tilt_deg[i] * M_PI / 180, 1e-9) << i;
    }
    const cv::Mat left = ImageFromMessage(m.left), right = ImageFromMessage(m.right);
    if (i < 2) {
      EXPECT_EQ(cv::norm(left, testing::FixtureImage(level[i]), cv::NORM_INF), 0.0) << i;
      EXPECT_EQ(cv::norm(right, testing::FixtureImage(level[i] + 1), cv::NORM_INF), 0.0) << i;
    } else if (i == 2) {
      ASSERT_EQ(left.type(), CV_8UC3);  // colour kept
      EXPECT_EQ(cv::norm(left, testing::FixtureColour(level[i]), cv::NORM_INF), 0.0);
      EXPECT_EQ(cv::norm(right, testing::FixtureColour(level[i] + 1), cv::NORM_INF), 0.0);
    } else {
      EXPECT_NEAR(cv::mean(left)[0], cv::mean(testing::FixtureImage(level[i]))[0], 1.0);  // JPEG
    }
  }
  ASSERT_EQ(events.size(), 4u);
  const SiteEventType type[] = {SiteEventType::kArrived, SiteEventType::kImagingDone, SiteEventType::kArrived,
                                SiteEventType::kImagingDone};
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(events[i].event, type[i]);
    EXPECT_EQ(events[i].site_id, static_cast<int>(i / 2));
    EXPECT_EQ(events[i].num_pairs, 2);
  }
  std::filesystem::remove_all(dir);
}

// A folder given as --manifest is read as PDS products.
TEST(NavcamDriver, AFolderGivenAsTheManifestIsReadAsPds) {
  const std::string dir = testing::MakeFixtureDir("navcam_pds_auto");
  const std::string folder = testing::WritePdsFixture(dir);
  const std::string log = dir + "/out.lcmlog";
  Subprocess driver({BinPath("navcam_driver"), "--manifest", folder, "--speed", "0", "--lcm-url", FileUrl(log)});
  ASSERT_EQ(driver.WaitExit(60), 0) << driver.output();
  EXPECT_NE(driver.output().find("2 sites, 4 pairs published, 9 skipped"), std::string::npos) << driver.output();
  EXPECT_EQ(ReadLog(log)["NAVCAM_STEREO"].size(), 4u);
  std::filesystem::remove_all(dir);
}

TEST(ImuOdometryDriver, PublishesTheGoodSamplesOverRealLcm) {
  const std::string dir = testing::MakeFixtureDir("imu_proc");
  const std::string imu_csv = testing::WriteImuFixture(dir), wheel_csv = testing::WriteWheelFixture(dir);
  const std::string url = testing::TestLcmUrl(7731);
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  std::vector<ImuSample> imu;
  std::vector<WheelOdometrySample> wheel;
  auto s1 = Subscribe<imu_t>(*transport, "IMU", [&](const std::string&, const imu_t& m) {
    imu.push_back(ImuFromMessage(m));
  }, 100);
  auto s2 = Subscribe<wheel_odometry_t>(*transport, "WHEEL_ODOM", [&](const std::string&, const wheel_odometry_t& m) {
    wheel.push_back(WheelOdometryFromMessage(m));
  }, 100);
  Subprocess driver({BinPath("imu_odometry_driver"), "--config", "config/procs/imu_odometry_driver.yaml", "--imu",
                     imu_csv, "--wheel", wheel_csv, "--speed", "1", "--lcm-url", url});
  const std::optional<int> code =
      ReceiveUntilExit(*transport, driver, [&] { return imu.size() >= 8 && wheel.size() >= 4; });
  ASSERT_TRUE(code.has_value()) << driver.output();
  ASSERT_EQ(*code, 0) << driver.output();
  ASSERT_EQ(imu.size(), 8u);
  ASSERT_EQ(wheel.size(), 4u);
  EXPECT_EQ(imu[0].utime, 10000000);
  EXPECT_NEAR(imu[1].angular_velocity.x(), 0.001, 1e-12);
  EXPECT_NEAR(imu[7].linear_acceleration.z(), 9.81, 1e-12);
  EXPECT_EQ(wheel[3].utime, 10080000);
  EXPECT_NEAR(wheel[3].distance, 0.004, 1e-12);
  const std::string& out = driver.output();
  EXPECT_EQ(CountOccurrences(out, "column 'gx' value 'abc' is not a number; row skipped"), 1) << out;
  EXPECT_EQ(CountOccurrences(out, "column 'gz' = 50 rad/s out of range"), 1) << out;
  EXPECT_EQ(CountOccurrences(out, "column 'speed' = 99 m/s out of range"), 1) << out;
  std::filesystem::remove_all(dir);
}

TEST(UavVideoDriver, PublishesFramesAndTelemetryInTimeOrder) {
  const std::string dir = testing::MakeFixtureDir("video_proc");
  const std::string frames = testing::WriteFrameFolder(dir), telemetry = testing::WriteTelemetry(dir);
  const std::string log = dir + "/out.lcmlog";
  Subprocess driver({BinPath("uav_video_driver"), "--config", "config/procs/uav_video_driver.yaml", "--video", frames,
                     "--telemetry", telemetry, "--fps", "5", "--speed", "0", "--lcm-url", FileUrl(log)});
  ASSERT_EQ(driver.WaitExit(60), 0) << driver.output();
  const std::string& out = driver.output();
  EXPECT_EQ(CountOccurrences(out, "frame_2.png cannot be decoded"), 1) << out;
  EXPECT_EQ(CountOccurrences(out, "column 'latitude' = 95.0 out of range"), 1) << out;
  // Read back in log order: GPS and frames interleaved by time.
  lcm::LogFile file(log, "r");
  ASSERT_TRUE(file.good());
  std::vector<int64_t> frame_times, gps_times;
  std::vector<uav_gps_t> fixes;
  int64_t last = -1;
  for (const lcm::LogEvent* e = file.readNextEvent(); e; e = file.readNextEvent()) {
    const auto* data = static_cast<const uint8_t*>(e->data);
    const std::vector<uint8_t> bytes(data, data + e->datalen);
    int64_t utime = 0;
    if (e->channel == "UAV_CAMERA") {
      const image_t msg = DecodeOrFail<image_t>(bytes);
      EXPECT_EQ(msg.frame_id, "uav_nadir");
      EXPECT_EQ(ImageFromMessage(msg).size(), cv::Size(160, 120));
      utime = msg.utime;
      frame_times.push_back(utime);
    } else if (e->channel == "UAV_GPS") {
      fixes.push_back(DecodeOrFail<uav_gps_t>(bytes));
      utime = fixes.back().utime;
      gps_times.push_back(utime);
    }
    EXPECT_GE(utime, last);
    last = utime;
  }
  EXPECT_EQ(frame_times, (std::vector<int64_t>{0, 200000, 600000, 800000}));  // frame 2 skipped
  EXPECT_EQ(gps_times, (std::vector<int64_t>{0, 200000, 600000}));             // the 0.4 s row is bad
  ASSERT_EQ(fixes.size(), 3u);
  EXPECT_DOUBLE_EQ(fixes[0].latitude, 45.0001);
  EXPECT_DOUBLE_EQ(fixes[1].height_above_ground, 31.0);
  EXPECT_EQ(int{fixes[2].fix}, int{uav_gps_t::FIX_NONE});
  EXPECT_TRUE(std::isnan(fixes[2].latitude));
  std::filesystem::remove_all(dir);
}

TEST(UavVideoDriver, MissingVideoStopsWithOneLine) {
  Subprocess driver({BinPath("uav_video_driver"), "--video", "/nonexistent/flight.mp4", "--lcm-url", "memq://"});
  EXPECT_EQ(driver.WaitExit(30), 1);
  EXPECT_EQ(CountOccurrences(driver.output(), "video /nonexistent/flight.mp4 missing"), 1) << driver.output();
}

}  // namespace
}  // namespace vloc
