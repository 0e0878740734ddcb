#include "vloc/lcm_io/convert.h"

#include "vloc/lcm_io/convert_image.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vloc {

ImageEncoding ParseImageEncoding(const std::string& name) {
  if (name == "gray8") return ImageEncoding::kGray8;
  if (name == "rgb8") return ImageEncoding::kRgb8;
  if (name == "png") return ImageEncoding::kPng;
  if (name == "jpeg" || name == "jpg") return ImageEncoding::kJpeg;
  throw std::invalid_argument("unknown image encoding '" + name + "' (use gray8, rgb8, png or jpeg)");
}

image_t ImageToMessage(const cv::Mat& image, ImageEncoding encoding, int64_t utime, const std::string& frame_id,
                       int jpeg_quality) {
  if (image.empty()) throw std::invalid_argument("image for " + frame_id + " is empty");
  if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3))
    throw std::invalid_argument("image for " + frame_id + " must be 8-bit with 1 or 3 channels");
  image_t msg;
  msg.utime = utime;
  msg.frame_id = frame_id;
  msg.width = image.cols;
  msg.height = image.rows;
  switch (encoding) {
    case ImageEncoding::kGray8:
    case ImageEncoding::kRgb8: {
      const int channels = encoding == ImageEncoding::kGray8 ? 1 : 3;
      if (image.channels() != channels)
        throw std::invalid_argument("image for " + frame_id + ": " + (channels == 1 ? "gray8" : "rgb8") +
                                    " needs " + std::to_string(channels) + " channel(s), got " +
                                    std::to_string(image.channels()));
      cv::Mat pixels;
      if (channels == 3) cv::cvtColor(image, pixels, cv::COLOR_BGR2RGB);
      else pixels = image.isContinuous() ? image : image.clone();
      msg.encoding = channels == 1 ? image_t::ENCODING_GRAY8 : image_t::ENCODING_RGB8;
      msg.data.assign(pixels.datastart, pixels.dataend);
      break;
    }
    case ImageEncoding::kPng:
    case ImageEncoding::kJpeg: {
      const bool png = encoding == ImageEncoding::kPng;
      std::vector<int> params;
      if (png) params = {cv::IMWRITE_PNG_COMPRESSION, 1};
      else params = {cv::IMWRITE_JPEG_QUALITY, jpeg_quality};
      if (!cv::imencode(png ? ".png" : ".jpg", image, msg.data, params))
        throw std::invalid_argument("image for " + frame_id + ": encoding failed");
      msg.encoding = png ? image_t::ENCODING_PNG : image_t::ENCODING_JPEG;
      break;
    }
  }
  msg.size = static_cast<int32_t>(msg.data.size());
  return msg;
}

cv::Mat ImageFromMessage(const image_t& msg) { return ImageFromMessage(msg, ImageLimits()); }

