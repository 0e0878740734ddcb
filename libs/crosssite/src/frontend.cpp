// The cross-site front end as a table of contents: CrossSiteFrontend::Run
// calls the steps (internal/frontend_steps.h, one file each) in order over
// one SitePairState, and times each under the name it reports in
// FRONTEND_STATUS. The options' loading and checking live here too.
#include "vloc/crosssite/frontend.h"

#include <omp.h>

#include <sstream>

#include "vloc/common/options.h"
#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc {

void FrontendOptions::Visit(OptionsReader& r) {
  r.Child("regions", [&](OptionsReader& c) { regions.Visit(c); });
  r.Child("wallis", [&](OptionsReader& c) { wallis.Visit(c); });
  r.Child("asift", [&](OptionsReader& c) { asift.Visit(c); });
  r.Child("matching", [&](OptionsReader& c) { matching.Visit(c); });
  r.Child("zncc", [&](OptionsReader& c) { zncc.Visit(c); });
  r.Child("median_filter", [&](OptionsReader& c) { median.Visit(c); });
  r.Child("lsm", [&](OptionsReader& c) { lsm.Visit(c); });
  r.Child("cross_lsm", [&](OptionsReader& c) { cross_lsm.Visit(c); });
  r.Child("consistency", [&](OptionsReader& c) { consistency.Visit(c); });
  r.Child("tiles", [&](OptionsReader& c) { tiles.Visit(c); });
  r.Child("motion", [&](OptionsReader& c) { motion.Visit(c); });
  r.Optional("fit_ground_planes", &fit_ground_planes, "fit each current image's ground plane to sparse stereo");
  r.Optional("ground_grid_px", &ground_grid_px, "px, grid of the stereo points for the ground plane");
  r.Optional("ground_min_points", &ground_min_points, "stereo points (and plane inliers) a ground plane needs");
  r.Optional("ground_tolerance_m", &ground_tolerance_m, "m, plane inlier tolerance at short range");
  r.Optional("ground_max_slope_deg", &ground_max_slope_deg, "deg, steepest accepted ground plane");
  r.Optional("ground_align", &ground_align, "correct the DR's relative height on both sites' stereo ground");
  r.Optional("ground_align_radius_m", &ground_align_radius_m, "m, neighbourhood of a local ground plane (x, y)");
  r.Optional("ground_align_min_points", &ground_align_min_points, "current points over the previous ground needed");
  r.Optional("motion_consistency", &motion_consistency, "keep only points that agree under one rigid motion");
  r.Child("grid_lsm", [&](OptionsReader& c) { grid_lsm.Visit(c); });
  r.Child("grid_lsm_retry", [&](OptionsReader& c) { grid_lsm_retry.Visit(c); });
  r.Optional("grid_retry_below", &grid_retry_below, "retry an overlap's grid LSM with grid_lsm_retry when it refined fewer candidates (0 = off)");
  r.Optional("grid_search_px", &grid_search_px, "px (grid), correlation search around a match before grid LSM");
  r.Optional("grid_min_zncc", &grid_min_zncc, "correlation peak needed before the grid LSM");
  r.Optional("grid_min_margin", &grid_min_margin, "peak minus the best correlation >= 3 px away");
  r.Optional("grid_back_check_px", &grid_back_check_px, "px (grid), LSM back from the warped current image must return this close (0 = off)");
  r.Optional("grid_max_shear", &grid_max_shear, "largest |dx/dy| of the grid LSM's affine (relief parallax), 0 = off");
  r.Optional("grid_lsm_enabled", &grid_lsm_enabled, "refine cross-site matches by LSM on the previous region's grid");
  r.Optional("keep_grid_unrefined", &keep_grid_unrefined, "keep matches the grid LSM could not refine");
  r.Optional("tile_registration", &tile_registration, "register the warped current image by tile correlation first");
  r.Optional("min_tile_inliers", &min_tile_inliers, "tiles agreeing on one motion needed to register");
  r.Optional("tile_inlier_px", &tile_inlier_px, "reduced px, RANSAC threshold of the tile motion");
  r.Optional("max_zoom", &max_zoom, "largest zoom of the previous region");
  r.Optional("min_zoom", &min_zoom, "smallest zoom of the previous region");
  r.Optional("tilt_margin", &tilt_margin, "simulate tilts up to the predicted tilt times this");
  r.Optional("longitude_margin_deg", &longitude_margin_deg, "deg, simulated longitudes around the predicted one");
  r.Optional("gate_margin_px", &gate_margin_px, "px, added to the predicted growth for the match gate");
  r.Optional("fundamental_threshold_px", &fundamental_threshold_px, "px, RANSAC threshold (0 = off)");
  r.Optional("max_motion_sigmas", &max_motion_sigmas, "tie-point motion vs DR gate in sigmas (0 = off)");
  r.Optional("dr_check_translation", &dr_check_translation,
             "the DR check compares the tie points' translation too (false: yaw only, for far-terrain tie points)");
  r.Optional("keep_unrefined_cross", &keep_unrefined_cross, "keep matches whose cross-site LSM failed");
  r.Optional("sigma_unrefined_px", &sigma_unrefined_px, "px, sigma of an unrefined cross-site position");
  r.Optional("warp_current", &warp_current, "match on the current image warped by the ground homography");
  r.Optional("match_previous_resolution", &match_previous_resolution,
             "blur the warped current image to the zoomed previous region's resolution");
  r.Optional("warp_max_tilt", &warp_max_tilt, "largest tilt simulated on the warped image");
  r.Optional("max_overlaps_per_image", &max_overlaps_per_image, "overlaps matched per current image (0 = all)");
  r.Optional("zoom_previous", &zoom_previous, "zoom the previous region up (else shrink the current one)");
  r.Optional("refine_homography_threshold_px", &refine_homography_threshold_px, "px, stage-1 homography RANSAC threshold");
  r.Optional("stage1_cluster_fraction", &stage1_cluster_fraction,
             "radius of the stage-1 offset cluster as a fraction of the gate");
  r.Optional("refine_gate_px", &refine_gate_px, "px, stage-2 gate");
  r.Optional("max_gate_px", &max_gate_px, "px, largest stage-1 gate");
  r.Optional("min_stage1_inliers", &min_stage1_inliers, "stage-1 epipolar inliers needed to refine the prediction");
  r.Optional("refine_ratio", &refine_ratio, "stage-2 ratio test");
  r.Optional("max_points_per_overlap", &max_points_per_overlap, "matches kept per overlap");
  r.Optional("stereo_min_depth", &stereo_min_depth, "m, nearest depth searched along the epipolar line");
  r.Optional("stereo_max_depth", &stereo_max_depth, "m, farthest depth searched along the epipolar line");
  r.Optional("cross_sigma_floor_px", &cross_sigma_floor_px, "px (previous image), least cross-site sigma");
  r.Optional("stereo_sigma_floor_px", &stereo_sigma_floor_px, "px, least stereo (right image) sigma");
  r.Optional("sigma_angle_px", &sigma_angle_px, "px, lateral error for the consistency threshold");
  r.Optional("min_sigma_parallax", &min_sigma_parallax, "px, floor of the parallax sigma in eq. 7");
  r.Optional("min_region_std", &min_region_std, "grey level, texture needed in the regions");
  r.Optional("duplicate_radius", &duplicate_radius, "px, tie points closer than this are merged");
  r.Optional("min_tie_points", &min_tie_points, "verified tie points needed for status OK");
  r.Optional("vehicle_boxes_m", &vehicle_boxes_m,
             "m, the rover's body as boxes in the body frame, 6 numbers each: x0 x1 y0 y1 z0 z1 (empty = none)");
  r.Optional("vehicle_margin_px", &vehicle_margin_px, "px, the body's mask grows by this");
  r.Optional("num_threads", &num_threads, "OpenMP threads of the whole front end");
}

