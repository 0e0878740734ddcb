#pragma once
// Conversion between vloc messages and library structs. The only place
// where message types and algorithm types meet.

#include <opencv2/core.hpp>
#include <string>

#include "vloc/common/pose.h"
#include "vloc/image_t.hpp"
#include "vloc/pose_t.hpp"
#include "vloc/site_pose_t.hpp"

namespace vloc {

enum class ImageEncoding { kGray8, kRgb8, kPng, kJpeg };

// Parses "gray8", "rgb8", "png", "jpeg"/"jpg"; throws std::invalid_argument.
ImageEncoding ParseImageEncoding(const std::string& name);

// `image` is CV_8UC1 or CV_8UC3 (BGR, OpenCV's order). kGray8 needs one
// channel, kRgb8 three. Throws std::invalid_argument on a mismatch.
image_t ImageToMessage(const cv::Mat& image, ImageEncoding encoding, int64_t utime,
                       const std::string& frame_id, int jpeg_quality = 90);

// Returns CV_8UC1 or CV_8UC3 (BGR). Throws std::invalid_argument naming the
// problem when the message is inconsistent or cannot be decoded.
cv::Mat ImageFromMessage(const image_t& msg);

pose_t PoseToMessage(const PoseWithCovariance& pose, const std::string& frame_id,
                     const std::string& child_frame_id);
// Throws std::invalid_argument when the pose is not finite or the
// quaternion is not (close to) unit length.
PoseWithCovariance PoseFromMessage(const pose_t& msg);

site_pose_t SitePoseToMessage(int site_id, int8_t source, const PoseWithCovariance& world_from_body);

}  // namespace vloc
