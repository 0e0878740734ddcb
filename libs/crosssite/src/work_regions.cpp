// Step 4: the work regions (Wan et al. 2.2). Per image the union of its
// forward overlaps' regions, Wallis-filtered, and zoomed by the predicted
// scale so that both sites see the ground at one resolution. The previous
// site's Wallis targets come from the current site's filtered regions (grey
// levels consistent across the sites). Backward overlaps are matched on the
// ground instead (backward_overlaps.cpp).
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/imgproc.hpp>

#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

namespace {

// Accumulated over each image's forward overlaps.
struct RegionSums {
  std::vector<double> lon_sin, lon_cos, zoom_sum, shrink_sum;
  std::vector<int> zoom_n, shrink_n;
};

RegionSums SumOverlaps(const WorkRegionOptions& o, SitePairState* s) {
  const size_t np = s->previous.pairs.size(), nc = s->current.pairs.size();
  RegionSums sums{std::vector<double>(nc, 0.0), std::vector<double>(nc, 0.0), std::vector<double>(np, 0.0),
                  std::vector<double>(nc, 0.0), std::vector<int>(np, 0), std::vector<int>(nc, 0)};
  for (const auto& ov : s->prediction.overlaps) {
    if (ov.backward) continue;
    WorkRegion& cur = s->current_regions[ov.current_pair];
    cur.region |= ov.current_region;
    s->previous_regions[ov.previous_pair].region |= ov.previous_region;
    cur.max_tilt = std::max(cur.max_tilt, ov.tilt);
    // Longitudes are axial (mod pi): average the doubled angle.
    sums.lon_sin[ov.current_pair] += ov.num_samples * std::sin(2 * ov.tilt_longitude);
    sums.lon_cos[ov.current_pair] += ov.num_samples * std::cos(2 * ov.tilt_longitude);
    sums.zoom_sum[ov.previous_pair] += std::clamp(1.0 / ov.scale, o.min_zoom, o.max_zoom);
    ++sums.zoom_n[ov.previous_pair];
    sums.shrink_sum[ov.current_pair] += std::clamp(ov.scale, 1.0 / o.max_zoom, 1.0 / o.min_zoom);
    ++sums.shrink_n[ov.current_pair];
  }
  for (size_t i = 0; i < nc; ++i) s->current_regions[i].longitude = 0.5 * std::atan2(sums.lon_sin[i], sums.lon_cos[i]);
  return sums;
}

}  // namespace

int MakeWorkRegions(const WorkRegionOptions& o, bool warp_current, int num_threads, SitePairState* s) {
  const int np = static_cast<int>(s->previous.pairs.size()), nc = static_cast<int>(s->current.pairs.size());
  s->previous_regions.assign(np, {});
  s->current_regions.assign(nc, {});
  const RegionSums sums = SumOverlaps(o, s);
  double best_std = 0;
  std::vector<double> cur_means, cur_stds;
  for (int i = 0; i < nc; ++i) {
    WorkRegion& w = s->current_regions[i];
    if (w.region.area() == 0) continue;
    const ImageStats raw = ComputeImageStats(s->current_left[i].gray(w.region));
    best_std = std::max(best_std, raw.std);
    w.image = WallisFilter(s->current_left[i].gray(w.region), o.wallis);
    const ImageStats st = ComputeImageStats(w.image);
    if (!o.zoom_previous) {
      // The same relative zoom, applied as a reduction of the current region
      // (the cheaper side to process).
      w.zoom = sums.shrink_sum[i] / std::max(1, sums.shrink_n[i]);
      if (std::abs(w.zoom - 1.0) > 1e-3) cv::resize(w.image, w.image, cv::Size(), w.zoom, w.zoom, cv::INTER_AREA);
    }
    cur_means.push_back(st.mean);
    cur_stds.push_back(st.std);
  }
  for (int j = 0; j < np; ++j) {
    const cv::Rect& r = s->previous_regions[j].region;
    if (r.area() == 0) continue;
    best_std = std::max(best_std, ComputeImageStats(s->previous_left[j].gray(r)).std);
  }
  s->largest_region_std = best_std;
  if (best_std < o.min_region_std) return 0;
  // Previous site's Wallis targets from the current site's filtered regions (grey-level consistency).
  s->previous_wallis = o.wallis;
  if (!cur_means.empty()) {
    s->previous_wallis.target_mean = std::accumulate(cur_means.begin(), cur_means.end(), 0.0) / cur_means.size();
    s->previous_wallis.target_std =
        std::max(1.0, std::accumulate(cur_stds.begin(), cur_stds.end(), 0.0) / cur_stds.size());
  }
  int num_regions = 0;
  for (const WorkRegion& w : s->current_regions) num_regions += w.image.empty() ? 0 : 1;
  for (int j = 0; j < np; ++j) {
    WorkRegion& w = s->previous_regions[j];
    if (w.region.area() == 0) continue;
    w.zoom = (o.zoom_previous || warp_current) ? sums.zoom_sum[j] / std::max(1, sums.zoom_n[j]) : 1.0;
    cv::Mat filtered = WallisFilter(s->previous_left[j].gray(w.region), s->previous_wallis);
    if (std::abs(w.zoom - 1.0) > 1e-3) {
      cv::resize(filtered, w.image, cv::Size(), w.zoom, w.zoom, cv::INTER_CUBIC);
    } else {
      w.image = filtered;
    }
    ++num_regions;
  }
  return num_regions;
}

void ChooseOverlaps(const WorkRegionOptions& o, bool warp_current, int num_threads, SitePairState* s) {
  const int nc = static_cast<int>(s->current.pairs.size());
  const auto& overlaps = s->prediction.overlaps;
  s->current_filtered.assign(nc, cv::Mat());
  if (warp_current) {
#pragma omp parallel for schedule(dynamic, 1) num_threads(num_threads)
    for (int i = 0; i < nc; ++i)
      if (!s->current_regions[i].image.empty()) s->current_filtered[i] = WallisFilter(s->current_left[i].gray, o.wallis);
  }
  // Per current image the overlaps with the most ground samples.
  s->overlap_used.assign(overlaps.size(), true);
  if (o.max_overlaps_per_image <= 0) return;
  for (int i = 0; i < nc; ++i) {
    std::vector<std::pair<int, int>> by_samples;
    for (size_t k = 0; k < overlaps.size(); ++k)
      if (overlaps[k].current_pair == i) by_samples.emplace_back(-overlaps[k].num_samples, static_cast<int>(k));
    std::sort(by_samples.begin(), by_samples.end());
    for (size_t r = o.max_overlaps_per_image; r < by_samples.size(); ++r) s->overlap_used[by_samples[r].second] = false;
  }
  // A previous region that no chosen overlap matches is not described (ASIFT) or warped onto.
  std::vector<bool> matched(s->previous_regions.size(), false);
  for (size_t k = 0; k < overlaps.size(); ++k)
    if (s->overlap_used[k] && !overlaps[k].backward) matched[overlaps[k].previous_pair] = true;
  for (size_t j = 0; j < matched.size(); ++j)
    if (!matched[j]) s->previous_regions[j] = WorkRegion();
}

}  // namespace vloc::frontend_internal
