#include "vloc/mosaic/survey_photos.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>

#include <map>

namespace vloc::mosaic {

namespace {

std::string SizeText(cv::Size s) { return std::to_string(s.width) + " x " + std::to_string(s.height); }

}  // namespace

SurveyPhotos CheckSurveyPhotos(const std::vector<std::string>& paths, const ImageLimits& limits, bool one_size) {
  SurveyPhotos out;
  std::vector<std::pair<std::string, ImageHeader>> readable;
  std::map<std::pair<int, int>, int> count;  // (width, height) -> photos
  for (const auto& path : paths) {
    ImageHeader h;
    std::string why;
    if (!ReadImageFileHeader(path, &h, &why) || !CheckImageHeader(h, limits, &why)) {
      out.refused.push_back((why.rfind(path, 0) == 0 ? why : path + ": " + why) + "; skipped");
      continue;
    }
    readable.emplace_back(path, h);
    ++count[{h.width, h.height}];
  }
  int best = 0;
  for (const auto& [path, h] : readable) {  // ties go to the earliest photo's size
    const int n = count[{h.width, h.height}];
    if (n > best) best = n, out.size = cv::Size(h.width, h.height);
  }
  for (const auto& [path, h] : readable) {
    if (!one_size || cv::Size(h.width, h.height) == out.size) {
      out.accepted.push_back(path);
      out.sizes.emplace_back(h.width, h.height);
    } else {
      out.refused.push_back(path + ": " + h.Describe() + " differs from the survey's " + SizeText(out.size) + " (" +
                            std::to_string(best) + " of " + std::to_string(readable.size()) + " photos); skipped");
    }
  }
  return out;
}

bool FitCamera(cv::Size size, double focal_px, cv::Size survey, double survey_focal_px, CameraFit* fit, std::string* why) {
  fit->scale = 1.0;
  if (size == survey && std::abs(focal_px / survey_focal_px - 1) < 1e-3) return true;
  fit->scale = survey_focal_px / focal_px;
  const cv::Size2d resampled(size.width * fit->scale, size.height * fit->scale);
  if (std::isfinite(fit->scale) && resampled.width >= survey.width - 0.5 && resampled.height >= survey.height - 0.5)
    return true;
  *why = SizeText(size) + " at a focal length of " + std::to_string(focal_px) + " px covers " +
         std::to_string(static_cast<int>(resampled.width)) + " x " + std::to_string(static_cast<int>(resampled.height)) +
         " px of the survey's " + SizeText(survey) + " at its " + std::to_string(survey_focal_px) +
         " px (a narrower view than the survey's camera)";
  return false;
}

cv::Mat ApplyCameraFit(const cv::Mat& photo, const CameraFit& fit, cv::Size survey) {
  if (fit.identity() || photo.empty()) return photo;
  cv::Mat resampled;
  cv::resize(photo, resampled, cv::Size(), fit.scale, fit.scale, fit.scale < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
  const cv::Rect crop((resampled.cols - survey.width) / 2, (resampled.rows - survey.height) / 2, survey.width,
                      survey.height);
  if ((crop & cv::Rect(0, 0, resampled.cols, resampled.rows)) != crop) return cv::Mat();
  return resampled(crop).clone();
}

cv::Mat LoadCheckedPhoto(const std::string& path, const ImageLimits& limits, cv::Size expected, std::string* error) {
  ImageHeader h;
  std::vector<uint8_t> bytes;
  if (!ReadCheckedImageFile(path, limits, &bytes, &h, error)) return cv::Mat();
  if (!expected.empty() && cv::Size(h.width, h.height) != expected) {
    if (error) *error = path + ": " + h.Describe() + " differs from the survey's " + SizeText(expected);
    return cv::Mat();
  }
  cv::Mat image;
  try {
    image = cv::imdecode(bytes, cv::IMREAD_COLOR);
  } catch (const cv::Exception& e) {
    if (error) *error = path + ": cannot be decoded (" + e.err + ")";
    return cv::Mat();
  }
  if (image.empty() && error) *error = path + ": " + h.Describe() + " cannot be decoded (corrupt data?)";
  return image;
}

}  // namespace vloc::mosaic
