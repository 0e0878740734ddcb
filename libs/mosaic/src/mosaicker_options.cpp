// MosaickerOptions, its status names and its summary (uav_mosaicker.h).
#include <sstream>

#include "vloc/common/options.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {

const char* ToString(TrackStatus status) {
  switch (status) {
    case TrackStatus::kCalibrating: return "CALIBRATING";
    case TrackStatus::kTracking: return "TRACKING";
    case TrackStatus::kLost: return "LOST";
    case TrackStatus::kRecovered: return "RECOVERED";
  }
  return "?";
}

void MosaickerOptions::Visit(OptionsReader& r) {
  r.Child("camera", [&](OptionsReader& c) { camera.Visit(c); });
  r.Child("calibration", [&](OptionsReader& c) { calibration.Visit(c); });
  r.Child("matcher", [&](OptionsReader& c) { matcher.Visit(c); });
  r.Child("height_filter", [&](OptionsReader& c) { height_filter.Visit(c); });
  r.Child("canvas", [&](OptionsReader& c) { canvas.Visit(c); });
  r.Child("geo", [&](OptionsReader& c) { geo.Visit(c); });
  r.Optional("mosaic_every_n_frames", &mosaic_every_n_frames, "blend every n-th tracked frame");
  r.Optional("keyframe_min_inliers", &keyframe_min_inliers, "new keyframe below this many background matches");
  r.Optional("keyframe_min_overlap", &keyframe_min_overlap, "new keyframe below this overlap");
  r.Optional("keyframe_max_scale", &keyframe_max_scale, "new keyframe beyond this scale change");
  r.Optional("recovery_view_scale", &recovery_view_scale, "frame sizes searched in the mosaic when lost");
  r.Optional("recovery_min_painted", &recovery_min_painted, "covered fraction needed for recovery");
  r.Optional("reregister_every_n_frames", &reregister_every_n_frames,
             "register every n-th tracked frame against the mosaic (0 = off)");
  r.Optional("reregister_scale", &reregister_scale, "re-registration also sets the scale (height)");
  r.Optional("reregister_max_shift", &reregister_max_shift,
             "largest accepted change of a re-registration (fraction of frame width / of scale)");
  r.Optional("min_spread", &min_spread, "fraction of the frame the background matches must span");
  r.Optional("guided_matching", &guided_matching, "match again around the predicted pose when plain matching fails");
  r.Optional("guide_gate", &guide_gate, "gate radius of guided matching, fraction of the frame width");
  r.Optional("gps_max_disagreement", &gps_max_disagreement, "largest distance from the GPS position, fraction of frame width");
  r.Optional("scale_source", &scale_source, "similarity | homography");
  r.Optional("route_point", &route_point, "centre | nadir");
  r.Optional("gps_check_below_inliers", &gps_check_below_inliers, "GPS agreement tested below this many matches");
  r.Optional("neighbour_frames", &neighbour_frames, "registered frames kept for matching a frame the keyframe misses");
  r.Optional("neighbour_tries", &neighbour_tries, "nearest kept frames tried");
  r.Optional("fallback_downscale", &fallback_downscale, "finer feature level tried against the keyframe (0 = off)");
  r.Optional("fallback_frames", &fallback_frames, "last registered frames also tried at the finer level");
  r.Optional("reseat_by_gps", &reseat_by_gps, "place an unregistered frame on new ground at its GPS position");
  r.Optional("reseat_after_gap_s", &reseat_after_gap_s, "s, likewise for a frame this long after the last registered one");
  r.Optional("num_threads", &num_threads, "OpenCV threads");
  r.Optional("async_mosaic", &async_mosaic, "blend on a worker thread");
  r.Optional("async_mosaic_queue", &async_mosaic_queue, "frames waiting for the worker, none dropped (0 = one, replaced)");
}

