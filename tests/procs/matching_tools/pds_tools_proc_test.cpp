// vloc_stereo and vloc_match on PDS3 products written by the test: a raw
// (non-rectified) CAHVOR stereo pair with known models, rectified by the
// tools through vloc::LineariseStereoPair before matching (issue 33).
//
// The scene: a plane 10 m out along the left camera's axis, tilted 20 deg,
// textured with a real Curiosity Navcam frame (sol60 NLA_402815759, when
// ../shared/data is present; else a synthetic blob texture) seen through
// the left camera: the left raw image is that frame, the right raw image
// is the plane seen through a second known CAHVOR camera (0.424 m to the
// right, toed in 1.5 deg, rolled 0.8 deg, its own distortion). The left
// model is the sol60 frame's label model.
//
// What is asserted, from the models: the raw pair's rows disagree by
// max_raw_row_error_px (> 5 px here: vloc_stereo refuses it with
// --no-rectify); after rectification the models' rows agree to
// model_row_error_max_px (~1e-9 px), so the matched points' row error is
// the resampling and feature localisation noise alone: median below
// kRowNoisePx (0.2 px: SIFT / LSM localisation on a bilinearly resampled
// image, ~0.1 px 1-sigma). The disparities lie within the range the models
// give the plane.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <regex>
#include <sstream>
#include <string>

#include <Eigen/Geometry>

#include "pds_fixtures.h"
#include "test_images.h"
#include "vloc/common/cahvor.h"
#include "vloc/common/pds_label.h"
#include "tool_run.h"
#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

constexpr double kRowNoisePx = 0.2;  // px, median row error of matched points on an exactly rectified pair

std::string TempDir() { return testing::ToolTempDir("vloc_pds_tools"); }

using testing::Number;
using testing::RunTool;
using testing::ToolRun;

std::string Vec(const Eigen::Vector3d& v) {
  std::ostringstream os;
  os.precision(17);
  os << "(" << v.x() << "," << v.y() << "," << v.z() << ")";
  return os.str();
}

CahvModel ParseModel(const char* const text[6]) {
  Eigen::Vector3d v[6];
  for (int k = 0; k < 6; ++k) {
    std::string s = text[k];
    for (char& c : s)
      if (c == '(' || c == ')' || c == ',') c = ' ';
    std::istringstream is(s);
    is >> v[k].x() >> v[k].y() >> v[k].z();
  }
  CahvModel m;
  m.kind = CahvKind::kCahvor;
  m.c = v[0], m.a = v[1].normalized(), m.h = v[2], m.v = v[3], m.o = v[4].normalized(), m.r = v[5];
  return m;
}

// MODEL_COMPONENT_1.. of a CAHVOR, or of a CAHVORE (E, type 3 = general, linearity).
std::vector<std::string> Components(const CahvModel& m) {
  std::vector<std::string> c = {Vec(m.c), Vec(m.a), Vec(m.h), Vec(m.v), Vec(m.o), Vec(m.r)};
  if (m.kind == CahvKind::kCahvore) c.insert(c.end(), {Vec(m.e), "3", std::to_string(m.linearity)});
  return c;
}

// The scene plane n.(p - c) = d, in the left model's reference frame.
struct Plane {
  Eigen::Vector3d n, c;
  double d;
  std::optional<Eigen::Vector3d> Hit(const CameraRay& ray) const {
    const double den = n.dot(ray.direction);
    if (!(den > 1e-6)) return std::nullopt;
    const double t = (d - n.dot(ray.origin - c)) / den;
    if (!(t > 0)) return std::nullopt;
    return ray.At(t);
  }
};

// The raw pair, its models, and the products written from them.
struct RawPair {
  CahvModel left, right;
  Plane plane;
  cv::Mat left_image, right_image;
  bool real = false;  // the left image is the shared Curiosity frame
  std::string left_path, right_path;  // left: .IMG (attached label); right: .LBL + browse .png
};

