// The cross-site front end as a table of contents: CrossSiteFrontend::Run
// runs three phases (PredictOverlaps, MatchOverlaps, VerifyTiePoints), each
// calling its steps (internal/frontend_steps.h, one file each) in order over
// one SitePairState and timing each under the name it reports in
// FRONTEND_STATUS; a phase that stops the pair says why. The options'
// loading and checking live here too.
#include "vloc/crosssite/frontend.h"

#include <omp.h>

#include <optional>
#include <sstream>

#include "vloc/common/options.h"
#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc {

void GroundPlaneOptions::Visit(OptionsReader& r) {
  r.Optional("fit_ground_planes", &fit_ground_planes, "fit each current image's ground plane to sparse stereo (tests only: false)");
  r.Optional("ground_grid_px", &ground_grid_px, "px, grid of the stereo points for the ground plane",
             AtLeast(frontend_internal::kGroundMinGridPx));
  r.Optional("ground_min_points", &ground_min_points, "stereo points (and plane inliers) a ground plane needs", AtLeast(3));
  r.Optional("ground_tolerance_m", &ground_tolerance_m, "m, plane inlier tolerance at short range", Positive());
  r.Optional("ground_max_slope_deg", &ground_max_slope_deg, "deg, steepest accepted ground plane", InLeftOpen(0, 90));
}

void GroundAlignOptions::Visit(OptionsReader& r) {
  r.Optional("ground_align", &ground_align, "correct the DR's relative height on both sites' stereo ground");
  r.Optional("ground_align_radius_m", &ground_align_radius_m, "m, neighbourhood of a local ground plane (x, y)",
             InLeftOpen(0, 10));
  r.Optional("ground_align_min_points", &ground_align_min_points, "current points over the previous ground needed",
             AtLeast(10));
}

void WorkRegionOptions::Visit(OptionsReader& r) {
  r.Child("wallis", [&](OptionsReader& c) { wallis.Visit(c); });
  r.Optional("max_zoom", &max_zoom, "largest zoom of the previous region");
  r.Optional("min_zoom", &min_zoom, "smallest zoom of the previous region", Positive());
  r.Optional("zoom_previous", &zoom_previous, "zoom the previous region up (else shrink the current one; tests only: true)");
  r.Optional("max_overlaps_per_image", &max_overlaps_per_image, "overlaps matched per current image (0 = all)",
             NonNegative());
  r.Optional("min_region_std", &min_region_std, "grey level, texture needed in the regions", NonNegative());
  r.Relation("max_zoom", max_zoom >= min_zoom, "must be >= min_zoom");
}

void FeatureOptions::Visit(OptionsReader& r) {
  r.Child("asift", [&](OptionsReader& c) { asift.Visit(c); });
  r.Optional("tilt_margin", &tilt_margin, "simulate tilts up to the predicted tilt times this", AtLeast(1));
  r.Optional("longitude_margin_deg", &longitude_margin_deg, "deg, simulated longitudes around the predicted one",
             NonNegative());
  r.Optional("warp_max_tilt", &warp_max_tilt, "largest tilt simulated on the warped image", AtLeast(1));
  r.Optional("sift_max_zoom", &sift_max_zoom,
             "SIFT on grids zoomed more than this runs on the grid resized to this zoom (0 = off)", NonNegative());
}

void GateOptions::Visit(OptionsReader& r) {
  r.Optional("gate_margin_px", &gate_margin_px, "px, added to the predicted growth for the match gate", NonNegative());
  r.Optional("max_gate_px", &max_gate_px, "px, largest stage-1 gate", Positive());
}

