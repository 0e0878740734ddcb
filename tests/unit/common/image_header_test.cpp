// Image sizes from headers, without decoding: real images written by
// OpenCV report their true size; crafted headers (a 12,000 x 12,000 16-bit
// PNG, a 20,000 x 16,000 progressive JPEG, with no valid pixel data behind
// them) report the size they claim and are refused by the limits; cut-short
// and garbage bytes are refused.
#include "vloc/common/image_header.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>

namespace vloc {
namespace {

std::vector<uint8_t> Encode(const cv::Mat& image, const std::string& ext, const std::vector<int>& params = {}) {
  std::vector<uint8_t> bytes;
  EXPECT_TRUE(cv::imencode(ext, image, bytes, params));
  return bytes;
}

cv::Mat Noise(int rows, int cols, int type) {
  cv::Mat m(rows, cols, type);
  cv::randu(m, 0, 255);
  return m;
}

void PutBigEndian(std::vector<uint8_t>* out, uint32_t v, int n) {
  for (int i = n - 1; i >= 0; --i) out->push_back(static_cast<uint8_t>(v >> (8 * i)));
}

// A PNG signature and IHDR claiming width x height, then a few bytes of a
// (not valid) IDAT: what a decompression bomb's header looks like.
std::vector<uint8_t> CraftedPng(uint32_t width, uint32_t height, int depth, int color) {
  std::vector<uint8_t> b = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  PutBigEndian(&b, 13, 4);
  for (char c : std::string("IHDR")) b.push_back(c);
  PutBigEndian(&b, width, 4);
  PutBigEndian(&b, height, 4);
  b.insert(b.end(), {uint8_t(depth), uint8_t(color), 0, 0, 0});
  PutBigEndian(&b, 0, 4);  // CRC (not checked by the header reader)
  PutBigEndian(&b, 4, 4);
  for (char c : std::string("IDAT")) b.push_back(c);
  b.insert(b.end(), {0x78, 0x9c, 0x00, 0x00});
  return b;
}

// SOI, an APP0 segment, a frame header `sof` (0xC0 baseline, 0xC2
// progressive) claiming width x height x 3, then `scans` minimal scans of
// one byte of entropy data each, then EOI when `end`.
std::vector<uint8_t> CraftedJpeg(uint16_t width, uint16_t height, uint8_t sof, int scans = 1, bool end = true) {
  std::vector<uint8_t> b = {0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x10, 'J', 'F', 'I', 'F', 0, 1, 1, 0, 0, 1, 0, 1, 0, 0};
  b.insert(b.end(), {0xFF, sof, 0x00, 0x11, 0x08});
  PutBigEndian(&b, height, 2);
  PutBigEndian(&b, width, 2);
  b.insert(b.end(), {3, 1, 0x22, 0, 2, 0x11, 1, 3, 0x11, 1});
  for (int s = 0; s < scans; ++s) b.insert(b.end(), {0xFF, 0xDA, 0x00, 0x08, 1, 1, 0x00, 0, 0x3F, 0, 0x5A, 0xFF, 0x00});
  if (end) b.insert(b.end(), {0xFF, 0xD9});
  return b;
}

ImageLimits Navcam() { return ImageLimits{4096, 4096, int64_t(4096) * 4096, 100}; }

TEST(ImageHeader, DefaultLimitsPassTheirCheck) {
  std::string error;
  EXPECT_TRUE(ImageLimits().Check(&error)) << error;
  ImageLimits bad;
  bad.max_pixels = int64_t(1) << 31;
  EXPECT_FALSE(bad.Check(&error));
}

TEST(ImageHeader, RealPngReportsItsTrueSize) {
  struct Case {
    int type;
    int channels, depth;
  };
  for (const Case& c : {Case{CV_8UC1, 1, 8}, Case{CV_8UC3, 3, 8}, Case{CV_16UC1, 1, 16}, Case{CV_8UC4, 4, 8}}) {
    const auto bytes = Encode(Noise(23, 37, c.type), ".png");
    ImageHeader h;
    std::string error;
    ASSERT_TRUE(InspectImage(bytes.data(), bytes.size(), Navcam(), &h, &error)) << error;
    EXPECT_EQ(h.format, ImageFormat::kPng);
    EXPECT_EQ(h.width, 37);
    EXPECT_EQ(h.height, 23);
    EXPECT_EQ(h.channels, c.channels);
    EXPECT_EQ(h.bit_depth, c.depth);
  }
}

TEST(ImageHeader, RealJpegBaselineAndProgressiveReportTheirTrueSize) {
  for (bool progressive : {false, true}) {
    const auto bytes = Encode(Noise(480, 640, CV_8UC3), ".jpg",
                              {cv::IMWRITE_JPEG_QUALITY, 90, cv::IMWRITE_JPEG_PROGRESSIVE, progressive ? 1 : 0});
    ImageHeader h;
    std::string error;
    ASSERT_TRUE(InspectImage(bytes.data(), bytes.size(), Navcam(), &h, &error)) << error;
    EXPECT_EQ(h.format, ImageFormat::kJpeg);
    EXPECT_EQ(h.width, 640);
    EXPECT_EQ(h.height, 480);
    EXPECT_EQ(h.channels, 3);
    EXPECT_EQ(h.bit_depth, 8);
    EXPECT_EQ(h.progressive, progressive);
    if (progressive) EXPECT_GT(h.jpeg_scans, 1) << h.Describe();
    else EXPECT_EQ(h.jpeg_scans, 1);
  }
}

TEST(ImageHeader, RealTiffReportsItsTrueSize) {
  const auto bytes = Encode(Noise(50, 70, CV_8UC3), ".tiff");
  ImageHeader h;
  std::string error;
  ASSERT_TRUE(ReadImageHeader(bytes.data(), bytes.size(), &h, &error)) << error;
  EXPECT_EQ(h.format, ImageFormat::kTiff);
  EXPECT_EQ(h.width, 70);
  EXPECT_EQ(h.height, 50);
  EXPECT_EQ(h.channels, 3);
  EXPECT_EQ(h.bit_depth, 8);
}

TEST(ImageHeader, CraftedPngBombReportsTheLieAndIsRefused) {
  const auto bytes = CraftedPng(12000, 12000, 16, 0);
  ImageHeader h;
  std::string error;
  ASSERT_TRUE(ReadImageHeader(bytes.data(), bytes.size(), &h, &error)) << error;
  EXPECT_EQ(h.width, 12000);
  EXPECT_EQ(h.height, 12000);
  EXPECT_EQ(h.bit_depth, 16);
  EXPECT_FALSE(InspectImage(bytes.data(), bytes.size(), Navcam(), &h, &error));
  EXPECT_NE(error.find("PNG 12000 x 12000"), std::string::npos) << error;
  EXPECT_NE(error.find("over the limit of 4096 x 4096"), std::string::npos) << error;
  // 32,000 x 32,000 is over the default (drone photo) limit too.
  const auto big = CraftedPng(32000, 32000, 8, 2);
  EXPECT_FALSE(InspectImage(big.data(), big.size(), ImageLimits(), &h, &error));
  EXPECT_NE(error.find("32000 x 32000"), std::string::npos) << error;
}

TEST(ImageHeader, CraftedProgressiveJpegBombReportsTheLieAndIsRefused) {
  // Cut short after its first scan: the size is still named.
  const auto bytes = CraftedJpeg(20000, 16000, 0xC2, 1, /*end=*/false);
  ImageHeader h;
  std::string error;
  ASSERT_TRUE(ReadImageHeader(bytes.data(), bytes.size(), &h, &error, /*count_jpeg_scans=*/false)) << error;
  EXPECT_EQ(h.width, 20000);
  EXPECT_EQ(h.height, 16000);
  EXPECT_TRUE(h.progressive);
  EXPECT_FALSE(InspectImage(bytes.data(), bytes.size(), ImageLimits(), &h, &error));
  EXPECT_NE(error.find("JPEG 20000 x 16000"), std::string::npos) << error;
  EXPECT_NE(error.find("progressive"), std::string::npos) << error;
}

TEST(ImageHeader, JpegWithTooManyScansIsRefused) {
  const auto ok = CraftedJpeg(64, 64, 0xC2, 20);
  ImageHeader h;
  std::string error;
  ASSERT_TRUE(InspectImage(ok.data(), ok.size(), Navcam(), &h, &error)) << error;
  EXPECT_EQ(h.jpeg_scans, 20);
  const auto bomb = CraftedJpeg(64, 64, 0xC2, 5000);
  EXPECT_FALSE(InspectImage(bomb.data(), bomb.size(), Navcam(), &h, &error));
  EXPECT_NE(error.find("5000 scan(s)"), std::string::npos) << error;
}

TEST(ImageHeader, TruncatedMalformedAndGarbageAreRefused) {
  ImageHeader h;
  std::string error;
  const auto png = Encode(Noise(8, 8, CV_8UC1), ".png");
  EXPECT_FALSE(ReadImageHeader(png.data(), 20, &h, &error));
  EXPECT_NE(error.find("cut short"), std::string::npos) << error;
  const auto jpg = Encode(Noise(8, 8, CV_8UC1), ".jpg");
  EXPECT_FALSE(ReadImageHeader(jpg.data(), 40, &h, &error));  // ends inside the tables, before SOF
  EXPECT_FALSE(ReadImageHeader(jpg.data(), jpg.size() - 2, &h, &error));  // no EOI
  EXPECT_NE(error.find("cut short"), std::string::npos) << error;
  EXPECT_FALSE(ReadImageHeader(nullptr, 0, &h, &error));
  const auto zero_height = CraftedJpeg(100, 0, 0xC0);
  EXPECT_FALSE(ReadImageHeader(zero_height.data(), zero_height.size(), &h, &error));
  EXPECT_NE(error.find("DNL"), std::string::npos) << error;
  const auto bad_depth = CraftedPng(10, 10, 7, 2);
  EXPECT_FALSE(ReadImageHeader(bad_depth.data(), bad_depth.size(), &h, &error));
  const auto zero_png = CraftedPng(0, 10, 8, 0);
  EXPECT_FALSE(ReadImageHeader(zero_png.data(), zero_png.size(), &h, &error));
  std::mt19937 rng(7);
  std::vector<uint8_t> garbage(4096);
  for (auto& g : garbage) g = static_cast<uint8_t>(rng());
  EXPECT_FALSE(ReadImageHeader(garbage.data(), garbage.size(), &h, &error));
  EXPECT_NE(error.find("not a PNG, JPEG or TIFF"), std::string::npos) << error;
  // A JPEG signature followed by garbage never reads past the bytes given.
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<uint8_t> fuzz = CraftedJpeg(640, 480, 0xC0, 3);
    for (int k = 0; k < 4; ++k) fuzz[2 + rng() % (fuzz.size() - 2)] = static_cast<uint8_t>(rng());
    fuzz.resize(2 + rng() % (fuzz.size() - 1));
    ReadImageHeader(fuzz.data(), fuzz.size(), &h, &error);
  }
}

TEST(ImageHeader, FileHeaderAfterLargeExifSegments) {
  const std::string dir = (std::filesystem::temp_directory_path() / ("vloc_image_header_" + std::to_string(getpid()))).string();
  std::filesystem::create_directories(dir);
  // Four 60 kB APP1 segments before the frame header: past the first 64 kB.
  std::vector<uint8_t> jpeg = CraftedJpeg(20000, 16000, 0xC2, 1, false);
  std::vector<uint8_t> app = {0xFF, 0xE1};
  PutBigEndian(&app, 60000, 2);
  app.resize(2 + 60000, 0x45);
  for (int i = 0; i < 4; ++i) jpeg.insert(jpeg.begin() + 2, app.begin(), app.end());
  const std::string path = dir + "/bomb.jpg";
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(jpeg.data()), jpeg.size());
  ImageHeader h;
  std::string error;
  ASSERT_TRUE(ReadImageFileHeader(path, &h, &error)) << error;
  EXPECT_EQ(h.width, 20000);
  EXPECT_EQ(h.height, 16000);
  EXPECT_FALSE(ReadImageFileHeader(dir, &h, &error));
  EXPECT_NE(error.find("not a regular file"), std::string::npos) << error;
  EXPECT_FALSE(ReadImageFileHeader(dir + "/missing.png", &h, &error));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vloc
