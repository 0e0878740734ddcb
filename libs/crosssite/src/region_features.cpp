// Step 5: ASIFT on the work regions (Wan et al. 2.2). Previous regions at
// t = 1; current regions (without warp_current) on the views the predicted
// viewpoint change allows: tilts up to the predicted tilt times
// tilt_margin, longitudes within longitude_margin_deg of the predicted one.
// One flat job list of (image, view) over both sites keeps the threads busy
// (with warp_current, asift_and_warps.cpp runs these jobs among the overlaps' own).
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <glog/logging.h>

#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

namespace {

// The restricted views of one current region.
std::vector<AffineView> CurrentViews(const WorkRegion& w, const FeatureOptions& o) {
  std::vector<AffineView> views{{1.0, 0.0}};
  const double lon_margin = o.longitude_margin_deg * M_PI / 180;
  for (double t : o.asift.tilts) {
    if (t <= 1.0 + 1e-6 || t > w.max_tilt * o.tilt_margin) continue;
    const double step = o.asift.longitude_step_deg * M_PI / 180 / t;
    const int kmax = static_cast<int>(std::floor(lon_margin / step + 1e-9));
    for (int k = -kmax; k <= kmax; ++k) views.push_back({t, w.longitude + k * step});
  }
  return views;
}

// Appends one view's features to the region's set, in ideal px of the full image.
void AddViewFeatures(const AffineView& view, const FeatureSet& s, WorkRegion* w) {
  FeatureSet& f = w->features;
  const int view_index = static_cast<int>(f.views.size());
  f.views.push_back(view);
  for (size_t q = 0; q < s.size(); ++q) {
    f.keypoints.push_back(s.keypoints[q]);
    // cv::resize maps pixel centres: work px u is region px (u + 0.5) / zoom - 0.5.
    f.points.push_back(Eigen::Vector2d(w->region.x, w->region.y) +
                       (s.points[q] + Eigen::Vector2d::Constant(0.5)) / w->zoom - Eigen::Vector2d::Constant(0.5));
    f.view.push_back(view_index);
  }
  if (!s.descriptors.empty()) {
    if (f.descriptors.empty()) f.descriptors = s.descriptors.clone();
    else cv::vconcat(f.descriptors, s.descriptors, f.descriptors);
  }
}

const WorkRegion& RegionOf(const RegionFeatureJob& job, const SitePairState& s) {
  return job.current ? s.current_regions[job.image] : s.previous_regions[job.image];
}

}  // namespace

std::vector<RegionFeatureJob> RegionFeatureJobs(const FeatureOptions& o, bool warp_current, SitePairState* s) {
  std::vector<RegionFeatureJob> jobs;
  for (int i = 0; i < static_cast<int>(s->current_regions.size()); ++i) {
    WorkRegion& w = s->current_regions[i];
    if (w.image.empty() || warp_current) continue;
    w.views = CurrentViews(w, o);
    for (const auto& v : w.views) jobs.push_back({true, i, v});
  }
  for (int j = 0; j < static_cast<int>(s->previous_regions.size()); ++j) {
    WorkRegion& w = s->previous_regions[j];
    if (w.image.empty()) continue;
    w.views.push_back({1.0, 0.0});
    jobs.push_back({false, j, {1.0, 0.0}});
  }
  for (size_t i = 0; i < s->current_regions.size(); ++i) {
    const WorkRegion& w = s->current_regions[i];
    if (!w.image.empty())
      VLOG(1) << "current image " << i << ": region " << w.region << " zoom " << w.zoom << " views " << w.views.size()
              << " (max tilt " << w.max_tilt << ")";
  }
  for (size_t j = 0; j < s->previous_regions.size(); ++j) {
    const WorkRegion& w = s->previous_regions[j];
    if (!w.image.empty()) VLOG(1) << "previous image " << j << ": region " << w.region << " zoom " << w.zoom;
  }
  return jobs;
}

