// Steps 5-6 with warp_current, as one pool of independent jobs: ASIFT on
// each previous region (region_features.cpp), and each matched forward
// overlap's warp, tile registration and ASIFT on the warped image
// (overlap_warp.cpp). An overlap's jobs need its previous region's image,
// not its features, so nothing waits between the steps: the largest jobs
// run first and neither core idles at a step's end.
#include <algorithm>

#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

namespace {

// The pixels of the overlap's grid (the zoomed previous region it lies on), what its warp, tiles and SIFT scale with.
double OverlapJobCost(const PairOverlap& ov, const SitePairState& s) {
  const WorkRegion& prev = s.previous_regions[ov.previous_pair];
  return (ov.previous_region & prev.region).area() * prev.zoom * prev.zoom;
}

// Warp, tile registration and ASIFT of forward overlap k, the features on the rover's body dropped.
void WarpAndDescribe(int k, const FeatureOptions& features, const WarpOptions& warp, const GateOptions& gate,
                     SitePairState* s) {
  const PairOverlap& ov = s->prediction.overlaps[k];
  OverlapWork& w = s->overlaps[k];
  w = WarpOverlap(ov, *s, warp, gate);
  DetectWarpedFeatures(features, warp.warp_current, s->previous_regions[ov.previous_pair].zoom, &w);
  DropVehicleFeatures(s->current_left[ov.current_pair].vehicle, w.current_from_train, &w.warped_features);
}

}  // namespace

int DescribeRegionsAndWarpOverlaps(const FeatureOptions& features, const WarpOptions& warp, const GateOptions& gate,
                                   int num_threads, SitePairState* s) {
  const std::vector<RegionFeatureJob> region_jobs = RegionFeatureJobs(features, warp.warp_current, s);
  std::vector<int> overlap_jobs;  // overlap indices
  s->overlaps.assign(s->prediction.overlaps.size(), OverlapWork());
  for (size_t k = 0; k < s->prediction.overlaps.size(); ++k)
    if (!s->prediction.overlaps[k].backward && s->overlap_used[k]) overlap_jobs.push_back(static_cast<int>(k));
  std::vector<double> costs;
  for (const RegionFeatureJob& job : region_jobs) costs.push_back(RegionFeatureJobCost(job, *s));
  for (int k : overlap_jobs) costs.push_back(OverlapJobCost(s->prediction.overlaps[k], *s));
  std::vector<FeatureSet> region_sets(region_jobs.size());
  const int num_region_jobs = static_cast<int>(region_jobs.size());
  RunLargestFirst(costs, num_threads, [&](int j) {
    if (j < num_region_jobs) region_sets[j] = DetectRegionFeatureJob(region_jobs[j], features, *s);
    else WarpAndDescribe(overlap_jobs[j - num_region_jobs], features, warp, gate, s);
  });
  int n = AddRegionFeatures(region_jobs, region_sets, s);
  for (const OverlapWork& w : s->overlaps) {
    n += static_cast<int>(w.warped_features.size());
    s->num_current_features += w.warped_features.size();
  }
  return n;
}

}  // namespace vloc::frontend_internal