void WarpOptions::Visit(OptionsReader& r) {
  r.Optional("warp_current", &warp_current, "match on the current image warped by the ground homography");
  r.Optional("match_previous_resolution", &match_previous_resolution,
             "blur the warped current image to the zoomed previous region's resolution (tests only: false)");
  r.Child("tiles", [&](OptionsReader& c) { tiles.Visit(c); });
  r.Optional("tile_registration", &tile_registration,
             "register the warped current image by tile correlation first (tests only: false)");
  r.Optional("min_tile_inliers", &min_tile_inliers, "tiles agreeing on one motion needed to register (a homography)",
             AtLeast(4));
  r.Optional("tile_inlier_px", &tile_inlier_px, "reduced px, RANSAC threshold of the tile motion", Positive());
}

void OverlapMatchOptions::Visit(OptionsReader& r) {
  r.Child("matching", [&](OptionsReader& c) { matching.Visit(c); });
  r.Optional("refine_homography_threshold_px", &refine_homography_threshold_px,
             "px, stage-1 homography RANSAC threshold", Positive());
  r.Optional("stage1_cluster_fraction", &stage1_cluster_fraction,
             "radius of the stage-1 offset cluster as a fraction of the gate", InLeftOpen(0, 1));
  r.Optional("refine_gate_px", &refine_gate_px, "px, stage-2 gate", Positive());
  r.Optional("min_stage1_inliers", &min_stage1_inliers, "stage-1 epipolar inliers needed to refine the prediction",
             AtLeast(4));
  r.Optional("refine_ratio", &refine_ratio, "stage-2 ratio test", InLeftOpen(0, 1));
  r.Optional("fundamental_threshold_px", &fundamental_threshold_px, "px, RANSAC threshold (0 = off)", NonNegative());
  r.Optional("max_points_per_overlap", &max_points_per_overlap, "matches kept per overlap", AtLeast(1));
}

void GridLsmStepOptions::Visit(OptionsReader& r) {
  r.Child("grid_lsm", [&](OptionsReader& c) { grid_lsm.Visit(c); });
  r.Child("grid_lsm_retry", [&](OptionsReader& c) { grid_lsm_retry.Visit(c); });
  r.Optional("grid_retry_below", &grid_retry_below,
             "retry an overlap's grid LSM with grid_lsm_retry when it refined fewer candidates (0 = off)", NonNegative());
  r.Optional("grid_search_px", &grid_search_px, "px (grid), correlation search around a match before grid LSM",
             AtLeast(1));
  r.Optional("grid_min_zncc", &grid_min_zncc, "correlation peak needed before the grid LSM", InRange(-1, 1));
  r.Optional("grid_min_margin", &grid_min_margin, "peak minus the best correlation >= 3 px away", InRange(0, 2));
  r.Optional("grid_back_check_px", &grid_back_check_px,
             "px (grid), LSM back from the warped current image must return this close (0 = off)", NonNegative());
  r.Optional("grid_max_shear", &grid_max_shear, "largest |dx/dy| of the grid LSM's affine (relief parallax), 0 = off",
             NonNegative());
}

void CrossSiteLsmOptions::Visit(OptionsReader& r) {
  r.Child("cross_lsm", [&](OptionsReader& c) { cross_lsm.Visit(c); });
  r.Optional("sigma_unrefined_px", &sigma_unrefined_px, "px, sigma of a manual click the cross-site LSM could not refine",
             Positive());
  r.Optional("duplicate_radius", &duplicate_radius, "px, tie points closer than this are merged", NonNegative());
}

void StereoStepOptions::Visit(OptionsReader& r) {
  r.Child("zncc", [&](OptionsReader& c) { zncc.Visit(c); });
  r.Child("median_filter", [&](OptionsReader& c) { median.Visit(c); });
  r.Child("lsm", [&](OptionsReader& c) { lsm.Visit(c); });
  r.Optional("stereo_min_depth", &stereo_min_depth, "m, nearest depth searched along the epipolar line", Positive());
  r.Optional("stereo_max_depth", &stereo_max_depth, "m, farthest depth searched along the epipolar line");
  r.Optional("sigma_angle_px", &sigma_angle_px, "px, lateral error for the consistency threshold", NonNegative());
  r.Optional("min_sigma_parallax", &min_sigma_parallax, "px, floor of the parallax sigma in eq. 7", Positive());
  r.Relation("stereo_max_depth", stereo_max_depth > stereo_min_depth, "must be > stereo_min_depth");
}

