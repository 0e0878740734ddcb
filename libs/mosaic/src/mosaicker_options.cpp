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
  r.Child("height_graph", [&](OptionsReader& c) { height_graph.Visit(c); });
  r.Child("canvas", [&](OptionsReader& c) { canvas.Visit(c); });
  r.Child("geo", [&](OptionsReader& c) { geo.Visit(c); });
  r.Optional("mosaic_every_n_frames", &mosaic_every_n_frames, "blend every n-th tracked frame", AtLeast(1));
  r.Optional("keyframe_min_inliers", &keyframe_min_inliers, "new keyframe below this many background matches");
  r.Optional("keyframe_min_overlap", &keyframe_min_overlap, "new keyframe below this overlap", InOpen(0.0, 1.0));
  r.Optional("keyframe_max_scale", &keyframe_max_scale, "new keyframe beyond this scale change", Above(1.0));
  r.Optional("recovery_view_scale", &recovery_view_scale, "frame sizes searched in the mosaic when lost",
             InRange(1.0, 4.0));
  r.Optional("recovery_min_painted", &recovery_min_painted, "covered fraction needed for recovery",
             InLeftOpen(0.0, 1.0));
  r.Optional("reregister_every_n_frames", &reregister_every_n_frames,
             "register every n-th tracked frame against the mosaic (0 = off)", NonNegative());
  r.Optional("reregister_scale", &reregister_scale, "re-registration also sets the scale (height)");
  r.Optional("reregister_max_shift", &reregister_max_shift,
             "largest accepted change of a re-registration (fraction of frame width / of scale)", InLeftOpen(0.0, 1.0));
  r.Optional("min_spread", &min_spread, "fraction of the frame the background matches must span", InRightOpen(0.0, 1.0));
  r.Optional("guided_matching", &guided_matching, "match again around the predicted pose when plain matching fails");
  r.Optional("guide_gate", &guide_gate, "gate radius of guided matching, fraction of the frame width",
             InLeftOpen(0.0, 1.0));
  r.Optional("gps_max_disagreement", &gps_max_disagreement,
             "largest distance from the GPS position, fraction of frame width", Positive());
  r.Optional("scale_source", &scale_source, "similarity | homography", OneOf({"similarity", "homography"}));
  r.Optional("route_point", &route_point, "centre | nadir", OneOf({"centre", "nadir"}));
  r.Optional("gps_check_below_inliers", &gps_check_below_inliers, "GPS agreement tested below this many matches (0 = never)",
             NonNegative());
  r.Optional("neighbour_frames", &neighbour_frames, "registered frames kept for matching a frame the keyframe misses",
             InRange(0, 1000));
  r.Optional("neighbour_tries", &neighbour_tries, "nearest kept frames tried", AtLeast(1));
  r.Optional("fallback_downscale", &fallback_downscale, "finer feature level tried against the keyframe (0 = off)",
             Is(0.0) || InLeftOpen(0.0, 1.0));
  r.Optional("fallback_frames", &fallback_frames, "last registered frames also tried at the finer level", InRange(0, 16));
  r.Optional("reseat_by_gps", &reseat_by_gps, "place an unregistered frame on new ground at its GPS position");
  r.Optional("reseat_after_gap_s", &reseat_after_gap_s,
             "s, likewise for a frame this long after the last registered one (0 = off)", NonNegative());
  r.Optional("num_threads", &num_threads, "OpenCV threads", AtLeast(1));
  r.Optional("async_mosaic", &async_mosaic, "blend on a worker thread");
  r.Optional("async_mosaic_queue", &async_mosaic_queue, "frames waiting for the worker, none dropped (0 = one, replaced)",
             InRange(0, 64));
  r.Relation("keyframe_min_inliers", keyframe_min_inliers >= matcher.min_inliers, "must be >= matcher.min_inliers");
  r.Relation("keyframe_max_scale", keyframe_max_scale < matcher.max_scale_change, "must be < matcher.max_scale_change");
  r.Relation("fallback_downscale", fallback_downscale == 0 || fallback_downscale > matcher.downscale,
             "must be 0 (off) or finer than matcher.downscale");
}

bool MosaickerOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

std::string MosaickerSummary::BriefReport() const {
  std::ostringstream s;
  s << "frames " << frames << ", tracked " << tracked << ", lost " << lost << ", recoveries " << recoveries
    << ", keyframes " << keyframes << ", blends " << blends << ", mosaic " << metres_per_pixel << " m/px, tiles "
    << canvas.tiles_total << " (" << canvas.tiles_in_memory << " in memory, peak " << canvas.peak_tiles_in_memory
    << ", spilled " << canvas.spills << "), " << (georeferenced ? "tied to GPS" : "not georeferenced");
  if (georeferenced) s << " (" << tie_pairs << " fixes, rms " << tie_rms << " m)";
  if (guided + gps_rejections + reseats > 0)
    s << ", guided " << guided << ", rejected by GPS " << gps_rejections << ", placed by GPS " << reseats;
  if (height_ties > 0)
    s << ", height ties " << height_ties << " (" << height_ties_dropped << " dropped, residual RMS " << height_tie_rms
      << " sigma)";
  if (reregistrations + reregistrations_rejected > 0)
    s << ", re-registered against the mosaic " << reregistrations << " times (" << reregistrations_rejected
      << " rejected)";
  if (!last_problem.empty()) s << "; last problem: " << last_problem;
  return s.str();
}

}  // namespace vloc::mosaic