// right_cahvore: the right camera is a CAHVORE (general, linearity 0.95, a moving pupil).
RawPair MakeRawPair(const std::string& dir, bool right_cahvore = false) {
  RawPair p;
  p.left = ParseModel(testing::kPdsFixtureModel);  // sol60 NLA_402815759
  p.left_image = cv::imread(std::string(VLOC_SOURCE_DIR) +
                                "/../shared/data/real/mars_navcam_pano/sol60/NLA_402815759EDR_F0050104NCAM00451M_.jpg",
                            cv::IMREAD_GRAYSCALE);
  p.real = !p.left_image.empty();
  if (!p.real) {
    const testing::BlobTexture tex(1024, 1024, 1024 * 1024 / 20, 33, 1.5, 4.0);
    p.left_image.create(1024, 1024, CV_8UC1);
    for (int y = 0; y < 1024; ++y)
      for (int x = 0; x < 1024; ++x) p.left_image.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(tex(x, y));
  }
  // The right camera: 0.424 m along the left's H', toed in and rolled, its own distortion.
  const Eigen::Vector3d hp = (p.left.h - p.left.hc() * p.left.a).normalized();
  const Eigen::Vector3d vp = (p.left.v - p.left.vc() * p.left.a).normalized();
  const Eigen::Matrix3d rot = (Eigen::AngleAxisd(1.5 * M_PI / 180, vp) * Eigen::AngleAxisd(0.8 * M_PI / 180, p.left.a))
                                  .toRotationMatrix();
  p.right = p.left;
  p.right.c = p.left.c + 0.424 * hp;
  p.right.a = rot * p.left.a, p.right.h = rot * p.left.h, p.right.v = rot * p.left.v, p.right.o = rot * p.left.o;
  p.right.h += 6.0 * p.right.a;  // principal point 6 px right
  p.right.r = Eigen::Vector3d(0.0005, -0.008, 0.03);
  if (right_cahvore) {
    p.right.kind = CahvKind::kCahvore;
    p.right.e = Eigen::Vector3d(0.002, 0.001, 0.0);
    p.right.linearity = 0.95;
  }
  // The plane: 10 m along A, its normal tilted 20 deg about H'.
  p.plane.c = p.left.c;
  p.plane.n = Eigen::AngleAxisd(20 * M_PI / 180, hp) * p.left.a;
  p.plane.d = 10.0;
  // The right image: each right pixel's ray onto the plane, through the left model into the left image.
  cv::Mat map_x(p.left_image.size(), CV_32FC1, cv::Scalar(-1)), map_y(p.left_image.size(), CV_32FC1, cv::Scalar(-1));
  for (int y = 0; y < map_x.rows; ++y)
    for (int x = 0; x < map_x.cols; ++x) {
      const std::optional<CameraRay> ray = p.right.BackProject(Eigen::Vector2d(x, y));
      const std::optional<Eigen::Vector3d> hit = ray ? p.plane.Hit(*ray) : std::nullopt;
      const std::optional<Eigen::Vector2d> px = hit ? p.left.Project(*hit) : std::nullopt;
      if (px) map_x.at<float>(y, x) = static_cast<float>(px->x()), map_y.at<float>(y, x) = static_cast<float>(px->y());
    }
  cv::remap(p.left_image, p.right_image, map_x, map_y, cv::INTER_CUBIC, cv::BORDER_CONSTANT, cv::Scalar(0));
  // The products.
  testing::PdsFixtureFrame f;
  f.lines = p.left_image.rows, f.samples = p.left_image.cols, f.record_bytes = 4096;
  f.model = Components(p.left);
  testing::WriteAttachedImg(dir + "/LEFT.IMG", f, p.left_image);
  f.frame_id = "RIGHT", f.instrument_id = "NAV_RIGHT_A", f.model = Components(p.right);
  f.model_type = right_cahvore ? "CAHVORE" : "CAHVOR";
  testing::WriteBrowse(dir, "RIGHT", "RIGHT.png", f, p.right_image);
  p.left_path = dir + "/LEFT.IMG";
  p.right_path = dir + "/RIGHT.LBL";
  return p;
}

