// Driver input parsing: what the files hold is read, every bad row is one
// clear line, and the good rows are kept.
#include <gtest/gtest.h>

#include <fstream>

#include <cmath>
#include <exiv2/exiv2.hpp>

#include "driver_fixtures.h"
#include "navcam_manifest.h"
#include "sensor_csv.h"
#include "uav_video_input.h"

namespace vloc {
namespace {

bool HasLine(const std::vector<std::string>& lines, const std::string& text) {
  for (const auto& l : lines)
    if (l.find(text) != std::string::npos) return true;
  return false;
}

std::string Join(const std::vector<std::string>& lines) {
  std::string s;
  for (const auto& l : lines) s += l + "\n";
  return s;
}

TEST(NavcamManifest, KeepsGoodRowsAndNamesEachBadOne) {
  const std::string dir = testing::MakeFixtureDir("manifest");
  const NavcamManifest m = ReadNavcamManifest(testing::WriteNavcamFixture(dir));
  ASSERT_TRUE(m.readable);
  // Rows 1, 2, 3 (corrupt image: found only when loading) and 4 are kept.
  ASSERT_EQ(m.entries.size(), 4u) << Join(m.problems);
  EXPECT_EQ(m.entries[0].site_id, 0);
  EXPECT_EQ(m.entries[0].pair_index, 0);
  EXPECT_NEAR(m.entries[0].pan, 30 * M_PI / 180, 1e-12);
  EXPECT_NEAR(m.entries[0].tilt, 20 * M_PI / 180, 1e-12);
  EXPECT_EQ(m.entries[0].utime, 100000000);
  EXPECT_EQ(m.entries[3].site_id, 1);
  ASSERT_EQ(m.problems.size(), 3u) << Join(m.problems);
  EXPECT_TRUE(HasLine(m.problems, "row 5 (site 1 pair 1): tilt 120.000000 out of range")) << Join(m.problems);
  EXPECT_TRUE(HasLine(m.problems, "row 6 (site 1 pair 2): image file")) << Join(m.problems);
  EXPECT_TRUE(HasLine(m.problems, "site1/R2.png missing; row skipped")) << Join(m.problems);
  EXPECT_TRUE(HasLine(m.problems, "row 7: missing 'time'; row skipped")) << Join(m.problems);
  // The corrupt image is reported when the pair is loaded.
  StereoPair pair;
  std::string error;
  EXPECT_TRUE(LoadNavcamPair(m.entries[1], &pair, &error)) << error;
  EXPECT_NEAR(cv::mean(pair.left)[0], cv::mean(testing::FixtureImage(20))[0], 0.01);
  EXPECT_FALSE(LoadNavcamPair(m.entries[2], &pair, &error));
  EXPECT_NE(error.find("site 0 pair 2: left image"), std::string::npos) << error;
  EXPECT_NE(error.find("cannot be decoded"), std::string::npos) << error;
  std::filesystem::remove_all(dir);
}

TEST(NavcamManifest, AnImageThatClaimsTooManyPixelsIsRefusedBeforeDecoding) {
  const std::string dir = testing::MakeFixtureDir("manifest_bomb");
  const NavcamManifest m = ReadNavcamManifest(testing::WriteNavcamFixture(dir));
  ASSERT_FALSE(m.entries.empty());
  // A PNG signature and an IHDR claiming 30,000 x 30,000 x 3 (2.7 GB decoded), then nothing worth decoding.
  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A, 0, 0, 0, 13, 'I', 'H', 'D', 'R'};
  for (const uint32_t side : {30000u, 30000u})
    for (int shift = 24; shift >= 0; shift -= 8) png.push_back(static_cast<uint8_t>(side >> shift));
  png.insert(png.end(), {8, 2, 0, 0, 0, 0, 0, 0, 0});
  std::ofstream(dir + "/site0/L0.png", std::ios::binary).write(reinterpret_cast<const char*>(png.data()), png.size());
  StereoPair pair;
  std::string error;
  EXPECT_FALSE(LoadNavcamPair(m.entries[0], &pair, &error));
  EXPECT_NE(error.find("site 0 pair 0: left image"), std::string::npos) << error;
  EXPECT_NE(error.find("over the limit"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos) << "one line: " << error;
  EXPECT_TRUE(LoadNavcamPair(m.entries[1], &pair, &error)) << error;  // the good pairs still load
  std::filesystem::remove_all(dir);
}

TEST(NavcamManifest, MissingManifestIsOneLine) {
  const NavcamManifest m = ReadNavcamManifest("/nonexistent/manifest.yaml");
  EXPECT_FALSE(m.readable);
  ASSERT_EQ(m.problems.size(), 1u);
  EXPECT_NE(m.problems[0].find("/nonexistent/manifest.yaml cannot be read"), std::string::npos);
}

TEST(SensorCsv, ImuRowsReadAndBadValuesNamed) {
  const std::string dir = testing::MakeFixtureDir("imu");
  const ImuCsv imu = ReadImuCsv(testing::WriteImuFixture(dir), SensorCsvLimits());
  ASSERT_TRUE(imu.readable);
  ASSERT_EQ(imu.samples.size(), 8u) << Join(imu.problems);
  EXPECT_EQ(imu.samples[0].utime, 10000000);
  EXPECT_NEAR(imu.samples[1].angular_velocity.x(), 0.001, 1e-12);
  EXPECT_NEAR(imu.samples[1].linear_acceleration.z(), 9.81, 1e-12);
  ASSERT_EQ(imu.problems.size(), 2u) << Join(imu.problems);
  EXPECT_TRUE(HasLine(imu.problems, "imu.csv line 5: column 'gx' value 'abc' is not a number; row skipped"))
      << Join(imu.problems);
  EXPECT_TRUE(HasLine(imu.problems, "imu.csv line 8: column 'gz' = 50 rad/s out of range")) << Join(imu.problems);
  std::filesystem::remove_all(dir);
}

TEST(SensorCsv, WheelRowsReadAndMissingColumnRejectsTheFile) {
  const std::string dir = testing::MakeFixtureDir("wheel");
  const WheelCsv wheel = ReadWheelCsv(testing::WriteWheelFixture(dir), SensorCsvLimits());
  ASSERT_TRUE(wheel.readable);
  ASSERT_EQ(wheel.samples.size(), 4u);
  EXPECT_EQ(wheel.samples[3].utime, 10080000);
  EXPECT_NEAR(wheel.samples[3].distance, 0.004, 1e-12);
  EXPECT_TRUE(HasLine(wheel.problems, "wheel.csv line 4: column 'speed' = 99 m/s out of range")) << Join(wheel.problems);
  std::ofstream(dir + "/bad.csv") << "time,distance\n1,2\n";
  const WheelCsv bad = ReadWheelCsv(dir + "/bad.csv", SensorCsvLimits());
  EXPECT_FALSE(bad.readable);
  ASSERT_EQ(bad.problems.size(), 1u);
  EXPECT_NE(bad.problems[0].find("no column 'speed' in the header"), std::string::npos) << bad.problems[0];
  const WheelCsv missing = ReadWheelCsv(dir + "/nope.csv", SensorCsvLimits());
  EXPECT_FALSE(missing.readable);
  EXPECT_NE(missing.problems[0].find("nope.csv: cannot open"), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(UavVideoInput, FolderFramesInOrderWithTheCorruptOneSkipped) {
  const std::string dir = testing::MakeFixtureDir("frames");
  UavVideoSource source;
  std::string error;
  ASSERT_TRUE(source.Open(testing::WriteFrameFolder(dir), 10.0, &error)) << error;
  std::vector<int64_t> times;
  std::vector<double> levels;
  std::vector<std::string> problems;
  cv::Mat frame;
  int64_t utime = 0;
  std::string problem;
  for (auto s = source.Next(&frame, &utime, &problem); s != UavVideoSource::Status::kEnd;
       s = source.Next(&frame, &utime, &problem)) {
    if (s == UavVideoSource::Status::kSkipped) {
      problems.push_back(problem);
      continue;
    }
    times.push_back(utime);
    levels.push_back(cv::mean(frame)[0]);
  }
  EXPECT_EQ(times, (std::vector<int64_t>{0, 100000, 300000, 400000}));
  ASSERT_EQ(levels.size(), 4u);
  EXPECT_LT(levels[0], levels[1]);
  EXPECT_LT(levels[2], levels[3]);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("frame_2.png cannot be decoded"), std::string::npos) << problems[0];
  std::filesystem::remove_all(dir);
}

// Three JPEG photos with EXIF GPS and capture times 2 s and 5 s apart (written
// here with exiv2); the second carries a DJI relative altitude.
TEST(UavVideoInput, GeotaggedPhotoFolderGivesExifTimesAndGpsFixes) {
  const std::string dir = testing::MakeFixtureDir("geotagged");
  const char* times[3] = {"2020:05:01 10:00:00", "2020:05:01 10:00:02", "2020:05:01 10:00:07"};
  for (int i = 0; i < 3; ++i) {
    const std::string path = dir + "/IMG_" + std::to_string(i) + ".jpg";
    ASSERT_TRUE(cv::imwrite(path, testing::FixtureImage(20 + 40 * i)));
    auto image = Exiv2::ImageFactory::open(path);
    image->readMetadata();
    Exiv2::ExifData& exif = image->exifData();
    exif["Exif.Photo.DateTimeOriginal"] = times[i];
    exif["Exif.GPSInfo.GPSLatitudeRef"] = "N";
    exif["Exif.GPSInfo.GPSLatitude"] = "41/1 2/1 " + std::to_string(500 + i * 10) + "/100";
    exif["Exif.GPSInfo.GPSLongitudeRef"] = "W";
    exif["Exif.GPSInfo.GPSLongitude"] = "83/1 18/1 20/1";
    exif["Exif.GPSInfo.GPSAltitude"] = Exiv2::URational(2800 + i, 10);
    if (i == 1) {
      Exiv2::XmpProperties::registerNs("http://www.dji.com/drone-dji/1.0/", "drone-dji");
      image->xmpData()["Xmp.drone-dji.RelativeAltitude"] = "+35.5";
    }
    image->writeMetadata();
  }
  UavVideoSource source;
  std::string error;
  ASSERT_TRUE(source.Open(dir, 0.0, &error)) << error;
  EXPECT_TRUE(source.exif_times());
  std::vector<int64_t> frame_times;
  cv::Mat frame;
  int64_t utime = 0;
  std::string problem;
  while (source.Next(&frame, &utime, &problem) == UavVideoSource::Status::kFrame) frame_times.push_back(utime);
  EXPECT_EQ(frame_times, (std::vector<int64_t>{0, 2000000, 7000000}));
  std::string how;
  const TelemetryCsv gps = source.GeotagTelemetry(2.5, &how);
  ASSERT_TRUE(gps.readable) << how;
  ASSERT_EQ(gps.fixes.size(), 3u);
  EXPECT_NE(how.find("3 of 3 photos geotagged"), std::string::npos) << how;
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(gps.fixes[i].utime, frame_times[i]);
    EXPECT_NEAR(gps.fixes[i].latitude, 41 + 2 / 60.0 + (5.0 + 0.1 * i) / 3600.0, 1e-9);
    EXPECT_NEAR(gps.fixes[i].longitude, -(83 + 18 / 60.0 + 20 / 3600.0), 1e-9);
    EXPECT_NEAR(gps.fixes[i].altitude, 280.0 + 0.1 * i, 1e-9);
    EXPECT_EQ(gps.fixes[i].horizontal_sigma, 2.5);
  }
  EXPECT_TRUE(std::isnan(gps.fixes[0].height_above_ground));
  EXPECT_NEAR(gps.fixes[1].height_above_ground, 35.5, 1e-9);
  // A forced frame rate wins over the EXIF times.
  UavVideoSource forced;
  ASSERT_TRUE(forced.Open(dir, 10.0, &error)) << error;
  EXPECT_FALSE(forced.exif_times());
  std::filesystem::remove_all(dir);
}

TEST(UavVideoInput, VideoFileFramesAtItsFrameRate) {
  const std::string dir = testing::MakeFixtureDir("video");
  const std::string video = testing::WriteVideo(dir, 6);
  if (video.empty()) GTEST_SKIP() << "no MJPG writer in this OpenCV build";
  UavVideoSource source;
  std::string error;
  ASSERT_TRUE(source.Open(video, 0.0, &error)) << error;
  EXPECT_NEAR(source.fps(), 10.0, 1e-6);
  cv::Mat frame;
  int64_t utime = 0;
  std::string problem;
  int n = 0;
  while (source.Next(&frame, &utime, &problem) == UavVideoSource::Status::kFrame) {
    EXPECT_EQ(utime, n * 100000);
    EXPECT_NEAR(cv::mean(frame)[0], 20 * n + 10, 6.0);
    ++n;
  }
  EXPECT_EQ(n, 6);
  UavVideoSource missing;
  EXPECT_FALSE(missing.Open(dir + "/nope.mp4", 0.0, &error));
  EXPECT_NE(error.find("nope.mp4 missing"), std::string::npos) << error;
  std::filesystem::remove_all(dir);
}

TEST(UavVideoInput, TelemetryRowsWithNoFixAndOutOfRangeLatitude) {
  const std::string dir = testing::MakeFixtureDir("telemetry");
  const TelemetryCsv t = ReadTelemetryCsv(testing::WriteTelemetry(dir), 0.0);
  ASSERT_TRUE(t.readable);
  ASSERT_EQ(t.fixes.size(), 3u) << Join(t.problems);
  EXPECT_EQ(t.fixes[1].utime, 200000);
  EXPECT_DOUBLE_EQ(t.fixes[1].latitude, 45.0002);
  EXPECT_DOUBLE_EQ(t.fixes[1].height_above_ground, 31.0);
  EXPECT_EQ(t.fixes[2].fix, 0);
  EXPECT_TRUE(std::isnan(t.fixes[2].latitude));
  EXPECT_TRUE(std::isnan(t.fixes[0].horizontal_sigma));  // not in the file
  ASSERT_EQ(t.problems.size(), 1u);
  EXPECT_NE(t.problems[0].find("telemetry.csv line 4: column 'latitude' = 95.0 out of range"), std::string::npos)
      << t.problems[0];
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vloc
