#include "vloc/mosaic/uav_mosaicker.h"

#include <glog/logging.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "vloc/common/options.h"
#include "vloc/mosaic/gis_export.h"

namespace vloc::mosaic {

namespace {
constexpr double kEarthRadius = 6378137.0;
constexpr double kDeg = M_PI / 180.0;

double Seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

cv::Point2d LatLonToEnu(double lat, double lon, double lat0, double lon0) {
  return {(lon - lon0) * kDeg * kEarthRadius * std::cos(lat0 * kDeg), (lat - lat0) * kDeg * kEarthRadius};
}
void EnuToLatLon(const cv::Point2d& enu, double lat0, double lon0, double* lat, double* lon) {
  *lat = lat0 + enu.y / kEarthRadius / kDeg;
  *lon = lon0 + enu.x / (kEarthRadius * std::cos(lat0 * kDeg)) / kDeg;
}

const char* ToString(TrackStatus status) {
  switch (status) {
    case TrackStatus::kCalibrating: return "CALIBRATING";
    case TrackStatus::kTracking: return "TRACKING";
    case TrackStatus::kLost: return "LOST";
    case TrackStatus::kRecovered: return "RECOVERED";
  }
  return "?";
}

void GeoOptions::Visit(OptionsReader& r) {
  r.Optional("min_fixes", &min_fixes, "fixes before the mosaic is tied to GPS");
  r.Optional("min_spread", &min_spread, "m, RMS spread of tied fixes");
  r.Optional("window_fixes", &window_fixes, "most recent pairs used in the tie");
  r.Optional("max_time_gap", &max_time_gap, "s, fix-to-frame pairing gap");
  r.Optional("gps_timeout", &gps_timeout, "s, after this without a fix the route is vision only");
  r.Optional("predict_window", &predict_window, "pairs of the local tie used for predictions (0 = the tie)");
}
bool GeoOptions::Check(std::string* error) const {
  if (min_fixes < 2) return Fail(error, "geo.min_fixes must be >= 2");
  if (!(min_spread >= 0)) return Fail(error, "geo.min_spread must be >= 0 m");
  if (window_fixes < min_fixes) return Fail(error, "geo.window_fixes must be >= geo.min_fixes");
  if (!(max_time_gap > 0)) return Fail(error, "geo.max_time_gap must be > 0 s");
  if (!(gps_timeout > 0)) return Fail(error, "geo.gps_timeout must be > 0 s");
  if (predict_window != 0 && predict_window < 3) return Fail(error, "geo.predict_window must be 0 (off) or >= 3");
  return true;
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
  r.Optional("guide_turn", &guide_turn, "deg, heading hypotheses +-this beside the predicted one (0 = only it)");
  r.Optional("guide_gate", &guide_gate, "gate radius of guided matching, fraction of the frame width");
  r.Optional("gps_max_disagreement", &gps_max_disagreement, "largest distance from the GPS position, fraction of frame width");
  r.Optional("scale_source", &scale_source, "similarity | homography");
  r.Optional("route_point", &route_point, "centre | nadir");
  r.Optional("gps_check_below_inliers", &gps_check_below_inliers, "GPS agreement tested below this many matches");
  r.Optional("reseat_only_new_ground", &reseat_only_new_ground, "reseat only where the mosaic has nothing");
  r.Optional("neighbour_frames", &neighbour_frames, "registered frames kept for matching a frame the keyframe misses");
  r.Optional("neighbour_tries", &neighbour_tries, "nearest kept frames tried");
  r.Optional("reseat_by_gps", &reseat_by_gps, "place an unregistered frame at its GPS position to restart tracking");
  r.Optional("num_threads", &num_threads, "OpenCV threads");
  r.Optional("async_mosaic", &async_mosaic, "blend on a worker thread");
}

bool MosaickerOptions::Check(std::string* error) const {
  if (neighbour_frames < 0 || neighbour_frames > 1000) return Fail(error, "neighbour_frames must be in [0, 1000]");
  if (neighbour_tries < 1) return Fail(error, "neighbour_tries must be >= 1");
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
  if (!(guide_turn >= 0 && guide_turn < 90)) return Fail(error, "guide_turn must be in [0, 90) deg");
  if (!(gps_max_disagreement > 0)) return Fail(error, "gps_max_disagreement must be > 0");
  if (route_point != "centre" && route_point != "nadir") return Fail(error, "route_point must be 'centre' or 'nadir'");
  if (scale_source != "similarity" && scale_source != "homography")
    return Fail(error, "scale_source must be 'similarity' or 'homography'");
  if (num_threads < 1) return Fail(error, "num_threads must be >= 1");
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

UavMosaicker::UavMosaicker(const MosaickerOptions& options)
    : options_(options), height_filter_(options.height_filter), camera_(options.camera) {
  cv::setNumThreads(options_.num_threads);
  if (options_.async_mosaic) worker_ = std::thread([this] { WorkerLoop(); });
}

UavMosaicker::~UavMosaicker() {
  if (worker_.joinable()) {
    {
      std::lock_guard<std::mutex> lock(job_mutex_);
      stop_worker_ = true;
    }
    job_cv_.notify_all();
    worker_.join();
  }
}

void UavMosaicker::WorkerLoop() {
  std::unique_lock<std::mutex> lock(job_mutex_);
  while (true) {
    job_cv_.wait(lock, [this] { return stop_worker_ || job_.has_value(); });
    if (stop_worker_ && !job_) return;
    BlendJob job = std::move(*job_);
    job_.reset();
    worker_busy_ = true;
    lock.unlock();
    std::string why;
    bool ok = false;
    {
      std::lock_guard<std::mutex> canvas_lock(canvas_mutex_);
      ok = canvas_->Blend(job.frame, job.mosaic_from_frame, &why);
    }
    if (!ok) {
      LOG_EVERY_N(WARNING, 50) << "mosaic: frame not blended: " << why;
    }
    lock.lock();
    worker_busy_ = false;
    if (ok) ++async_blends_;
    job_cv_.notify_all();
  }
}

void UavMosaicker::FlushMosaic() {
  if (!worker_.joinable()) return;
  std::unique_lock<std::mutex> lock(job_mutex_);
  job_cv_.wait(lock, [this] { return !job_.has_value() && !worker_busy_; });
}

bool UavMosaicker::BlendOrQueue(const cv::Mat& frame, const Similarity2& S, FrameState* state) {
  if (options_.async_mosaic) {
    {
      std::lock_guard<std::mutex> lock(job_mutex_);
      if (job_) ++async_dropped_;  // the worker fell behind: the newer frame replaces the queued one
      job_ = BlendJob{frame.clone(), S};
    }
    job_cv_.notify_all();
    state->mosaic_updated = true;
    return true;
  }
  const auto t1 = std::chrono::steady_clock::now();
  std::string why;
  bool ok = false;
  {
    std::lock_guard<std::mutex> lock(canvas_mutex_);
    ok = canvas_->Blend(frame, S, &why);
  }
  state->mosaic_seconds = Seconds(t1);
  if (!ok) {
    LOG_EVERY_N(WARNING, 50) << "mosaic: frame not blended: " << why;
    return false;
  }
  state->mosaic_updated = true;
  ++summary_.blends;
  return true;
}

cv::Mat UavMosaicker::Undistort(const cv::Mat& image) {
  if (image.cols != camera_.width || image.rows != camera_.height) {
    // Scale the configured intrinsics to the frame size (same field of view).
    const double sx = static_cast<double>(image.cols) / options_.camera.width;
    const double sy = static_cast<double>(image.rows) / options_.camera.height;
    camera_ = options_.camera;
    camera_.width = image.cols;
    camera_.height = image.rows;
    camera_.fx *= sx; camera_.cx = (camera_.cx + 0.5) * sx - 0.5;
    camera_.fy *= sy; camera_.cy = (camera_.cy + 0.5) * sy - 0.5;
    map1_.release();
    if (!camera_scaled_warned_) {
      LOG(WARNING) << "uav frames are " << image.cols << "x" << image.rows << " but camera is configured for "
                   << options_.camera.width << "x" << options_.camera.height
                   << "; intrinsics scaled to fit (fix camera.width/height in the config)";
      camera_scaled_warned_ = true;
    }
  }
  if (!camera_.HasDistortion()) return image;
  if (map1_.empty() || map_size_ != image.size()) {
    cv::initUndistortRectifyMap(camera_.K(), camera_.DistortionCoeffs(), cv::noArray(), camera_.K(), image.size(),
                                CV_16SC2, map1_, map2_);
    map_size_ = image.size();
  }
  cv::Mat out;
  cv::remap(image, out, map1_, map2_, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return out;
}

void UavMosaicker::SetCalibration(const Calibration& calibration) {
  calibration_ = calibration;
  calibrated_ = calibration.valid;
  focal_ = calibration.focal_px;
}

bool UavMosaicker::TryCalibrate(const cv::Mat& frame, FrameState* state) {
  const CalibrationOptions& co = options_.calibration;
  std::string why;
  Calibration c;
  const double focal = camera_.fx;
  if (co.source == "config") {
    c.valid = true;
    c.source = "config";
    c.height = co.height;
    c.height_source = "config";
    c.focal_px = focal;
    c.pixels_per_metre = focal / co.height;
  } else if (co.source == "gps") {
    if (!(last_hag_ > 0)) {
      why = "waiting for a GPS fix with height_above_ground (calibration.source: gps)";
    } else {
      c.valid = true;
      c.source = "gps";
      c.height = last_hag_;
      c.height_source = "gps";
      c.focal_px = focal;
      c.pixels_per_metre = focal / last_hag_;
    }
  } else {
    MarkerObservation marker = DetectMarker(frame, co);
    const double height_for_marker = co.height > 0 ? co.height : (co.use_gps_height ? last_hag_ : std::nan(""));
    const bool need_height = co.use_gps_height || !co.focal_known;
    if (marker.found && need_height && !(height_for_marker > 0)) {
      why = "marker seen but no height yet (GPS height_above_ground or calibration.height)";
    } else if (marker.found) {
      marker_sides_.push_back(marker.side_px);
      marker_heights_.push_back(height_for_marker);
      if (static_cast<int>(marker_sides_.size()) < co.frames_to_average) {
        why = "marker seen " + std::to_string(marker_sides_.size()) + " of " + std::to_string(co.frames_to_average) +
              " times (averaging)";
      } else {
        double side = 0, height = 0;
        for (size_t i = 0; i < marker_sides_.size(); ++i) {
          side += marker_sides_[i] / marker_sides_.size();
          height += marker_heights_[i] / marker_heights_.size();
        }
        marker.side_px = side;
        c = CalibrateFromMarker(marker, need_height ? height : std::nan(""), focal, co, &why);
      }
    } else {
      why = marker.why;
    }
  }
  if (!c.valid) {
    state->status = TrackStatus::kCalibrating;
    state->message = why;
    if (summary_.frames == co.max_frames)
      LOG(WARNING) << "uav_mosaicker: no calibration after " << co.max_frames << " frames: " << why
                   << " (or set calibration.source: config with calibration.height)";
    return false;
  }
  SetCalibration(c);
  LOG(INFO) << c.Describe();
  return true;
}

void UavMosaicker::StartMosaic(const cv::Mat& frame, const FrameFeatures& features, int64_t utime, FrameState* state) {
  // Ground px of the first frame: height / focal m/px.
  const double ground = calibration_.height / focal_;
  metres_per_pixel_ = options_.canvas.metres_per_pixel > 0 ? options_.canvas.metres_per_pixel
                                                           : ground * options_.canvas.resolution_factor;
  canvas_ = std::make_unique<TiledCanvas>(options_.canvas);
  const double s = ground / metres_per_pixel_;
  // The principal point of the first frame is mosaic px (0, 0).
  Similarity2 S{s, 0, -s * camera_.cx, -s * camera_.cy};
  keyframe_ = Keyframe{features, S, utime};
  last_good_ = S;
  last_scale_ = s;
  prev_good_.reset();
  last_good_index_ = state->frame_index;
  last_good_enu_ = GpsEnuAt(utime);
  height_filter_.Reset(calibration_.height, utime);
  BlendOrQueue(frame, S, state);
  frames_since_blend_ = 0;
  state->status = TrackStatus::kTracking;
  state->keyframe = true;
  state->height = state->height_raw = calibration_.height;
  ++summary_.keyframes;
  LOG(INFO) << "mosaic started: " << metres_per_pixel_ << " m/px, first frame at height " << calibration_.height
            << " m, " << features.points.size() << " features";
}

bool UavMosaicker::PlaneFromHomography(const cv::Matx33d& H, const Keyframe& reference, double* height_ratio,
                                       cv::Vec3d* normal) const {
  std::vector<cv::Mat> rotations, translations, normals;
  int n = 0;
  try {
    n = cv::decomposeHomographyMat(cv::Mat(H), cv::Mat(camera_.K()), rotations, translations, normals);
  } catch (const cv::Exception&) {
    return false;
  }
  // H = K (R + t n^T / d) K^-1, n^T X = d in the keyframe (OpenCV returns t / d).
  // Of the solutions facing the camera, the one whose normal is nearest the keyframe's.
  double best = 0.5;  // within 60 degrees
  bool found = false;
  for (int i = 0; i < n; ++i) {
    const cv::Vec3d nk(normals[i]);
    if (nk[2] <= 0) continue;
    const double agree = nk.dot(reference.normal) / cv::norm(nk);
    if (agree <= best) continue;
    const cv::Matx33d R(rotations[i]);
    const cv::Vec3d t(translations[i]);
    const double ratio = 1.0 + nk.dot(R.t() * t);
    if (!(ratio > 0.2 && ratio < 5)) continue;
    best = agree;
    *height_ratio = ratio;
    const cv::Vec3d nc = R * nk;
    *normal = nc / cv::norm(nc);
    found = true;
  }
  return found;
}

double UavMosaicker::KeyframeOverlap(const Similarity2& key_to_cur, cv::Size size) const {
  const Similarity2 cur_to_key = key_to_cur.Inverse();
  std::vector<cv::Point2f> rect = {{0, 0}, {float(size.width), 0}, {float(size.width), float(size.height)}, {0, float(size.height)}};
  std::vector<cv::Point2f> quad;
  for (const auto& p : rect) quad.push_back(cur_to_key.Apply(p));
  std::vector<cv::Point2f> inter;
  const float area = cv::intersectConvexConvex(rect, quad, inter, true);
  return area / (static_cast<double>(size.area()) + 1e-9);
}

bool UavMosaicker::RegisterToMosaic(const cv::Mat& frame, const FrameFeatures& features,
                                    Similarity2* mosaic_from_frame, MotionEstimate* motion, std::string* why,
                                    double view_scale) {
  if (!canvas_) return false;
  const double k = view_scale > 0 ? view_scale : options_.recovery_view_scale;
  const cv::Size view_size(static_cast<int>(frame.cols * k), static_cast<int>(frame.rows * k));
  const cv::Point2d offset((view_size.width - frame.cols) / 2.0, (view_size.height - frame.rows) / 2.0);
  // view px v -> frame px v - offset -> mosaic via the last good pose.
  const Similarity2 mosaic_from_view = last_good_ * Similarity2{1, 0, -offset.x, -offset.y};
  cv::Mat view, mask;
  double painted = 0;
  {
    std::lock_guard<std::mutex> lock(canvas_mutex_);
    painted = canvas_->Render(mosaic_from_view, view_size, &view, &mask);
  }
  last_painted_ = painted;
  if (painted < options_.recovery_min_painted) {
    *why += "; mosaic covers only " + std::to_string(painted) + " of the search area";
    return false;
  }
  FrameFeatures vf = ExtractFeatures(view, options_.matcher);
  // Drop features on the border of the painted area (artificial corners).
  cv::erode(mask, mask, cv::Mat(), cv::Point(-1, -1), 6);
  FrameFeatures kept;
  kept.size = vf.size;
  for (size_t i = 0; i < vf.points.size(); ++i) {
    const cv::Point p(cvRound(vf.points[i].x), cvRound(vf.points[i].y));
    if (p.inside(cv::Rect(0, 0, mask.cols, mask.rows)) && mask.at<uchar>(p)) {
      kept.points.push_back(vf.points[i]);
      kept.descriptors.push_back(vf.descriptors.row(static_cast<int>(i)));
    }
  }
  *motion = EstimateMotion(kept, features, options_.matcher);
  if (!motion->ok && options_.guided_matching) {
    // Guided: the view was rendered where the frame is expected (view px - offset = frame px).
    MotionPrior prior;
    prior.to_from_from = Similarity2{1, 0, -offset.x, -offset.y};
    prior.gate_px = options_.guide_gate * frame.cols + offset.x;
    MotionEstimate guided = EstimateMotion(kept, features, options_.matcher, &prior);
    if (guided.ok) *motion = guided;
  }
  if (!motion->ok) {
    *why += "; against the mosaic: " + motion->why;
    return false;
  }
  *mosaic_from_frame = mosaic_from_view * motion->similarity.Inverse();
  return true;
}

void UavMosaicker::KeepNeighbour(const FrameFeatures& features, const Similarity2& mosaic_from_frame, int64_t utime) {
  if (options_.neighbour_frames <= 0) return;
  neighbours_.push_back(Keyframe{features, mosaic_from_frame, utime, ground_normal_});
  while (static_cast<int>(neighbours_.size()) > options_.neighbour_frames) neighbours_.pop_front();
}

bool UavMosaicker::RegisterToNeighbours(const FrameFeatures& features, const std::optional<Prediction>& prediction,
                                        MotionEstimate* motion, Similarity2* mosaic_from_frame,
                                        const Keyframe** matched, std::string* why) {
  // Where the frame centre is expected in the mosaic, and how far a frame that overlaps it can be.
  const cv::Point2d c(camera_.cx, camera_.cy);
  const Similarity2& expected = prediction ? prediction->mosaic_from_frame : last_good_;
  const cv::Point2d at = expected.Apply(c);
  const double reach = expected.Scale() * features.size.width;
  std::vector<std::pair<double, const Keyframe*>> near;
  for (const auto& n : neighbours_) {
    if (keyframe_ && n.utime == keyframe_->utime) continue;  // tried already
    const double d = cv::norm(n.mosaic_from_frame.Apply(c) - at);
    if (d < reach) near.emplace_back(d, &n);
  }
  std::sort(near.begin(), near.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  if (near.size() > static_cast<size_t>(options_.neighbour_tries)) near.resize(options_.neighbour_tries);
  std::string tried;
  for (const auto& [d, n] : near) {
    MotionEstimate m = EstimateMotion(n->features, features, options_.matcher);
    std::string reason = m.ok ? "" : m.why;
    Similarity2 S;
    if (m.ok) {
      S = n->mosaic_from_frame * m.similarity.Inverse();
      if (Evidence(m, S, prediction, &reason)) {
        *motion = m;
        *mosaic_from_frame = S;
        *matched = n;
        return true;
      }
    }
    tried = reason;
  }
  if (!near.empty()) *why += "; " + std::to_string(near.size()) + " earlier frames nearby: " + tried;
  return false;
}

bool UavMosaicker::Reregister(const cv::Mat& frame, const FrameFeatures& features, Similarity2* mosaic_from_frame) {
  // Render the mosaic around the pose predicted by the chain and register the frame to it.
  const Similarity2 saved = last_good_;
  last_good_ = *mosaic_from_frame;
  Similarity2 S;
  MotionEstimate m;
  std::string why;
  const bool ok = RegisterToMosaic(frame, features, &S, &m, &why, 1.0 + 2 * options_.reregister_max_shift);
  last_good_ = saved;
  if (!ok) {
    ++summary_.reregistrations_rejected;
    return false;
  }
  // Accept only a correction the size of drift, not a different place.
  const cv::Point2d c(camera_.cx, camera_.cy);
  const double shift_frames = cv::norm(S.Apply(c) - mosaic_from_frame->Apply(c)) / (mosaic_from_frame->Scale() * frame.cols);
  const double scale_change = std::abs(S.Scale() / mosaic_from_frame->Scale() - 1.0);
  if (shift_frames > options_.reregister_max_shift || scale_change > options_.reregister_max_shift ||
      m.num_background < options_.matcher.min_inliers) {
    ++summary_.reregistrations_rejected;
    return false;
  }
  if (!options_.reregister_scale) {
    // Position and heading from the mosaic, scale (height) from the chain: the
    // mosaic is often coarser than the frame, its scale the less precise.
    const double scale = mosaic_from_frame->Scale(), angle = S.Angle();
    Similarity2 kept = Similarity2::FromScaleAngle(scale, angle, 0, 0);
    const cv::Point2d target = S.Apply(c), moved = kept.Apply(c);
    kept.tx = target.x - moved.x;
    kept.ty = target.y - moved.y;
    S = kept;
  }
  *mosaic_from_frame = S;
  ++summary_.reregistrations;
  return true;
}

FrameState UavMosaicker::ProcessFrame(const cv::Mat& image_in, int64_t utime) {
  const auto t0 = std::chrono::steady_clock::now();
  FrameState state = last_state_;
  state.utime = utime;
  state.frame_index = frame_counter_++;
  state.message.clear();
  state.keyframe = state.mosaic_updated = false;
  state.mosaic_seconds = 0;
  state.num_matches = state.num_inliers = state.num_foreground = 0;
  state.scale = 1.0;
  ++summary_.frames;
  if (image_in.empty() || (image_in.type() != CV_8UC1 && image_in.type() != CV_8UC3)) {
    state.status = calibrated_ ? TrackStatus::kLost : TrackStatus::kCalibrating;
    state.message = "frame empty or not 8-bit gray/BGR; skipped";
    if (calibrated_) lost_ = true;
    summary_.last_problem = state.message;
    last_state_ = state;
    return state;
  }
  const cv::Mat frame = Undistort(image_in);
  if (!calibrated_ && !TryCalibrate(frame, &state)) {
    last_state_ = state;
    return state;
  }
  const FrameFeatures features = ExtractFeatures(frame, options_.matcher);
  if (!canvas_) {
    if (features.points.size() < static_cast<size_t>(options_.matcher.min_inliers)) {
      state.status = TrackStatus::kCalibrating;
      state.message = "calibrated, waiting for a frame with enough features to start the mosaic";
      last_state_ = state;
      return state;
    }
    StartMosaic(frame, features, utime, &state);
    state.tracking_seconds = Seconds(t0) - state.mosaic_seconds;
    history_.emplace_back(utime, cv::Point2d(0, 0));
    FillRoute(&state);
    PairPendingFixes();
    last_state_ = state;
    ++summary_.tracked;
    return state;
  }

  // Track against the keyframe: plain matching, then (when that fails or
  // disagrees with the GPS) guided matching around the predicted pose.
  const std::optional<Prediction> prediction = Predict(utime, frame.size());
  MotionEstimate motion = EstimateMotion(keyframe_->features, features, options_.matcher);
  Similarity2 S;
  std::string why = motion.ok ? "" : "matching failed: " + motion.why;
  if (motion.ok) {
    S = keyframe_->mosaic_from_frame * motion.similarity.Inverse();
    if (!Evidence(motion, S, prediction, &why)) motion.ok = false;
  }
  if (!motion.ok && options_.guided_matching && prediction) {
    // Heading hypotheses: the predicted one, then turned by +-guide_turn
    // (a fixed wing's heading between photos is the least certain part).
    const cv::Point2d c(camera_.cx, camera_.cy);
    const double turn = options_.guide_turn * M_PI / 180.0;
    std::string guided_why;
    for (const double dangle : {0.0, turn, -turn}) {
      if (dangle != 0.0 && turn <= 0) break;
      Similarity2 P = Similarity2::FromScaleAngle(prediction->mosaic_from_frame.Scale(),
                                                  prediction->mosaic_from_frame.Angle() + dangle, 0, 0);
      const cv::Point2d at = prediction->mosaic_from_frame.Apply(c), moved = P.Apply(c);
      P.tx = at.x - moved.x;
      P.ty = at.y - moved.y;
      MotionPrior prior;
      prior.to_from_from = P.Inverse() * keyframe_->mosaic_from_frame;
      prior.gate_px = prediction->gate_px;
      MotionEstimate guided = EstimateMotion(keyframe_->features, features, options_.matcher, &prior);
      guided_why = guided.ok ? "" : guided.why;
      Similarity2 G;
      if (guided.ok) {
        G = keyframe_->mosaic_from_frame * guided.similarity.Inverse();
        if (!Evidence(guided, G, prediction, &guided_why)) guided.ok = false;
      }
      if (guided.ok) {
        motion = guided;
        S = G;
        ++summary_.guided;
        break;
      }
      if (guided.num_matches > motion.num_matches) motion.num_matches = guided.num_matches;
    }
    if (!motion.ok) why += "; guided by the " + std::string(prediction->from_gps ? "GPS" : "last motion") + ": " + guided_why;
  }
  bool ok = motion.ok;
  bool via_neighbour = false;
  const Keyframe* reference = &*keyframe_;  // the frame `motion` is relative to
  if (!ok && !neighbours_.empty()) {
    Similarity2 N;
    MotionEstimate m2;
    if (RegisterToNeighbours(features, prediction, &m2, &N, &reference, &why)) {
      ok = via_neighbour = true;
      motion = m2;
      S = N;
    }
  }
  bool via_mosaic = false;
  bool reregistered = false;
  if (ok) {
    if (!lost_ && options_.reregister_every_n_frames > 0 &&
        ++frames_since_reregister_ >= options_.reregister_every_n_frames) {
      frames_since_reregister_ = 0;
      reregistered = Reregister(frame, features, &S);
    }
  } else if (lost_ && !ok) {
    last_painted_ = 1.0;
    MotionEstimate m2;
    // Search the mosaic where the GPS says the frame is, else around the last good pose.
    const Similarity2 saved = last_good_;
    if (prediction && prediction->from_gps) last_good_ = prediction->mosaic_from_frame;
    Similarity2 R;
    if (RegisterToMosaic(frame, features, &R, &m2, &why) && Evidence(m2, R, prediction, &why)) {
      ok = true;
      via_mosaic = true;
      motion = m2;
      S = R;
    }
    last_good_ = saved;
  }
  state.num_matches = motion.num_matches;
  state.num_inliers = motion.num_inliers;
  state.num_foreground = motion.num_foreground;
  state.guided = ok && motion.guided;
  state.reseated = false;
  state.spread = ok ? motion.spread : 0.0;
  if (!ok) {
    // Keep the last good state; say why.
    state.status = TrackStatus::kLost;
    if (!lost_) ++summary_.lost;
    lost_ = true;
    const bool new_ground = last_painted_ < options_.recovery_min_painted;
    if (options_.reseat_by_gps && prediction && prediction->from_gps && (new_ground || !options_.reseat_only_new_ground)) {
      // Restart from this frame at its GPS position (heading and scale of the
      // last registered frame): the next frame is matched against it.
      keyframe_ = Keyframe{features, prediction->mosaic_from_frame, utime, ground_normal_};
      last_good_ = prediction->mosaic_from_frame;
      prev_good_.reset();
      last_good_index_ = state.frame_index;
      last_good_enu_ = GpsEnuAt(utime);
      state.reseated = true;
      ++summary_.reseats;
      why += "; placed at its GPS position, tracking restarts from this frame";
    }
    state.message = why;
    summary_.last_problem = why;
    state.tracking_seconds = Seconds(t0);
    last_state_ = state;
    return state;
  }
  state.status = lost_ ? TrackStatus::kRecovered : TrackStatus::kTracking;
  if (lost_) {
    ++summary_.recoveries;
    state.message = via_mosaic      ? "re-acquired against the mosaic"
                    : via_neighbour ? "re-acquired against an earlier frame"
                                    : "re-acquired against the last keyframe";
    LOG(INFO) << "frame " << state.frame_index << ": " << state.message;
  }
  const bool was_lost = lost_;
  lost_ = false;
  ++summary_.tracked;

  // The ground plane from the homography: the camera's tilt and its height
  // relative to the keyframe.
  double height_ratio = 1;
  cv::Vec3d normal;
  const bool plane_ok = !via_mosaic && PlaneFromHomography(motion.homography, *reference, &height_ratio, &normal);
  if (plane_ok) {
    ground_normal_ = normal;
    state.tilt = std::acos(std::clamp(normal[2], -1.0, 1.0));
    if (options_.scale_source == "homography") {
      // Scale from the height ratio; heading from the fit; placed so that the
      // matches' centroid lands where the fit puts it.
      cv::Point2d centroid(0, 0);
      for (const auto& p : motion.to_background) centroid += cv::Point2d(p);
      centroid *= 1.0 / std::max<size_t>(1, motion.to_background.size());
      Similarity2 H = Similarity2::FromScaleAngle(reference->mosaic_from_frame.Scale() * height_ratio, S.Angle(), 0, 0);
      const cv::Point2d target = S.Apply(centroid), moved = H.Apply(centroid);
      H.tx = target.x - moved.x;
      H.ty = target.y - moved.y;
      S = H;
    }
  }

  // Height (eqs. 4-5 chained through the similarity scale) and lambda.
  const double s = S.Scale();
  state.scale = last_scale_ / s;
  state.height_raw = s * metres_per_pixel_ * focal_;
  state.height = height_filter_.UpdateVision(state.height_raw, utime);
  if (last_good_index_ == state.frame_index - 1 && !was_lost) {
    prev_good_ = last_good_;
  } else {
    prev_good_.reset();
  }
  last_good_ = S;
  last_scale_ = s;
  last_good_index_ = state.frame_index;
  last_good_enu_ = GpsEnuAt(utime);
  UpdateYawOffset(S, utime);

  // New keyframe?
  const double key_scale = motion.lambda;
  state.reregistered = reregistered;
  KeepNeighbour(features, S, utime);
  const bool new_key = was_lost || via_mosaic || via_neighbour || reregistered || motion.num_background < options_.keyframe_min_inliers ||
                       key_scale > options_.keyframe_max_scale || key_scale < 1.0 / options_.keyframe_max_scale ||
                       (!via_mosaic && KeyframeOverlap(motion.similarity, frame.size()) < options_.keyframe_min_overlap);
  if (new_key) {
    keyframe_ = Keyframe{features, S, utime, plane_ok ? ground_normal_ : keyframe_->normal};
    state.keyframe = true;
    ++summary_.keyframes;
  }
  state.tracking_seconds = Seconds(t0);

  cv::Point2d route_pixel(camera_.cx, camera_.cy);
  if (options_.route_point == "nadir" && plane_ok) {
    const cv::Vec3d& g = ground_normal_;  // the point below the camera is K n
    route_pixel = {camera_.fx * g[0] / g[2] + camera_.cx, camera_.fy * g[1] / g[2] + camera_.cy};
  }
  history_.emplace_back(utime, S.Apply(route_pixel));
  while (history_.size() > 256) history_.pop_front();
  FillRoute(&state);
  PairPendingFixes();

  // Mosaic.
  ++frames_since_blend_;
  if (new_key || frames_since_blend_ >= options_.mosaic_every_n_frames) {
    if (BlendOrQueue(frame, S, &state)) frames_since_blend_ = 0;
  }
  last_state_ = state;
  return state;
}

std::optional<cv::Point2d> UavMosaicker::GpsEnuAt(int64_t utime, double* sigma) const {
  if (!origin_fix_) return std::nullopt;
  const GpsFix* fix = nullptr;
  const int64_t gap = static_cast<int64_t>(options_.geo.max_time_gap * 1e6);
  for (const auto& f : recent_fixes_)
    if (std::llabs(f.utime - utime) <= gap && (!fix || std::llabs(f.utime - utime) < std::llabs(fix->utime - utime))) fix = &f;
  if (!fix) return std::nullopt;
  if (sigma) *sigma = fix->horizontal_sigma;
  return LatLonToEnu(fix->latitude, fix->longitude, origin_fix_->latitude, origin_fix_->longitude);
}

std::optional<double> UavMosaicker::GpsCourseAt(int64_t utime) const {
  if (!origin_fix_) return std::nullopt;
  const GpsFix* fix = nullptr;
  const int64_t gap = static_cast<int64_t>(options_.geo.max_time_gap * 1e6);
  for (const auto& f : recent_fixes_)
    if (std::llabs(f.utime - utime) <= gap && (!fix || std::llabs(f.utime - utime) < std::llabs(fix->utime - utime))) fix = &f;
  const GpsFix* before = nullptr;
  for (const auto& f : recent_fixes_)
    if (fix && f.utime < fix->utime) before = &f;
  if (!fix || !before) return std::nullopt;
  const cv::Point2d d = LatLonToEnu(fix->latitude, fix->longitude, before->latitude, before->longitude);
  if (cv::norm(d) < 2 * fix->horizontal_sigma) return std::nullopt;
  return std::atan2(d.y, d.x);
}

// Heading of a frame's "up" (-y) in ENU = pi/2 - angle + tie angle (the tie maps (x, -y) mosaic px to ENU).
void UavMosaicker::UpdateYawOffset(const Similarity2& mosaic_from_frame, int64_t utime) {
  const Similarity2* tie = PredictionTie();
  if (!tie) return;
  const std::optional<double> course = GpsCourseAt(utime);
  if (!course) return;
  const double heading = M_PI / 2 - mosaic_from_frame.Angle() + tie->Angle();
  const cv::Point2d u(std::cos(heading - *course), std::sin(heading - *course));
  yaw_offset_ = yaw_offset_ ? 0.7 * *yaw_offset_ + 0.3 * u : u;
}

std::optional<UavMosaicker::Prediction> UavMosaicker::Predict(int64_t utime, cv::Size size) const {
  if (!keyframe_) return std::nullopt;
  const double scale = last_good_.Scale();
  const double width = static_cast<double>(size.width);
  // GPS: the fix nearest in time (within max_time_gap) mapped through the tie.
  const GpsFix* fix = nullptr;
  const int64_t gap = static_cast<int64_t>(options_.geo.max_time_gap * 1e6);
  for (const auto& f : recent_fixes_)
    if (std::llabs(f.utime - utime) <= gap && (!fix || std::llabs(f.utime - utime) < std::llabs(fix->utime - utime))) fix = &f;
  const Similarity2* tie = PredictionTie();
  if (fix && tie && origin_fix_ && scale > 0) {
    const cv::Point2d enu = LatLonToEnu(fix->latitude, fix->longitude, origin_fix_->latitude, origin_fix_->longitude);
    const cv::Point2d flipped = tie->Inverse().Apply(enu);
    Prediction p;
    p.from_gps = true;
    p.gps_px = {flipped.x, -flipped.y};
    if (last_good_enu_) {
      // GPS motion since the last registered frame, from its registered centre
      // (the tie is a global fit: its local bias cancels in a difference).
      const Similarity2 lin{tie->a, tie->b, 0, 0};
      const cv::Point2d d = lin.Inverse().Apply(enu - *last_good_enu_);
      p.gps_px = last_good_.Apply({camera_.cx, camera_.cy}) + cv::Point2d(d.x, -d.y);
    }
    // Heading: the last registered frame's, turned by the change of the GPS course.
    double angle = last_good_.Angle();
    const double metres_per_frame_px = scale * std::abs(tie->Scale());
    const GpsFix* before = nullptr;
    const GpsFix* older = nullptr;
    for (const auto& f : recent_fixes_) {
      if (f.utime < fix->utime) {
        older = before;
        before = &f;
      }
    }
    const std::optional<double> course = GpsCourseAt(utime);
    if (course && yaw_offset_ && cv::norm(*yaw_offset_) > 0.5) {
      // The camera's heading relative to the course, learnt on registered frames (turns of a fixed wing).
      const double heading = *course + std::atan2(yaw_offset_->y, yaw_offset_->x);
      angle = M_PI / 2 + tie->Angle() - heading;
    } else if (before && older) {
      const cv::Point2d e0 = LatLonToEnu(older->latitude, older->longitude, origin_fix_->latitude, origin_fix_->longitude);
      const cv::Point2d e1 = LatLonToEnu(before->latitude, before->longitude, origin_fix_->latitude, origin_fix_->longitude);
      const cv::Point2d d0 = e1 - e0, d1 = enu - e1;
      if (cv::norm(d0) > 2 * fix->horizontal_sigma && cv::norm(d1) > 2 * fix->horizontal_sigma) {
        const double turn = std::atan2(d0.x * d1.y - d0.y * d1.x, d0.dot(d1));  // CCW in ENU = CW in mosaic px
        if (std::abs(turn) < M_PI / 3) angle -= turn;
      }
    }
    p.mosaic_from_frame = Similarity2::FromScaleAngle(scale, angle, 0, 0);
    const cv::Point2d c(camera_.cx, camera_.cy), moved = p.mosaic_from_frame.Apply(c);
    p.mosaic_from_frame.tx = p.gps_px.x - moved.x;
    p.mosaic_from_frame.ty = p.gps_px.y - moved.y;
    const double sigma_px = fix->horizontal_sigma / std::max(1e-9, metres_per_frame_px);
    p.gate_px = options_.guide_gate * width + 3 * sigma_px;
    p.gps_tolerance_px = std::max(options_.gps_max_disagreement * width, 5 * sigma_px);
    return p;
  }
  // Constant motion: the last frame-to-frame motion once more.
  if (prev_good_ && last_good_index_ >= 0) {
    Prediction p;
    p.mosaic_from_frame = last_good_ * (prev_good_->Inverse() * last_good_);
    p.gate_px = 1.5 * options_.guide_gate * width;
    return p;
  }
  return std::nullopt;
}

bool UavMosaicker::Evidence(const MotionEstimate& motion, const Similarity2& mosaic_from_frame,
                            const std::optional<Prediction>& p, std::string* why) {
  if (!why->empty()) *why += "; ";
  if (motion.spread < options_.min_spread) {
    *why += "matches cover only " + std::to_string(motion.spread) + " of the frame (" +
            std::to_string(motion.num_background) + " matches)";
    return false;
  }
  if (p && p->from_gps && motion.num_background < options_.gps_check_below_inliers) {
    const cv::Point2d c(camera_.cx, camera_.cy);
    const double off_px = cv::norm(mosaic_from_frame.Apply(c) - p->gps_px) / std::max(1e-9, mosaic_from_frame.Scale());
    if (off_px > p->gps_tolerance_px) {
      ++summary_.gps_rejections;
      *why += "registration lands " + std::to_string(static_cast<int>(off_px)) + " px (frame) from the GPS position (" +
              std::to_string(motion.num_background) + " matches)";
      return false;
    }
  }
  return true;
}

void UavMosaicker::FillRoute(FrameState* state) {
  state->route_px = history_.empty() ? cv::Point2d(0, 0) : history_.back().second;
  state->route_local = MosaicToLocal(state->route_px);
  state->georeferenced = enu_from_flipped_.has_value();
  state->gps_aided = state->georeferenced && (state->utime - last_fix_utime_) * 1e-6 <= options_.geo.gps_timeout;
  if (state->georeferenced && origin_fix_) {
    EnuToLatLon(state->route_local, origin_fix_->latitude, origin_fix_->longitude, &state->latitude, &state->longitude);
  }
  route_.push_back(state->route_px);
  if (route_.size() > 200000) route_.erase(route_.begin(), route_.begin() + 100000);
}

cv::Point2d UavMosaicker::MosaicToLocal(const cv::Point2d& p) const {
  if (enu_from_flipped_) return enu_from_flipped_->Apply({p.x, -p.y});
  // Not tied: the first frame's image up is taken as north.
  return {p.x * metres_per_pixel_, -p.y * metres_per_pixel_};
}

void UavMosaicker::AddGps(const GpsFix& fix) {
  if (std::isfinite(fix.height_above_ground) && fix.height_above_ground > 0) {
    last_hag_ = fix.height_above_ground;
    if (canvas_) height_filter_.UpdateGps(fix.height_above_ground, fix.utime);
  }
  if (!fix.valid || !std::isfinite(fix.latitude) || !std::isfinite(fix.longitude)) return;
  if (!origin_fix_) origin_fix_ = fix;
  recent_fixes_.push_back(fix);
  if (!(recent_fixes_.back().horizontal_sigma > 0 && std::isfinite(recent_fixes_.back().horizontal_sigma)))
    recent_fixes_.back().horizontal_sigma = GpsFix().horizontal_sigma;  // unknown accuracy (NaN): the default
  while (recent_fixes_.size() > 64) recent_fixes_.pop_front();
  last_fix_utime_ = std::max(last_fix_utime_, fix.utime);
  pending_fixes_.push_back(fix);
  while (pending_fixes_.size() > 256) pending_fixes_.pop_front();
  PairPendingFixes();
}

void UavMosaicker::PairPendingFixes() {
  if (history_.empty() || !origin_fix_) return;
  bool added = false;
  const int64_t gap = static_cast<int64_t>(options_.geo.max_time_gap * 1e6);
  while (!pending_fixes_.empty()) {
    const GpsFix& f = pending_fixes_.front();
    if (f.utime > history_.back().first) {
      // Frames for this fix may still come; give up only when it is far behind.
      break;
    }
    // Interpolate the route at the fix time.
    std::optional<cv::Point2d> p;
    for (size_t i = history_.size(); i-- > 0;) {
      if (history_[i].first <= f.utime) {
        if (i + 1 < history_.size()) {
          const auto& a = history_[i];
          const auto& b = history_[i + 1];
          if (b.first - a.first <= 2 * gap) {
            const double w = b.first > a.first ? double(f.utime - a.first) / double(b.first - a.first) : 0.0;
            p = a.second + w * (b.second - a.second);
          }
        } else if (f.utime - history_[i].first <= gap) {
          p = history_[i].second;
        }
        break;
      }
    }
    if (p) {
      pairs_.push_back({*p, LatLonToEnu(f.latitude, f.longitude, origin_fix_->latitude, origin_fix_->longitude)});
      added = true;
    }
    pending_fixes_.pop_front();
  }
  while (static_cast<int>(pairs_.size()) > options_.geo.window_fixes) pairs_.pop_front();
  if (added) RefitTie();
}

bool UavMosaicker::FitTie(size_t first, Similarity2* tie, double* rms) const {
  std::vector<cv::Point2d> from, to;
  cv::Point2d mean(0, 0);
  for (size_t i = first; i < pairs_.size(); ++i) {
    from.emplace_back(pairs_[i].mosaic_px.x, -pairs_[i].mosaic_px.y);
    to.push_back(pairs_[i].enu);
    mean += pairs_[i].enu;
  }
  if (to.size() < 2) return false;
  mean *= 1.0 / to.size();
  double spread = 0;
  for (const auto& e : to) spread += (e - mean).dot(e - mean);
  spread = std::sqrt(spread / to.size());
  if (spread < options_.geo.min_spread) return false;
  return FitSimilarity(from, to, tie, rms);
}

const Similarity2* UavMosaicker::PredictionTie() const {
  if (local_tie_) return &*local_tie_;
  return enu_from_flipped_ ? &*enu_from_flipped_ : nullptr;
}

void UavMosaicker::RefitTie() {
  if (static_cast<int>(pairs_.size()) < options_.geo.min_fixes) return;
  Similarity2 T;
  double rms = 0;
  if (FitTie(0, &T, &rms)) {
    if (!enu_from_flipped_) LOG(INFO) << "mosaic tied to GPS: " << pairs_.size() << " fixes, rms " << rms << " m";
    enu_from_flipped_ = T;
    tie_rms_ = rms;
  }
  const int w = options_.geo.predict_window;
  if (w > 0 && static_cast<int>(pairs_.size()) >= std::min(w, options_.geo.min_fixes)) {
    Similarity2 L;
    const size_t first = pairs_.size() > static_cast<size_t>(w) ? pairs_.size() - w : 0;
    if (FitTie(first, &L, nullptr)) local_tie_ = L;
  }
}

cv::Mat UavMosaicker::Preview(int max_side, bool draw_route) const {
  if (!canvas_) return {};
  double scale = 1;
  cv::Point2d origin;
  cv::Mat preview;
  {
    std::lock_guard<std::mutex> lock(canvas_mutex_);
    preview = canvas_->Preview(max_side, &scale, &origin);
  }
  if (preview.empty() || !draw_route || route_.size() < 2) return preview;
  preview = preview.clone();
  const size_t step = std::max<size_t>(1, route_.size() / 2000);
  for (size_t i = step; i < route_.size(); i += step) {
    const cv::Point2d a = (route_[i - step] - origin) * scale, b = (route_[i] - origin) * scale;
    cv::line(preview, a, b, cv::Scalar(0, 0, 255), 1, cv::LINE_AA);
  }
  cv::circle(preview, (route_.back() - origin) * scale, 3, cv::Scalar(0, 255, 255), -1);
  return preview;
}

bool UavMosaicker::ExportCanvas(cv::Mat* bgra, double* scale, cv::Point2d* origin, std::string* error) {
  FlushMosaic();
  std::lock_guard<std::mutex> lock(canvas_mutex_);
  return canvas_->Export(bgra, scale, origin, error);
}

bool UavMosaicker::WriteMosaic(const std::string& png_path, std::string* error) {
  if (!canvas_) {
    if (error) *error = "no mosaic yet (not calibrated or no frame tracked)";
    return false;
  }
  cv::Mat bgra;
  double scale = 1;
  cv::Point2d origin;
  if (!ExportCanvas(&bgra, &scale, &origin, error)) return false;
  std::error_code ec;
  const std::filesystem::path path(png_path);
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path(), ec);
  // Written under temporary names, then renamed world file first, image last:
  // a reader watching the image (map_localizer) never sees half a file or an
  // image with another export's world file.
  std::filesystem::path world = path, tmp_png = path, tmp_world;
  world.replace_extension(".pgw");
  tmp_png.replace_filename("." + path.stem().string() + ".writing" + path.extension().string());
  tmp_world = tmp_png;
  tmp_world.replace_extension(".pgw");
  bool written = false;
  try {
    written = cv::imwrite(tmp_png.string(), bgra);
  } catch (const cv::Exception& e) {
    written = false;
  }
  if (!written) {
    std::filesystem::remove(tmp_png, ec);
    if (error) *error = "cannot write " + png_path + " (folder writable? name ends in .png?)";
    return false;
  }
  if (enu_from_flipped_ && origin_fix_) {
    // pixel (col,row) -> mosaic px origin + (col,row)/scale -> (x,-y) -> ENU -> lon/lat.
    const Similarity2& T = *enu_from_flipped_;
    const double lat0 = origin_fix_->latitude, lon0 = origin_fix_->longitude;
    const double ke = 1.0 / (kEarthRadius * std::cos(lat0 * kDeg)) / kDeg, kn = 1.0 / kEarthRadius / kDeg;
    const double a = T.a, b = T.b, s = scale, ox = origin.x, oy = origin.y;
    std::ofstream out(tmp_world);
    out << std::setprecision(12) << ke * a / s << "\n"
        << kn * b / s << "\n"
        << ke * b / s << "\n"
        << -kn * a / s << "\n"
        << lon0 + ke * (a * ox + b * oy + T.tx) << "\n"
        << lat0 + kn * (b * ox - a * oy + T.ty) << "\n";
    out.close();
    if (!out) {
      std::filesystem::remove(tmp_world, ec);
      if (error) *error = "mosaic written but not its world file " + world.string();
    } else {
      std::filesystem::rename(tmp_world, world, ec);
    }
  } else {
    std::filesystem::remove(world, ec);
  }
  std::filesystem::rename(tmp_png, path, ec);
  if (ec) {
    if (error) *error = "cannot rename " + tmp_png.string() + " to " + png_path + ": " + ec.message();
    return false;
  }
  LOG(INFO) << "mosaic written: " << png_path << " (" << bgra.cols << "x" << bgra.rows << ", "
            << metres_per_pixel_ / scale << " m/px" << (enu_from_flipped_ ? ", world file " + world.string() : "")
            << ")";
  return true;
}

bool UavMosaicker::MosaicToLatLon(const cv::Point2d& mosaic_px, cv::Point2d* lat_lon) const {
  if (!enu_from_flipped_ || !origin_fix_) return false;
  EnuToLatLon(enu_from_flipped_->Apply({mosaic_px.x, -mosaic_px.y}), origin_fix_->latitude, origin_fix_->longitude,
              &lat_lon->x, &lat_lon->y);
  return true;
}

bool UavMosaicker::WriteGeoTiff(const std::string& tif_path, std::string* error) {
  if (!canvas_ || !enu_from_flipped_ || !origin_fix_) {
    if (error) *error = "no GeoTIFF for " + tif_path + ": the mosaic is not tied to GPS (no geotags or too few)";
    return false;
  }
  cv::Mat bgra;
  double scale = 1;
  cv::Point2d origin;
  if (!ExportCanvas(&bgra, &scale, &origin, error)) return false;
  auto lat_lon_of_pixel = [&](const cv::Point2d& p) {
    cv::Point2d ll;
    MosaicToLatLon(origin + p * (1.0 / scale), &ll);
    return ll;
  };
  const int epsg = UtmEpsg(origin_fix_->latitude, origin_fix_->longitude);
  if (!vloc::mosaic::WriteGeoTiff(bgra, lat_lon_of_pixel, epsg, tif_path, error)) return false;
  LOG(INFO) << "GeoTIFF written: " << tif_path << " (EPSG:" << epsg << ")";
  return true;
}

MosaickerSummary UavMosaicker::summary() const {
  MosaickerSummary s = summary_;
  s.calibration = calibration_;
  s.metres_per_pixel = metres_per_pixel_;
  s.georeferenced = enu_from_flipped_.has_value();
  s.tie_rms = tie_rms_;
  s.tie_pairs = static_cast<int>(pairs_.size());
  if (canvas_) {
    std::lock_guard<std::mutex> lock(canvas_mutex_);
    s.canvas = canvas_->stats();
  }
  if (options_.async_mosaic) {
    std::lock_guard<std::mutex> lock(job_mutex_);
    s.blends = static_cast<int>(async_blends_);
  }
  return s;
}

}  // namespace vloc::mosaic