cv::Mat ImageFromMessage(const image_t& msg, const ImageLimits& limits) {
  const std::string who = "image '" + msg.frame_id + "'";
  if (msg.size != static_cast<int32_t>(msg.data.size()))
    throw std::invalid_argument(who + ": size field does not match the data");
  switch (msg.encoding) {
    case image_t::ENCODING_GRAY8:
    case image_t::ENCODING_RGB8: {
      const int channels = msg.encoding == image_t::ENCODING_GRAY8 ? 1 : 3;
      if (msg.width <= 0 || msg.height <= 0)
        throw std::invalid_argument(who + ": width and height must be positive");
      if (msg.width > limits.max_width || msg.height > limits.max_height ||
          int64_t(msg.width) * msg.height > limits.max_pixels)
        throw std::invalid_argument(who + ": raw " + std::to_string(msg.width) + " x " + std::to_string(msg.height) +
                                    " over the limit of " + limits.Describe());
      const int64_t expected = int64_t(msg.width) * msg.height * channels;
      if (expected != msg.size)
        throw std::invalid_argument(who + ": " + std::to_string(msg.size) + " bytes for a " +
                                    std::to_string(msg.width) + "x" + std::to_string(msg.height) + "x" +
                                    std::to_string(channels) + " image (expected " + std::to_string(expected) + ")");
      cv::Mat view(msg.height, msg.width, channels == 1 ? CV_8UC1 : CV_8UC3,
                   const_cast<uint8_t*>(msg.data.data()));
      cv::Mat out;
      if (channels == 3) cv::cvtColor(view, out, cv::COLOR_RGB2BGR);
      else out = view.clone();
      return out;
    }
    case image_t::ENCODING_PNG:
    case image_t::ENCODING_JPEG: {
      // The header first: a 2 MB PNG can claim 12,000 x 12,000 16-bit pixels.
      ImageHeader header;
      std::string why;
      if (!InspectImage(msg.data.data(), msg.data.size(), limits, &header, &why))
        throw std::invalid_argument(who + ": " + why);
      const ImageFormat declared = msg.encoding == image_t::ENCODING_PNG ? ImageFormat::kPng : ImageFormat::kJpeg;
      if (header.format != declared)
        throw std::invalid_argument(who + ": declared " + ToString(declared) + " but the bytes are " +
                                    ToString(header.format));
      cv::Mat out = cv::imdecode(msg.data, cv::IMREAD_UNCHANGED);
      if (out.empty()) throw std::invalid_argument(who + ": compressed data cannot be decoded");
      if (out.depth() != CV_8U) out.convertTo(out, CV_8U);
      if (out.channels() == 4) cv::cvtColor(out, out, cv::COLOR_BGRA2BGR);
      return out;
    }
    default:
      throw std::invalid_argument(who + ": unknown encoding " + std::to_string(int(msg.encoding)));
  }
}

pose_t PoseToMessage(const PoseWithCovariance& pose, const std::string& frame_id, const std::string& child_frame_id) {
  pose_t msg;
  msg.utime = pose.utime;
  msg.frame_id = frame_id;
  msg.child_frame_id = child_frame_id;
  const Eigen::Vector3d t = pose.pose.translation();
  const Eigen::Quaterniond q(pose.pose.linear());
  for (int i = 0; i < 3; ++i) msg.position[i] = t[i];
  msg.orientation[0] = q.w();
  msg.orientation[1] = q.x();
  msg.orientation[2] = q.y();
  msg.orientation[3] = q.z();
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) msg.covariance[r * 6 + c] = pose.covariance(r, c);
  return msg;
}

PoseWithCovariance PoseFromMessage(const pose_t& msg) {
  PoseWithCovariance out;
  out.utime = msg.utime;
  Eigen::Vector3d t(msg.position[0], msg.position[1], msg.position[2]);
  Eigen::Quaterniond q(msg.orientation[0], msg.orientation[1], msg.orientation[2], msg.orientation[3]);
  if (!t.allFinite() || !q.coeffs().allFinite())
    throw std::invalid_argument("pose " + msg.frame_id + "_from_" + msg.child_frame_id + " is not finite");
  if (std::abs(q.norm() - 1.0) > 1e-3)
    throw std::invalid_argument("pose " + msg.frame_id + "_from_" + msg.child_frame_id +
                                ": quaternion is not unit length (norm " + std::to_string(q.norm()) + ")");
  out.pose = MakePose(q.normalized().toRotationMatrix(), t);
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) out.covariance(r, c) = msg.covariance[r * 6 + c];
  out.covariance = 0.5 * (out.covariance + out.covariance.transpose()).eval();
  std::string why;
  if (!IsPlausiblePose(out, &why))
    throw std::invalid_argument("pose " + msg.frame_id + "_from_" + msg.child_frame_id + ": " + why);
  return out;
}

site_pose_t SitePoseToMessage(int site_id, int8_t source, const PoseWithCovariance& world_from_body) {
  site_pose_t msg;
  msg.utime = world_from_body.utime;
  msg.site_id = site_id;
  msg.source = source;
  msg.pose = PoseToMessage(world_from_body, "world", "body");
  return msg;
}

}  // namespace vloc
