// Images are decompression bombs until proven otherwise, and files lie
// (issue 30, items 5, 6, 9, 11). Every hostile input is generated here: a
// bomb is a real header claiming a huge size in front of a few bytes, which
// the header check must refuse before decoding. Before the fix:
//  5. feature_frontend: two 12,000 x 12,000 16-bit PNGs on NAVCAM_STEREO
//     cost 22 s and 1.85 GB, no log line;
//  6. uav_mosaic_files: a 32,000 x 32,000 PNG among the photos grew it to
//     8-9 GB and aborted on a cv::Exception;
//  9. an XMP RelativeAltitude of 1e308 gave "height_m": inf (invalid JSON),
//     an EXIF focal length of 1/2147483647 mm gave 1.3e9 m/px, exit 0;
// 11. vloc_match on a 1 x 1 image aborted (exit 134).
#include <exiv2/exiv2.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <filesystem>
#include <fstream>
#include <random>

#include "hostile_bus.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/site_pose_t.hpp"
#include "vloc/stereo_image_t.hpp"

namespace vloc {
namespace {

using namespace vloc::testing;
namespace fs = std::filesystem;

template <class Msg>
std::vector<uint8_t> Bytes(const Msg& msg) {
  std::vector<uint8_t> b(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

struct Scratch {
  explicit Scratch(const std::string& name)
      : dir(::testing::TempDir() + "/untrusted_" + name + "_" + std::to_string(getpid())) {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() { fs::remove_all(dir); }
  std::string dir;
};

void Put(std::vector<uint8_t>* out, uint32_t v, int n) {
  for (int i = n - 1; i >= 0; --i) out->push_back(static_cast<uint8_t>(v >> (8 * i)));
}

// A PNG header claiming width x height (colour type `color`, `depth` bits),
// then a few kB of deflated zeros: what the probe's bombs begin with.
std::vector<uint8_t> PngBomb(uint32_t width, uint32_t height, int depth, int color) {
  std::vector<uint8_t> b = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  Put(&b, 13, 4);
  for (char c : std::string("IHDR")) b.push_back(static_cast<uint8_t>(c));
  Put(&b, width, 4);
  Put(&b, height, 4);
  b.insert(b.end(), {uint8_t(depth), uint8_t(color), 0, 0, 0});
  Put(&b, 0, 4);
  Put(&b, 4096, 4);
  for (char c : std::string("IDAT")) b.push_back(static_cast<uint8_t>(c));
  b.resize(b.size() + 4096, 0);
  return b;
}

// A progressive JPEG header (SOF2) claiming width x height x 3 and one scan.
std::vector<uint8_t> JpegBomb(uint16_t width, uint16_t height) {
  std::vector<uint8_t> b = {0xFF, 0xD8, 0xFF, 0xC2, 0x00, 0x11, 0x08};
  Put(&b, height, 2);
  Put(&b, width, 2);
  b.insert(b.end(), {3, 1, 0x22, 0, 2, 0x11, 1, 3, 0x11, 1});
  b.insert(b.end(), {0xFF, 0xDA, 0x00, 0x08, 1, 1, 0x00, 0, 0x3F, 0});
  b.resize(b.size() + 4096, 0x5A);
  b.insert(b.end(), {0xFF, 0xD9});
  return b;
}

void WriteFile(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

image_t RawImage(const std::vector<uint8_t>& bytes, int encoding, const std::string& frame_id) {
  image_t m;
  m.frame_id = frame_id;
  m.encoding = static_cast<int8_t>(encoding);
  m.data = bytes;
  m.size = static_cast<int32_t>(bytes.size());
  return m;
}

// Peak resident memory of a running process, MB (VmHWM).
double PeakMb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return -1;
}

int CountOf(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// ---- 5: feature_frontend ------------------------------------------------

TEST(UntrustedImages, FeatureFrontendRefusesBombStereoPairsInOneLineAndKeepsServing) {
  const std::string url = TestLcmUrl(7931);
  Bus bus(url, "NONE");
  auto proc = StartProc({BinPath("feature_frontend"), "--config", "config/procs/feature_frontend.yaml", "--lcm-url", url});
  bus.Watch(proc.get());
  stereo_image_t png;
  png.site_id = 0, png.pair_index = 0, png.num_pairs = 1;
  png.left = RawImage(PngBomb(12000, 12000, 16, 0), image_t::ENCODING_PNG, "navcam_left");
  png.right = RawImage(PngBomb(12000, 12000, 16, 0), image_t::ENCODING_PNG, "navcam_right");
  bus.Send("NAVCAM_STEREO", Bytes(png));
  ASSERT_TRUE(bus.PumpUntil([&] { return CountOf(proc->output(), "refused before decoding") >= 1; }, 60))
      << proc->output();
  // Rejections are logged at most once per 5 s (RateLimitedLog): the next one after that.
  bus.Pump(5500);
  stereo_image_t jpeg = png;
  jpeg.left = RawImage(JpegBomb(20000, 16000), image_t::ENCODING_JPEG, "navcam_left");
  jpeg.right = RawImage(JpegBomb(20000, 16000), image_t::ENCODING_JPEG, "navcam_right");
  bus.Send("NAVCAM_STEREO", Bytes(jpeg));
  ASSERT_TRUE(bus.PumpUntil([&] { return CountOf(proc->output(), "refused before decoding") >= 2; }, 60))
      << proc->output();
  const std::string& out = proc->output();
  EXPECT_NE(out.find("channel NAVCAM_STEREO: stereo_image_t rejected: stereo pair 0 of site 0: image "
                     "'navcam_left': PNG 12000 x 12000 (144.0 MP), 1 channel(s) of 16 bit: over the limit of 4096 x "
                     "4096 px, 16.8 MP"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("JPEG 20000 x 16000 (320.0 MP), 3 channel(s) of 8 bit, progressive"), std::string::npos) << out;
  // Still serving: a good 1024 x 1024 pair and its DR pose make site 0.
  cv::Mat left(1024, 1024, CV_8UC1);
  cv::randu(left, 0, 255);
  StereoPair good;
  good.site_id = 0, good.pair_index = 0, good.num_pairs = 1, good.left = left, good.right = left.clone();
  bus.Send("NAVCAM_STEREO", Bytes(StereoPairToMessage(good, ImageEncoding::kPng)));
  PoseWithCovariance pose;
  pose.covariance = Matrix6d::Identity() * 0.01;
  bus.Send("SITE_POSE_DR", Bytes(SitePoseToMessage(0, site_pose_t::SOURCE_DEAD_RECKONING, pose)));
  EXPECT_TRUE(bus.PumpUntil([&] { return proc->output().find("site 0: first site (1 pairs)") != std::string::npos; },
                            60))
      << proc->output();
  const double peak_mb = PeakMb(proc->pid());
  std::printf("[untrusted] feature_frontend peak memory after two bomb pairs and a good pair: %.0f MB\n", peak_mb);
  EXPECT_LT(peak_mb, 800) << "a bomb was decoded (1.85 GB before the header check)";
  proc->Signal(SIGTERM);
  EXPECT_EQ(proc->WaitExit(20), std::optional<int>(0)) << proc->output();
}

// ---- 6 and 9: uav_mosaic_files -----------------------------------------

// `count` photos of one textured scene, 480 x 360, each shifted 60 px east of
// the previous, geotagged (EXIF GPS, time, focal length 4.5 mm of a 6.17 mm
// sensor) as a nadir survey at about 50 m would be.
std::vector<std::string> WriteSurvey(const std::string& dir, int count) {
  std::mt19937 rng(11);
  cv::Mat noise(720, 1200, CV_8UC1);
  cv::randu(noise, 0, 255);
  cv::Mat scene;
  cv::GaussianBlur(noise, scene, cv::Size(0, 0), 2.0);
  cv::normalize(scene, scene, 0, 255, cv::NORM_MINMAX);
  for (int k = 0; k < 60; ++k)
    cv::circle(scene, cv::Point(rng() % 1200, rng() % 720), 5 + rng() % 30, cv::Scalar(rng() % 256), -1);
  cv::cvtColor(scene, scene, cv::COLOR_GRAY2BGR);
  Exiv2::XmpParser::initialize();
  std::vector<std::string> paths;
  for (int i = 0; i < count; ++i) {
    const std::string path = dir + "/photo_" + std::to_string(i) + ".jpg";
    EXPECT_TRUE(cv::imwrite(path, scene(cv::Rect(100 + 60 * i, 150, 480, 360))));
    auto image = Exiv2::ImageFactory::open(path);
    image->readMetadata();
    Exiv2::ExifData& exif = image->exifData();
    exif["Exif.Image.Make"] = "Canon";
    exif["Exif.Image.Model"] = "Canon PowerShot SX260 HS";
    exif["Exif.GPSInfo.GPSLatitudeRef"] = "N";
    exif["Exif.GPSInfo.GPSLatitude"] = "30/1 10/1 164/10";
    exif["Exif.GPSInfo.GPSLongitudeRef"] = "W";
    // About 2.5 m east per photo (60 px at ~0.04 m/px... the test checks refusals, not the fit).
    exif["Exif.GPSInfo.GPSLongitude"] = "98/1 5/1 " + std::to_string(2400 - 10 * i) + "/100";
    exif["Exif.GPSInfo.GPSAltitude"] = Exiv2::URational(3173, 10);
    exif["Exif.Photo.DateTimeOriginal"] = "2014:10:19 13:20:" + std::to_string(10 + 2 * i);
    exif["Exif.Photo.FocalLength"] = Exiv2::URational(45, 10);
    image->writeMetadata();
    paths.push_back(path);
  }
  return paths;
}

TEST(UntrustedImages, UavMosaicFilesRefusesBombsAndAnOddSizedPhotoByNameTheRestRegisters) {
  Scratch s("bombs");
  const std::string photos = s.dir + "/photos";
  fs::create_directories(photos);
  WriteSurvey(photos, 4);
  WriteFile(photos + "/photo_2a_bomb.png", PngBomb(32000, 32000, 8, 2));
  WriteFile(photos + "/photo_2b_bomb.jpg", JpegBomb(20000, 16000));
  cv::Mat odd(200, 400, CV_8UC3, cv::Scalar(90, 120, 150));  // no EXIF: the survey's view assumed, too short
  ASSERT_TRUE(cv::imwrite(photos + "/photo_2c_odd.png", odd));
  Subprocess p({BinPath("uav_mosaic_files"), "--config", "config/procs/uav_mosaic_files.yaml", "--out",
                s.dir + "/mosaic.png", "--geojson", s.dir + "/route.geojson", photos});
  const std::optional<int> rc = p.WaitExit(240);
  const std::string& out = p.output();
  ASSERT_TRUE(rc.has_value()) << "hung:\n" << out;
  EXPECT_EQ(*rc, 2) << "photos were refused: outputs written, exit code 2\n" << out;
  EXPECT_NE(out.find("photo_2a_bomb.png: PNG 32000 x 32000 (1024.0 MP), 3 channel(s) of 8 bit: over the limit of "
                     "20000 x 20000 px, 100.0 MP; refused before decoding; skipped"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("photo_2b_bomb.jpg: JPEG 20000 x 16000"), std::string::npos) << out;
  EXPECT_NE(out.find("photo_2c_odd.png: 400 x 200 at a focal length of 291.7"), std::string::npos) << out;
  EXPECT_NE(out.find("px covers 480 x 240 px of the survey's 480 x 360 at its 350.08"), std::string::npos) << out;
  EXPECT_NE(out.find("(a narrower view than the survey's camera); skipped"), std::string::npos)
      << out;
  EXPECT_EQ(out.find("OpenCV error"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(s.dir + "/mosaic.png")) << out;
  EXPECT_NE(out.find("registered 4 of 4 frames"), std::string::npos) << out;
}

TEST(UntrustedImages, UavMosaicFilesRefusesExifAndXmpLiesByTagAndWritesValidGeoJson) {
  Scratch s("lies");
  const std::string photos = s.dir + "/photos";
  fs::create_directories(photos);
  const std::vector<std::string> paths = WriteSurvey(photos, 3);
  {
    auto image = Exiv2::ImageFactory::open(paths[0]);
    image->readMetadata();
    image->exifData()["Exif.Photo.FocalLength"] = Exiv2::URational(1, 2147483647);
    Exiv2::XmpProperties::registerNs("http://www.dji.com/drone-dji/1.0/", "drone-dji");
    image->xmpData()["Xmp.drone-dji.RelativeAltitude"] = "1e308";
    image->writeMetadata();
  }
  Subprocess p({BinPath("uav_mosaic_files"), "--config", "config/procs/uav_mosaic_files.yaml", "--out",
                s.dir + "/mosaic.png", "--geojson", s.dir + "/route.geojson", photos});
  const std::optional<int> rc = p.WaitExit(240);
  const std::string& out = p.output();
  ASSERT_TRUE(rc.has_value()) << "hung:\n" << out;
  EXPECT_EQ(*rc, 2) << "tags were refused: exit code 2\n" << out;
  EXPECT_NE(out.find("photo_0.jpg: Exif.Photo.FocalLength = 4.65661e-10 mm is outside [0.5, 2000] mm: refused"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("photo_0.jpg: Xmp.drone-dji.RelativeAltitude = 1e+308 m is outside [-500, 10000] m: refused"),
            std::string::npos)
      << out;
  // What is used instead is said: no focal length from EXIF, no relative altitude.
  EXPECT_EQ(out.find("focal length 4.5"), std::string::npos) << out;
  EXPECT_EQ(out.find("DJI relative altitude"), std::string::npos) << out;
  std::ifstream in(s.dir + "/route.geojson");
  ASSERT_TRUE(in) << out;
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  nlohmann::json json;
  ASSERT_NO_THROW(json = nlohmann::json::parse(text)) << text;
  EXPECT_EQ(json["type"], "FeatureCollection");
  EXPECT_EQ(text.find("inf"), std::string::npos) << text;
  EXPECT_EQ(text.find("nan"), std::string::npos) << text;
  for (const auto& f : json["features"])
    if (f["properties"].contains("height_m") && f["properties"]["height_m"].is_number()) {
      EXPECT_LT(std::abs(f["properties"]["height_m"].get<double>()), 1e4) << f.dump();
    }
}

// ---- 11: vloc_match, vloc_stereo ----------------------------------------

TEST(UntrustedImages, MatchingToolsRefuseTinyAndBombImagesInOneLine) {
  Scratch s("match");
  const std::string tiny = s.dir + "/tiny.png", bomb = s.dir + "/bomb.png", ok = s.dir + "/ok.png";
  ASSERT_TRUE(cv::imwrite(tiny, cv::Mat(1, 1, CV_8UC1, cv::Scalar(7))));
  WriteFile(bomb, PngBomb(32000, 32000, 8, 0));
  cv::Mat texture(200, 200, CV_8UC1);
  cv::randu(texture, 0, 255);
  ASSERT_TRUE(cv::imwrite(ok, texture));
  struct Case {
    std::vector<std::string> argv;
    std::string expected;
    bool refused = true;  // else: may run (exit 0), but must not crash
  };
  const std::vector<Case> cases = {
      {{BinPath("vloc_match"), tiny, tiny}, "vloc_match: " + tiny + ": PNG 1 x 1 (0.0 MP), 1 channel(s) of 8 bit is too "
                                            "small to match (at least 32 x 32 px)"},
      {{BinPath("vloc_match"), ok, bomb}, "vloc_match: " + bomb + ": PNG 32000 x 32000"},
      // vloc_stereo says its pair check cannot tell, and writes an empty map: no crash.
      {{BinPath("vloc_stereo"), tiny, tiny, "--out", s.dir + "/d.png"}, "", false},
      {{BinPath("vloc_stereo"), bomb, bomb, "--out", s.dir + "/d.png"}, bomb + ": PNG 32000 x 32000"},
      {{BinPath("vloc_stereo"), tiny, tiny, "--no-pair-check", "--out", s.dir + "/d.png"}, "", false},
  };
  for (const Case& c : cases) {
    Subprocess p(c.argv);
    const std::optional<int> rc = p.WaitExit(60);
    ASSERT_TRUE(rc.has_value()) << c.argv[0] << " hung:\n" << p.output();
    EXPECT_NE(*rc, 134) << "aborted:\n" << p.output();
    EXPECT_LT(*rc, 128) << "killed by a signal:\n" << p.output();
    EXPECT_EQ(p.output().find("OpenCV error"), std::string::npos) << p.output();
    if (!c.refused) continue;
    EXPECT_EQ(*rc, 1) << p.output();
    EXPECT_NE(p.output().find(c.expected), std::string::npos) << p.output();
    EXPECT_EQ(ErrorLines(p.output()).size(), 1u) << "one line:\n" << p.output();
  }
}

}  // namespace
}  // namespace vloc
