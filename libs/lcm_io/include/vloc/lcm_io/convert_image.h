#pragma once
// Images from the bus with their size checked before decoding: the PNG or
// JPEG header (vloc/common/image_header.h) against the receiving channel's
// limits. ImageFromMessage(msg) of convert.h uses the default ImageLimits
// (any drone photo, about 100 MP); a channel whose camera is known passes
// its own (a Navcam image is 1024 x 1024):
//
//   ImageLimits navcam;  navcam.max_width = navcam.max_height = 4096;  navcam.max_pixels = 4096 * 4096;
//   StereoPair pair = StereoPairFromMessage(msg, navcam);  // throws: "... PNG 12000 x 12000 ...: over the limit ..."

#include <opencv2/core.hpp>

#include "vloc/common/image_header.h"
#include "vloc/common/rover_data.h"
#include "vloc/image_t.hpp"
#include "vloc/stereo_image_t.hpp"

namespace vloc {

// As ImageFromMessage(msg), refusing (std::invalid_argument, one line naming
// the image and its size) an image over `limits`, compressed bytes whose
// header is not the declared encoding, and a JPEG with too many scans.
cv::Mat ImageFromMessage(const image_t& msg, const ImageLimits& limits);

// As StereoPairFromMessage(msg), both images checked against `limits`.
StereoPair StereoPairFromMessage(const stereo_image_t& msg, const ImageLimits& limits);

}  // namespace vloc
