#pragma once
// Section 2.1: the pixels-per-metre ratio at a known height from an ArUco
// marker of known size, and (equation 1) the focal length f = h p / w when
// it is not known. Calibration can also come straight from the config.

#include <opencv2/core.hpp>
#include <string>

namespace vloc {
class OptionsReader;
}

namespace vloc::mosaic {

struct CalibrationOptions {
  std::string source = "marker";        // "marker" (ArUco, sec. 2.1), "config" (height + camera fx), "gps" (first GPS height above ground + camera fx)
  std::string dictionary = "DICT_4X4_50";  // ArUco dictionary of the marker
  int marker_id = -1;                   // marker id to use; -1 = any
  double marker_size = 1.0;             // m, side of the black square of the marker (w of eq. 1)
  double height = 0.0;                  // m, known height at calibration; 0 = take it from GPS height above ground
  bool focal_known = true;              // false = estimate f with equation 1 (needs a marker and a height)
  int max_frames = 100;                 // frames to search for the marker before reporting the problem (keeps trying)
  int frames_to_average = 10;           // marker sightings (and GPS heights) averaged before calibrating
  bool use_gps_height = true;           // marker: true = height from GPS height above ground (sec. 2.1); false = from the known focal (h = f w / p)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// What the marker detector saw.
struct MarkerObservation {
  bool found = false;
  int id = -1;
  double side_px = 0.0;                  // px, mean side length (p of eq. 1)
  cv::Point2d centre;                    // px
  std::string why;                       // when !found
};

// Detects the marker in `image` (gray or BGR, undistorted).
MarkerObservation DetectMarker(const cv::Mat& image, const CalibrationOptions& options);

// The result of calibration.
struct Calibration {
  bool valid = false;
  double height = 0.0;                   // m, height at the calibration frame
  double focal_px = 0.0;                 // px, focal length used from then on
  double pixels_per_metre = 0.0;         // px/m on the ground at `height` (= focal / height)
  bool focal_from_marker = false;        // equation 1 was used
  std::string source;                    // "marker", "config", "gps"
  std::string height_source;             // "gps", "config", "marker+focal"
  std::string Describe() const;
};

// Equation 1: f = h p / w.
double FocalFromMarker(double height, double side_px, double marker_size);

// Marker calibration. `known_height` (m) <= 0 or NaN means unknown; then the
// height comes from the known focal length (h = f w / p).
Calibration CalibrateFromMarker(const MarkerObservation& marker, double known_height, double camera_focal,
                                const CalibrationOptions& options, std::string* why);

}  // namespace vloc::mosaic
