// UavMosaicker::ProcessFrame as a table of contents over one FrameWork:
// decode and undistort, calibrate (first frames), detect, start the mosaic
// (first frame), predict, register (ranked candidates, registration.h), then
// refine, ground plane, height ties (height_ties.cpp), height, keyframe, route
// and GPS tie, blend.
#include "vloc/mosaic/uav_mosaicker.h"

#include <glog/logging.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace vloc::mosaic {

namespace {
double Seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The match counts of the registration (or, unregistered, of the keyframe attempts) into the frame's state.
void ReportMatches(const MotionEstimate& motion, bool registered, FrameState* state) {
  state->num_matches = motion.num_matches;
  state->num_inliers = motion.num_inliers;
  state->num_foreground = motion.num_foreground;
  state->guided = registered && motion.guided;
  state->reseated = false;
  state->spread = registered ? motion.spread : 0.0;
}
}  // namespace

UavMosaicker::UavMosaicker(const MosaickerOptions& options)
    : options_(options),
      calibration_step_(options.calibration),
      undistorter_(options.camera),
      height_filter_(options.height_filter),
      heights_(options.height_graph),
      gps_(options.geo),
      blender_(options.canvas, options.async_mosaic, options.async_mosaic_queue) {
  cv::setNumThreads(options_.num_threads);
}

UavMosaicker::~UavMosaicker() = default;

const std::vector<UavMosaicker::Candidate>& UavMosaicker::Candidates() {
  static const std::vector<Candidate> candidates = {
      {"keyframe", &RegisterToKeyframe, nullptr},
      {"guided", &RegisterGuided, &MosaickerSummary::guided},
      {"neighbours", &RegisterToNeighbours, nullptr},
      {"finer", &RegisterAtFinerLevel, nullptr},
      {"mosaic", &RegisterToMosaicAfterLoss, nullptr},
  };
  return candidates;
}

FrameState UavMosaicker::ProcessFrame(const cv::Mat& image, int64_t utime) {
  FrameWork w = BeginFrame(utime);
  if (!Decode(image, &w)) return Finish(&w);
  return Process(&w);
}

FrameState UavMosaicker::ProcessFrame(PreparedFrame frame, int64_t utime) {
  FrameWork w = BeginFrame(utime);
  if (!frame.usable) {
    RejectUnusable(&w);
    return Finish(&w);
  }
  undistorter_.Adopt(frame.camera);
  w.frame = std::move(frame.frame);
  w.features = std::move(frame.features);
  w.detected = true;
  return Process(&w);
}

FrameState UavMosaicker::Process(FrameWork* w) {
  if (!Calibrate(w)) return Finish(w);
  Detect(w);
  if (!blender_.started()) {
    StartMosaic(w);
    return Finish(w);
  }
  PredictPose(w);
  if (!Register(w)) {
    MarkLost(w);
    return Finish(w);
  }
  RefinePose(w);
  MarkRegistered(w);
  EstimateGroundPlane(w);
  TieHeights(w);
  EstimateHeight(w);
  UpdateKeyframe(w);
  TieRouteToGps(w);
  Blend(w);
  return Finish(w);
}

PreparedFrame FramePreparer::Prepare(const cv::Mat& image) {
  const auto t0 = std::chrono::steady_clock::now();
  PreparedFrame p;
  p.usable = !image.empty() && (image.type() == CV_8UC1 || image.type() == CV_8UC3);
  if (!p.usable) return p;
  p.frame = undistorter_.Undistort(image);
  p.camera = undistorter_.camera();
  p.features = ExtractFeatures(p.frame, matcher_);
  p.seconds = Seconds(t0);
  return p;
}

UavMosaicker::FrameWork UavMosaicker::BeginFrame(int64_t utime) {
  FrameWork w;
  w.t0 = std::chrono::steady_clock::now();
  w.utime = utime;
  FrameState& state = w.state;
  state = last_state_;
  state.utime = utime;
  state.frame_index = frame_counter_++;
  state.message.clear();
  state.keyframe = state.mosaic_updated = false;
  state.mosaic_seconds = 0;
  state.num_matches = state.num_inliers = state.num_foreground = 0;
  state.scale = 1.0;
  ++summary_.frames;
  return w;
}

