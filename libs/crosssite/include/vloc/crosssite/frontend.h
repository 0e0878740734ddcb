#pragma once
// The cross-site feature front end (Wan et al. 2.1-2.2): from the stereo
// panoramas of two adjacent sites and their dead-reckoning poses to tie
// points for the bundle adjustment. Run() is a table of contents of named
// steps (internal/frontend_steps.h, one file each); each step is timed under
// the name below and reported in FrontendSummary::stages (FRONTEND_STATUS)
// with a count (in brackets):
//
//   prepare_images (images)              undistortion, LSM gradients of every image
//   ground_planes (planes)               each current image's ground plane from sparse stereo
//   region_prediction (overlaps)         predicted overlaps (current x previous pair), grown by the DR uncertainty
//   ground_alignment (points)            DR relative height corrected on both sites' stereo ground, regions again
//   region_wallis_zoom (regions)         Wallis filter and zoom of the regions (previous targets from the current)
//   current_wallis (images)              Wallis filter of the whole current images (for the warp), overlap choice
//   asift_and_warps (features)           ASIFT on the regions (current: tilts/longitudes the prediction allows);
//                                        each overlap's current image warped onto the previous region's grid,
//                                        tile registration, ASIFT on it (all as one pool of jobs)
//   overlap_matching (matches)           gated matching (DR gate, then refined gate), epipolar RANSAC, spread
//   overlap_grid_lsm (refined)           cross-site LSM on the previous region's grid, with the relief gates
//   backward_matching (matches)          opposite views matched on ground-plane ortho images
//   cross_lsm_merge (matches)            cross-site LSM of what the grid LSM did not refine; duplicates merged
//   stereo_zncc (matches)                ZNCC along the epipolar segment at both sites
//   median_filter (matches)              median filter of the disparities against the neighbours
//   stereo_lsm (matches)                 least-squares matching left -> right at both sites, intersection
//   distance_consistency (points)        distance-consistency voting (eq. 2) with thresholds from eq. 7
//   motion_consistency (points)          one rigid motion within each point's anisotropic covariance
//   dr_check (tie points)                the motion the tie points imply against dead reckoning
//
// VLOC_FRONTEND_DUMP=<dir> writes each forward overlap's warped current
// image and previous region (PNG) there, to look at what was matched.
//
// Observations are ideal (undistorted) pixels; images with distortion are
// undistorted first.

#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/rover_data.h"
#include "vloc/crosssite/regions.h"
#include "vloc/features/asift.h"
#include "vloc/features/consistency.h"
#include "vloc/features/lsm.h"
#include "vloc/features/stereo_match.h"
#include "vloc/features/tile_registration.h"
#include "vloc/features/wallis.h"