void VerificationOptions::Visit(OptionsReader& r) {
  r.Child("consistency", [&](OptionsReader& c) { consistency.Visit(c); });
  r.Child("motion", [&](OptionsReader& c) { motion.Visit(c); });
  r.Optional("motion_consistency", &motion_consistency,
             "keep only points that agree under one rigid motion (tests only: false)");
  r.Optional("cross_sigma_floor_px", &cross_sigma_floor_px, "px (previous image), least cross-site sigma",
             NonNegative());
  r.Optional("stereo_sigma_floor_px", &stereo_sigma_floor_px, "px, least stereo (right image) sigma", NonNegative());
  r.Optional("max_motion_sigmas", &max_motion_sigmas, "tie-point motion vs DR gate in sigmas (0 = off)", NonNegative());
  r.Optional("dr_check_translation", &dr_check_translation,
             "the DR check compares the tie points' translation too (false: yaw only, for far-terrain tie points)");
}

namespace {

// Whole boxes of 6 numbers (x0 x1 y0 y1 z0 z1), each min below its max (NaN fails).
bool ValidBoxes(const std::vector<double>& boxes) {
  if (boxes.size() % 6 != 0) return false;
  for (size_t b = 0; b < boxes.size(); b += 6)
    for (size_t a = 0; a < 3; ++a)
      if (!(boxes[b + 2 * a] < boxes[b + 2 * a + 1])) return false;
  return true;
}

}  // namespace

void VehicleOptions::Visit(OptionsReader& r) {
  r.Optional("vehicle_boxes_m", &vehicle_boxes_m,
             "m, the rover's body as boxes in the body frame, 6 numbers each: x0 x1 y0 y1 z0 z1 (empty = none)",
             Rule<std::vector<double>>(ValidBoxes, "6 numbers per box (x0 x1 y0 y1 z0 z1), each min below its max"));
  r.Optional("vehicle_margin_px", &vehicle_margin_px, "px, the body's mask grows by this", InRange(0, 100));
}

// Every step's keys in the one map (the configs' flat `frontend:` section).
void FrontendOptions::Visit(OptionsReader& r) {
  r.Child("regions", [&](OptionsReader& c) { regions.Visit(c); });
  ground.Visit(r);
  ground_alignment.Visit(r);
  work_regions.Visit(r);
  features.Visit(r);
  gate.Visit(r);
  warp.Visit(r);
  overlap_matching.Visit(r);
  grid.Visit(r);
  cross_site.Visit(r);
  stereo.Visit(r);
  verification.Visit(r);
  vehicle.Visit(r);
  r.Optional("min_tie_points", &min_tie_points, "verified tie points needed for status OK", AtLeast(1));
  r.Optional("num_threads", &num_threads, "OpenMP threads of the whole front end", AtLeast(1));
}

bool FrontendOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

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

// Where a pair's run stops early, and why (FRONTEND_STATUS's status and message).
struct Stop {
  FrontendStatus status;
  std::string message;
};

