#pragma once
// The steps of the cross-site front end (Wan et al. 2.1-2.2), for
// CrossSiteFrontend::Run (frontend.cpp, which calls them in this order) and
// for their unit tests. Internal: not an API, it changes with the steps.
//
//   step                     file                        paper                               options (FrontendOptions.)
//   PrepareImages            prepare_images.cpp          (undistortion)                      vehicle
//   FitGroundPlanes          ground_planes.cpp           2.1, the ground the regions lie on  ground (+ regions, stereo.zncc)
//   MeasureFarTerrain        ground_planes.cpp           (far-terrain stereo, regions.far_*) regions, stereo.zncc
//   PredictRegions           regions.cpp                 2.1, initial matching regions       regions
//   AlignToPreviousGround    ground_alignment.cpp        (DR relative height on the ground)  ground_alignment (+ ground,
//                                                                                            regions, stereo.zncc)
//   MakeWorkRegions          work_regions.cpp            2.2, Wallis filter and zoom         work_regions
//   DetectRegionFeatures     region_features.cpp         2.2, ASIFT, restricted tilts        features
//   WarpOverlap              overlap_warp.cpp            (ground-plane warp + tiles)         warp (+ gate)
//   DescribeRegionsAnd-      asift_and_warps.cpp         the two above as one pool of jobs   features, warp, gate
//     WarpOverlaps                                       (warp_current)
//   MatchOverlap             overlap_matching.cpp        2.2, gated matching + epipolar      overlap_matching (+ gate)
//   RefineOnGrid             grid_lsm.cpp                2.2, cross-site LSM                 grid
//   MatchBackwardOverlap     backward_overlaps.cpp       2.2, opposite views on the ground   regions, work_regions.wallis,
//                                                                                            features.asift, gate,
//                                                                                            overlap_matching.matching
//   RefineCrossSite          cross_site_refinement.cpp   2.2, cross-site LSM, full res.      cross_site
//   CorrelateStereo ..       stereo.cpp                  2.2, ZNCC + median + LSM, both      stereo
//   CheckConsistency .. DR   verification.cpp            2.2 eq. 2 (eq. 7, 3.1)              verification
// warp.warp_current (which image the matching steps use) and num_threads
// are passed to the steps that need them as plain arguments.
//
// One SitePairState carries everything between the steps.

#include <Eigen/Core>
#include <algorithm>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "vloc/common/stopwatch.h"
#include "vloc/crosssite/frontend.h"