// The disparities the rectified models give the plane (over the left
// rectified image): min and max, px.
std::pair<double, double> PlaneDisparities(const RawPair& p) {
  const RectifiedStereoPair r = LineariseStereoPair(p.left, p.right, p.left_image.size());
  double lo = 1e9, hi = -1e9;
  for (int gy = 1; gy < 16; ++gy)
    for (int gx = 1; gx < 16; ++gx) {
      const std::optional<CameraRay> ray = r.left.BackProject(Eigen::Vector2d(64.0 * gx, 64.0 * gy));
      const std::optional<Eigen::Vector3d> hit = ray ? p.plane.Hit(*ray) : std::nullopt;
      if (!hit) continue;
      const auto l = r.left.Project(*hit), q = r.right.Project(*hit);
      if (!l || !q || q->x() < 0 || q->x() > 1023) continue;
      lo = std::min(lo, l->x() - q->x()), hi = std::max(hi, l->x() - q->x());
    }
  return {lo, hi};
}

TEST(PdsTools, VlocStereoRectifiesARawCahvorPairBeforeMatching) {
  const std::string dir = TempDir();
  const RawPair p = MakeRawPair(dir);
  if (!p.real) std::cout << "../shared/data absent: the scene is textured with a synthetic image\n";
  const std::pair<double, double> expected = PlaneDisparities(p);
  const ToolRun raw = RunTool({testing::BinPath("vloc_stereo"), p.left_path, p.right_path, "--no-rectify", "--auto-range",
                           "--out", dir + "/raw.png"});
  EXPECT_EQ(raw.exit_code, 1) << raw.output;
  EXPECT_NE(raw.output.find("not rectified"), std::string::npos) << raw.output;
  const ToolRun r = RunTool({testing::BinPath("vloc_stereo"), p.left_path, p.right_path, "--auto-range", "--rectified",
                         dir + "/rect", "--out", dir + "/disp.pfm"});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::cout << r.output;
  EXPECT_NE(r.output.find("linearised: true"), std::string::npos) << r.output;
  EXPECT_GT(Number(r.output, "raw_row_error_max_px"), 5.0) << r.output;
  EXPECT_LT(Number(r.output, "model_row_error_max_px"), 1e-6) << r.output;
  const double row_median = Number(r.output, "median"), row_p90 = Number(r.output, "p90");
  EXPECT_LT(row_median, kRowNoisePx) << r.output;
  EXPECT_LT(row_p90, 3 * kRowNoisePx) << r.output;
  const double disparity = Number(r.output, "disparity_median_px");
  EXPECT_GT(disparity, expected.first - 1) << r.output;
  EXPECT_LT(disparity, expected.second + 1) << r.output;
  EXPECT_GT(Number(r.output, "lsm_matches"), 1000) << r.output;
  EXPECT_FALSE(cv::imread(dir + "/rect_left.png").empty());
  std::filesystem::remove_all(dir);
}

// The same with a CAHVORE right camera (rays taken at the plane's range, 10 m).
TEST(PdsTools, VlocStereoRectifiesARawCahvorCahvorePair) {
  const std::string dir = TempDir();
  const RawPair p = MakeRawPair(dir, true);
  const std::pair<double, double> expected = PlaneDisparities(p);
  const ToolRun r = RunTool({testing::BinPath("vloc_stereo"), p.left_path, p.right_path, "--auto-range",
                             "--rectify-range", "10", "--out", dir + "/disp.pfm"});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::cout << r.output;
  EXPECT_NE(r.output.find("raw_models: [CAHVOR, CAHVORE]"), std::string::npos) << r.output;
  EXPECT_GT(Number(r.output, "raw_row_error_max_px"), 5.0) << r.output;
  EXPECT_LT(Number(r.output, "model_row_error_max_px"), 1e-6) << r.output;
  EXPECT_LT(Number(r.output, "median"), kRowNoisePx) << r.output;
  EXPECT_LT(Number(r.output, "p90"), 3 * kRowNoisePx) << r.output;
  const double disparity = Number(r.output, "disparity_median_px");
  EXPECT_GT(disparity, expected.first - 1) << r.output;
  EXPECT_LT(disparity, expected.second + 1) << r.output;
  std::filesystem::remove_all(dir);
}