namespace vloc {

class OptionsReader;

// One site's panorama and its dead-reckoning pose.
struct SiteImages {
  int site_id = 0;
  PoseWithCovariance world_from_body;  // DR pose of the site
  std::vector<StereoPair> pairs;       // indexed by pair_index after sorting; grey or BGR colour (matched on luminance)
};

// Cross-site LSM on the previous region's grid: a larger window (the grid
// is zoomed) and a lower correlation floor (the two sites' views differ).
// The window is wide and short (53 x 11 grid px): at grazing angles a
// previous window row spans ~0.1 m of ground along the range and the
// texture is streaked across it. A tall window spans metres of relief whose
// parallax between the sites (along the cross-site epipolar lines, mostly
// horizontal) is not affine, and the match slides along the streaks: on
// the simulated pairs 21 x 21 px left 1.8 % of the tie points > 2 px off,
// 53 x 11 px 0.5 % (median 0.47 -> 0.33 px). With a 0.2 grid px gate on
// the least precise direction and the relief gates below (back match,
// shear), 0.24 % over ten pairs with DR errors in four directions.
inline LsmOptions GridLsmDefaults() {
  LsmOptions o;
  o.half_window = 26;
  o.half_height = 5;
  o.min_correlation = 0.6;
  o.max_sigma_px = 0.5;
  o.max_sigma_axis_px = 0.2;
  o.convergence_px = 0.02;  // the two views differ: the last hundredths of a px oscillate
  o.max_iterations = 30;
  return o;
}

// Second try of an overlap the first grid LSM refined too little of (poor
// texture: regolith photometry flattens the shading that gives the default
// images their texture): a larger window (61 x 15) holds enough gradient to
// reach the same precision gate. Measured on the hard profile's test pair:
// 14 -> 30 tie points, none wrong; on the default pairs it would add 3 wrong
// of 435 if used everywhere, so it is a retry, not the default.
inline LsmOptions GridLsmRetryDefaults() {
  LsmOptions o = GridLsmDefaults();
  o.half_window = 30;
  o.half_height = 7;
  return o;
}

// 95 % (chi-square 3 DoF): the stated covariances hold the angular error
// floor (sigma_angle_px), so misplaced matches sit just beyond.
inline MotionConsistencyOptions MotionDefaults() {
  MotionConsistencyOptions o;
  o.max_mahalanobis_sq = 7.81;
  return o;
}

// The front end's options, one struct per step (the steps and their timers
// are listed above; internal/frontend_steps.h gives each step's signature).
// Each step takes its own struct, plus the few shared ones it needs
// (regions, the gate, num_threads, warp.warp_current). All keys stay in the
// one `frontend:` map of the configs: a step's struct visits its keys into
// it, so config/procs/feature_frontend*.yaml read as before. Switches marked
// "(tests only)" are set by no config: they select a variant that the step
// tests compare with (the default is what every config uses).

// ground_planes: each current image's ground plane from sparse stereo (also uses regions.*_range_current, stereo.zncc).
struct GroundPlaneOptions {
  bool fit_ground_planes = true;    // (tests only) false: no planes, the regions lie on z = regions.ground_height
  int ground_grid_px = 48;          // px, grid of the stereo points for it
  int ground_min_points = 20;       // stereo points (and plane inliers) a plane needs
  double ground_tolerance_m = 0.1;  // m, inlier tolerance at short range (grows with the stereo range error)
  double ground_max_slope_deg = 30; // deg, steepest plane accepted
  void Visit(OptionsReader& reader);
};

// ground_alignment: the DR's relative height corrected on both sites' stereo ground (needs the ground planes).
struct GroundAlignOptions {
  bool ground_align = true;            // apply it
  double ground_align_radius_m = 1.0;  // m, the previous points a local ground plane is fitted to (x, y)
  int ground_align_min_points = 50;    // current points over the previous site's ground it needs
  void Visit(OptionsReader& reader);
};

// region_wallis_zoom, current_wallis: Wallis filter and zoom of the regions, the overlaps matched.
struct WorkRegionOptions {
  WallisOptions wallis;
  double max_zoom = 2.0;               // the previous region is zoomed by min(1 / predicted scale, max_zoom)
  double min_zoom = 1.0;               // ... and at least this
  bool zoom_previous = false;          // (tests only) true: zoom the previous region up (paper); false: the same
                                       // relative zoom as a reduction of the current region (4-9x fewer pixels)
  int max_overlaps_per_image = 2;      // per current image, match the overlaps with the most ground samples (0 = all)
  double min_region_std = 4.0;         // grey level: regions flatter than this have too little texture
  void Visit(OptionsReader& reader);
};

// asift_and_warps: ASIFT on the regions and on the warped current images.
struct FeatureOptions {
  AsiftOptions asift = [] {            // SIFT capped at 5000 features a view: at zoom 1 (sift_max_zoom) as many tie
    AsiftOptions a;                    // points as 4000 kept on the zoomed grids
    a.max_features_per_view = 5000;
    return a;
  }();
  double tilt_margin = 1.25;           // simulate tilts t <= predicted tilt * tilt_margin (and always t = 1)
  double longitude_margin_deg = 30.0;  // deg, simulated longitudes within this of the predicted one
  double warp_max_tilt = 1.0;          // tilts simulated on the warped image: the warp by the predicted ground
                                       // homography leaves tilt ~1, so the restricted set is {1}
  double sift_max_zoom = 1.0;          // SIFT on a previous region zoomed more than this, and on the current images
                                       // warped onto it, runs on the grid resized to this zoom (0 = off: on the
                                       // grid itself, which cv::SIFT doubles again: its first octave is then 4x
                                       // the region's pixels at zoom 2, ~75 % of its pyramid, for detail the
                                       // previous image does not hold; README, "Where the front end's time goes")
  void Visit(OptionsReader& reader);
};

// The stage-1 gate around the DR prediction (asift_and_warps' tiles search it, overlap_matching and
// backward_matching match within it).
struct GateOptions {
  double gate_margin_px = 20.0;        // px, gate radius = region growth + this (current-image px)
  double max_gate_px = 300.0;          // px, largest stage-1 gate (current-image px)
  void Visit(OptionsReader& reader);
};

// asift_and_warps: the current image warped onto the previous region's grid, registered by tiles.
struct WarpOptions {
  bool warp_current = true;            // match on the current image warped onto the zoomed previous region by
                                       // the predicted ground-plane homography (false: ASIFT on the current region)
  bool match_previous_resolution = true;  // (tests only) blur the warped current image to the zoomed previous
                                          // region's resolution
  TileRegistrationOptions tiles;       // stage 1: correlation of the warped current image's tiles with the previous region
  bool tile_registration = true;       // (tests only) stage 1 by tile correlation (false: the SIFT offset cluster)
  int min_tile_inliers = 6;            // tiles agreeing on one similarity needed to register an overlap
  double tile_inlier_px = 1.5;         // reduced px, RANSAC threshold of that similarity
  void Visit(OptionsReader& reader);
};

// overlap_matching: gated matching (DR gate, then refined gate), epipolar RANSAC, spread.
struct OverlapMatchOptions {
  GatedMatchOptions matching;
  double refine_homography_threshold_px = 12.0;  // px, RANSAC threshold of the stage-1 homography
  double stage1_cluster_fraction = 0.06; // stage-1 matches kept: offsets within 2x this fraction of the gate of the densest cluster
  double refine_gate_px = 10.0;        // px, stage-2 gate around the refined prediction
  int min_stage1_inliers = 12;         // stage-1 epipolar inliers needed to trust the refined prediction
  double refine_ratio = 0.85;          // stage-2 ratio test
  double fundamental_threshold_px = 2.0;  // px, RANSAC threshold on cross-site matches (0 = no RANSAC)
  int max_points_per_overlap = 300;    // strongest matches kept per overlap, spread over a grid
  void Visit(OptionsReader& reader);
};

// overlap_grid_lsm: cross-site LSM on the previous region's grid, with the relief gates (with warp_current;
// the forward matches it does not refine are dropped).
struct GridLsmStepOptions {
  LsmOptions grid_lsm = GridLsmDefaults();  // previous region -> warped current image, on the previous grid
  LsmOptions grid_lsm_retry = GridLsmRetryDefaults();  // the unrefined candidates of a poorly refined overlap again
  int grid_retry_below = 40;           // retry an overlap whose grid LSM refined fewer candidates than this (0 = off)
  int grid_search_px = 6;              // px (grid), correlation search around a match before the grid LSM
  double grid_min_zncc = 0.6;          // correlation peak needed before the grid LSM ...
  double grid_min_margin = 0.0;        // ... and its lead over the best score >= 3 grid px away (uniqueness)
  // Relief gates (0: off). A window on relief whose parallax is not affine
  // matches differently forward and backward, and its x shift changes along
  // the rows (shear): both flag matches that slid along the cross-site
  // epipolar lines, which geometry cannot see (about 1 px there).
  double grid_back_check_px = 0.5;     // px (grid): LSM from the warped current image back must land this close
  double grid_max_shear = 0.5;         // largest |dx/dy| of the grid LSM's affine
  void Visit(OptionsReader& reader);
};

// cross_lsm_merge: cross-site LSM of what the grid LSM did not refine, duplicates merged (and the manual clicks).
// A match it cannot refine is dropped: backward matches kept at their features (on the 2 cm ground grid) were
// 11.6 % > 2 px off, dropped 0.5 %.
struct CrossSiteLsmOptions {
  LsmOptions cross_lsm;                // previous-left -> current-left LSM
  double sigma_unrefined_px = 1.0;     // px, sigma of a manual click the cross-site LSM could not refine (kept at
                                       // the click; an automatic match is dropped)
  double duplicate_radius = 1.5;       // px, tie points closer than this in a current left image are merged
  void Visit(OptionsReader& reader);
};

// stereo_zncc, median_filter, stereo_lsm: stereo at both sites and the intersection.
struct StereoStepOptions {
  ZnccOptions zncc;
  MedianFilterOptions median;
  LsmOptions lsm;                      // stereo LSM (left -> right)
  double stereo_min_depth = 1.0;       // m, epipolar search starts at this depth ...
  double stereo_max_depth = 80.0;      // m, ... and ends at this one
  double sigma_angle_px = 0.5;         // px, lateral error of cross-site positions for the consistency threshold
  double min_sigma_parallax = 0.1;     // px, floor of the stereo parallax sigma (eq. 7)
  void Visit(OptionsReader& reader);
};

// distance_consistency, motion_consistency, dr_check: the verification and the tie points' sigmas.
struct VerificationOptions {
  ConsistencyOptions consistency;
  MotionConsistencyOptions motion = MotionDefaults();  // after eq. 2: one rigid motion within each point's covariance
  bool motion_consistency = true;      // (tests only) apply it
  double cross_sigma_floor_px = 0.3;   // px (previous image), least sigma of a cross-site left observation:
                                       // LSM's own precision ignores relief and resolution differences (the
                                       // simulated traverses' matches are 0.28-0.31 px per axis from the truth)
  double stereo_sigma_floor_px = 0.07; // px, least sigma of a right-image observation (stereo LSM against the
                                       // rendered depth: 0.06 px per axis, default profile)
  double max_motion_sigmas = 5.0;      // the motion implied by the tie points must agree with DR within this (0 = off);
                                       // a gross-error gate: DR understates wheel slip (hard seed 3, pair 18 -> 19:
                                       // 221 consistent, right tie points 3.0 sigma from DR)
  bool dr_check_translation = true;    // the DR check compares the translation too (false: yaw only; where the
                                       // tie points are far terrain, 40-400 m, their 3D-3D translation is not
                                       // determined within the DR's sigma: Devon 2 -> 3 gave 37 m off)
  void Visit(OptionsReader& reader);
};

// vehicle_mask (and prepare_images): the rover's body (deck, wheels, mast base) in the body frame: no feature or
// tie point on it.
struct VehicleOptions {
  // Boxes of 6 numbers each (x0 x1 y0 y1 z0 z1, m); a pixel whose ray from the left camera meets one is masked.
  std::vector<double> vehicle_boxes_m;
  double vehicle_margin_px = 6.0;      // px, the mask grows by this (the boxes are approximate)
  void Visit(OptionsReader& reader);
};

struct FrontendOptions {
  RegionOptions regions;                  // region_prediction (and far_stereo, ground_alignment, backward_matching)
  GroundPlaneOptions ground;              // ground_planes
  GroundAlignOptions ground_alignment;    // ground_alignment
  WorkRegionOptions work_regions;         // region_wallis_zoom, current_wallis
  FeatureOptions features;                // asift_and_warps
  GateOptions gate;                       // asift_and_warps, overlap_matching, backward_matching
  WarpOptions warp;                       // asift_and_warps
  OverlapMatchOptions overlap_matching;   // overlap_matching (its `matching` also backward_matching)
  GridLsmStepOptions grid;                // overlap_grid_lsm
  CrossSiteLsmOptions cross_site;         // cross_lsm_merge, manual_cross_lsm
  StereoStepOptions stereo;               // stereo_zncc, median_filter, stereo_lsm (its zncc also ground_planes)
  VerificationOptions verification;       // distance_consistency, motion_consistency, dr_check
  VehicleOptions vehicle;                 // prepare_images (the masks), vehicle_mask
  int min_tie_points = 12;                // fewer verified points: STATUS too few points
  int num_threads = 2;                    // OpenMP threads (stereo, LSM); asift/matching use their own

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;  // every step's bounds and relations (CheckOptions)
};

enum class FrontendStatus { kOk = 0, kNoOverlap = 1, kLowTexture = 2, kTooFewPoints = 3, kMissingInput = 4, kError = 5 };
const char* FrontendStatusName(FrontendStatus status);

struct StageReport {
  std::string name;
  int count = 0;         // points (or regions) surviving the stage
  double seconds = 0;    // wall time
};

struct FrontendSummary {
  FrontendStatus status = FrontendStatus::kError;
  std::string message;               // why, when not OK
  std::vector<StageReport> stages;
  double total_seconds = 0;
  int num_overlaps = 0;
  int num_tie_points = 0;

