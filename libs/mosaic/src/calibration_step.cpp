#include "vloc/mosaic/calibration_step.h"

#include <glog/logging.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>

namespace vloc::mosaic {

Calibration CalibrationStep::Try(const cv::Mat& frame, double focal, double hag, std::string* why) {
  Calibration c;
  if (options_.source == "config") {
    c.valid = true;
    c.source = "config";
    c.height = options_.height;
    c.height_source = "config";
    c.focal_px = focal;
    c.pixels_per_metre = focal / options_.height;
  } else if (options_.source == "gps") {
    if (!(hag > 0)) {
      *why = "waiting for a GPS fix with height_above_ground (calibration.source: gps)";
    } else {
      c.valid = true;
      c.source = "gps";
      c.height = hag;
      c.height_source = "gps";
      c.focal_px = focal;
      c.pixels_per_metre = focal / hag;
    }
  } else {
    c = FromMarker(frame, focal, hag, why);
  }
  return c;
}

Calibration CalibrationStep::FromMarker(const cv::Mat& frame, double focal, double hag, std::string* why) {
  const CalibrationOptions& co = options_;
  MarkerObservation marker = DetectMarker(frame, co);
  const double height_for_marker = co.height > 0 ? co.height : (co.use_gps_height ? hag : std::nan(""));
  const bool need_height = co.use_gps_height || !co.focal_known;
  if (!marker.found) {
    *why = marker.why;
    return {};
  }
  if (need_height && !(height_for_marker > 0)) {
    *why = "marker seen but no height yet (GPS height_above_ground or calibration.height)";
    return {};
  }
  marker_sides_.push_back(marker.side_px);
  marker_heights_.push_back(height_for_marker);
  if (static_cast<int>(marker_sides_.size()) < co.frames_to_average) {
    *why = "marker seen " + std::to_string(marker_sides_.size()) + " of " + std::to_string(co.frames_to_average) +
           " times (averaging)";
    return {};
  }
  double side = 0, height = 0;
  for (size_t i = 0; i < marker_sides_.size(); ++i) {
    side += marker_sides_[i] / marker_sides_.size();
    height += marker_heights_[i] / marker_heights_.size();
  }
  marker.side_px = side;
  return CalibrateFromMarker(marker, need_height ? height : std::nan(""), focal, co, why);
}

cv::Mat FrameUndistorter::Undistort(const cv::Mat& image) {
  if (image.cols != camera_.width || image.rows != camera_.height) {
    // Scale the configured intrinsics to the frame size (same field of view).
    const double sx = static_cast<double>(image.cols) / configured_.width;
    const double sy = static_cast<double>(image.rows) / configured_.height;
    camera_ = configured_;
    camera_.width = image.cols;
    camera_.height = image.rows;
    camera_.fx *= sx; camera_.cx = (camera_.cx + 0.5) * sx - 0.5;
    camera_.fy *= sy; camera_.cy = (camera_.cy + 0.5) * sy - 0.5;
    map1_.release();
    if (!scaled_warned_) {
      LOG(WARNING) << "uav frames are " << image.cols << "x" << image.rows << " but camera is configured for "
                   << configured_.width << "x" << configured_.height
                   << "; intrinsics scaled to fit (fix camera.width/height in the config)";
      scaled_warned_ = true;
    }
  }
  if (!camera_.HasDistortion()) return image;
  if (map1_.empty() || map_size_ != image.size()) {
    cv::initUndistortRectifyMap(camera_.K(), camera_.DistortionCoeffs(), cv::noArray(), camera_.K(), image.size(),
                                CV_16SC2, map1_, map2_);
    map_size_ = image.size();
  }
  cv::Mat out;
  cv::remap(image, out, map1_, map2_, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return out;
}

}  // namespace vloc::mosaic