namespace vloc::frontend_internal {

// ---- constants (not worth an option; named so a reader can find them)
constexpr int kGroundRansacIterations = 300;       // 3-point samples of the ground-plane RANSAC
constexpr unsigned kGroundRansacSeed = 7;          // its fixed seed (the front end is deterministic)
constexpr double kGroundMinInlierFraction = 0.3;   // of the stereo points, for a plane to be accepted
constexpr int kGroundMinGridPx = 8;                // px, finest grid of the ground-plane stereo points
constexpr int kTileRansacIterations = 5000;        // iterations of the tile-registration homography RANSAC
constexpr double kRansacConfidence = 0.999;        // of the tile homography and the epipolar RANSAC
constexpr int kTileRegistrationPasses = 2;         // whole gate, then a few px around the correction
constexpr double kSecondPassRadiusTiles = 3.0;     // reduced px, search radius of the second pass
constexpr int kCoverageErodePx = 9;                // px, the warped image's coverage mask is eroded by this box
constexpr int kWarpedSiftMarginPx = 160;            // px, around the coverage, of the warped image SIFT describes
constexpr int kWarpedSiftAlignPx = 32;             // px, that part starts on a multiple of this
constexpr int kMinEpipolarMatches = 12;            // stage-2 matches needed for the epipolar RANSAC
constexpr double kMinClusterRadiusPx = 8.0;        // current px, smallest radius of the stage-1 offset cluster
constexpr double kSpreadCellPx = 24.0;             // px, grid cell of the spread selection per overlap
constexpr double kOrthoResolutionM = 0.02;         // m per ortho pixel, backward overlaps
constexpr int kMaxOrthoPx = 2000;                  // px, largest side of a backward overlap's ortho image
constexpr int kMinOrthoPx = 32;                    // px, smaller ortho images are not matched
constexpr double kBackwardImageMarginPx = 10;      // px, backward matches this close to a border are dropped
constexpr int kMinCurrentFeatures = 20;            // fewer ASIFT features in the current regions: low texture
constexpr double kMinPlaneNormal = 0.5;            // |n| of a fitted plane; zero vector = no plane
constexpr int kAlignMinNeighbours = 5;             // previous stereo points a local ground plane needs
constexpr size_t kAlignMaxPoints = 4000;           // per site, thinned beyond (a fine ground_grid_px)
constexpr double kAlignMinNormalZ = 0.7;           // steeper local planes (45 deg) are not ground
constexpr double kAlignParallaxSigmaPx = 0.5;      // px, the ground points' ZNCC parallax sigma
constexpr double kAlignRoughnessM = 0.03;          // m, the ground's relief about a local plane
constexpr int kAlignIterations = 8;                // Gauss-Newton steps (the planes are found again at each)
constexpr double kAlignHuber = 2.0;                // normalised residual where Huber's loss turns linear
constexpr double kAlignConvergenceM = 0.002;       // m, stop when the step is below this
constexpr double kAlignMaxPriorSigmas = 3.0;       // a correction farther from the DR than this is refused
constexpr double kAlignMinPriorSigmaM = 0.02;      // m, floor of the DR's relative height sigma as the prior

// One image as the steps use it: ideal (undistorted) 8-bit and LSM form.
struct PreparedImage {
  cv::Mat gray;     // CV_8UC1, ideal pixels
  LsmImage lsm;     // float + gradients
  cv::Mat vehicle;  // CV_8UC1, non-zero where the rover's body is (left images; empty = none in view)
};

// One image's part in the matching: the union of its overlaps' regions,
// Wallis-filtered and zoomed, and the features found on it (ideal px of the
// full image).
struct WorkRegion {
  cv::Rect region;                 // px, union of the forward overlaps' regions (empty: not used)
  double zoom = 1.0;               // work px per region px
  cv::Mat image;                   // Wallis-filtered region, zoomed
  double max_tilt = 1.0;           // current images: largest predicted tilt of its overlaps
  double longitude = 0.0;          // rad, current images: sample-weighted axial mean tilt longitude
  std::vector<AffineView> views;   // ASIFT views simulated on it
  FeatureSet features;             // in ideal px of the full image
};

// A cross-site candidate on its way through the steps.
struct Candidate {
  int overlap = 0;
  int prev_pair = 0, cur_pair = 0;
  Eigen::Vector2d prev_left = Eigen::Vector2d::Zero(), cur_left = Eigen::Vector2d::Zero();
  Eigen::Vector2d prev_right = Eigen::Vector2d::Zero(), cur_right = Eigen::Vector2d::Zero();
  double descriptor_distance = 0;
  double sigma_cross = 0, sigma_prev_right = 0, sigma_cur_right = 0;
  Eigen::Vector3d p_prev = Eigen::Vector3d::Zero(), p_cur = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov_prev = Eigen::Matrix3d::Zero(), cov_cur = Eigen::Matrix3d::Zero();
  bool ok = true;
  bool grid_refined = false;  // cross-site position already refined by LSM on the previous region's grid
  double grid_correlation = 0, grid_sigma_max = 0;                 // of the grid LSM (grid px)
  Eigen::Matrix2d grid_affine = Eigen::Matrix2d::Identity();       // its shape
  const char* why = "";
  Eigen::Matrix2d initial_affine = Eigen::Matrix2d::Identity();  // current px per previous px
};

// One forward overlap on the previous region's grid ("train" image): the
// current image warped there by the predicted (and tile-corrected) ground
// homography. Without warp_current the train image is the current region.
struct OverlapWork {
  bool skipped = false;                 // nothing to match (empty region, no features, stage 1 failed)
  cv::Mat warped;                       // warped current image (warp_current)
  cv::Mat coverage;                     // CV_8UC1, where `warped` holds current pixels
  cv::Mat previous_crop;                // the previous work region on the same grid
  cv::Matx33d current_from_train = cv::Matx33d::eye();  // train px -> current-left px
  cv::Matx33d train_from_previous = cv::Matx33d::eye(); // previous-left px -> train px
  bool registered = false;              // the warp was corrected by tile registration
  int tile_inliers = 0;                 // tiles agreeing on that correction
  FeatureSet warped_features;           // ASIFT on `warped`
  std::vector<Candidate> candidates;    // matches of this overlap
};

// The stages of one front-end run (Run, RunManual): each named step timed
// and its count kept in result->summary.stages; Finish closes the summary
// with the status, the tie-point count and the total time.
class StageLog {
 public:
  explicit StageLog(FrontendResult* result) : result_(result) {}
  template <class Body>
  int Step(const char* name, Body&& body) {
    const Stopwatch watch;
    const int count = body();
    result_->summary.stages.push_back({name, count, watch.Seconds()});
    return count;
  }
  FrontendResult Finish(FrontendStatus status, const std::string& message) {
    FrontendSummary& sum = result_->summary;
    sum.status = status;
    sum.message = message;
    sum.total_seconds = total_.Seconds();
    sum.num_tie_points = static_cast<int>(result_->tie_points.points.size());
    return *result_;
  }
  const std::vector<StageReport>& stages() const { return result_->summary.stages; }