  bool IsUsable() const { return status == FrontendStatus::kOk; }
  std::string BriefReport() const;
};

struct FrontendResult {
  TiePointSet tie_points;
  FrontendSummary summary;
};

// A tie point an operator picked by hand: the same ground point clicked in
// a left image of each site (raw px, as the images were received).
struct ManualTie {
  int previous_pair = 0;                                   // pair_index at the previous site
  Eigen::Vector2d previous_px = Eigen::Vector2d::Zero();   // px, raw left image
  int current_pair = 0;                                    // pair_index at the current site
  Eigen::Vector2d current_px = Eigen::Vector2d::Zero();    // px, raw left image
};

class CrossSiteFrontend {
 public:
  CrossSiteFrontend(NavcamModel navcam, FrontendOptions options);

  // Never throws for bad data: problems end up in summary.status/message.
  FrontendResult Run(const SiteImages& previous, const SiteImages& current) const;
  // The tie points of an operator's clicks (manual_ties.cpp): each click
  // refined as the front end refines its own matches (cross-site LSM of the
  // current click from the previous one, kept at sigma_unrefined_px when LSM
  // cannot refine it; ZNCC + LSM stereo at both sites; intersection). Usable
  // when at least one click survives; the BA decides whether they suffice.
  FrontendResult RunManual(const SiteImages& previous, const SiteImages& current,
                           const std::vector<ManualTie>& ties) const;

  const FrontendOptions& options() const { return options_; }
  const NavcamModel& navcam() const { return navcam_; }

 private:
  NavcamModel navcam_;
  FrontendOptions options_;
};

}  // namespace vloc
