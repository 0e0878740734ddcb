#pragma once
// Geotags of a still photo: EXIF GPS position and altitude, time, focal
// length (and sensor size or 35 mm equivalent), and DJI's XMP tags (relative
// altitude above the take-off point, gimbal and flight attitude), read with
// exiv2. No LCM, no OpenCV.
//
//   ImageGeotag tag;
//   std::string error;
//   if (ReadGeotag("DJI_0001.JPG", &tag, &error) && tag.has_gps) ...
//   std::string how;
//   double f_px = FocalPixelsFromExif(tag, 4000, &how);  // NaN when EXIF cannot give it

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace vloc::mosaic {

struct ImageGeotag {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  std::string make, model;              // EXIF Image.Make / Image.Model
  bool has_gps = false;                 // latitude and longitude present
  double latitude = kNaN;               // deg, WGS84, north positive
  double longitude = kNaN;              // deg, WGS84, east positive
  double altitude = kNaN;               // m, GPS altitude (above sea level unless altitude_ref says below)
  bool has_gps_time = false;            // GPSDateStamp and GPSTimeStamp present: when the fix was taken (UTC)
  int64_t gps_utime = 0;                // us since 1970; a camera's GPS may tag a photo with an older fix
  bool has_time = false;                // DateTimeOriginal (or DateTime) present
  int64_t utime = 0;                    // us since 1970, the camera clock read as UTC (EXIF has no zone)
  double focal_mm = kNaN;               // mm, Photo.FocalLength
  double focal_35mm = kNaN;             // mm, Photo.FocalLengthIn35mmFilm
  double sensor_width_mm = kNaN;        // mm, from FocalPlaneXResolution (with the EXIF image width) or the camera table
  std::string sensor_width_source;      // "exif focal plane resolution", "camera table", ""
  int exif_width = 0;                   // px, Photo.PixelXDimension (0 = absent)
  // DJI XMP (drone-dji namespace); NaN when absent.
  double relative_altitude = kNaN;      // m, above the take-off point
  double gimbal_pitch = kNaN, gimbal_roll = kNaN, gimbal_yaw = kNaN;  // deg; nadir = pitch -90
  double flight_pitch = kNaN, flight_roll = kNaN, flight_yaw = kNaN;  // deg
  // Tags present but outside their physical range (GeotagRanges), one line
  // each naming the tag, e.g. "Xmp.drone-dji.RelativeAltitude = 1e+308 m is
  // outside [-500, 10000] m: refused". Their fields above stay NaN (absent).
  std::vector<std::string> refused;
};

// The physical ranges a tag must lie in to be used (outside: refused, the
// field left absent, ImageGeotag::refused says which).
struct GeotagRanges {
  static constexpr double kMinAltitude = -500, kMaxAltitude = 10000;            // m: GPS, absolute and relative altitude
  static constexpr double kMinFocal = 0.5, kMaxFocal = 2000;                    // mm: Photo.FocalLength
  static constexpr double kMinFocal35 = 2, kMaxFocal35 = 5000;                  // mm: Photo.FocalLengthIn35mmFilm
  static constexpr double kMinSensorWidth = 1, kMaxSensorWidth = 100;           // mm: from FocalPlaneXResolution
  static constexpr double kMaxAngle = 360;                                      // deg: gimbal and flight attitude, +-
  static constexpr int kMaxExifWidth = 200000;                                  // px: Photo.PixelXDimension
};

// False with one line in *error when the file cannot be read as an image
// with metadata. A file without any tag returns true with nothing set. A
// tag outside GeotagRanges is left absent and named in tag->refused.
bool ReadGeotag(const std::string& path, ImageGeotag* tag, std::string* error);

// Focal length in px for an image `image_width` px wide, from the EXIF focal
// length and sensor width, else the 35 mm equivalent (36 mm wide frame).
// NaN when neither is known. *how says which.
double FocalPixelsFromExif(const ImageGeotag& tag, int image_width, std::string* how);

// Sensor width (mm) of a few common survey cameras by EXIF model, NaN when
// not in the table.
double KnownSensorWidth(const std::string& make, const std::string& model);

// "YYYY:MM:DD HH:MM:SS" -> us since 1970 (read as UTC); false when malformed.
bool ParseExifDateTime(const std::string& text, int64_t* utime);

}  // namespace vloc::mosaic
