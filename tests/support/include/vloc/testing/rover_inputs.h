#pragma once
// Rover inputs the process tests send: textureless Navcam pairs, which the
// front end must answer (LOW_TEXTURE) without any rendering. Header-only;
// the test links vloc::common.

#include <cmath>
#include <opencv2/core.hpp>

#include "vloc/common/rover_data.h"

namespace vloc::testing {

// Stereo pair k (of 3) of `site`: uniform grey 80 + site, 1024 x 1024,
// panned (1 - k) x 26 deg and tilted 25 deg down; taken at
// (site * 10 + k + 1) s.
inline StereoPair TexturelessPair(int site, int k) {
  StereoPair p;
  p.utime = 1000000LL * (site * 10 + k + 1);
  p.site_id = site;
  p.pair_index = k;
  p.num_pairs = 3;
  p.mast_pan = (1 - k) * 26.0 * M_PI / 180;
  p.mast_tilt = 25.0 * M_PI / 180;
  p.left = cv::Mat(1024, 1024, CV_8UC1, cv::Scalar(80 + site));
  p.right = p.left.clone();
  return p;
}

}  // namespace vloc::testing