// SIFT's time grows with the pixels (the zoomed previous regions differ up to 7x).
double RegionFeatureJobCost(const RegionFeatureJob& job, const SitePairState& s) {
  return RegionOf(job, s).image.total() / job.view.tilt;
}

FeatureSet DetectRegionFeatureJob(const RegionFeatureJob& job, const FeatureOptions& o, const SitePairState& s) {
  const WorkRegion& w = RegionOf(job, s);
  return DetectOnGrid(w.image, cv::Mat(), {job.view}, job.current ? 1.0 : w.zoom, o);
}

FeatureSet DetectOnGrid(const cv::Mat& image, const cv::Mat& mask, const std::vector<AffineView>& views, double zoom,
                        const FeatureOptions& o) {
  AsiftOptions single = o.asift;
  single.num_threads = 1;
  if (!(o.sift_max_zoom > 0 && zoom > o.sift_max_zoom)) return DetectAsift(image, mask, views, single);
  const double f = o.sift_max_zoom / zoom;
  const cv::Size size(std::max(1, static_cast<int>(std::lround(image.cols * f))),
                      std::max(1, static_cast<int>(std::lround(image.rows * f))));
  cv::Mat reduced, reduced_mask;
  cv::resize(image, reduced, size, 0, 0, cv::INTER_AREA);
  if (!mask.empty()) cv::resize(mask, reduced_mask, size, 0, 0, cv::INTER_NEAREST);
  FeatureSet out = DetectAsift(reduced, reduced_mask, views, single);
  // Back onto the grid; cv::resize maps pixel centres: grid px = (reduced px + 0.5) * s - 0.5.
  const double sx = static_cast<double>(image.cols) / size.width, sy = static_cast<double>(image.rows) / size.height;
  for (Eigen::Vector2d& p : out.points) p = Eigen::Vector2d((p.x() + 0.5) * sx - 0.5, (p.y() + 0.5) * sy - 0.5);
  for (cv::KeyPoint& k : out.keypoints) {
    k.pt = cv::Point2f(static_cast<float>((k.pt.x + 0.5) * sx - 0.5), static_cast<float>((k.pt.y + 0.5) * sy - 0.5));
    k.size *= static_cast<float>(sx);
  }
  return out;
}

int AddRegionFeatures(const std::vector<RegionFeatureJob>& jobs, const std::vector<FeatureSet>& sets,
                      SitePairState* s) {
  for (size_t k = 0; k < jobs.size(); ++k)
    AddViewFeatures(jobs[k].view, sets[k],
                    jobs[k].current ? &s->current_regions[jobs[k].image] : &s->previous_regions[jobs[k].image]);
  for (size_t j = 0; j < s->previous_regions.size() && j < s->previous_left.size(); ++j)
    DropVehicleFeatures(s->previous_left[j].vehicle, cv::Matx33d::eye(), &s->previous_regions[j].features);
  for (size_t i = 0; i < s->current_regions.size() && i < s->current_left.size(); ++i)
    DropVehicleFeatures(s->current_left[i].vehicle, cv::Matx33d::eye(), &s->current_regions[i].features);
  int n = 0;
  for (const auto& w : s->previous_regions) n += static_cast<int>(w.features.size());
  for (const auto& w : s->current_regions) n += static_cast<int>(w.features.size());
  for (const auto& w : s->current_regions) s->num_current_features += w.features.size();
  return n;
}

int DetectRegionFeatures(const FeatureOptions& o, bool warp_current, int num_threads, SitePairState* s) {
  const std::vector<RegionFeatureJob> jobs = RegionFeatureJobs(o, warp_current, s);
  std::vector<double> costs;
  for (const RegionFeatureJob& job : jobs) costs.push_back(RegionFeatureJobCost(job, *s));
  std::vector<FeatureSet> sets(jobs.size());
  RunLargestFirst(costs, num_threads, [&](int k) { sets[k] = DetectRegionFeatureJob(jobs[k], o, *s); });
  return AddRegionFeatures(jobs, sets, s);
}

}  // namespace vloc::frontend_internal
