#include "vloc/mosaic/survey_eval.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <stdexcept>

#include "vloc/common/printable.h"
#include "vloc/common/stats.h"

namespace vloc::mosaic {

namespace {

// Similarity (x, -y) route px -> ENU over the frames with fit[i].
bool FitRoute(const std::vector<cv::Point2d>& route_px, const std::vector<cv::Point2d>& gps_enu,
              const std::vector<bool>& fit, Similarity2* enu_from_flipped) {
  std::vector<cv::Point2d> from, to;
  for (size_t i = 0; i < route_px.size(); ++i) {
    if (!fit[i]) continue;
    from.emplace_back(route_px[i].x, -route_px[i].y);
    to.push_back(gps_enu[i]);
  }
  return from.size() >= 3 && FitSimilarity(from, to, enu_from_flipped);
}

}  // namespace

RouteComparison CompareRouteToGps(const std::vector<cv::Point2d>& route_px, const std::vector<cv::Point2d>& gps_enu,
                                  const std::vector<bool>& usable, const std::vector<bool>& in_fit,
                                  const RouteFitOptions& options) {
  RouteComparison r;
  const size_t n = route_px.size();
  if (gps_enu.size() != n || usable.size() != n || in_fit.size() != n) {
    r.why = "inputs of different lengths";
    return r;
  }
  std::vector<bool> fit(n);
  for (size_t i = 0; i < n; ++i) fit[i] = usable[i] && in_fit[i];
  r.pairs = static_cast<int>(std::count(fit.begin(), fit.end(), true));
  if (!FitRoute(route_px, gps_enu, fit, &r.enu_from_flipped)) {
    r.why = "fewer than 3 registered frames with GPS";
    return r;
  }
  auto residual = [&](size_t i) {
    return cv::norm(r.enu_from_flipped.Apply({route_px[i].x, -route_px[i].y}) - gps_enu[i]);
  };
  // Robust: drop the worst fix beyond the threshold and refit, until none is left or the budget is spent.
  const int budget = static_cast<int>(options.max_outlier_fraction * r.pairs);
  std::vector<bool> final_fit = fit;
  while (options.robust && r.gps_outliers < budget) {
    std::vector<double> res;
    size_t worst = n;
    double worst_d = 0;
    for (size_t i = 0; i < n; ++i) {
      if (!final_fit[i]) continue;
      const double d = residual(i);
      res.push_back(d);
      if (d > worst_d) worst_d = d, worst = i;
    }
    const double limit = std::max(options.outlier_sigmas * 1.4826 * (res.empty() ? 0.0 : Median(res)), options.min_outlier_m);
    if (worst == n || worst_d <= limit) break;
    final_fit[worst] = false;
    r.outlier_frames.push_back(static_cast<int>(worst));
    ++r.gps_outliers;
    Similarity2 refit;
    if (!FitRoute(route_px, gps_enu, final_fit, &refit)) break;
    r.enu_from_flipped = refit;
  }
  std::sort(r.outlier_frames.begin(), r.outlier_frames.end());
  r.residual_m.assign(n, std::numeric_limits<double>::quiet_NaN());
  double sum = 0, held = 0, inl = 0;
  const cv::Point2d* last = nullptr;
  for (size_t i = 0; i < n; ++i) {
    if (!usable[i]) continue;
    const double d = residual(i);
    r.residual_m[i] = d;
    if (in_fit[i]) {
      sum += d * d;
      if (final_fit[i]) inl += d * d;
    } else {
      held += d * d;
      ++r.held_out;
    }
    if (last) r.path_m += cv::norm(gps_enu[i] - *last);
    last = &gps_enu[i];
  }
  r.rms_m = std::sqrt(sum / r.pairs);
  r.inlier_rms_m = std::sqrt(inl / std::max(1, r.pairs - r.gps_outliers));
  r.held_out_rms_m = r.held_out > 0 ? std::sqrt(held / r.held_out) : 0.0;
  r.ok = true;
  return r;
}

HeightComparison CompareHeights(const std::vector<double>& height, const std::vector<double>& gps, bool fit_offset) {
  HeightComparison h;
  const size_t n = std::min(height.size(), gps.size());
  double diff = 0;
  for (size_t i = 0; i < n; ++i) {
    if (std::isfinite(height[i]) && std::isfinite(gps[i]) && height[i] > 0) {
      diff += gps[i] - height[i];
      ++h.pairs;
    }
  }
  if (h.pairs == 0) return h;
  h.offset_m = fit_offset ? diff / h.pairs : 0.0;
  h.error_m.assign(height.size(), std::numeric_limits<double>::quiet_NaN());
  double sum = 0, mean_ref = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!(std::isfinite(height[i]) && std::isfinite(gps[i]) && height[i] > 0)) continue;
    const double ref = gps[i] - h.offset_m;
    const double e = height[i] - ref;
    h.error_m[i] = e;
    sum += e * e;
    mean_ref += ref / h.pairs;
  }
  h.rms_m = std::sqrt(sum / h.pairs);
  h.rms_percent = mean_ref > 0 ? 100.0 * h.rms_m / mean_ref : std::numeric_limits<double>::quiet_NaN();
  h.ok = true;
  return h;
}

namespace {

// The tab-separated fields of a line (n tabs: n + 1 fields, empty ones kept).
std::vector<std::string> SplitTabs(const std::string& line) {
  std::vector<std::string> fields;
  size_t from = 0;
  for (size_t tab; (tab = line.find('\t', from)) != std::string::npos; from = tab + 1)
    fields.push_back(line.substr(from, tab - from));
  fields.push_back(line.substr(from));
  return fields;
}

}  // namespace

