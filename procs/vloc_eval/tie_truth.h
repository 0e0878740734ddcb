#pragma once
// The front end's tie points of a simulated run against the terrain they were
// rendered from: each current-left observation's ray from the site's true
// camera meets the terrain at the true point; projected into the previous
// site's true left camera it says how far the cross-site match is off, and
// the stereo points of both sites say how far their ranges are off. A match
// is judged in the coarser of its two images (the farther camera's pixels):
// a forward tie point's previous view is the far one; a backward pair's tie
// point sees near ground of the previous site, whose pixels are several
// times finer than the current site's at its range.

#include <map>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/pose.h"
#include "vloc/common/rover_data.h"
#include "vloc/sim/terrain.h"

namespace vloc::eval {

struct TieTruthOptions {
  double wrong_px = 2.0;                 // px, a cross-site match farther than this from the truth is wrong
                                         // (in the coarser image: CoarseErrorPx)
  double max_range_m = 300.0;            // m, rays farther than this find no truth
  double occlusion_tolerance_m = 0.05;   // m, the previous camera sees the true point unless the terrain is nearer by this
};

// One checked tie point: where its previous-left observation is against the truth.
struct TieTruthPoint {
  int reference = 0, site = 0, previous_pair = 0, current_pair = 0;
  Eigen::Vector2d previous_px = Eigen::Vector2d::Zero();  // observed, ideal px
  Eigen::Vector2d error_px = Eigen::Vector2d::Zero();     // observed - true
  double range_m = 0;                                     // true range from the previous left camera
  double current_range_m = 0;                             // ... and from the current left camera
  // |error| in the farther camera's pixels (same focal length): the previous-left error, scaled down by
  // range_m / current_range_m when the current camera is the farther one.
  double CoarseErrorPx() const {
    return error_px.norm() * (current_range_m > range_m ? range_m / current_range_m : 1.0);
  }
};

struct TieTruthRow {
  int reference = 0, site = 0;
  int points = 0;     // tie points with a current-left and a previous-left observation
  int checked = 0;    // ... whose true point the terrain gives and the previous camera sees
  int wrong = 0;      // ... more than wrong_px from the truth in the coarser image
  double cross_median_px = NAN, cross_p90_px = NAN;           // of CoarseErrorPx
  double cross_median_du_px = NAN, cross_median_dv_px = NAN;  // signed (observed - true): a shared shift shows here
  // Signed median of (stereo range - true range) / true range, %, per site's left camera.
  double range_error_median_pct_previous = NAN, range_error_median_pct_current = NAN;
};

// Per set a row; every checked point into `points` when not null.
std::vector<TieTruthRow> CheckTiePoints(const std::vector<TiePointSet>& sets,
                                        const std::map<int, PoseWithCovariance>& truth, const NavcamModel& navcam,
                                        const sim::Terrain& terrain, const TieTruthOptions& options = {},
                                        std::vector<TieTruthPoint>* points = nullptr);

// tiepoints.csv (per set) and tiepoint_errors.csv (per point) in `dir`, and the report's line on them (empty
// when no rows).
void WriteTieTruth(const std::vector<TieTruthRow>& rows, const std::vector<TieTruthPoint>& points,
                   const std::string& dir);
std::string TieTruthSummary(const std::vector<TieTruthRow>& rows, const TieTruthOptions& options = {});

}  // namespace vloc::eval
