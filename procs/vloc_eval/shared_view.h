#pragma once
// How much of what the previous site saw the current site sees again, from
// the truth of a simulated run: the previous site's left images are sampled
// on a grid, each sample's ray meets the terrain within the front end's
// matching range; a sample is shared when some left camera of the current
// site sees that ground point unoccluded, in its image and within its
// matching range. A pair with little shared view cannot be matched, however
// good the matcher: this says whether a failed pair had anything to match.
// Seen again is not yet matchable: the two views of a shared ground patch
// differ by an affine map whose tilt (ratio of its singular values, as in
// ASIFT) grows when one site sees the patch at a grazing angle; past a tilt
// of about 4 feature matching and correlation no longer see the same texture.

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
  double max_tilt = 4.0;                // the two views' affine tilt up to which a shared sample counts as matchable
};

struct SharedViewRow {
  int reference = 0, site = 0;
  int samples = 0;                 // previous-left samples on the ground within range
  int shared = 0;                  // ... that the current site sees within its range
  int matchable = 0;               // ... with the two views' affine tilt <= max_tilt
  double median_range_ratio = NAN; // current / previous range of the shared samples (the scale change)
  double median_tilt = NAN;        // the shared samples' affine tilt between the views
  double SharedPct() const { return samples > 0 ? 100.0 * shared / samples : 0.0; }
  double MatchablePct() const { return samples > 0 ? 100.0 * matchable / samples : 0.0; }
};

// One row per consecutive pair of sites in `truth` (site ids in order); every site takes the same `pointing`.
std::vector<SharedViewRow> SharedViews(const std::map<int, PoseWithCovariance>& truth,
                                       const std::vector<MastPointing>& pointing, const NavcamModel& navcam,
                                       const sim::Terrain& terrain, const SharedViewOptions& options = {});

// shared_view.csv in `dir`; the report's line on it (`localized`: the pairs with tie points).
void WriteSharedViews(const std::vector<SharedViewRow>& rows, const std::string& dir);
std::string SharedViewSummary(const std::vector<SharedViewRow>& rows, const std::vector<TiePointSet>& localized,
                              const SharedViewOptions& options = {});

}  // namespace vloc::eval
