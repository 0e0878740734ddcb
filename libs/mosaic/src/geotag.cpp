#include "vloc/mosaic/geotag.h"

#include <exiv2/exiv2.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <mutex>

namespace vloc::mosaic {

namespace {

void InitExiv2Once() {
  static std::once_flag once;
  std::call_once(once, [] {
    Exiv2::XmpParser::initialize();
    Exiv2::LogMsg::setLevel(Exiv2::LogMsg::mute);
    try {
      Exiv2::XmpProperties::registerNs("http://www.dji.com/drone-dji/1.0/", "drone-dji");
    } catch (const std::exception&) {
      // Already registered (another library did it): fine.
    }
  });
}

double RationalValue(const Exiv2::Exifdatum& d, long i) {
  const Exiv2::Rational r = d.toRational(i);
  return r.second == 0 ? std::numeric_limits<double>::quiet_NaN() : static_cast<double>(r.first) / r.second;
}

double ExifNumber(const Exiv2::ExifData& exif, const char* key) {
  const auto it = exif.findKey(Exiv2::ExifKey(key));
  if (it == exif.end() || it->count() < 1) return std::numeric_limits<double>::quiet_NaN();
  if (it->typeId() == Exiv2::unsignedRational || it->typeId() == Exiv2::signedRational) return RationalValue(*it, 0);
  return static_cast<double>(it->toLong(0));
}

std::string ExifString(const Exiv2::ExifData& exif, const char* key) {
  const auto it = exif.findKey(Exiv2::ExifKey(key));
  if (it == exif.end()) return "";
  std::string s = it->toString();
  while (!s.empty() && (s.back() == '\0' || std::isspace(static_cast<unsigned char>(s.back())))) s.pop_back();
  return s;
}

// Degrees, minutes, seconds (three rationals) -> degrees.
double ExifDegrees(const Exiv2::ExifData& exif, const char* key) {
  const auto it = exif.findKey(Exiv2::ExifKey(key));
  if (it == exif.end() || it->count() < 1) return std::numeric_limits<double>::quiet_NaN();
  double deg = 0, unit = 1;
  for (long i = 0; i < std::min<long>(3, it->count()); ++i, unit /= 60) deg += RationalValue(*it, i) * unit;
  return deg;
}

// NaN when absent; a value present but not a number ("abc", "nan", "12 m")
// is named in tag->refused.
double XmpNumber(const Exiv2::XmpData& xmp, const char* key, ImageGeotag* tag) {
  std::string s;
  try {
    const auto it = xmp.findKey(Exiv2::XmpKey(key));
    if (it == xmp.end()) return std::numeric_limits<double>::quiet_NaN();
    s = it->toString();
  } catch (const std::exception&) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  while (end && std::isspace(static_cast<unsigned char>(*end))) ++end;
  if (end == s.c_str() || *end != '\0' || std::isnan(v)) {
    tag->refused.push_back(std::string(key) + " = '" + s.substr(0, 40) + "' is not a number: refused");
    return std::numeric_limits<double>::quiet_NaN();
  }
  return v;
}

// `*value` (read from `key`) when finite and in [lo, hi]; else NaN with a
// line in tag->refused. An absent tag (NaN) stays absent silently.
void RequireRange(const char* key, double lo, double hi, const char* unit, double* value, ImageGeotag* tag) {
  if (std::isnan(*value)) return;  // absent, or a rational with a zero denominator
  if (*value >= lo && *value <= hi) return;
  char line[256];
  std::snprintf(line, sizeof(line), "%s = %g %s is outside [%g, %g] %s: refused", key, *value, unit, lo, hi, unit);
  tag->refused.push_back(line);
  *value = std::numeric_limits<double>::quiet_NaN();
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

}  // namespace

bool ParseExifDateTime(const std::string& text, int64_t* utime) {
  int Y, M, D, h, m, s;
  if (std::sscanf(text.c_str(), "%d:%d:%d %d:%d:%d", &Y, &M, &D, &h, &m, &s) != 6) return false;
  if (Y < 1970 || M < 1 || M > 12 || D < 1 || D > 31 || h > 23 || m > 59 || s > 60) return false;
  std::tm t{};
  t.tm_year = Y - 1900;
  t.tm_mon = M - 1;
  t.tm_mday = D;
  t.tm_hour = h;
  t.tm_min = m;
  t.tm_sec = s;
  *utime = static_cast<int64_t>(timegm(&t)) * 1000000;
  return true;
}

double KnownSensorWidth(const std::string& make, const std::string& model) {
  // Widths in mm (1/2.3" compacts are 6.17 mm); DJI models by their EXIF model code.
  static const std::pair<const char*, double> kTable[] = {
      {"canon powershot sx260 hs", 6.17}, {"canon powershot elph 300 hs", 6.17}, {"canon powershot s100", 7.44},
      {"canon powershot s110", 7.44},     {"fc300s", 6.17},                      {"fc300x", 6.17},
      {"fc330", 6.17},                    {"fc6310", 13.2},                      {"fc220", 6.17},
      {"fc2103", 6.17},                   {"fc7203", 6.17},                      {"l1d-20c", 13.2},
      {"fc6510", 13.2},                   {"fc6520", 17.3},                      {"fc3170", 6.4},
      {"fc3411", 13.2},                   {"gopro hero4 black", 6.17},           {"dsc-rx100m2", 13.2},
  };
  const std::string key = Lower(model), key2 = Lower(make + " " + model);
  for (const auto& [name, width] : kTable)
    if (key == name || key2 == name) return width;
  return std::numeric_limits<double>::quiet_NaN();
}

namespace {

// GPS latitude, longitude (with their hemispheres) and altitude.
void ReadGpsPosition(const Exiv2::ExifData& exif, ImageGeotag* tag) {
  const double lat = ExifDegrees(exif, "Exif.GPSInfo.GPSLatitude");
  const double lon = ExifDegrees(exif, "Exif.GPSInfo.GPSLongitude");
  if (std::isfinite(lat) && std::isfinite(lon)) {
    const std::string lat_ref = ExifString(exif, "Exif.GPSInfo.GPSLatitudeRef");
    const std::string lon_ref = ExifString(exif, "Exif.GPSInfo.GPSLongitudeRef");
    tag->latitude = (!lat_ref.empty() && (lat_ref[0] == 'S' || lat_ref[0] == 's')) ? -lat : lat;
    tag->longitude = (!lon_ref.empty() && (lon_ref[0] == 'W' || lon_ref[0] == 'w')) ? -lon : lon;
    RequireRange("Exif.GPSInfo.GPSLatitude", -90, 90, "deg", &tag->latitude, tag);
    RequireRange("Exif.GPSInfo.GPSLongitude", -180, 180, "deg", &tag->longitude, tag);
    tag->has_gps = std::isfinite(tag->latitude) && std::isfinite(tag->longitude);
    if (!tag->has_gps) tag->latitude = tag->longitude = ImageGeotag::kNaN;
  }
  tag->altitude = ExifNumber(exif, "Exif.GPSInfo.GPSAltitude");
  if (std::isfinite(tag->altitude) && ExifNumber(exif, "Exif.GPSInfo.GPSAltitudeRef") == 1) tag->altitude = -tag->altitude;
  RequireRange("Exif.GPSInfo.GPSAltitude", GeotagRanges::kMinAltitude, GeotagRanges::kMaxAltitude, "m", &tag->altitude,
               tag);
}

// The GPS fix's UTC time and the camera's capture time (with its sub-seconds).
void ReadTimes(const Exiv2::ExifData& exif, ImageGeotag* tag) {
  const double gps_hours = ExifDegrees(exif, "Exif.GPSInfo.GPSTimeStamp");  // h, m, s rationals read as h + m/60 + s/3600
  int64_t gps_day = 0;
  if (std::isfinite(gps_hours) && gps_hours >= 0 && gps_hours < 24.0 &&
      ParseExifDateTime(ExifString(exif, "Exif.GPSInfo.GPSDateStamp") + " 00:00:00", &gps_day)) {
    tag->has_gps_time = true;
    tag->gps_utime = gps_day + static_cast<int64_t>(std::llround(gps_hours * 3600.0 * 1e6));
  }
  std::string when = ExifString(exif, "Exif.Photo.DateTimeOriginal");
  if (when.empty()) when = ExifString(exif, "Exif.Image.DateTime");
  tag->has_time = ParseExifDateTime(when, &tag->utime);
  if (tag->has_time) {
    const double sub = ExifNumber(exif, "Exif.Photo.SubSecTimeOriginal");
    if (std::isfinite(sub)) {
      const std::string digits = ExifString(exif, "Exif.Photo.SubSecTimeOriginal");
      tag->utime += static_cast<int64_t>(std::llround(std::atof(("0." + digits).c_str()) * 1e6));
    }
  }
}

// The lens and sensor: focal length (and its 35 mm equivalent), the EXIF
// width, the sensor width from the focal plane resolution or the camera
// table.
void ReadCamera(const Exiv2::ExifData& exif, ImageGeotag* tag) {
  tag->focal_mm = ExifNumber(exif, "Exif.Photo.FocalLength");
  RequireRange("Exif.Photo.FocalLength", GeotagRanges::kMinFocal, GeotagRanges::kMaxFocal, "mm", &tag->focal_mm, tag);
  tag->focal_35mm = ExifNumber(exif, "Exif.Photo.FocalLengthIn35mmFilm");
  if (tag->focal_35mm == 0) tag->focal_35mm = ImageGeotag::kNaN;  // 0: "unknown" in EXIF
  RequireRange("Exif.Photo.FocalLengthIn35mmFilm", GeotagRanges::kMinFocal35, GeotagRanges::kMaxFocal35, "mm",
               &tag->focal_35mm, tag);
  double px_w = ExifNumber(exif, "Exif.Photo.PixelXDimension");
  RequireRange("Exif.Photo.PixelXDimension", 1, GeotagRanges::kMaxExifWidth, "px", &px_w, tag);
  tag->exif_width = std::isfinite(px_w) ? static_cast<int>(px_w) : 0;
  // Focal plane resolution: pixels per unit (2 = inch, 3 = cm, 4 = mm).
  const double fpx = ExifNumber(exif, "Exif.Photo.FocalPlaneXResolution");
  const double unit = ExifNumber(exif, "Exif.Photo.FocalPlaneResolutionUnit");
  const double unit_mm = unit == 3 ? 10.0 : unit == 4 ? 1.0 : 25.4;
  if (fpx > 0 && tag->exif_width > 0) {
    tag->sensor_width_mm = tag->exif_width / fpx * unit_mm;
    tag->sensor_width_source = "exif focal plane resolution";
    RequireRange("Exif.Photo.FocalPlaneXResolution (sensor width)", GeotagRanges::kMinSensorWidth,
                 GeotagRanges::kMaxSensorWidth, "mm", &tag->sensor_width_mm, tag);
  }
  if (!std::isfinite(tag->sensor_width_mm)) {
    tag->sensor_width_mm = KnownSensorWidth(tag->make, tag->model);
    if (std::isfinite(tag->sensor_width_mm)) tag->sensor_width_source = "camera table";
  }
}

// DJI's XMP: relative altitude, gimbal and aircraft attitude, and the
// absolute altitude where EXIF has none.
void ReadDjiXmp(const Exiv2::XmpData& xmp, ImageGeotag* tag) {
  tag->relative_altitude = XmpNumber(xmp, "Xmp.drone-dji.RelativeAltitude", tag);
  tag->gimbal_pitch = XmpNumber(xmp, "Xmp.drone-dji.GimbalPitchDegree", tag);
  tag->gimbal_roll = XmpNumber(xmp, "Xmp.drone-dji.GimbalRollDegree", tag);
  tag->gimbal_yaw = XmpNumber(xmp, "Xmp.drone-dji.GimbalYawDegree", tag);
  tag->flight_pitch = XmpNumber(xmp, "Xmp.drone-dji.FlightPitchDegree", tag);
  tag->flight_roll = XmpNumber(xmp, "Xmp.drone-dji.FlightRollDegree", tag);
  tag->flight_yaw = XmpNumber(xmp, "Xmp.drone-dji.FlightYawDegree", tag);
  RequireRange("Xmp.drone-dji.RelativeAltitude", GeotagRanges::kMinAltitude, GeotagRanges::kMaxAltitude, "m",
               &tag->relative_altitude, tag);
  const double a = GeotagRanges::kMaxAngle;
  RequireRange("Xmp.drone-dji.GimbalPitchDegree", -a, a, "deg", &tag->gimbal_pitch, tag);
  RequireRange("Xmp.drone-dji.GimbalRollDegree", -a, a, "deg", &tag->gimbal_roll, tag);
  RequireRange("Xmp.drone-dji.GimbalYawDegree", -a, a, "deg", &tag->gimbal_yaw, tag);
  RequireRange("Xmp.drone-dji.FlightPitchDegree", -a, a, "deg", &tag->flight_pitch, tag);
  RequireRange("Xmp.drone-dji.FlightRollDegree", -a, a, "deg", &tag->flight_roll, tag);
  RequireRange("Xmp.drone-dji.FlightYawDegree", -a, a, "deg", &tag->flight_yaw, tag);
  if (!std::isfinite(tag->altitude)) {
    double abs_alt = XmpNumber(xmp, "Xmp.drone-dji.AbsoluteAltitude", tag);
    RequireRange("Xmp.drone-dji.AbsoluteAltitude", GeotagRanges::kMinAltitude, GeotagRanges::kMaxAltitude, "m",
                 &abs_alt, tag);
    if (std::isfinite(abs_alt)) tag->altitude = abs_alt;
  }
}

}  // namespace

bool ReadGeotag(const std::string& path, ImageGeotag* tag, std::string* error) {
  InitExiv2Once();
  *tag = ImageGeotag();
  try {
    auto image = Exiv2::ImageFactory::open(path);
    if (!image.get()) {
      if (error) *error = path + ": not an image exiv2 can read";
      return false;
    }
    image->readMetadata();
    const Exiv2::ExifData& exif = image->exifData();
    tag->make = ExifString(exif, "Exif.Image.Make");
    tag->model = ExifString(exif, "Exif.Image.Model");
    ReadGpsPosition(exif, tag);
    ReadTimes(exif, tag);
    ReadCamera(exif, tag);
    ReadDjiXmp(image->xmpData(), tag);
  } catch (const std::exception& e) {
    if (error) *error = path + ": cannot read its metadata (" + e.what() + ")";
    return false;
  }
  return true;
}

double FocalPixelsFromExif(const ImageGeotag& tag, int image_width, std::string* how) {
  if (tag.focal_mm > 0 && tag.sensor_width_mm > 0 && image_width > 0) {
    if (how)
      *how = "EXIF focal length " + std::to_string(tag.focal_mm) + " mm on a " + std::to_string(tag.sensor_width_mm) +
             " mm wide sensor (" + tag.sensor_width_source + ")";
    return tag.focal_mm / tag.sensor_width_mm * image_width;
  }
  if (tag.focal_35mm > 0 && image_width > 0) {
    if (how) *how = "EXIF 35 mm equivalent focal length " + std::to_string(tag.focal_35mm) + " mm";
    return tag.focal_35mm / 36.0 * image_width;
  }
  if (how) *how = "";
  return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace vloc::mosaic