 private:
  FrontendResult* result_;
  const Stopwatch total_;
};

// Sparse stereo points of one pair (body frame) and the left camera they were seen from.
struct GroundPointSet {
  Eigen::Vector3d camera = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> points;
};

struct SitePairState {
  SiteImages previous, current;  // pairs sorted by pair_index
  std::vector<PreparedImage> previous_left, previous_right, current_left, current_right;
  std::vector<Eigen::Vector4d> ground_planes;  // per current pair, body frame; zero = none
  std::vector<GroundPointSet> current_ground;  // per current pair: the plane's stereo points
  std::vector<std::vector<ScenePoint>> current_far;  // per current pair: far-terrain stereo points (regions.far_*)
  Pose3 dr_previous_from_current = Pose3::Identity();  // the DR's relative pose (the prediction may be ground-aligned)
  RegionPrediction prediction;
  std::vector<WorkRegion> previous_regions, current_regions;
  WallisOptions previous_wallis;            // Wallis targets of the previous site (from the current regions)
  double largest_region_std = 0;            // grey level, raw std of the most textured region
  std::vector<cv::Mat> current_filtered;    // whole current left images, Wallis-filtered (warp_current)
  std::vector<bool> overlap_used;           // per overlap: matched (max_overlaps_per_image)
  std::vector<OverlapWork> overlaps;        // per overlap
  std::vector<Candidate> candidates;        // after the overlaps, then through the remaining steps
  size_t num_current_features = 0;          // ASIFT features in the current regions and warped images
};

// ---- geometry shared by the steps (stereo_geometry.cpp)

// Epipolar segment in the right image for depths [z0, z1] of the left
// pixel, clipped to the image; false if it misses the image.
bool EpipolarSegment(const StereoRig& rig, const Eigen::Vector2d& left_px, double z0, double z1, Eigen::Vector2d* a,
                     Eigen::Vector2d* b);
// Midpoint triangulation of two rays (origins o, directions d) in one frame;
// false when parallel or behind either origin.
bool Triangulate(const Eigen::Vector3d& o1, const Eigen::Vector3d& d1, const Eigen::Vector3d& o2,
                 const Eigen::Vector3d& d2, Eigen::Vector3d* p);

// ---- steps

// ---- the rover's body in the images (vehicle_mask.cpp)

// Left-image mask (full size, dilated by vehicle_margin_px) of the pixels
// whose ray meets one of vehicle_boxes_m; empty when none does.
cv::Mat VehicleMask(const NavcamModel& navcam, const MastPointing& pointing, const VehicleOptions& options);
bool OnVehicle(const cv::Mat& mask, const Eigen::Vector2d& px);
// Removes the features whose image position (image_from_feature applied to
// the feature's point) lies on the mask.
void DropVehicleFeatures(const cv::Mat& mask, const cv::Matx33d& image_from_feature, FeatureSet* features);
// Removes the candidates on the body in either left image; returns how many.
int DropVehicleCandidates(SitePairState* state);

// Sorts the pairs and checks every image (8-bit grey or BGR colour of the calibrated
// size); the problem when not usable.
std::optional<std::string> CheckInput(const SiteImages& previous, const SiteImages& current, const NavcamModel& navcam,
                                      SitePairState* state);
// The tie point set's header: site ids, poses, pointings, time.
void InitTiePointSet(const SitePairState& state, TiePointSet* tie_points);
// Whether an LSM of the steps interpolates by B-spline (stereo.lsm, cross_site.cross_lsm): PrepareImages then
// makes the images' B-spline form.
bool UsesBspline(const FrontendOptions& options);
// Undistorts all images and makes their LSM form (with B-spline
// interpolation when `bspline`),
// and the left images' vehicle masks.
void PrepareImages(const NavcamModel& navcam, const VehicleOptions& vehicle, bool bspline, int num_threads,
                   SitePairState* state);

// The ground seen by one current pair as a plane n . p + e = 0 (n up, unit)
// in the body frame, from ZNCC stereo on a coarse grid and RANSAC; zero
// when there are too few points or the plane is implausible. The points
// lie within the regions' current ranges; `zncc` matches them.
Eigen::Vector4d FitGroundPlane(const NavcamModel& navcam, const MastPointing& pointing, const cv::Mat& left,
                               const cv::Mat& right, const GroundPlaneOptions& options, const RegionOptions& regions,
                               const ZnccOptions& zncc, GroundPointSet* points = nullptr);
// The sparse stereo points a ground plane is fitted to.
GroundPointSet GroundStereoPoints(const NavcamModel& navcam, const MastPointing& pointing, const cv::Mat& left,
                                  const cv::Mat& right, const GroundPlaneOptions& options, const RegionOptions& regions,
                                  const ZnccOptions& zncc);
// Every current pair's ground plane (fit_ground_planes); returns how many.
int FitGroundPlanes(const NavcamModel& navcam, const TiePointSet& tie_points, const GroundPlaneOptions& options,
                    const RegionOptions& regions, const ZnccOptions& zncc, int num_threads, SitePairState* state);

// Every current pair's far-terrain stereo points (regions.far_min_range to
// far_max_range, on the regions' grid, range sigma from
// far_disparity_sigma_px); returns how many.
int MeasureFarTerrain(const NavcamModel& navcam, const TiePointSet& tie_points, const RegionOptions& regions,
                      const ZnccOptions& zncc, int num_threads, SitePairState* state);

// ---- the DR's relative height on the ground both sites measured (ground_alignment.cpp)
// DR knows the height gained between two sites worst (wheel slip on a
// slope, a pitch error), and at grazing views a few tenths of a metre of
// height move the predicted overlap by metres along the range. Both sites'
// stereo measured the ground between them: the current site's points,
// moved by the DR's relative pose, must lie on the previous site's ground
// (local planes of its points). A robust point-to-plane fit of the height
// offset, with the DR's vertical sigma as its prior, corrects it; the region
// prediction is then made again from the corrected pose. Only the height:
// the ground's normals are near vertical, so the horizontal position is
// weakly observed and a full translation fit wandered by metres (hard
// traverse, sites 8 -> 9). The DR check on the final motion still compares
// with the DR itself.
struct GroundAlignment {
  bool ok = false;
  Eigen::Vector3d delta = Eigen::Vector3d::Zero();  // m, along `up` in the frame of the points
  int points = 0;                                   // current points on the previous site's ground
  double rms_before = 0, rms_after = 0;             // robust normalised point-to-plane residual
  std::string why;                                  // when not ok
};
// Points in one frame (the previous site's, turned level by AlignToPreviousGround): `previous` there,
// `current` in the current body frame with `previous_from_current` taking them there; `up`: the vertical in it
// (unit); `prior_sigma_m`: the DR's relative height sigma.
GroundAlignment AlignGround(const std::vector<GroundPointSet>& previous, const std::vector<GroundPointSet>& current,
                            const Pose3& previous_from_current, const Eigen::Vector3d& up, double prior_sigma_m,
                            const NavcamModel& navcam, const GroundAlignOptions& options, int num_threads);
// Runs AlignGround for the pair (options.ground_align, when the ground
// planes were fitted; the previous site's points as the planes' are) and, when it holds, predicts the regions again from the
// corrected pose; returns the points used.
int AlignToPreviousGround(const NavcamModel& navcam, const TiePointSet& tie_points, const GroundAlignOptions& options,
                          const GroundPlaneOptions& ground, const RegionOptions& regions, const ZnccOptions& zncc,
                          int num_threads, SitePairState* state);

// Regions per image, Wallis filter, zoom, previous site's Wallis targets.
// Returns the number of regions; state->largest_region_std says whether
// there is texture at all.
int MakeWorkRegions(const WorkRegionOptions& options, bool warp_current, int num_threads, SitePairState* state);
// Per current image the overlaps with the most ground samples
// (max_overlaps_per_image), and the current images filtered whole (warp_current).
// The previous regions no chosen overlap matches are cleared.
void ChooseOverlaps(const WorkRegionOptions& options, bool warp_current, int num_threads, SitePairState* state);

// Runs body(i) for every i < costs.size() on num_threads threads, the
// largest cost first: the last job to finish is a small one.
template <class Body>
void RunLargestFirst(const std::vector<double>& costs, int num_threads, Body body) {
  std::vector<int> order(costs.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return costs[a] > costs[b]; });
#pragma omp parallel for schedule(dynamic, 1) num_threads(num_threads)
  for (int i = 0; i < static_cast<int>(order.size()); ++i) body(order[i]);
}

