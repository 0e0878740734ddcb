#include "vloc/mosaic/survey_eval.h"

#include <algorithm>
#include <cmath>
#include <limits>

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

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
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
    const double limit = std::max(options.outlier_sigmas * 1.4826 * Median(res), options.min_outlier_m);
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

}  // namespace vloc::mosaic