bool UavMosaicker::Decode(const cv::Mat& image, FrameWork* w) {
  if (image.empty() || (image.type() != CV_8UC1 && image.type() != CV_8UC3)) return RejectUnusable(w);
  w->frame = undistorter_.Undistort(image);
  return true;
}

bool UavMosaicker::RejectUnusable(FrameWork* w) {
  w->state.status = calibrated_ ? TrackStatus::kLost : TrackStatus::kCalibrating;
  w->state.message = "frame empty or not 8-bit gray/BGR; skipped";
  if (calibrated_) lost_ = true;
  summary_.last_problem = w->state.message;
  return false;
}

bool UavMosaicker::Calibrate(FrameWork* w) {
  if (calibrated_) return true;
  std::string why;
  const Calibration c = calibration_step_.Try(w->frame, undistorter_.camera().fx, last_hag_, &why);
  if (!c.valid) {
    w->state.status = TrackStatus::kCalibrating;
    w->state.message = why;
    if (summary_.frames == options_.calibration.max_frames)
      LOG(WARNING) << "uav_mosaicker: no calibration after " << options_.calibration.max_frames << " frames: " << why
                   << " (or set calibration.source: config with calibration.height)";
    return false;
  }
  SetCalibration(c);
  LOG(INFO) << c.Describe();
  return true;
}

void UavMosaicker::SetCalibration(const Calibration& calibration) {
  calibration_ = calibration;
  calibrated_ = calibration.valid;
  focal_ = calibration.focal_px;
}

void UavMosaicker::Detect(FrameWork* w) {
  w->state.features_seconds = 0;
  if (w->detected) return;
  w->features = ExtractFeatures(w->frame, options_.matcher);
  w->state.features_seconds = w->features.seconds;
}

cv::Point2d UavMosaicker::PrincipalPoint() const {
  return {undistorter_.camera().cx, undistorter_.camera().cy};
}

void UavMosaicker::StartMosaic(FrameWork* w) {
  FrameState& state = w->state;
  if (w->features.points.size() < static_cast<size_t>(options_.matcher.min_inliers)) {
    state.status = TrackStatus::kCalibrating;
    state.message = "calibrated, waiting for a frame with enough features to start the mosaic";
    return;
  }
  // Ground px of the first frame: height / focal m/px.
  const double ground = calibration_.height / focal_;
  metres_per_pixel_ = options_.canvas.metres_per_pixel > 0 ? options_.canvas.metres_per_pixel
                                                           : ground * options_.canvas.resolution_factor;
  blender_.Start();
  const double s = ground / metres_per_pixel_;
  // The principal point of the first frame is mosaic px (0, 0).
  const cv::Point2d c = PrincipalPoint();
  const Similarity2 S{s, 0, -s * c.x, -s * c.y};
  keyframe_ = Keyframe{w->features, S, w->utime, w->state.frame_index};
  if (options_.height_graph.ties > 0) heights_.AddFrame(w->state.frame_index, std::log(S.Scale()));
  KeepImageForFinerLevel(w->frame);
  last_ = LastPoses{S, std::nullopt, gps_.GpsEnuAt(w->utime)};
  last_scale_ = s;
  last_good_index_ = state.frame_index;
  height_filter_.Reset(calibration_.height, w->utime);
  const BlendResult blend = blender_.Blend(w->frame, S);
  state.mosaic_seconds = blend.seconds;
  state.mosaic_updated = blend.done;
  frames_since_blend_ = 0;
  state.status = TrackStatus::kTracking;
  state.keyframe = true;
  state.height = state.height_raw = calibration_.height;
  ++summary_.keyframes;
  LOG(INFO) << "mosaic started: " << metres_per_pixel_ << " m/px, first frame at height " << calibration_.height
            << " m, " << w->features.points.size() << " features";
  state.tracking_seconds = Seconds(w->t0) - state.mosaic_seconds;
  gps_.AddRoutePoint(w->utime, cv::Point2d(0, 0));
  FillRoute(&state);
  gps_.PairPendingFixes();
  ++summary_.tracked;
}

