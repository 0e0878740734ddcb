// The EXIF/XMP reader on JPEG files written here with known tags (exiv2).
#include <gtest/gtest.h>

#include <exiv2/exiv2.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <filesystem>
#include <string>

#include "vloc/mosaic/geotag.h"

namespace vloc::mosaic {
namespace {

std::string TempJpeg(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / "vloc_geotag_test";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / name).string();
  cv::Mat image(48, 64, CV_8UC3, cv::Scalar(40, 120, 200));
  EXPECT_TRUE(cv::imwrite(path, image));
  return path;
}

// 30 deg 10' 16.4" S, 98 deg 5' 24.0" W, 317.3 m, a DJI-style XMP packet.
void WriteKnownTags(const std::string& path, bool dji) {
  auto image = Exiv2::ImageFactory::open(path);
  ASSERT_TRUE(image.get());
  image->readMetadata();
  Exiv2::ExifData& exif = image->exifData();
  exif["Exif.Image.Make"] = dji ? "DJI" : "Canon";
  exif["Exif.Image.Model"] = dji ? "FC300S" : "Canon PowerShot SX260 HS";
  exif["Exif.GPSInfo.GPSLatitudeRef"] = "S";
  exif["Exif.GPSInfo.GPSLatitude"] = "30/1 10/1 164/10";
  exif["Exif.GPSInfo.GPSLongitudeRef"] = "W";
  exif["Exif.GPSInfo.GPSLongitude"] = "98/1 5/1 24/1";
  exif["Exif.GPSInfo.GPSAltitudeRef"] = uint8_t(0);
  exif["Exif.GPSInfo.GPSAltitude"] = Exiv2::URational(3173, 10);
  exif["Exif.Photo.DateTimeOriginal"] = "2014:10:19 13:20:51";
  if (!dji) {  // the fix's own time (UTC), 3.5 s after the camera clock's 13:20:51 read as UTC + 5 h
    exif["Exif.GPSInfo.GPSDateStamp"] = "2014:10:19";
    exif["Exif.GPSInfo.GPSTimeStamp"] = "18/1 20/1 545/10";
  }
  exif["Exif.Photo.FocalLength"] = Exiv2::URational(45, 10);
  if (dji) {
    Exiv2::XmpProperties::registerNs("http://www.dji.com/drone-dji/1.0/", "drone-dji");
    Exiv2::XmpData& xmp = image->xmpData();
    xmp["Xmp.drone-dji.RelativeAltitude"] = "+40.10";
    xmp["Xmp.drone-dji.GimbalPitchDegree"] = "-90.00";
    xmp["Xmp.drone-dji.GimbalYawDegree"] = "12.50";
    xmp["Xmp.drone-dji.FlightYawDegree"] = "11.20";
    xmp["Xmp.drone-dji.FlightRollDegree"] = "-1.50";
  }
  image->writeMetadata();
}

TEST(Geotag, ExifGpsTimeAndFocalReadBack) {
  const std::string path = TempJpeg("canon.jpg");
  WriteKnownTags(path, false);
  ImageGeotag tag;
  std::string error;
  ASSERT_TRUE(ReadGeotag(path, &tag, &error)) << error;
  ASSERT_TRUE(tag.has_gps);
  EXPECT_NEAR(tag.latitude, -(30 + 10 / 60.0 + 16.4 / 3600.0), 1e-9);
  EXPECT_NEAR(tag.longitude, -(98 + 5 / 60.0 + 24 / 3600.0), 1e-9);
  EXPECT_NEAR(tag.altitude, 317.3, 1e-9);
  ASSERT_TRUE(tag.has_time);
  EXPECT_EQ(tag.utime, int64_t{1413724851} * 1000000);  // 2014-10-19 13:20:51 UTC
  ASSERT_TRUE(tag.has_gps_time);
  EXPECT_EQ(tag.gps_utime, tag.utime + (int64_t{5} * 3600 * 1000000 + 3500000));
  EXPECT_NEAR(tag.focal_mm, 4.5, 1e-12);
  EXPECT_EQ(tag.model, "Canon PowerShot SX260 HS");
  EXPECT_TRUE(std::isnan(tag.relative_altitude));  // no XMP written
  std::string how;
  // 4.5 mm on the 6.17 mm sensor of the camera table, 1000 px wide: 729.3 px.
  EXPECT_NEAR(FocalPixelsFromExif(tag, 1000, &how), 4.5 / 6.17 * 1000, 1e-6);
  EXPECT_NE(how.find("camera table"), std::string::npos) << how;
}

TEST(Geotag, DjiXmpRelativeAltitudeAndAttitude) {
  const std::string path = TempJpeg("dji.jpg");
  WriteKnownTags(path, true);
  ImageGeotag tag;
  std::string error;
  ASSERT_TRUE(ReadGeotag(path, &tag, &error)) << error;
  EXPECT_NEAR(tag.relative_altitude, 40.10, 1e-9);
  EXPECT_FALSE(tag.has_gps_time);  // no GPSTimeStamp written
  EXPECT_NEAR(tag.gimbal_pitch, -90.0, 1e-9);
  EXPECT_NEAR(tag.gimbal_yaw, 12.5, 1e-9);
  EXPECT_NEAR(tag.flight_yaw, 11.2, 1e-9);
  EXPECT_NEAR(tag.flight_roll, -1.5, 1e-9);
  EXPECT_TRUE(std::isnan(tag.flight_pitch));
  EXPECT_EQ(tag.sensor_width_source, "camera table");  // FC300S (Phantom 3): 6.17 mm
}

TEST(Geotag, ThirtyFiveMillimetreEquivalentWhenTheSensorIsUnknown) {
  const std::string path = TempJpeg("unknown.jpg");
  {
    auto image = Exiv2::ImageFactory::open(path);
    image->readMetadata();
    image->exifData()["Exif.Image.Model"] = "Some Camera 9000";
    image->exifData()["Exif.Photo.FocalLength"] = Exiv2::URational(50, 10);
    image->exifData()["Exif.Photo.FocalLengthIn35mmFilm"] = uint16_t(24);
    image->writeMetadata();
  }
  ImageGeotag tag;
  ASSERT_TRUE(ReadGeotag(path, &tag, nullptr));
  EXPECT_FALSE(tag.has_gps);
  EXPECT_FALSE(tag.has_time);
  std::string how;
  EXPECT_NEAR(FocalPixelsFromExif(tag, 1200, &how), 24.0 / 36.0 * 1200, 1e-9);
  EXPECT_NE(how.find("35 mm"), std::string::npos) << how;
}

TEST(Geotag, UntaggedFileAndMissingFile) {
  const std::string path = TempJpeg("plain.jpg");
  ImageGeotag tag;
  std::string error;
  ASSERT_TRUE(ReadGeotag(path, &tag, &error)) << error;
  EXPECT_FALSE(tag.has_gps);
  EXPECT_TRUE(std::isnan(FocalPixelsFromExif(tag, 1000, nullptr)));
  EXPECT_FALSE(ReadGeotag("/nonexistent/photo.jpg", &tag, &error));
  EXPECT_NE(error.find("/nonexistent/photo.jpg"), std::string::npos) << error;
}

TEST(Geotag, ExifDateTimeParsing) {
  int64_t t = 0;
  EXPECT_TRUE(ParseExifDateTime("1970:01:02 00:00:00", &t));
  EXPECT_EQ(t, int64_t{86400} * 1000000);
  EXPECT_FALSE(ParseExifDateTime("2014-10-19", &t));
  EXPECT_FALSE(ParseExifDateTime("2014:13:19 10:00:00", &t));
}

}  // namespace
}  // namespace vloc::mosaic
