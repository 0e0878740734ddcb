// navcam_driver's PDS mode (procs/navcam_driver/navcam_pds.h): a folder of
// PDS3 products grouped into sites and stereo pairs by their labels alone.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "navcam_pds.h"
#include "pds_fixtures.h"

namespace vloc {
namespace {

constexpr double kDeg = M_PI / 180;

int CountLines(const std::vector<std::string>& lines, const std::string& text) {
  int n = 0;
  for (const std::string& line : lines) n += line.find(text) != std::string::npos;
  return n;
}

TEST(NavcamPds, UtcTimesInBothForms) {
  int64_t t = 0;
  ASSERT_TRUE(ParsePdsUtcTime("2012-10-06T17:18:59.259", &t));
  EXPECT_EQ(t, 1349543939259000);
  int64_t doy = 0;
  ASSERT_TRUE(ParsePdsUtcTime("2012-280T17:18:59.259Z", &doy));
  EXPECT_EQ(doy, t);
  for (const char* bad : {"", "2012-10-06", "2012-13-01T00:00:00", "2012-400T00:00:00", "2012-10-06T25:00:00",
                          "2012-10-06T17:18:59.259 junk", "UNK"})
    EXPECT_FALSE(ParsePdsUtcTime(bad, &t)) << bad;
}

// Two sites of two pairs each, every kind of product; each bad product one
// line naming its file and the keyword, the good ones all kept.
TEST(NavcamPds, ProductsGroupIntoSitesAndPairsByTheirLabels) {
  const std::string dir = testing::MakeFixtureDir("pds_unit");
  const std::string folder = testing::WritePdsFixture(dir);
  const NavcamPdsFolder read = ReadNavcamPdsFolder(folder, NavcamPdsOptions());
  const NavcamManifest& m = read.manifest;
  ASSERT_TRUE(m.readable);
  for (const std::string& problem : testing::kPdsFixtureProblems)
    EXPECT_EQ(CountLines(m.problems, problem), 1) << problem;
  EXPECT_EQ(m.problems.size(), testing::kPdsFixtureProblems.size());
  for (const std::string& p : m.problems) std::cout << "  " << p << "\n";

  ASSERT_EQ(read.sites.size(), 2u);
  EXPECT_EQ(read.sites[0].Describe(), "site 0: SITE 3 DRIVE 10 (sol 100): 2 stereo pair(s) of 5 frame(s)");
  EXPECT_EQ(read.sites[1].Describe(), "site 1: SITE 3 DRIVE 20 (sol 100): 2 stereo pair(s) of 4 frame(s)");
  ASSERT_EQ(m.entries.size(), 4u);
  const int site[] = {0, 0, 1, 1}, pair[] = {0, 1, 0, 1};
  const int64_t t0 = 1577836800000000;  // 2020-01-01T00:00:00 UTC
  const int64_t utime[] = {t0 + 10000000, t0 + 30000000, t0 + 110000000, t0 + 120000000};
  const Eigen::Vector3d a(-0.964222, 0.184182, -0.190622);  // the fixture model's axis (rover frame)
  const double pan[] = {-30 * kDeg, 15 * kDeg, -std::atan2(a.y(), a.x()), -90 * kDeg};
  const double tilt[] = {20 * kDeg, 25 * kDeg, -std::asin(-a.normalized().z()), 0};
  const char* left[] = {"L0.IMG", "L1.LBL", "L2.png", "NLA_0001M_.jpg"};
  const char* right[] = {"R0.IMG", "R1.LBL", "R2.png", "NRA_0001M_.jpg"};
  for (size_t i = 0; i < 4; ++i) {
    const NavcamManifestEntry& e = m.entries[i];
    EXPECT_EQ(e.site_id, site[i]) << i;
    EXPECT_EQ(e.pair_index, pair[i]) << i;
    EXPECT_EQ(e.utime, utime[i]) << i;
    EXPECT_NEAR(e.pan, pan[i], 1e-9) << i;
    EXPECT_NEAR(e.tilt, tilt[i], 1e-6) << i;
    EXPECT_EQ(std::filesystem::path(e.left_path).filename(), left[i]);
    EXPECT_EQ(std::filesystem::path(e.right_path).filename(), right[i]);
    EXPECT_TRUE(e.has_rover_pose);
    EXPECT_NEAR(e.site_from_rover.translation().x(), 1.5 + (site[i] == 0 ? 10 : 20), 1e-12);
  }
  // The pixels: 8-bit and 16-bit (12-bit data) .IMG as 8 bit, colour kept.
  const int level[] = {10, 20, 40, 60};
  for (size_t i = 0; i < 4; ++i) {
    StereoPair p;
    std::string error;
    ASSERT_TRUE(LoadNavcamPair(m.entries[i], &p, &error)) << error;
    ASSERT_EQ(p.left.size(), cv::Size(64, 48));
    if (i == 2) {
      ASSERT_EQ(p.left.type(), CV_8UC3);
      EXPECT_EQ(cv::norm(p.left, testing::FixtureColour(level[i]), cv::NORM_INF), 0.0);
      EXPECT_EQ(cv::norm(p.right, testing::FixtureColour(level[i] + 1), cv::NORM_INF), 0.0);
    } else if (i < 2) {
      ASSERT_EQ(p.left.type(), CV_8UC1);
      EXPECT_EQ(cv::norm(p.left, testing::FixtureImage(level[i]), cv::NORM_INF), 0.0) << i;
      EXPECT_EQ(cv::norm(p.right, testing::FixtureImage(level[i] + 1), cv::NORM_INF), 0.0) << i;
    } else {
      EXPECT_NEAR(cv::mean(p.left)[0], cv::mean(testing::FixtureImage(level[i]))[0], 1.0);  // JPEG
    }
  }
  std::filesystem::remove_all(dir);
}

TEST(NavcamPds, LeftAndRightFurtherApartThanTheToleranceAreNotAPair) {
  const std::string dir = testing::MakeFixtureDir("pds_dt");
  const std::string folder = testing::WritePdsFixture(dir);
  NavcamPdsOptions options;
  options.pair_max_dt = 0.02;  // site 0 pair 1's right eye is 40 ms late
  const NavcamPdsFolder read = ReadNavcamPdsFolder(folder, options);
  EXPECT_EQ(read.manifest.entries.size(), 3u);
  EXPECT_EQ(CountLines(read.manifest.problems, "L1.LBL: FRAME_ID LEFT: no RIGHT frame of SEQUENCE_ID 'ncam00001' within 0.02 s"), 1);
  EXPECT_EQ(CountLines(read.manifest.problems, "R1.LBL: FRAME_ID RIGHT: no LEFT frame"), 1);
  std::filesystem::remove_all(dir);
}

TEST(NavcamPds, AFolderThatIsNotOneIsOneLine) {
  const NavcamPdsFolder read = ReadNavcamPdsFolder("/nonexistent/pds", NavcamPdsOptions());
  EXPECT_FALSE(read.manifest.readable);
  ASSERT_EQ(read.manifest.problems.size(), 1u);
  EXPECT_NE(read.manifest.problems[0].find("/nonexistent/pds is not a folder"), std::string::npos);
}

// The shared Curiosity panoramas: left frames only. They group into their
// two sites (sol 38: SITE 4 DRIVE 404, 6 frames; sol 60: SITE 5 DRIVE 104,
// 12 frames), and each frame is one line: no right frame, not published.
TEST(NavcamPds, SharedCuriosityPanoramasGroupIntoSitesWithoutRightFrames) {
  const std::string folder = std::string(VLOC_SOURCE_DIR) + "/../shared/data/real/mars_navcam_pano";
  if (!std::filesystem::is_directory(folder)) GTEST_SKIP() << "../shared/data is absent: " << folder;
  const NavcamPdsFolder read = ReadNavcamPdsFolder(folder, NavcamPdsOptions());
  ASSERT_TRUE(read.manifest.readable);
  ASSERT_EQ(read.sites.size(), 2u);
  EXPECT_EQ(read.sites[0].Describe(), "site 0: SITE 4 DRIVE 404 (sol 38): 0 stereo pair(s) of 6 frame(s)");
  EXPECT_EQ(read.sites[1].Describe(), "site 1: SITE 5 DRIVE 104 (sol 60): 0 stereo pair(s) of 12 frame(s)");
  EXPECT_TRUE(read.manifest.entries.empty());
  EXPECT_EQ(read.manifest.problems.size(), 18u);
  EXPECT_EQ(CountLines(read.manifest.problems, ": FRAME_ID LEFT: no RIGHT frame of SEQUENCE_ID"), 18);
}

}  // namespace
}  // namespace vloc