void UavMosaicker::PredictPose(FrameWork* w) {
  w->prediction = gps_.Predict(w->utime, w->frame.size(), PrincipalPoint(), last_,
                               PredictionGates{options_.guide_gate, options_.gps_max_disagreement});
}

RegistrationInput UavMosaicker::InputFor(const FrameWork& w) const {
  RegistrationInput in;
  in.frame = &w.frame;
  in.features = &w.features;
  in.principal_point = PrincipalPoint();
  in.prediction = &w.prediction;
  in.last_good = last_.last_good;
  in.lost = lost_;
  in.seconds_since_registered = last_good_index_ >= 0 ? (w.utime - last_good_utime_) * 1e-6 : 0.0;
  in.keyframe = keyframe_ ? &*keyframe_ : nullptr;
  in.neighbours = &neighbours_;
  in.recent = &recent_;
  in.mosaic = &blender_;
  return in;
}

// The candidates in rank order until one registers the frame. A failed
// candidate adds its reason to the frame's; the frame reports the keyframe
// attempts' counts (the most matches of plain and guided) when none registers.
bool UavMosaicker::Register(FrameWork* w) {
  const RegistrationInput in = InputFor(*w);
  bool counted = false;
  for (const Candidate& candidate : Candidates()) {
    Registration r = candidate.run(in, options_);
    if (!r.tried) continue;
    summary_.gps_rejections += r.gps_rejections;
    if (r.ok) {
      if (candidate.registered_count) ++(summary_.*candidate.registered_count);
      w->registration = std::move(r);
      w->registered_by = candidate.name;
      return true;
    }
    if (r.source == RegistrationSource::kKeyframe) {
      if (!counted) {
        w->registration.motion = r.motion;
      } else {
        w->registration.motion.num_matches = std::max(w->registration.motion.num_matches, r.motion.num_matches);
      }
      counted = true;
    }
    if (!r.why.empty()) w->why += (w->why.empty() ? "" : "; ") + r.why;
  }
  return false;
}

void UavMosaicker::MarkLost(FrameWork* w) {
  FrameState& state = w->state;
  ReportMatches(w->registration.motion, /*registered=*/false, &state);
  // Keep the last good state; say why.
  state.status = TrackStatus::kLost;
  if (!lost_) ++summary_.lost;
  lost_ = true;
  std::string placed;
  if (const std::optional<Similarity2> P = PlaceByGps(InputFor(*w), options_, &placed)) {
    // Restart from this frame at its GPS position: the next frame is matched against it.
    keyframe_ = Keyframe{w->features, *P, w->utime, w->state.frame_index, ground_normal_};
    KeepImageForFinerLevel(w->frame);
    last_ = LastPoses{*P, std::nullopt, gps_.GpsEnuAt(w->utime)};
    last_good_index_ = state.frame_index;
    last_good_utime_ = w->utime;
    state.reseated = true;
    ++summary_.reseats;
    w->why += "; " + placed;
  }
  state.message = w->why;
  summary_.last_problem = w->why;
  state.tracking_seconds = Seconds(w->t0);
}

void UavMosaicker::RefinePose(FrameWork* w) {
  if (lost_ || options_.reregister_every_n_frames <= 0 ||
      ++frames_since_reregister_ < options_.reregister_every_n_frames)
    return;
  frames_since_reregister_ = 0;
  const std::optional<Similarity2> refined = RefineAgainstMosaic(
      w->frame, w->features, blender_, w->registration.mosaic_from_frame, PrincipalPoint(), options_);
  if (!refined) {
    ++summary_.reregistrations_rejected;
    return;
  }
  w->registration.mosaic_from_frame = *refined;
  w->reregistered = true;
  ++summary_.reregistrations;
}

void UavMosaicker::MarkRegistered(FrameWork* w) {
  FrameState& state = w->state;
  ReportMatches(w->registration.motion, /*registered=*/true, &state);
  state.status = lost_ ? TrackStatus::kRecovered : TrackStatus::kTracking;
  if (lost_) {
    ++summary_.recoveries;
    const RegistrationSource source = w->registration.source;
    state.message = source == RegistrationSource::kMosaic      ? "re-acquired against the mosaic"
                    : source == RegistrationSource::kNeighbour ? "re-acquired against an earlier frame"
                                                               : "re-acquired against the last keyframe";
    LOG(INFO) << "frame " << state.frame_index << ": " << state.message;
  }
  w->was_lost = lost_;
  lost_ = false;
  ++summary_.tracked;
}