// Paper 2.1 and additions (1)-(4): the images prepared, the ground under both sites, the overlaps the DR
// predicts and the DR height aligned on the previous site's ground.
std::optional<Stop> PredictOverlaps(const NavcamModel& navcam, const FrontendOptions& o, StageLog* stages,
                                    SitePairState* state, TiePointSet* tps) {
  SitePairState& s = *state;
  stages->Step("prepare_images", [&] {
    PrepareImages(navcam, o.vehicle, UsesBspline(o), o.num_threads, &s);
    return static_cast<int>(2 * (s.previous.pairs.size() + s.current.pairs.size()));
  });
  stages->Step("ground_planes",
               [&] { return FitGroundPlanes(navcam, *tps, o.ground, o.regions, o.stereo.zncc, o.num_threads, &s); });
  if (o.regions.far_max_range > 0)
    stages->Step("far_stereo",
                 [&] { return MeasureFarTerrain(navcam, *tps, o.regions, o.stereo.zncc, o.num_threads, &s); });
  stages->Step("region_prediction", [&] {
    s.prediction = PredictRegions(navcam, s.previous.world_from_body, s.current.world_from_body,
                                  tps->previous_pointing, tps->current_pointing, o.regions, s.ground_planes,
                                  s.current_far);
    return static_cast<int>(s.prediction.overlaps.size());
  });
  stages->Step("ground_alignment", [&] {
    return AlignToPreviousGround(navcam, *tps, o.ground_alignment, o.ground, o.regions, o.stereo.zncc, o.num_threads,
                                 &s);
  });
  if (s.prediction.overlaps.empty())
    return Stop{FrontendStatus::kNoOverlap,
                "no current image sees ground that a previous image sees within the range limits "
                "(check the DR poses, mast pointing and regions.max_range_*)"};
  return std::nullopt;
}

// Paper 2.2 up to the candidate matches: work regions (Wallis, zoom), ASIFT on the regions and on each forward
// overlap's warp in one pool, then each forward overlap's matching and grid LSM in parallel, the backward
// overlaps, and the matches on the rover's own body dropped.
std::optional<Stop> MatchOverlaps(const NavcamModel& navcam, const FrontendOptions& o, StageLog* stages,
                                  SitePairState* state, TiePointSet* tps) {
  SitePairState& s = *state;
  const bool warp_current = o.warp.warp_current;
  stages->Step("region_wallis_zoom", [&] { return MakeWorkRegions(o.work_regions, warp_current, o.num_threads, &s); });
  if (s.largest_region_std < o.work_regions.min_region_std) {
    std::ostringstream os;
    os << "the overlap regions are flat (largest grey-level std " << s.largest_region_std << " < min_region_std "
       << o.work_regions.min_region_std << "): too little texture to match";
    return Stop{FrontendStatus::kLowTexture, os.str()};
  }
  stages->Step("current_wallis", [&] {
    ChooseOverlaps(o.work_regions, warp_current, o.num_threads, &s);
    int n = 0;
    for (const cv::Mat& m : s.current_filtered) n += m.empty() ? 0 : 1;
    return n;
  });
  stages->Step("asift_and_warps",
               [&] { return DescribeRegionsAndWarpOverlaps(o.features, o.warp, o.gate, o.num_threads, &s); });
  stages->Step("overlap_matching", [&] {
    ForEachForwardOverlap(s, o.num_threads, [&](int k) {
      MatchOverlap(k, s.prediction.overlaps[k], s, o.overlap_matching, o.gate, warp_current, &s.overlaps[k]);
    });
    int n = 0;
    for (const OverlapWork& w : s.overlaps) n += static_cast<int>(w.candidates.size());
    return n;
  });
  stages->Step("overlap_grid_lsm", [&] {
    int n = 0;
    ForEachForwardOverlap(s, o.num_threads, [&](int k) {
      const int refined = RefineOverlapOnGrid(o.grid, warp_current, &s.overlaps[k]);
#pragma omp atomic
      n += refined;
    });
    return n;
  });
  stages->Step("backward_matching", [&] {
    int n = 0;
    const BackwardMatchOptions backward = BackwardMatchOptions::Of(o);
    for (size_t k = 0; k < s.prediction.overlaps.size(); ++k) {
      if (!s.prediction.overlaps[k].backward) continue;
      s.overlaps[k].candidates = MatchBackwardOverlap(static_cast<int>(k), navcam, *tps, s, backward);
      n += static_cast<int>(s.overlaps[k].candidates.size());
    }
    return n;
  });
  for (OverlapWork& w : s.overlaps) s.candidates.insert(s.candidates.end(), w.candidates.begin(), w.candidates.end());
  stages->Step("vehicle_mask", [&] {
    DropVehicleCandidates(&s);
    return static_cast<int>(s.candidates.size());
  });
  if (s.num_current_features < static_cast<size_t>(kMinCurrentFeatures))
    return Stop{FrontendStatus::kLowTexture, "ASIFT found almost no features in the current regions (" +
                                                 std::to_string(s.num_current_features) + "): too little texture"};
  s.overlaps.clear();  // the warped images are no longer needed
  return std::nullopt;
}

