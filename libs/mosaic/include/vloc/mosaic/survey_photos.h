#pragma once
// A survey's photos checked before any is decoded: each header (PNG, JPEG,
// TIFF: vloc/common/image_header.h) against the tool's limits (a drone
// photo is at most about 100 MP) and against the other photos of the survey
// (one camera: one size). A 1 MB PNG claiming 32,000 x 32,000 px is refused
// by name and the rest of the survey still registers.
//
//   SurveyPhotos photos = CheckSurveyPhotos(paths, ImageLimits());
//   for (const auto& r : photos.refused) std::cerr << r << "\n";          // one line per refused photo
//   cv::Mat image = LoadCheckedPhoto(photos.accepted[0], limits, photos.size, &why);  // empty + why when refused

#include <opencv2/core.hpp>

#include <string>
#include <vector>

#include "vloc/common/image_header.h"

namespace vloc::mosaic {

struct SurveyPhotos {
  std::vector<std::string> accepted;  // in the given order
  std::vector<std::string> refused;   // one line each: "<path>: <why>; skipped"
  cv::Size size;                      // the survey's photo size (px): the most common one, ties to the earliest
};

// Reads every photo's header (no decoding): refuses the unreadable, those
// over `limits`, and those whose size differs from the survey's.
SurveyPhotos CheckSurveyPhotos(const std::vector<std::string>& paths, const ImageLimits& limits);

// Reads the file once, checks its header (limits, JPEG scans, and
// `expected` size unless empty) and decodes it as 8-bit BGR. Empty, with one
// line in *error naming the file, when refused or not decodable.
cv::Mat LoadCheckedPhoto(const std::string& path, const ImageLimits& limits, cv::Size expected, std::string* error);

}  // namespace vloc::mosaic
