#include "vloc/mosaic/survey_eval.h"

#include <cmath>
#include <limits>

namespace vloc::mosaic {

RouteComparison CompareRouteToGps(const std::vector<cv::Point2d>& route_px, const std::vector<cv::Point2d>& gps_enu,
                                  const std::vector<bool>& usable, const std::vector<bool>& in_fit) {
  RouteComparison r;
  const size_t n = route_px.size();
  if (gps_enu.size() != n || usable.size() != n || in_fit.size() != n) {
    r.why = "inputs of different lengths";
    return r;
  }
  std::vector<cv::Point2d> from, to;
  for (size_t i = 0; i < n; ++i) {
    if (!usable[i] || !in_fit[i]) continue;
    from.emplace_back(route_px[i].x, -route_px[i].y);
    to.push_back(gps_enu[i]);
  }
  r.pairs = static_cast<int>(from.size());
  if (r.pairs < 3 || !FitSimilarity(from, to, &r.enu_from_flipped)) {
    r.why = "fewer than 3 registered frames with GPS";
    return r;
  }
  r.residual_m.assign(n, std::numeric_limits<double>::quiet_NaN());
  double sum = 0, held = 0;
  const cv::Point2d* last = nullptr;
  for (size_t i = 0; i < n; ++i) {
    if (!usable[i]) continue;
    const cv::Point2d e = r.enu_from_flipped.Apply({route_px[i].x, -route_px[i].y});
    const double d = cv::norm(e - gps_enu[i]);
    r.residual_m[i] = d;
    if (in_fit[i]) {
      sum += d * d;
    } else {
      held += d * d;
      ++r.held_out;
    }
    if (last) r.path_m += cv::norm(gps_enu[i] - *last);
    last = &gps_enu[i];
  }
  r.rms_m = std::sqrt(sum / r.pairs);
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

}  // namespace vloc::mosaic
