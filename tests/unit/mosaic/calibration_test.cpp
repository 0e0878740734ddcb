// Section 2.1: an ArUco marker rendered into a synthetic nadir image at a
// known height gives back the pixels-per-metre ratio and (eq. 1) the focal.
#include <gtest/gtest.h>

#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include "synthetic_nadir.h"
#include "vloc/common/options.h"
#include "vloc/mosaic/calibration.h"

namespace vloc::mosaic {
namespace {

// A nadir frame at height h with focal f: a marker of `size` m (black square
// side; ArUco's own white border around it) centred at (cx, cy), rotated.
cv::Mat FrameWithMarker(double f, double h, double size, double angle_deg, cv::Point2d centre) {
  const testing::NadirCamera cam{cv::Size(1280, 720), f};
  const auto ground = testing::MakeGround(1500, 0.04, 3);
  cv::Mat frame = testing::RenderNadir(ground, cam, 0, 0, 20.0, 0.0);
  const int bits_px = 60;  // 4x4 dictionary: 6 cells across the black square
  cv::Mat marker;
  cv::aruco::drawMarker(cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50), 7, bits_px * 6, marker, 1);
  cv::Mat bordered;
  cv::copyMakeBorder(marker, bordered, bits_px, bits_px, bits_px, bits_px, cv::BORDER_CONSTANT, cv::Scalar(255));
  cv::cvtColor(bordered, bordered, cv::COLOR_GRAY2BGR);
  const double side_px = f * size / h;  // p = f w / h
  const double s = side_px / (bits_px * 6);
  cv::Mat M = cv::getRotationMatrix2D(cv::Point2f(bordered.cols / 2.0f, bordered.rows / 2.0f), angle_deg, s);
  M.at<double>(0, 2) += centre.x - bordered.cols / 2.0;
  M.at<double>(1, 2) += centre.y - bordered.rows / 2.0;
  cv::Mat warped, mask;
  cv::warpAffine(bordered, warped, M, frame.size(), cv::INTER_AREA);
  cv::warpAffine(cv::Mat(bordered.size(), CV_8UC1, cv::Scalar(255)), mask, M, frame.size(), cv::INTER_NEAREST);
  warped.copyTo(frame, mask);
  return frame;
}

TEST(MosaicCalibration, MarkerGivesRatioAndFocal) {
  CalibrationOptions options;
  options.marker_size = 1.0;
  options.focal_known = false;
  const double f = 1000.0, h = 10.0;
  const cv::Mat frame = FrameWithMarker(f, h, 1.0, 17.0, {700, 300});
  const MarkerObservation obs = DetectMarker(frame, options);
  ASSERT_TRUE(obs.found) << obs.why;
  EXPECT_EQ(obs.id, 7);
  EXPECT_NEAR(obs.side_px, 100.0, 1.0);  // subpixel corners: < 1 %
  std::string why;
  const Calibration c = CalibrateFromMarker(obs, h, 0.0, options, &why);
  ASSERT_TRUE(c.valid) << why;
  EXPECT_NEAR(c.pixels_per_metre, 100.0, 1.0);
  EXPECT_NEAR(c.focal_px, f, 10.0);  // eq. 1
  EXPECT_TRUE(c.focal_from_marker);
  EXPECT_DOUBLE_EQ(FocalFromMarker(10.0, 100.0, 1.0), 1000.0);
}

TEST(MosaicCalibration, KnownFocalGivesHeight) {
  CalibrationOptions options;
  options.marker_size = 0.8;
  const double f = 900.0, h = 15.0;
  const cv::Mat frame = FrameWithMarker(f, h, 0.8, -40.0, {400, 400});
  const MarkerObservation obs = DetectMarker(frame, options);
  ASSERT_TRUE(obs.found) << obs.why;
  std::string why;
  const Calibration c = CalibrateFromMarker(obs, std::nan(""), f, options, &why);
  ASSERT_TRUE(c.valid) << why;
  EXPECT_NEAR(c.height, h, 0.15);
  EXPECT_EQ(c.height_source, "marker+focal");
}

TEST(MosaicCalibration, NoMarkerSaysWhyAndBadOptionsAreRejected) {
  CalibrationOptions options;
  const cv::Mat plain = testing::RenderNadir(testing::MakeGround(800, 0.05, 1), testing::NadirCamera{}, 0, 0, 30, 0);
  const MarkerObservation obs = DetectMarker(plain, options);
  EXPECT_FALSE(obs.found);
  EXPECT_FALSE(obs.why.empty());
  YAML::Node node = YAML::Load("{source: marker, dictionary: DICT_9X9_1}");
  EXPECT_THROW(LoadOptions<CalibrationOptions>(node, "test"), ConfigError);
  node = YAML::Load("{source: marker, marker_sise: 1.0}");
  EXPECT_THROW(LoadOptions<CalibrationOptions>(node, "test"), ConfigError);
}

}  // namespace
}  // namespace vloc::mosaic
