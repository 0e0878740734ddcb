#pragma once
// How much of what the previous site saw the current site sees again, from
// the truth of a simulated run: the previous site's left images are sampled
// on a grid, each sample's ray meets the terrain within the front end's
// matching range; a sample is shared when some left camera of the current
// site sees that ground point unoccluded, in its image and within its
// matching range. A pair with little shared view cannot be matched, however
// good the matcher: this says whether a failed pair had anything to match.

#include <map>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/pose.h"
#include "vloc/common/rover_data.h"
#include "vloc/sim/terrain.h"

namespace vloc::eval {

struct SharedViewOptions {
  int grid_px = 32;                     // px, sample spacing in the previous left images
  double max_range_previous_m = 30.0;   // m, the front end's matching ranges (feature_frontend.yaml regions)
  double min_range_current_m = 5.0;     // m
  double max_range_current_m = 30.0;    // m
  double occlusion_tolerance_m = 0.05;  // m, seen unless the terrain is nearer than the point by this
};

struct SharedViewRow {
  int reference = 0, site = 0;
  int samples = 0;                 // previous-left samples on the ground within range
  int shared = 0;                  // ... that the current site sees within its range
  double median_range_ratio = NAN; // current / previous range of the shared samples (the scale change)
  double SharedPct() const { return samples > 0 ? 100.0 * shared / samples : 0.0; }
};

// One row per consecutive pair of sites in `truth` (site ids in order); every site takes the same `pointing`.
std::vector<SharedViewRow> SharedViews(const std::map<int, PoseWithCovariance>& truth,
                                       const std::vector<MastPointing>& pointing, const NavcamModel& navcam,
                                       const sim::Terrain& terrain, const SharedViewOptions& options = {});

// shared_view.csv in `dir`; the report's line on it (`localized`: the pairs with tie points).
void WriteSharedViews(const std::vector<SharedViewRow>& rows, const std::string& dir);
std::string SharedViewSummary(const std::vector<SharedViewRow>& rows, const std::vector<TiePointSet>& localized);

}  // namespace vloc::eval
