// vloc_match and vloc_stereo as an operator runs them: image files in,
// YAML and a disparity file out, on synthetic pairs rendered exactly
// (ground truth known), plus the one-line errors for bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <string>

#include "test_images.h"
#include "tool_run.h"
#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

std::string TempDir() { return testing::ToolTempDir("vloc_matching_tools"); }

cv::Mat ToU8(const cv::Mat& f) {
  cv::Mat out;
  f.convertTo(out, CV_8U);
  return out;
}

using testing::Number;
using testing::RunTool;
using testing::ToolRun;

TEST(VlocMatch, FindsASyntheticHomographyToATenthOfAPixel) {
  const std::string dir = TempDir();
  const vloc::testing::BlobTexture tex(520, 420, 520 * 420 / 18, 17, 1.5, 4.0);
  const cv::Matx33d b_from_a(0.8, -0.12, 60, 0.15, 0.95, -20, 2e-4, -5e-5, 1.0);
  const cv::Matx33d a_from_b = b_from_a.inv();
  cv::imwrite(dir + "/a.png", ToU8(tex.Render(480, 360, [](int x, int y) { return std::make_pair<double, double>(x, y); })));
  cv::imwrite(dir + "/b.png", ToU8(tex.Render(480, 360, [&](int x, int y) {
                const cv::Vec3d p = a_from_b * cv::Vec3d(x, y, 1);
                return std::make_pair(p[0] / p[2], p[1] / p[2]);
              })));
  {
    std::ofstream f(dir + "/truth.yaml");
    f << "homography: [";
    for (int k = 0; k < 9; ++k) f << (k ? ", " : "") << b_from_a(k / 3, k % 3);
    f << "]\n";
  }
  const ToolRun r = RunTool({vloc::testing::BinPath("vloc_match"), dir + "/a.png", dir + "/b.png", "--truth",
                         dir + "/truth.yaml", "--out", dir + "/overlay.jpg"});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_LT(Number(r.output, "max"), 0.1) << r.output;
  EXPECT_GT(Number(r.output, "refined_inliers"), 200) << r.output;
  EXPECT_FALSE(cv::imread(dir + "/overlay.jpg").empty());
  std::filesystem::remove_all(dir);
}

TEST(VlocMatch, MissingImageIsOneClearLine) {
  const ToolRun r = RunTool({vloc::testing::BinPath("vloc_match"), "/nonexistent/a.png", "/nonexistent/b.png"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("cannot read image /nonexistent/a.png"), std::string::npos) << r.output;
}

// Reads a PFM written by vloc_stereo (little endian, rows bottom-up).
cv::Mat ReadPfm(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::string magic;
  int w = 0, h = 0;
  double scale = 0;
  f >> magic >> w >> h >> scale;
  f.get();
  if (magic != "Pf" || w <= 0 || h <= 0) return cv::Mat();
  cv::Mat m(h, w, CV_32F);
  for (int y = h - 1; y >= 0; --y) f.read(reinterpret_cast<char*>(m.ptr<float>(y)), w * 4);
  return f ? m : cv::Mat();
}

// A slanted plane seen by a rectified pair, disparity d0 + gx x + gy y at
// left pixel (x, y); the right image `dy` px lower (0: rectified).
constexpr int kPlaneW = 240, kPlaneH = 160;
constexpr double kD0 = 9.4, kGx = 0.02, kGy = 0.015;
void WritePlanePair(const std::string& dir, double dy) {
  const vloc::testing::BlobTexture tex(kPlaneW + 60, kPlaneH, (kPlaneW + 60) * kPlaneH / 18, 23);
  cv::imwrite(dir + "/l.png",
              ToU8(tex.Render(kPlaneW, kPlaneH, [](int x, int y) { return std::make_pair<double, double>(x, y); })));
  cv::imwrite(dir + "/r.png", ToU8(tex.Render(kPlaneW, kPlaneH, [&](int x, int y) {
                return std::make_pair<double, double>((x + kD0 + kGy * y) / (1.0 - kGx), y - dy);
              })));
}

// Median |error| of a step-2 disparity map of the plane, after checking its
// size and that most of it is matched.
double PlaneMedianError(const cv::Mat& d, const std::string& output) {
  EXPECT_EQ(d.cols, kPlaneW / 2);
  EXPECT_EQ(d.rows, kPlaneH / 2);
  std::vector<double> err;
  for (int i = 0; i < d.rows; ++i)
    for (int j = 0; j < d.cols; ++j)
      if (std::isfinite(d.at<float>(i, j))) err.push_back(std::abs(d.at<float>(i, j) - (kD0 + kGx * 2 * j + kGy * 2 * i)));
  EXPECT_GT(err.size(), 0.7 * (kPlaneW / 2 - 20) * (kPlaneH / 2 - 6)) << output;
  EXPECT_EQ(Number(output, "lsm_matches"), static_cast<double>(err.size())) << output;
  if (err.empty()) return NAN;
  std::nth_element(err.begin(), err.begin() + err.size() / 2, err.end());
  return err[err.size() / 2];
}

TEST(VlocStereo, SlantedPlaneDisparitiesToAFewHundredthsOfAPixel) {
  const std::string dir = TempDir();
  WritePlanePair(dir, 0);
  const ToolRun r = RunTool({vloc::testing::BinPath("vloc_stereo"), dir + "/l.png", dir + "/r.png", "--min-disp", "0",
                         "--max-disp", "30", "--step", "2", "--out", dir + "/d.pfm"});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_LT(PlaneMedianError(ReadPfm(dir + "/d.pfm"), r.output), 0.05);
  std::filesystem::remove_all(dir);
}

// --auto-range takes the search range from the pair's feature matches:
// the plane's disparities (9.4-14.6 px) inside it, the same precision.
TEST(VlocStereo, AutoRangeCoversThePairsDisparities) {
  const std::string dir = TempDir();
  WritePlanePair(dir, 0);
  const ToolRun r = RunTool({vloc::testing::BinPath("vloc_stereo"), dir + "/l.png", dir + "/r.png", "--auto-range",
                         "--step", "2", "--out", dir + "/d.pfm"});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("pair_check: \"rectified"), std::string::npos) << r.output;
  EXPECT_LT(PlaneMedianError(ReadPfm(dir + "/d.pfm"), r.output), 0.05);
  std::filesystem::remove_all(dir);
}

