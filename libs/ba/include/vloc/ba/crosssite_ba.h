#pragma once
// Cross-site bundle adjustment (Wan et al., section 2.3). The image network
// is every stereo image of two adjacent sites. The previous site's pose is
// held fixed; the current site is ONE 6-DoF unknown (world_from_body), and
// every camera pose follows from it through the mast pan/tilt and the
// stereo rig (eqs. 3 and 5 hold exactly, by construction):
//   world_from_left(pair)  = world_from_body * mast.BodyFromLeft(pan, tilt, rig)
//   world_from_right(pair) = world_from_left(pair) * rig.left_from_right
// Tie points are free. Initial values: points by space intersection from
// the previous site's pairs, the current site by space resection from the
// dead-reckoning pose. Robust (Huber) passes with outlier rejection, then a
// plain least-squares pass whose covariance is the site pose's covariance.

#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/pose.h"
#include "vloc/common/rover_data.h"

namespace vloc {

class OptionsReader;

struct CrossSiteBaOptions {
  int min_tie_points = 6;                  // usable tie points needed (seen from both sites)
  double huber_sigmas = 2.0;               // Huber loss threshold, in observation sigmas
  double outlier_sigmas = 4.0;             // reject a tie point whose worst residual exceeds this (sigmas, scaled by the robust RMS when larger than 1)
  int rejection_rounds = 2;                // robust solve + rejection rounds before the final pass
  int max_iterations = 100;                // Ceres iterations per solve
  double function_tolerance = 1e-10;       // Ceres relative cost change to stop
  double max_condition_number = 1e6;       // of the site pose covariance, rotation scaled by the mean point range; above: ILL_CONDITIONED
  double max_final_rms_sigmas = 3.0;       // final normalised reprojection RMS above this: NOT_CONVERGED
  double max_correction_m = 10.0;          // a solution further than this from the dead-reckoning pose: NOT_CONVERGED
  double min_intersection_parallax_rad = 1e-3;  // rays closer than this do not intersect a point
  bool far_points = true;                  // such a point (far terrain) enters as an inverse depth in its first
                                           // previous left camera, its left observations only (bearings, defined
                                           // at infinity: they fix the rotation); false: it is unusable
  bool inflate_by_variance_factor = true;  // multiply the covariance by max(1, a-posteriori variance factor)
  int max_independent_points = 0;          // ... and by max(1, points / this): for points of one site pair that
                                           // share errors (calibration, relief-biased matching) that do not
                                           // average down with their number; 0 = off (the simulated traverses
                                           // show none once the rover rests while it images)
  int num_threads = 2;                     // Ceres threads

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

enum class CrossSiteBaStatus { kOk = 0, kTooFewPoints = 1, kIllConditioned = 2, kNotConverged = 3, kBadInput = 4 };
const char* ToString(CrossSiteBaStatus status);

struct CrossSiteBaSummary {
  bool usable = false;                 // status == kOk: the pose may replace dead reckoning
  CrossSiteBaStatus status = CrossSiteBaStatus::kBadInput;
  std::string message;                 // one line: what happened, or why it failed
  int previous_site_id = 0;
  int current_site_id = 0;
  PoseWithCovariance world_from_current;    // adjusted (or the DR pose when !usable)
  PoseWithCovariance previous_from_current; // relative pose, covariance from the adjustment
  Pose3 world_from_current_initial = Pose3::Identity();  // after resection, before adjustment
  int num_tie_points_in = 0;           // in the input
  int num_tie_points_used = 0;         // inliers in the final adjustment
  int num_tie_points_rejected = 0;     // outliers removed
  int num_tie_points_unusable = 0;     // not seen from both sites, not intersectable, bad data
  int num_far_points = 0;              // of the used: inverse-depth points (options.far_points)
  int num_observations = 0;            // image observations in the final adjustment
  int num_bad_observations = 0;        // dropped for bad data (unknown pair, bad sigma, not finite)
  double initial_rms_px = 0;           // reprojection RMS at the initial values (inliers)
  double final_rms_px = 0;             // after the adjustment (inliers)
  double final_normalised_rms = 0;     // RMS of residual / sigma
  int iterations = 0;                  // Ceres iterations, all passes
  double solve_seconds = 0;            // wall time of everything
  double condition_number = 0;         // of the scaled pose covariance; inf when singular
  std::vector<Pose3> world_from_left_previous;   // output camera poses, per pair
  std::vector<Pose3> world_from_right_previous;
  std::vector<Pose3> world_from_left_current;
  std::vector<Pose3> world_from_right_current;

  std::string BriefReport() const;
};

// Camera poses of a site from its body pose (eqs. 3, 5).
void SiteCameraPoses(const Pose3& world_from_body, const std::vector<MastPointing>& pointing,
                     const NavcamModel& navcam, std::vector<Pose3>* world_from_left,
                     std::vector<Pose3>* world_from_right);

// Adjusts the current site of `tie_points`; previous_site_pose is held fixed,
// current_site_pose_dr is the initial value. Never throws on bad data: the
// status says what went wrong.
CrossSiteBaSummary SolveCrossSiteBa(const TiePointSet& tie_points, const NavcamModel& navcam,
                                    const CrossSiteBaOptions& options);

}  // namespace vloc