namespace {

// "frontend.<field> = <value>: must be <rule>".
template <typename T>
bool Bad(std::string* error, const char* field, T value, const char* rule) {
  std::ostringstream os;
  os << "frontend." << field << " = " << value << ": must be " << rule;
  return Fail(error, os.str());
}

// A child's Check with the child's name in front of its message.
template <typename Options>
bool CheckChild(const Options& child, const char* name, std::string* error) {
  std::string e;
  if (child.Check(&e)) return true;
  return Fail(error, std::string("frontend.") + name + ": " + e);
}

}  // namespace

bool FrontendOptions::Check(std::string* error) const {
  if (!CheckChild(regions, "regions", error) || !CheckChild(wallis, "wallis", error) ||
      !CheckChild(asift, "asift", error) || !CheckChild(matching, "matching", error) ||
      !CheckChild(zncc, "zncc", error) || !CheckChild(median, "median_filter", error) ||
      !CheckChild(lsm, "lsm", error) || !CheckChild(cross_lsm, "cross_lsm", error) ||
      !CheckChild(consistency, "consistency", error) || !CheckChild(grid_lsm, "grid_lsm", error) ||
      !CheckChild(grid_lsm_retry, "grid_lsm_retry", error) ||
      !CheckChild(motion, "motion", error) || !CheckChild(tiles, "tiles", error))
    return false;
  // Booleans (motion_consistency, fit_ground_planes, ground_align, zoom_previous,
  // keep_unrefined_cross, warp_current, match_previous_resolution,
  // grid_lsm_enabled, keep_grid_unrefined, tile_registration) have no bad value.
  // NaN fails every check below: each is written as !(good).
  if (vehicle_boxes_m.size() % 6 != 0)
    return Bad(error, "vehicle_boxes_m", vehicle_boxes_m.size(), "a multiple of 6 numbers (x0 x1 y0 y1 z0 z1 per box)");
  for (size_t b = 0; b + 6 <= vehicle_boxes_m.size(); b += 6)
    for (int a = 0; a < 3; ++a)
      if (!(vehicle_boxes_m[b + 2 * a] < vehicle_boxes_m[b + 2 * a + 1]))
        return Bad(error, "vehicle_boxes_m", "box " + std::to_string(b / 6), "finite, each min below its max");
  if (!(vehicle_margin_px >= 0 && vehicle_margin_px <= 100))
    return Bad(error, "vehicle_margin_px", vehicle_margin_px, "in [0, 100] px");
  if (!(ground_grid_px >= frontend_internal::kGroundMinGridPx)) return Bad(error, "ground_grid_px", ground_grid_px, ">= 8 px");
  if (!(ground_min_points >= 3)) return Bad(error, "ground_min_points", ground_min_points, ">= 3");
  if (!(ground_tolerance_m > 0)) return Bad(error, "ground_tolerance_m", ground_tolerance_m, "> 0 m");
  if (!(ground_align_radius_m > 0 && ground_align_radius_m <= 10))
    return Bad(error, "ground_align_radius_m", ground_align_radius_m, "in (0, 10] m");
  if (!(ground_align_min_points >= 10)) return Bad(error, "ground_align_min_points", ground_align_min_points, ">= 10");
  if (!(ground_max_slope_deg > 0 && ground_max_slope_deg <= 90))
    return Bad(error, "ground_max_slope_deg", ground_max_slope_deg, "in (0, 90] deg");
  if (!(min_zoom > 0)) return Bad(error, "min_zoom", min_zoom, "> 0");
  if (!(max_zoom >= min_zoom)) return Bad(error, "max_zoom", max_zoom, ">= min_zoom");
  if (!(max_motion_sigmas >= 0)) return Bad(error, "max_motion_sigmas", max_motion_sigmas, ">= 0 (0 = off)");
  if (!(sigma_unrefined_px > 0)) return Bad(error, "sigma_unrefined_px", sigma_unrefined_px, "> 0 px");
  if (!(warp_max_tilt >= 1)) return Bad(error, "warp_max_tilt", warp_max_tilt, ">= 1");
  if (!(max_overlaps_per_image >= 0)) return Bad(error, "max_overlaps_per_image", max_overlaps_per_image, ">= 0 (0 = all)");
  if (!(grid_min_zncc >= -1 && grid_min_zncc <= 1)) return Bad(error, "grid_min_zncc", grid_min_zncc, "in [-1, 1]");
  if (!(grid_min_margin >= 0 && grid_min_margin <= 2)) return Bad(error, "grid_min_margin", grid_min_margin, "in [0, 2]");
  if (!(grid_back_check_px >= 0)) return Bad(error, "grid_back_check_px", grid_back_check_px, ">= 0 px (0 = off)");
  if (!(grid_max_shear >= 0)) return Bad(error, "grid_max_shear", grid_max_shear, ">= 0 (0 = off)");
  if (!(grid_retry_below >= 0)) return Bad(error, "grid_retry_below", grid_retry_below, ">= 0 (0 = off)");
  if (!(grid_search_px >= 1)) return Bad(error, "grid_search_px", grid_search_px, ">= 1 px");
  if (!(min_tile_inliers >= 4)) return Bad(error, "min_tile_inliers", min_tile_inliers, ">= 4 (a homography)");
  if (!(tile_inlier_px > 0)) return Bad(error, "tile_inlier_px", tile_inlier_px, "> 0 px");
  if (!(refine_homography_threshold_px > 0))
    return Bad(error, "refine_homography_threshold_px", refine_homography_threshold_px, "> 0 px");
  if (!(stage1_cluster_fraction > 0 && stage1_cluster_fraction <= 1))
    return Bad(error, "stage1_cluster_fraction", stage1_cluster_fraction, "in (0, 1]");
  if (!(refine_gate_px > 0)) return Bad(error, "refine_gate_px", refine_gate_px, "> 0 px");
  if (!(max_gate_px > 0)) return Bad(error, "max_gate_px", max_gate_px, "> 0 px");
  if (!(min_stage1_inliers >= 4)) return Bad(error, "min_stage1_inliers", min_stage1_inliers, ">= 4 (a homography)");
  if (!(refine_ratio > 0 && refine_ratio <= 1)) return Bad(error, "refine_ratio", refine_ratio, "in (0, 1]");
  if (!(tilt_margin >= 1)) return Bad(error, "tilt_margin", tilt_margin, ">= 1");
  if (!(longitude_margin_deg >= 0)) return Bad(error, "longitude_margin_deg", longitude_margin_deg, ">= 0 deg");
  if (!(gate_margin_px >= 0)) return Bad(error, "gate_margin_px", gate_margin_px, ">= 0 px");
  if (!(fundamental_threshold_px >= 0))
    return Bad(error, "fundamental_threshold_px", fundamental_threshold_px, ">= 0 px (0 = no RANSAC)");
  if (!(max_points_per_overlap >= 1)) return Bad(error, "max_points_per_overlap", max_points_per_overlap, ">= 1");
  if (!(stereo_min_depth > 0)) return Bad(error, "stereo_min_depth", stereo_min_depth, "> 0 m");
  if (!(stereo_max_depth > stereo_min_depth)) return Bad(error, "stereo_max_depth", stereo_max_depth, "> stereo_min_depth");
  if (!(cross_sigma_floor_px >= 0)) return Bad(error, "cross_sigma_floor_px", cross_sigma_floor_px, ">= 0 px");
  if (!(stereo_sigma_floor_px >= 0)) return Bad(error, "stereo_sigma_floor_px", stereo_sigma_floor_px, ">= 0 px");
  if (!(sigma_angle_px >= 0)) return Bad(error, "sigma_angle_px", sigma_angle_px, ">= 0 px");
  if (!(min_sigma_parallax > 0)) return Bad(error, "min_sigma_parallax", min_sigma_parallax, "> 0 px");
  if (!(min_region_std >= 0)) return Bad(error, "min_region_std", min_region_std, ">= 0 grey levels");
  if (!(duplicate_radius >= 0)) return Bad(error, "duplicate_radius", duplicate_radius, ">= 0 px");
  if (!(min_tie_points >= 1)) return Bad(error, "min_tie_points", min_tie_points, ">= 1");
  if (!(num_threads >= 1)) return Bad(error, "num_threads", num_threads, ">= 1");
  return true;
}