// ASIFT on the work regions (previous: t = 1; current, without
// warp_current: the tilts and longitudes the prediction allows). Returns
// the number of features.
int DetectRegionFeatures(const FeatureOptions& options, bool warp_current, int num_threads, SitePairState* state);
// The same in parts, for a caller that runs the jobs among others: one job
// per (region, view) (sets the regions' views), its cost, its features (in
// the view's region px), and all jobs' features added to their regions
// (returns how many).
struct RegionFeatureJob {
  bool current = false;  // a current region (else a previous one)
  int image = 0;         // its index
  AffineView view;
};
std::vector<RegionFeatureJob> RegionFeatureJobs(const FeatureOptions& options, bool warp_current,
                                                SitePairState* state);
double RegionFeatureJobCost(const RegionFeatureJob& job, const SitePairState& state);
// ASIFT (one thread) on `image`, a grid zoomed by `zoom` from its region; where zoom > options.sift_max_zoom (> 0)
// on the grid resized to that zoom, the features mapped back onto the grid.
FeatureSet DetectOnGrid(const cv::Mat& image, const cv::Mat& mask, const std::vector<AffineView>& views, double zoom,
                        const FeatureOptions& options);
FeatureSet DetectRegionFeatureJob(const RegionFeatureJob& job, const FeatureOptions& options,
                                  const SitePairState& state);
