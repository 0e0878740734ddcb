#include "vloc/mosaic/calibration.h"

#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <map>
#include <sstream>

#include "vloc/common/options.h"

namespace vloc::mosaic {

namespace {
bool DictionaryId(const std::string& name, int* id) {
  static const std::map<std::string, int> kIds = {
      {"DICT_4X4_50", cv::aruco::DICT_4X4_50},     {"DICT_4X4_100", cv::aruco::DICT_4X4_100},
      {"DICT_4X4_250", cv::aruco::DICT_4X4_250},   {"DICT_5X5_50", cv::aruco::DICT_5X5_50},
      {"DICT_5X5_100", cv::aruco::DICT_5X5_100},   {"DICT_6X6_50", cv::aruco::DICT_6X6_50},
      {"DICT_6X6_250", cv::aruco::DICT_6X6_250},   {"DICT_7X7_50", cv::aruco::DICT_7X7_50},
      {"DICT_ARUCO_ORIGINAL", cv::aruco::DICT_ARUCO_ORIGINAL}};
  auto it = kIds.find(name);
  if (it == kIds.end()) return false;
  *id = it->second;
  return true;
}
}  // namespace

void CalibrationOptions::Visit(OptionsReader& r) {
  r.Optional("source", &source, "marker | config | gps", OneOf({"marker", "config", "gps"}));
  r.Optional("dictionary", &dictionary, "ArUco dictionary, e.g. DICT_4X4_50",
             Rule<std::string>([](const std::string& d) { int id; return DictionaryId(d, &id); },
                               "an ArUco dictionary, e.g. DICT_4X4_50"));
  r.Optional("marker_id", &marker_id, "marker id, -1 = any");
  r.Optional("marker_size", &marker_size, "m, marker side", Positive());
  r.Optional("height", &height, "m, known calibration height; 0 = from GPS", NonNegative());
  r.Optional("focal_known", &focal_known, "false = estimate f by equation 1");
  r.Optional("max_frames", &max_frames, "frames to search for the marker before warning", AtLeast(1));
  r.Optional("frames_to_average", &frames_to_average, "marker sightings averaged", AtLeast(1));
  r.Optional("use_gps_height", &use_gps_height, "marker: height from GPS (true) or from the known focal (false)");
  r.Relation("height", source != "config" || height > 0, "must be > 0 with source 'config'");
  r.Relation("focal_known", focal_known || source == "marker", "false needs source 'marker'");
  r.Relation("height", focal_known || use_gps_height || height > 0,
             "must be > 0 (or use_gps_height true) when focal_known is false");
}

bool CalibrationOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

std::string Calibration::Describe() const {
  std::ostringstream s;
  s << "calibration " << (valid ? "valid" : "invalid") << ": source " << source << ", height " << height
    << " m (" << height_source << "), focal " << focal_px << " px" << (focal_from_marker ? " (eq. 1)" : "")
    << ", " << pixels_per_metre << " px/m";
  return s.str();
}

MarkerObservation DetectMarker(const cv::Mat& image, const CalibrationOptions& options) {
  MarkerObservation obs;
  int dict_id = cv::aruco::DICT_4X4_50;
  if (!DictionaryId(options.dictionary, &dict_id)) {
    obs.why = "unknown dictionary " + options.dictionary;
    return obs;
  }
  if (image.empty()) {
    obs.why = "empty frame";
    return obs;
  }
  cv::Mat gray;
  if (image.channels() == 3) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY); else gray = image;
  auto dictionary = cv::aruco::getPredefinedDictionary(dict_id);
  auto params = cv::aruco::DetectorParameters::create();
  params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
  std::vector<std::vector<cv::Point2f>> corners;
  std::vector<int> ids;
  cv::aruco::detectMarkers(gray, dictionary, corners, ids, params);
  for (size_t i = 0; i < ids.size(); ++i) {
    if (options.marker_id >= 0 && ids[i] != options.marker_id) continue;
    const auto& c = corners[i];
    double side = 0;
    cv::Point2d centre(0, 0);
    for (int k = 0; k < 4; ++k) {
      side += cv::norm(c[k] - c[(k + 1) % 4]);
      centre += cv::Point2d(c[k]);
    }
    obs.found = true;
    obs.id = ids[i];
    obs.side_px = side / 4.0;
    obs.centre = centre / 4.0;
    return obs;
  }
  obs.why = ids.empty() ? "no ArUco marker of " + options.dictionary + " in the frame"
                        : "marker id " + std::to_string(options.marker_id) + " not among the detected markers";
  return obs;
}

double FocalFromMarker(double height, double side_px, double marker_size) { return height * side_px / marker_size; }

Calibration CalibrateFromMarker(const MarkerObservation& marker, double known_height, double camera_focal,
                                const CalibrationOptions& options, std::string* why) {
  Calibration c;
  c.source = "marker";
  if (!marker.found || !(marker.side_px > 0)) {
    if (why) *why = marker.why.empty() ? "no marker" : marker.why;
    return c;
  }
  const bool height_known = std::isfinite(known_height) && known_height > 0;
  if (!options.focal_known) {
    if (!height_known) {
      if (why) *why = "focal length unknown and no height (GPS height above ground or calibration.height) to use eq. 1";
      return c;
    }
    c.height = known_height;
    c.focal_px = FocalFromMarker(known_height, marker.side_px, options.marker_size);
    c.focal_from_marker = true;
    c.height_source = options.height > 0 ? "config" : "gps";
  } else if (height_known) {
    c.height = known_height;
    c.focal_px = camera_focal;
    c.height_source = options.height > 0 ? "config" : "gps";
  } else {
    // Known focal length: the marker gives the height (triangle similarity).
    c.focal_px = camera_focal;
    c.height = camera_focal * options.marker_size / marker.side_px;
    c.height_source = "marker+focal";
  }
  // pixels per metre on the ground at the calibration height: p / w.
  c.pixels_per_metre = marker.side_px / options.marker_size;
  c.valid = c.focal_px > 0 && c.height > 0;
  if (!c.valid && why) *why = "calibration produced a non-positive focal length or height";
  return c;
}

}  // namespace vloc::mosaic