// Paper 2.2 from the candidates to the tie points: cross-site LSM (with warp_current the grid LSM refined the
// forward matches: what it did not is dropped), stereo at both sites, the distance and motion consistency, and
// the tie points checked against the DR.
std::optional<Stop> VerifyTiePoints(const NavcamModel& navcam, const FrontendOptions& o, StageLog* stages,
                                    SitePairState* state, TiePointSet* tps) {
  SitePairState& s = *state;
  stages->Step("cross_lsm_merge", [&] { return RefineCrossSite(o.cross_site, o.warp.warp_current, o.num_threads, &s); });
  stages->Step("stereo_zncc", [&] { return CorrelateStereo(navcam, o.stereo, o.num_threads, &s); });
  stages->Step("median_filter", [&] { return MedianFilterDisparities(o.stereo, &s); });
  stages->Step("stereo_lsm", [&] { return RefineStereoAndIntersect(navcam, *tps, o.stereo, o.num_threads, &s); });
  Verification v;
  stages->Step("distance_consistency", [&] {
    v = CheckConsistency(s.candidates, o.verification);
    return v.num_consistent;
  });
  stages->Step("motion_consistency", [&] {
    CheckMotion(s.candidates, o.verification, &v);
    return v.num_kept;
  });
  MakeTiePoints(s.candidates, v, s.prediction, o.verification, tps);
  std::optional<std::string> dr_problem;
  stages->Step("dr_check", [&] {
    RegionPrediction dr;  // the DR itself, not the ground-aligned prediction
    dr.previous_from_current = s.dr_previous_from_current;
    dr.relative_sigma = s.prediction.relative_sigma;
    dr_problem = CheckAgainstDeadReckoning(dr, o.verification, tps);
    return static_cast<int>(tps->points.size());
  });
  if (dr_problem) return Stop{FrontendStatus::kTooFewPoints, *dr_problem};
  if (static_cast<int>(tps->points.size()) < o.min_tie_points) {
    std::ostringstream os;
    os << "only " << tps->points.size() << " verified tie points (need " << o.min_tie_points << "); "
       << MatchChain(stages->stages());
    return Stop{FrontendStatus::kTooFewPoints, os.str()};
  }
  return std::nullopt;
}

}  // namespace

FrontendResult CrossSiteFrontend::Run(const SiteImages& previous, const SiteImages& current) const {
  FrontendResult result;
  StageLog stages(&result);
  SitePairState s;
  Stop stop{FrontendStatus::kOk, ""};
  try {
    if (auto problem = CheckInput(previous, current, navcam_, &s)) {
      stop = {FrontendStatus::kMissingInput, *problem};
    } else {
      InitTiePointSet(s, &result.tie_points);
      for (const auto phase : {PredictOverlaps, MatchOverlaps, VerifyTiePoints}) {
        if (std::optional<Stop> early = phase(navcam_, options_, &stages, &s, &result.tie_points)) {
          stop = *early;
          break;
        }
      }
    }
  } catch (const std::exception& e) {
    result.tie_points.points.clear();
    stop = {FrontendStatus::kError, std::string("internal error: ") + e.what()};
  }
  result.summary.num_overlaps = static_cast<int>(s.prediction.overlaps.size());
  return stages.Finish(stop.status, stop.message);
}

}  // namespace vloc