bool MosaickerOptions::Check(std::string* error) const {
  if (neighbour_frames < 0 || neighbour_frames > 1000) return Fail(error, "neighbour_frames must be in [0, 1000]");
  if (neighbour_tries < 1) return Fail(error, "neighbour_tries must be >= 1");
  if (!(reseat_after_gap_s >= 0)) return Fail(error, "reseat_after_gap_s must be >= 0 s (0 = off)");
  if (fallback_downscale != 0 && !(fallback_downscale > matcher.downscale && fallback_downscale <= 1))
    return Fail(error, "fallback_downscale must be 0 (off) or in (matcher.downscale, 1]");
  if (fallback_frames < 0 || fallback_frames > 16) return Fail(error, "fallback_frames must be in [0, 16]");
  if (!camera.Check(error) || !calibration.Check(error) || !matcher.Check(error) || !height_filter.Check(error) ||
      !canvas.Check(error) || !geo.Check(error))
    return false;
  if (mosaic_every_n_frames < 1) return Fail(error, "mosaic_every_n_frames must be >= 1");
  if (keyframe_min_inliers < matcher.min_inliers)
    return Fail(error, "keyframe_min_inliers must be >= matcher.min_inliers");
  if (!(keyframe_min_overlap > 0 && keyframe_min_overlap < 1)) return Fail(error, "keyframe_min_overlap must be in (0, 1)");
  if (!(keyframe_max_scale > 1 && keyframe_max_scale < matcher.max_scale_change))
    return Fail(error, "keyframe_max_scale must be in (1, matcher.max_scale_change)");
  if (!(recovery_view_scale >= 1 && recovery_view_scale <= 4)) return Fail(error, "recovery_view_scale must be in [1, 4]");
  if (!(recovery_min_painted > 0 && recovery_min_painted <= 1)) return Fail(error, "recovery_min_painted must be in (0, 1]");
  if (reregister_every_n_frames < 0) return Fail(error, "reregister_every_n_frames must be >= 0 (0 = off)");
  if (!(reregister_max_shift > 0 && reregister_max_shift <= 1)) return Fail(error, "reregister_max_shift must be in (0, 1]");
  if (!(min_spread >= 0 && min_spread < 1)) return Fail(error, "min_spread must be in [0, 1)");
  if (!(guide_gate > 0 && guide_gate <= 1)) return Fail(error, "guide_gate must be in (0, 1]");
  if (gps_check_below_inliers < 0) return Fail(error, "gps_check_below_inliers must be >= 0 (0 = never)");
  if (!(gps_max_disagreement > 0)) return Fail(error, "gps_max_disagreement must be > 0");
  if (route_point != "centre" && route_point != "nadir") return Fail(error, "route_point must be 'centre' or 'nadir'");
  if (scale_source != "similarity" && scale_source != "homography")
    return Fail(error, "scale_source must be 'similarity' or 'homography'");
  if (num_threads < 1) return Fail(error, "num_threads must be >= 1");
  if (async_mosaic_queue < 0 || async_mosaic_queue > 64) return Fail(error, "async_mosaic_queue must be in [0, 64]");
  return true;
}

std::string MosaickerSummary::BriefReport() const {
  std::ostringstream s;
  s << "frames " << frames << ", tracked " << tracked << ", lost " << lost << ", recoveries " << recoveries
    << ", keyframes " << keyframes << ", blends " << blends << ", mosaic " << metres_per_pixel << " m/px, tiles "
    << canvas.tiles_total << " (" << canvas.tiles_in_memory << " in memory, peak " << canvas.peak_tiles_in_memory
    << ", spilled " << canvas.spills << "), " << (georeferenced ? "tied to GPS" : "not georeferenced");
  if (georeferenced) s << " (" << tie_pairs << " fixes, rms " << tie_rms << " m)";
  if (guided + gps_rejections + reseats > 0)
    s << ", guided " << guided << ", rejected by GPS " << gps_rejections << ", placed by GPS " << reseats;
  if (reregistrations + reregistrations_rejected > 0)
    s << ", re-registered against the mosaic " << reregistrations << " times (" << reregistrations_rejected
      << " rejected)";
  if (!last_problem.empty()) s << "; last problem: " << last_problem;
  return s.str();
}

}  // namespace vloc::mosaic
