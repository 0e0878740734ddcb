#pragma once
// The mosaicker's first step on a new flight: the scale of the first frame
// (calibration.source: marker sightings averaged over frames, a GPS height
// above ground, or the configured height), and the frames' undistortion.

#include <opencv2/core.hpp>

#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/mosaic/calibration.h"

namespace vloc::mosaic {

// Calibration from the frames seen so far (sec. 2.1).
class CalibrationStep {
 public:
  explicit CalibrationStep(const CalibrationOptions& options) : options_(options) {}
  // Another frame (undistorted) with the camera's focal length (px) and the
  // latest GPS height above ground (NaN when none). A valid calibration, or
  // an invalid one with *why saying what is missing.
  Calibration Try(const cv::Mat& frame, double focal_px, double gps_height_above_ground, std::string* why);

 private:
  Calibration FromMarker(const cv::Mat& frame, double focal_px, double gps_height_above_ground, std::string* why);

  CalibrationOptions options_;
  std::vector<double> marker_sides_, marker_heights_;  // sightings being averaged
};

// Undistorts frames with the configured camera, its intrinsics scaled to the
// frame size when that differs from the configuration (one warning).
class FrameUndistorter {
 public:
  explicit FrameUndistorter(const PinholeCamera& camera) : configured_(camera), camera_(camera) {}
  cv::Mat Undistort(const cv::Mat& image);
  // The camera of the last frame (scaled to its size).
  const PinholeCamera& camera() const { return camera_; }
  // A frame undistorted elsewhere (FramePreparer) with this camera.
  void Adopt(const PinholeCamera& camera) { camera_ = camera; }

 private:
  PinholeCamera configured_;
  PinholeCamera camera_;
  cv::Mat map1_, map2_;
  cv::Size map_size_;
  bool scaled_warned_ = false;
};

}  // namespace vloc::mosaic
