#include "vloc/mosaic/survey_photos.h"

#include <opencv2/imgcodecs.hpp>

#include <map>

namespace vloc::mosaic {

namespace {

std::string SizeText(cv::Size s) { return std::to_string(s.width) + " x " + std::to_string(s.height); }

}  // namespace

SurveyPhotos CheckSurveyPhotos(const std::vector<std::string>& paths, const ImageLimits& limits) {
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
    if (cv::Size(h.width, h.height) == out.size) {
      out.accepted.push_back(path);
    } else {
      out.refused.push_back(path + ": " + h.Describe() + " differs from the survey's " + SizeText(out.size) + " (" +
                            std::to_string(best) + " of " + std::to_string(readable.size()) + " photos); skipped");
    }
  }
  return out;
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