const char* FrontendStatusName(FrontendStatus s) {
  switch (s) {
    case FrontendStatus::kOk: return "ok";
    case FrontendStatus::kNoOverlap: return "no overlap";
    case FrontendStatus::kLowTexture: return "too little texture";
    case FrontendStatus::kTooFewPoints: return "too few tie points";
    case FrontendStatus::kMissingInput: return "missing input";
    case FrontendStatus::kError: return "error";
  }
  return "unknown";
}

std::string FrontendSummary::BriefReport() const {
  std::ostringstream os;
  os << "front end: " << FrontendStatusName(status);
  if (!message.empty()) os << " (" << message << ")";
  os << ", " << num_tie_points << " tie points in " << total_seconds << " s;";
  for (const auto& s : stages) os << " " << s.name << " " << s.count << " (" << s.seconds << " s)";
  return os.str();
}

CrossSiteFrontend::CrossSiteFrontend(NavcamModel navcam, FrontendOptions options)
    : navcam_(std::move(navcam)), options_(std::move(options)) {}

namespace {

using namespace frontend_internal;

// Runs `body` on every forward overlap that is matched, in parallel.
template <typename Body>
void ForEachForwardOverlap(const SitePairState& s, int num_threads, Body body) {
  const int n = static_cast<int>(s.prediction.overlaps.size());
#pragma omp parallel for schedule(dynamic, 1) num_threads(num_threads)
  for (int k = 0; k < n; ++k)
    if (!s.prediction.overlaps[k].backward && s.overlap_used[k]) body(k);
}

// Where the matches of a pair that ends with too few went: the survivors of each step along the match chain.
std::string MatchChain(const std::vector<StageReport>& stages) {
  auto count = [&](const std::string& name) {
    for (const StageReport& s : stages)
      if (s.name == name) return s.count;
    return 0;
  };
  std::ostringstream os;
  os << "matches: " << count("overlap_matching") << " in the overlaps";
  if (const int backward = count("backward_matching")) os << " + " << backward << " backward";
  os << ", " << count("cross_lsm_merge") << " after cross-site LSM, " << count("stereo_lsm") << " after stereo, "
     << count("distance_consistency") << " distance-consistent, " << count("motion_consistency")
     << " consistent with one motion";
  return os.str();
}

}  // namespace