int AddRegionFeatures(const std::vector<RegionFeatureJob>& jobs, const std::vector<FeatureSet>& sets,
                      SitePairState* state);

// The DR gate of a forward overlap, current-image px: the region's growth
// under the DR uncertainty (growth_px over the scale) plus gate_margin_px,
// at most max_gate_px. WarpOverlap's first tile pass and MatchOverlap's
// stage 1 search within it (times their train px per current px).
double DrGateRadiusPx(const PairOverlap& overlap, const GateOptions& gate);
// Warps the current image of a forward overlap onto the previous
// region's grid and registers it by tile correlation (two passes).
OverlapWork WarpOverlap(const PairOverlap& overlap, const SitePairState& state, const WarpOptions& options,
                        const GateOptions& gate);
// ASIFT on a warped overlap (tilts up to warp_max_tilt); zoom: its previous region's (DetectOnGrid).
void DetectWarpedFeatures(const FeatureOptions& options, bool warp_current, double zoom, OverlapWork* work);

// With warp_current, DetectRegionFeatures and every matched forward
// overlap's WarpOverlap + DetectWarpedFeatures (features on the rover's
// body dropped) as one pool of jobs, largest first (asift_and_warps.cpp).
// Fills state->overlaps; returns the features (regions and warped images).
int DescribeRegionsAndWarpOverlaps(const FeatureOptions& features, const WarpOptions& warp, const GateOptions& gate,
                                   int num_threads, SitePairState* state);

// Stage 1: the densest cluster of match offsets (current - predicted, train
// px) within radius r of one offset, kept within 2r of its mean.
std::vector<FeatureMatch> DensestOffsetCluster(const std::vector<FeatureMatch>& matches, const FeatureSet& train,
                                               const std::vector<Eigen::Vector2d>& predicted, double r,
                                               Eigen::Vector2d* mode = nullptr, int* mode_count = nullptr);
// Keeps the `cap` best (by descriptor distance) of `idx`, spread over a grid of `cell` px in the current image.
std::vector<int> SpreadSelect(const std::vector<Candidate>& candidates, const std::vector<int>& idx, int cap,
                              double cell);