// The ground plane from the homography: the camera's tilt and its height
// relative to the reference frame (scale_source homography).
void UavMosaicker::EstimateGroundPlane(FrameWork* w) {
  const Registration& r = w->registration;
  const std::optional<PlaneRatio> plane =
      r.source == RegistrationSource::kMosaic
          ? std::nullopt
          : PlaneFromHomography(r.motion.homography, undistorter_.camera().K(), r.reference->normal);
  w->plane_ok = plane.has_value();
  if (!w->plane_ok) return;
  const double height_ratio = plane->height_ratio;
  const cv::Vec3d normal = plane->normal;
  ground_normal_ = normal;
  w->state.tilt = std::acos(std::clamp(normal[2], -1.0, 1.0));
  if (options_.scale_source != "homography") return;
  // Scale from the height ratio; heading from the fit; placed so that the
  // matches' centroid lands where the fit puts it.
  Similarity2& S = w->registration.mosaic_from_frame;
  cv::Point2d centroid(0, 0);
  for (const auto& p : r.motion.to_background) centroid += cv::Point2d(p);
  centroid *= 1.0 / std::max<size_t>(1, r.motion.to_background.size());
  Similarity2 H = Similarity2::FromScaleAngle(r.reference->mosaic_from_frame.Scale() * height_ratio, S.Angle(), 0, 0);
  const cv::Point2d target = S.Apply(centroid), moved = H.Apply(centroid);
  H.tx = target.x - moved.x;
  H.ty = target.y - moved.y;
  S = H;
}

// Height (eqs. 4-5 chained through the similarity scale) and lambda; the
// registered pose becomes the last good one.
void UavMosaicker::EstimateHeight(FrameWork* w) {
  FrameState& state = w->state;
  const Similarity2& S = w->registration.mosaic_from_frame;
  const double s = S.Scale();
  state.scale = last_scale_ / s;
  state.height_raw = GraphScale(w->state.frame_index).value_or(s) * metres_per_pixel_ * focal_;
  state.height = height_filter_.UpdateVision(state.height_raw, w->utime);
  if (last_good_index_ == state.frame_index - 1 && !w->was_lost) {
    last_.prev_good = last_.last_good;
  } else {
    last_.prev_good.reset();
  }
  last_.last_good = S;
  last_scale_ = s;
  last_good_index_ = state.frame_index;
  last_good_utime_ = w->utime;
  last_.last_good_enu = gps_.GpsEnuAt(w->utime);
  gps_.UpdateYawOffset(S, w->utime);
}

// A new keyframe after a loss, a registration not against the keyframe, a
// re-registration, or too little support, scale change or overlap.
void UavMosaicker::UpdateKeyframe(FrameWork* w) {
  const Registration& r = w->registration;
  const Similarity2& S = r.mosaic_from_frame;
  const double key_scale = r.motion.lambda;
  const bool via_mosaic = r.source == RegistrationSource::kMosaic;
  const bool via_neighbour = r.source == RegistrationSource::kNeighbour;
  w->state.reregistered = w->reregistered;
  KeepNeighbour(w->features, S, w->utime, w->state.frame_index);
  if (options_.fallback_downscale > 0 && options_.fallback_frames > 0) {
    recent_.push_back(Keyframe{w->features, S, w->utime, w->state.frame_index, ground_normal_, w->frame});
    while (static_cast<int>(recent_.size()) > options_.fallback_frames) recent_.pop_front();
  }
  w->new_keyframe = w->was_lost || via_mosaic || via_neighbour || w->reregistered ||
                    r.motion.num_background < options_.keyframe_min_inliers ||
                    key_scale > options_.keyframe_max_scale || key_scale < 1.0 / options_.keyframe_max_scale ||
                    (!via_mosaic &&
                     OverlapFraction(r.motion.similarity.Inverse(), w->frame.size()) < options_.keyframe_min_overlap);
  if (w->new_keyframe) {
    const cv::Vec3d normal = w->plane_ok ? ground_normal_ : keyframe_->normal;
    keyframe_ = Keyframe{w->features, S, w->utime, w->state.frame_index, normal};
    KeepImageForFinerLevel(w->frame);
    w->state.keyframe = true;
    ++summary_.keyframes;
  }
  w->state.tracking_seconds = Seconds(w->t0);
}

