// The evidence test every registration candidate's result must pass (registration.h).
#include <algorithm>
#include <string>

#include "vloc/mosaic/registration.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {

bool Evidence(const MotionEstimate& motion, const Similarity2& mosaic_from_frame,
              const std::optional<Prediction>& p, const cv::Point2d& c, const MosaickerOptions& options,
              std::string* why, int* gps_rejections) {
  if (!why->empty()) *why += "; ";
  if (motion.spread < options.min_spread) {
    *why += "matches cover only " + std::to_string(motion.spread) + " of the frame (" +
            std::to_string(motion.num_background) + " matches)";
    return false;
  }
  if (p && p->from_gps && motion.num_background < options.gps_check_below_inliers) {
    const double off_px = cv::norm(mosaic_from_frame.Apply(c) - p->gps_px) / std::max(1e-9, mosaic_from_frame.Scale());
    if (off_px > p->gps_tolerance_px) {
      ++*gps_rejections;
      *why += "registration lands " + std::to_string(static_cast<int>(off_px)) + " px (frame) from the GPS position (" +
              std::to_string(motion.num_background) + " matches)";
      return false;
    }
  }
  return true;
}

}  // namespace vloc::mosaic