FrontendResult CrossSiteFrontend::Run(const SiteImages& previous, const SiteImages& current) const {
  FrontendResult result;
  FrontendSummary& sum = result.summary;
  TiePointSet& tps = result.tie_points;
  const FrontendOptions& o = options_;
  const NavcamModel& navcam = navcam_;
  StageLog stages(&result);
  try {
    SitePairState s;
    if (auto problem = CheckInput(previous, current, navcam, &s))
      return stages.Finish(FrontendStatus::kMissingInput, *problem);
    InitTiePointSet(s, &tps);
    stages.Step("prepare_images", [&] {
      PrepareImages(navcam, o, &s);
      return static_cast<int>(2 * (s.previous.pairs.size() + s.current.pairs.size()));
    });
    stages.Step("ground_planes", [&] { return FitGroundPlanes(navcam, tps, o, &s); });
    if (o.regions.far_max_range > 0) stages.Step("far_stereo", [&] { return MeasureFarTerrain(navcam, tps, o, &s); });
    stages.Step("region_prediction", [&] {
      s.prediction = PredictRegions(navcam, s.previous.world_from_body, s.current.world_from_body,
                                    tps.previous_pointing, tps.current_pointing, o.regions, s.ground_planes,
                                    s.current_far);
      return static_cast<int>(s.prediction.overlaps.size());
    });
    stages.Step("ground_alignment", [&] { return AlignToPreviousGround(navcam, tps, o, &s); });
    sum.num_overlaps = static_cast<int>(s.prediction.overlaps.size());
    if (s.prediction.overlaps.empty())
      return stages.Finish(FrontendStatus::kNoOverlap,
                    "no current image sees ground that a previous image sees within the range limits "
                    "(check the DR poses, mast pointing and regions.max_range_*)");
    stages.Step("region_wallis_zoom", [&] { return MakeWorkRegions(o, &s); });
    if (s.largest_region_std < o.min_region_std) {
      std::ostringstream os;
      os << "the overlap regions are flat (largest grey-level std " << s.largest_region_std << " < min_region_std "
         << o.min_region_std << "): too little texture to match";
      return stages.Finish(FrontendStatus::kLowTexture, os.str());
    }
    stages.Step("current_wallis", [&] {
      ChooseOverlaps(o, &s);
      int n = 0;
      for (const cv::Mat& m : s.current_filtered) n += m.empty() ? 0 : 1;
      return n;
    });
    stages.Step("region_asift", [&] { return DetectRegionFeatures(o, &s); });

    // Forward overlaps, each step over all of them in parallel.
    s.overlaps.assign(s.prediction.overlaps.size(), OverlapWork());
    stages.Step("overlap_warp_tiles", [&] {
      ForEachForwardOverlap(s, o.num_threads, [&](int k) { s.overlaps[k] = WarpOverlap(s.prediction.overlaps[k], s, o); });
      int n = 0;
      for (const OverlapWork& w : s.overlaps) n += w.registered ? 1 : 0;
      return n;
    });
    stages.Step("overlap_asift", [&] {
      ForEachForwardOverlap(s, o.num_threads, [&](int k) {
        OverlapWork& w = s.overlaps[k];
        DetectWarpedFeatures(o, &w);
        DropVehicleFeatures(s.current_left[s.prediction.overlaps[k].current_pair].vehicle, w.current_from_train,
                            &w.warped_features);
      });
      size_t n = 0;
      for (const OverlapWork& w : s.overlaps) n += w.warped_features.size();
      s.num_current_features += n;
      return static_cast<int>(n);
    });
    stages.Step("overlap_matching", [&] {
      ForEachForwardOverlap(s, o.num_threads,
                            [&](int k) { MatchOverlap(k, s.prediction.overlaps[k], s, o, &s.overlaps[k]); });
      int n = 0;
      for (const OverlapWork& w : s.overlaps) n += static_cast<int>(w.candidates.size());
      return n;
    });
    stages.Step("overlap_grid_lsm", [&] {
      int n = 0;
      ForEachForwardOverlap(s, o.num_threads, [&](int k) {
        const int refined = RefineOverlapOnGrid(o, &s.overlaps[k]);
#pragma omp atomic
        n += refined;
      });
      return n;
    });
    stages.Step("backward_matching", [&] {
      int n = 0;
      for (size_t k = 0; k < s.prediction.overlaps.size(); ++k) {
        if (!s.prediction.overlaps[k].backward) continue;
        s.overlaps[k].candidates = MatchBackwardOverlap(static_cast<int>(k), navcam, tps, s, o);
        n += static_cast<int>(s.overlaps[k].candidates.size());
      }
      return n;
    });
    for (OverlapWork& w : s.overlaps) s.candidates.insert(s.candidates.end(), w.candidates.begin(), w.candidates.end());
    stages.Step("vehicle_mask", [&] {
      DropVehicleCandidates(&s);
      return static_cast<int>(s.candidates.size());
    });
    if (s.num_current_features < static_cast<size_t>(kMinCurrentFeatures))
      return stages.Finish(FrontendStatus::kLowTexture, "ASIFT found almost no features in the current regions (" +
                                                     std::to_string(s.num_current_features) + "): too little texture");
    s.overlaps.clear();  // the warped images are no longer needed

    stages.Step("cross_lsm_merge", [&] { return RefineCrossSite(o, &s); });
    stages.Step("stereo_zncc", [&] { return CorrelateStereo(navcam, o, &s); });
    stages.Step("median_filter", [&] { return MedianFilterDisparities(o, &s); });
    stages.Step("stereo_lsm", [&] { return RefineStereoAndIntersect(navcam, tps, o, &s); });
    Verification v;
    stages.Step("distance_consistency", [&] {
      v = CheckConsistency(s.candidates, o);
      return v.num_consistent;
    });
    stages.Step("motion_consistency", [&] {
      CheckMotion(s.candidates, o, &v);
      return v.num_kept;
    });
    MakeTiePoints(s.candidates, v, s.prediction, o, &tps);
    std::optional<std::string> dr_problem;
    stages.Step("dr_check", [&] {
      RegionPrediction dr;  // the DR itself, not the ground-aligned prediction
      dr.previous_from_current = s.dr_previous_from_current;
      dr.relative_sigma = s.prediction.relative_sigma;
      dr_problem = CheckAgainstDeadReckoning(dr, o, &tps);
      return static_cast<int>(tps.points.size());
    });
    if (dr_problem) return stages.Finish(FrontendStatus::kTooFewPoints, *dr_problem);
    if (static_cast<int>(tps.points.size()) < o.min_tie_points) {
      std::ostringstream os;
      os << "only " << tps.points.size() << " verified tie points (need " << o.min_tie_points << ")";
      os << "; " << MatchChain(result.summary.stages);
      return stages.Finish(FrontendStatus::kTooFewPoints, os.str());
    }
    return stages.Finish(FrontendStatus::kOk, "");
  } catch (const std::exception& e) {
    tps.points.clear();
    return stages.Finish(FrontendStatus::kError, std::string("internal error: ") + e.what());
  }
}

}  // namespace vloc