void UavMosaicker::KeepImageForFinerLevel(const cv::Mat& frame) {
  if (options_.fallback_downscale > 0) keyframe_->image = frame;
}

void UavMosaicker::KeepNeighbour(const FrameFeatures& features, const Similarity2& mosaic_from_frame, int64_t utime,
                                 int frame_index) {
  if (options_.neighbour_frames <= 0) return;
  neighbours_.push_back(Keyframe{features, mosaic_from_frame, utime, frame_index, ground_normal_});
  while (static_cast<int>(neighbours_.size()) > options_.neighbour_frames) neighbours_.pop_front();
}

// The route point (the frame centre, or the nadir point from the ground
// normal), the frame's place in ENU, and the fixes paired with the route.
void UavMosaicker::TieRouteToGps(FrameWork* w) {
  const PinholeCamera& camera = undistorter_.camera();
  cv::Point2d route_pixel = PrincipalPoint();
  if (options_.route_point == "nadir" && w->plane_ok) {
    const cv::Vec3d& g = ground_normal_;  // the point below the camera is K n
    route_pixel = {camera.fx * g[0] / g[2] + camera.cx, camera.fy * g[1] / g[2] + camera.cy};
  }
  gps_.AddRoutePoint(w->utime, w->registration.mosaic_from_frame.Apply(route_pixel));
  FillRoute(&w->state);
  gps_.PairPendingFixes();
}

void UavMosaicker::FillRoute(FrameState* state) {
  state->route_px = gps_.LastRoutePoint();
  state->route_local = MosaicToLocal(state->route_px);
  state->georeferenced = gps_.tied();
  state->gps_aided = state->georeferenced && (state->utime - gps_.last_fix_utime()) * 1e-6 <= options_.geo.gps_timeout;
  if (state->georeferenced && gps_.origin()) {
    EnuToLatLon(state->route_local, gps_.origin()->latitude, gps_.origin()->longitude, &state->latitude,
                &state->longitude);
  }
  route_.push_back(state->route_px);
  if (route_.size() > 200000) route_.erase(route_.begin(), route_.begin() + 100000);
}

// Every keyframe and every mosaic_every_n_frames-th registered frame.
void UavMosaicker::Blend(FrameWork* w) {
  ++frames_since_blend_;
  if (!w->new_keyframe && frames_since_blend_ < options_.mosaic_every_n_frames) return;
  const BlendResult blend = blender_.Blend(w->frame, w->registration.mosaic_from_frame);
  w->state.mosaic_seconds = blend.seconds;
  w->state.mosaic_updated = blend.done;
  if (blend.done) frames_since_blend_ = 0;
}

FrameState UavMosaicker::Finish(FrameWork* w) {
  last_state_ = w->state;
  return w->state;
}

cv::Point2d UavMosaicker::MosaicToLocal(const cv::Point2d& p) const { return gps_.MosaicToLocal(p, metres_per_pixel_); }

void UavMosaicker::AddGps(const GpsFix& fix) {
  if (std::isfinite(fix.height_above_ground) && fix.height_above_ground > 0) {
    last_hag_ = fix.height_above_ground;
    if (blender_.started()) height_filter_.UpdateGps(fix.height_above_ground, fix.utime);
  }
  gps_.AddFix(fix);
}

MosaickerSummary UavMosaicker::summary() const {
  MosaickerSummary s = summary_;
  s.calibration = calibration_;
  s.metres_per_pixel = metres_per_pixel_;
  s.georeferenced = gps_.tied();
  s.tie_rms = gps_.tie_rms();
  s.tie_pairs = gps_.tie_pairs();
  s.canvas = blender_.stats();
  s.blends = blender_.blends();
  s.blend_seconds = blender_.seconds();
  return s;
}

}  // namespace vloc::mosaic