TEST(PdsTools, VlocMatchRectifiesAndReportsTheRowErrorOfItsInliers) {
  const std::string dir = TempDir();
  const RawPair p = MakeRawPair(dir);
  const ToolRun r = RunTool({testing::BinPath("vloc_match"), p.left_path, p.right_path, "--rectify"});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::cout << r.output;
  EXPECT_NE(r.output.find("linearised: true"), std::string::npos) << r.output;
  EXPECT_GT(Number(r.output, "refined_inliers"), 100) << r.output;
  EXPECT_LT(Number(r.output, "median"), kRowNoisePx) << r.output;
  EXPECT_LT(Number(r.output, "p95"), 3 * kRowNoisePx) << r.output;
  std::filesystem::remove_all(dir);
}

// The shared Curiosity products as the galleries serve them (a browse .jpg
// and its ...M1.LBL): two adjacent frames of the sol60 panorama, one named
// by its image, one by its label, matched by vloc_match (a mast rotation: a
// homography up to the lenses' distortion).
TEST(PdsTools, VlocMatchReadsTheSharedCuriosityProducts) {
  const std::string dir = std::string(VLOC_SOURCE_DIR) + "/../shared/data/real/mars_navcam_pano/sol60/";
  if (!std::filesystem::exists(dir + "NLA_402815759EDR_F0050104NCAM00451M1.LBL"))
    GTEST_SKIP() << "../shared/data/real/mars_navcam_pano absent (real data beside the repo, see ../shared/data/README.md)";
  const ToolRun r = RunTool({testing::BinPath("vloc_match"), dir + "NLA_402815759EDR_F0050104NCAM00451M_.jpg",
                             dir + "NLA_402815839EDR_F0050104NCAM00451M1.LBL"});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::cout << r.output;
  EXPECT_GT(Number(r.output, "inliers"), 30) << r.output;
}

TEST(PdsTools, UnusableLabelsAndPairsAreOneLineNamingFileAndKeyword) {
  const std::string dir = TempDir();
  const cv::Mat image = testing::FixtureImage(50);
  testing::PdsFixtureFrame f;
  testing::WriteAttachedImg(dir + "/GOOD.IMG", f, image);
  f.model_4 = "(1.0, 2.0)";
  testing::WriteAttachedImg(dir + "/BAD.IMG", f, image);
  for (const std::string tool : {"vloc_stereo", "vloc_match"}) {
    std::vector<std::string> argv = {testing::BinPath(tool), dir + "/GOOD.IMG", dir + "/BAD.IMG"};
    if (tool == "vloc_stereo") argv.insert(argv.end(), {"--out", dir + "/d.png"});
    if (tool == "vloc_match") argv.push_back("--rectify");
    const ToolRun r = RunTool(argv);
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("BAD.IMG: MODEL_COMPONENT_4 of GEOMETRIC_CAMERA_MODEL_PARMS"), std::string::npos) << r.output;
  }
  // Two products of the same camera centre are no stereo pair.
  const ToolRun same = RunTool({testing::BinPath("vloc_stereo"), dir + "/GOOD.IMG", dir + "/GOOD.IMG", "--out", dir + "/d.png"});
  EXPECT_EQ(same.exit_code, 1) << same.output;
  EXPECT_NE(same.output.find("GEOMETRIC_CAMERA_MODEL_PARMS: the camera models cannot be rectified"), std::string::npos)
      << same.output;
  // A browse image without its label.
  cv::imwrite(dir + "/orphan.png", image);
  const ToolRun orphan = RunTool({testing::BinPath("vloc_stereo"), dir + "/GOOD.IMG", dir + "/orphan.png", "--out", dir + "/d.png"});
  EXPECT_EQ(orphan.exit_code, 1) << orphan.output;
  EXPECT_NE(orphan.output.find("orphan.png is not a PDS product"), std::string::npos) << orphan.output;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vloc