bool ReadReferenceHeights(const std::string& path, std::map<std::string, double>* heights, std::string* error) {
  heights->clear();
  auto fail = [&](const std::string& why) {
    *error = "height reference " + path + ": " + why;
    heights->clear();
    return false;
  };
  std::ifstream in(path);
  if (!in) return fail("cannot be read");
  const std::string no_header = "no tab-separated header with the columns name and height_m";
  std::string line;
  int name_col = -1, height_col = -1, line_number = 0;
  size_t columns = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line_number == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);  // a UTF-8 byte-order mark
    if (!line.empty() && line.back() == '\r') line.pop_back();                       // CRLF line ends
    if (line.empty() || line[0] == '#') continue;
    const std::vector<std::string> fields = SplitTabs(line);
    if (name_col < 0) {  // the header
      for (size_t k = 0; k < fields.size(); ++k) {
        if (fields[k] == "name" && name_col < 0) name_col = static_cast<int>(k);
        if (fields[k] == "height_m" && height_col < 0) height_col = static_cast<int>(k);
      }
      if (name_col < 0 || height_col < 0) return fail(no_header);
      columns = fields.size();
      continue;
    }
    const std::string where = "line " + std::to_string(line_number);
    if (fields.size() != columns)
      return fail(where + " has " + std::to_string(fields.size()) + " fields, the header " + std::to_string(columns));
    const std::string& name = fields[name_col];
    const std::string& value = fields[height_col];
    if (name.empty()) return fail(where + ": no photo name");
    char* end = nullptr;
    const double h = std::strtod(value.c_str(), &end);
    if (end == value.c_str() || *end != '\0' || !(h > 0 && h < 1e5))
      return fail(where + ": height_m \"" + Printable(value, 40) + "\" is not a height in (0, 100 km)");
    if (!heights->emplace(name, h).second) return fail(where + ": photo \"" + Printable(name, 40) + "\" twice");
  }
  if (name_col < 0) return fail(no_header);
  if (heights->empty()) return fail("no photo");
  return true;
}

struct ReferenceLocator::Impl {
  ReferenceLocatorOptions options;
  cv::Ptr<cv::SIFT> sift;
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  cv::FlannBasedMatcher matcher;
};

ReferenceLocator::ReferenceLocator(const cv::Mat& reference, const ReferenceLocatorOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (reference.empty() || reference.depth() != CV_8U) throw std::invalid_argument("reference orthomosaic: empty or not 8-bit");
  impl_->options = options;
  impl_->sift = cv::SIFT::create(options.reference_features);
  impl_->sift->detectAndCompute(ToGray(reference), cv::noArray(), impl_->keypoints, impl_->descriptors);
  if (!impl_->descriptors.empty()) impl_->matcher.add(impl_->descriptors), impl_->matcher.train();
}

ReferenceLocator::~ReferenceLocator() = default;

int ReferenceLocator::reference_features() const { return static_cast<int>(impl_->keypoints.size()); }

ReferenceFix ReferenceLocator::Locate(const cv::Mat& photo) const {
  ReferenceFix fix;
  const auto& o = impl_->options;
  if (photo.empty() || impl_->keypoints.size() < 4) return fix;
  cv::Mat small;
  cv::resize(ToGray(photo), small, cv::Size(), o.photo_scale, o.photo_scale, cv::INTER_AREA);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  cv::SIFT::create()->detectAndCompute(small, cv::noArray(), keypoints, descriptors);
  if (keypoints.size() < 4) return fix;
  std::vector<std::vector<cv::DMatch>> knn;
  impl_->matcher.knnMatch(descriptors, knn, 2);
  std::vector<cv::Point2f> from, to;
  for (const auto& m : knn) {
    if (m.size() < 2 || m[0].distance >= o.ratio * m[1].distance) continue;
    from.push_back(keypoints[m[0].queryIdx].pt);
    to.push_back(impl_->keypoints[m[0].trainIdx].pt);
  }
  if (from.size() < 4) return fix;
  cv::Mat mask;
  const cv::Mat H = cv::findHomography(from, to, cv::RANSAC, o.ransac_px, mask, 5000, 0.999);
  fix.inliers = H.empty() ? 0 : cv::countNonZero(mask);
  if (fix.inliers < o.min_inliers) return fix;
  const cv::Point2d c((photo.cols - 1) / 2.0 * o.photo_scale, (photo.rows - 1) / 2.0 * o.photo_scale);
  std::vector<cv::Point2d> centre{c}, mapped;
  cv::perspectiveTransform(centre, mapped, H);
  fix.px = mapped[0];
  fix.ok = std::isfinite(fix.px.x) && std::isfinite(fix.px.y);
  return fix;
}

ReferenceComparison CompareWithReference(const std::vector<ReferenceFix>& fixes, const std::vector<cv::Point2d>& route_m,
                                         const std::vector<cv::Point2d>& gps_m, const std::vector<bool>& has_gps) {
  ReferenceComparison c;
  const size_t n = fixes.size();
  std::vector<cv::Point2d> px(n);
  std::vector<bool> located(n), located_gps(n);
  for (size_t i = 0; i < n; ++i) {
    located[i] = fixes[i].ok && i < route_m.size();
    located_gps[i] = located[i] && i < has_gps.size() && has_gps[i] && i < gps_m.size();
    if (located[i]) px[i] = fixes[i].px, ++c.located;
  }
  RouteFitOptions plain;
  plain.robust = false;
  const std::vector<bool> all(n, true);
  std::vector<cv::Point2d> route = route_m, gps = gps_m;
  route.resize(n), gps.resize(n);
  c.route = CompareRouteToGps(px, route, located, all, plain);
  c.gps = CompareRouteToGps(px, gps, located_gps, all, plain);
  return c;
}

}  // namespace vloc::mosaic