// The same pair with the right image 2 px lower: a common row offset the
// matches agree on (real rectified pairs keep a few tenths of a pixel) is
// absorbed, the right image shifted by it; 6 px (over max_row_offset_px) is
// refused in one line and nothing is written.
TEST(VlocStereo, RowOffsetIsAbsorbedAndALargeOneRefusedInOneLine) {
  const std::string dir = TempDir();
  WritePlanePair(dir, 2.0);
  const ToolRun r = RunTool({vloc::testing::BinPath("vloc_stereo"), dir + "/l.png", dir + "/r.png", "--min-disp", "0",
                         "--max-disp", "30", "--step", "2", "--out", dir + "/d.pfm"});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("absorbed"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("row_offset_px: 2"), std::string::npos) << r.output;
  EXPECT_LT(PlaneMedianError(ReadPfm(dir + "/d.pfm"), r.output), 0.1);
  std::filesystem::remove_all(dir);

  const std::string dir6 = TempDir();
  WritePlanePair(dir6, 6.0);
  const ToolRun big = RunTool({vloc::testing::BinPath("vloc_stereo"), dir6 + "/l.png", dir6 + "/r.png", "--min-disp", "0",
                           "--max-disp", "30", "--out", dir6 + "/d.pfm"});
  EXPECT_EQ(big.exit_code, 1) << big.output;
  EXPECT_NE(big.output.find("not rectified"), std::string::npos) << big.output;
  EXPECT_FALSE(std::filesystem::exists(dir6 + "/d.pfm"));
  const ToolRun forced = RunTool({vloc::testing::BinPath("vloc_stereo"), dir6 + "/l.png", dir6 + "/r.png", "--min-disp",
                              "0", "--max-disp", "30", "--no-pair-check", "--out", dir6 + "/d.pfm"});
  EXPECT_EQ(forced.exit_code, 0) << forced.output;
  std::filesystem::remove_all(dir6);
}

TEST(VlocStereo, MissingImagesAreOneClearLine) {
  const ToolRun r = RunTool({vloc::testing::BinPath("vloc_stereo"), "/nonexistent/l.png", "/nonexistent/r.png", "--out",
                         "/tmp/x.pfm"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("cannot read two images"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace vloc
