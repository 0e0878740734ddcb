#pragma once
// A survey's photos checked before any is decoded: each header (PNG, JPEG,
// TIFF: vloc/common/image_header.h) against the tool's limits (a drone
// photo is at most about 100 MP) and, for one_size, against the other photos
// of the survey. A 1 MB PNG claiming 32,000 x 32,000 px is refused by name
// and the rest of the survey still registers. Photos of another camera (a
// second flight) are brought to the survey's by FitCamera.
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
  std::vector<cv::Size> sizes;        // of each accepted photo (px)
  std::vector<std::string> refused;   // one line each: "<path>: <why>; skipped"
  cv::Size size;                      // the survey's photo size (px): the most common one, ties to the earliest
};

// Reads every photo's header (no decoding): refuses the unreadable, those
// over `limits`, and (one_size) those whose size differs from the survey's.
SurveyPhotos CheckSurveyPhotos(const std::vector<std::string>& paths, const ImageLimits& limits, bool one_size = true);

// A photo of another camera (size, focal length) brought to the survey's:
// resampled by `scale` (the survey's focal / the photo's, both in px) and
// cropped about its centre to the survey's size. Identity when the photo is
// of the survey's camera.
struct CameraFit {
  double scale = 1.0;
  bool identity() const { return scale == 1.0; }
};
// The fit of a photo of `size` and focal `focal_px` to a survey of `survey`
// px and focal `survey_focal_px`; false with *why when, resampled, it does
// not cover the survey's frame (a narrower view than the survey's camera).
bool FitCamera(cv::Size size, double focal_px, cv::Size survey, double survey_focal_px, CameraFit* fit, std::string* why);
cv::Mat ApplyCameraFit(const cv::Mat& photo, const CameraFit& fit, cv::Size survey);

// Reads the file once, checks its header (limits, JPEG scans, and
// `expected` size unless empty) and decodes it as 8-bit BGR. Empty, with one
// line in *error naming the file, when refused or not decodable.
cv::Mat LoadCheckedPhoto(const std::string& path, const ImageLimits& limits, cv::Size expected, std::string* error);

}  // namespace vloc::mosaic