// Gated matching of forward overlap k: DR prediction (stage 1), refined
// prediction (stage 2), epipolar test, spread selection. Fills work->candidates.
void MatchOverlap(int k, const PairOverlap& overlap, const SitePairState& state, const OverlapMatchOptions& options,
                  const GateOptions& gate, bool warp_current, OverlapWork* work);

// The correlation peak of the window around templ_px of `templ` within
// +-radius px of *target_px in `target` (both CV_8UC1), sub-pixel by a
// parabola fit; false without a clear peak of at least min_score.
bool ZnccPeakNear(const cv::Mat& templ, const Eigen::Vector2d& templ_px, const cv::Mat& target, int radius, int half,
                  int half_y, double min_score, double min_margin, Eigen::Vector2d* target_px);
// Cross-site LSM of one candidate on the previous region's grid, with the
// relief gates (back match, shear). `previous` and `warped` are the LSM
// forms of work.previous_crop and work.warped; `lsm` the window and gates
// (options.grid_lsm, or options.grid_lsm_retry on a second try). False: not refined.
bool RefineOnGrid(const OverlapWork& work, const LsmImage& previous, const LsmImage& warped,
                  const GridLsmStepOptions& options, const LsmOptions& lsm, Candidate* candidate);
// RefineOnGrid on every candidate of the overlap (warp_current only);
// returns how many were refined.
int RefineOverlapOnGrid(const GridLsmStepOptions& options, bool warp_current, OverlapWork* work);

// What the backward matching reuses of the forward steps' options.
struct BackwardMatchOptions {
  RegionOptions regions;       // regions: the ground height and the sigma scale of the gate
  WallisOptions wallis;        // work_regions.wallis: the current ortho image's filter
  AsiftOptions asift;          // features.asift: detection on both ortho images
  GatedMatchOptions matching;  // overlap_matching.matching: the matcher
  GateOptions gate;            // gate: the gate margin
  static BackwardMatchOptions Of(const FrontendOptions& options);
};
// A backward overlap matched on the ground plane (ortho images of both sites).
std::vector<Candidate> MatchBackwardOverlap(int k, const NavcamModel& navcam, const TiePointSet& tie_points,
                                            const SitePairState& state, const BackwardMatchOptions& options);

// Cross-site LSM of the candidates the grid LSM did not refine (full
// resolution; dropped when it fails), then duplicates merged. Returns the
// count left. `grid_refined_only` (warp_current): the grid LSM ran on the
// forward overlaps and what it did not refine is dropped (only backward
// candidates are refined here).
int RefineCrossSite(const CrossSiteLsmOptions& options, bool grid_refined_only, int num_threads, SitePairState* state);
// Of candidates sorted by sigma_cross, drops those within `radius` px of a kept one in the same current image.
void MergeDuplicates(double radius, std::vector<Candidate>* candidates);

// Stereo at both sites, in three steps.
int CorrelateStereo(const NavcamModel& navcam, const StereoStepOptions& options, int num_threads, SitePairState* state);
int MedianFilterDisparities(const StereoStepOptions& options, SitePairState* state);
int RefineStereoAndIntersect(const NavcamModel& navcam, const TiePointSet& tie_points, const StereoStepOptions& options,
                             int num_threads, SitePairState* state);

// Verification: distance consistency (eq. 2), one rigid motion, the tie
// points with their sigmas, and the check against dead reckoning.
struct Verification {
  std::vector<bool> consistent;  // per candidate, eq. 2
  std::vector<int> weights;      // per candidate, consistency votes
  int num_consistent = 0;
  std::vector<bool> keep;        // per candidate, also one rigid motion
  int num_kept = 0;
};
Verification CheckConsistency(const std::vector<Candidate>& candidates, const VerificationOptions& options);
void CheckMotion(const std::vector<Candidate>& candidates, const VerificationOptions& options, Verification* v);
void MakeTiePoints(const std::vector<Candidate>& candidates, const Verification& v, const RegionPrediction& prediction,
                   const VerificationOptions& options, TiePointSet* tie_points);
// The motion the tie points imply against the DR prediction; the problem
// (and the points cleared) when it is beyond max_motion_sigmas.
std::optional<std::string> CheckAgainstDeadReckoning(const RegionPrediction& prediction,
                                                     const VerificationOptions& options, TiePointSet* tie_points);

}  // namespace vloc::frontend_internal
