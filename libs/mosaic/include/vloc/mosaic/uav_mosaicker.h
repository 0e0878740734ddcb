#pragma once
// The UAV nadir SLAM of Avola et al. (seeds/004): calibration (sec. 2.1),
// flight height from the frame-to-frame scale change (sec. 2.2, eqs. 2-5)
// and the route from frame centres on an incremental mosaic (sec. 2.3).
//
//   UavMosaicker m(options);
//   m.AddGps(fix);                       // whenever a fix arrives (optional)
//   FrameState s = m.ProcessFrame(bgr, utime);
//   m.WriteMosaic("out/mosaic.png");     // PNG (+ .pgw when tied to GPS)
//
// Geometry: every frame gets mosaic_from_frame, a similarity taking frame
// pixels (undistorted) to mosaic pixels. The mosaic has one fixed ground
// resolution r (m/px), so the similarity's scale s gives the height,
// h = s r f (f = focal length in px; eqs. 4-5 chained), and the frame centre
// (principal point) gives the route. Frames are matched against the current
// keyframe (the last frame that started a new reference), which is the
// frame-to-frame chain of the paper with fewer links, hence less drift.

#include <opencv2/core.hpp>
#include <cstdint>
#include <condition_variable>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <thread>
#include <optional>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/mosaic/calibration.h"
#include "vloc/mosaic/frame_matcher.h"
#include "vloc/mosaic/geometry.h"
#include "vloc/mosaic/height_filter.h"
#include "vloc/mosaic/tiled_canvas.h"

namespace vloc {
class OptionsReader;
}

namespace vloc::mosaic {

struct GeoOptions {
  int min_fixes = 5;              // GPS fixes paired with frames before the mosaic is tied to GPS
  double min_spread = 10.0;       // m, RMS spread of those fixes needed (the rotation needs a baseline)
  int window_fixes = 2000;        // most recent pairs used for the mosaic -> local ENU fit
  double max_time_gap = 0.25;     // s, a fix pairs with the frames around it only within this gap
  double gps_timeout = 1.5;       // s, without a fix for this long the route is carried by vision alone
  int predict_window = 0;         // most recent pairs of a local tie used only to predict where frames land
                                  // (robust to a chain whose scale drifts); 0 = the tie itself

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct MosaickerOptions {
  PinholeCamera camera;                 // intrinsics and distortion of the nadir camera
  CalibrationOptions calibration;       // sec. 2.1
  MatcherOptions matcher;               // sec. 2.2, eqs. 2-3
  HeightFilterOptions height_filter;    // smoothing of eqs. 4-5, GPS fusion option
  CanvasOptions canvas;                 // tiled mosaic, blending, memory budget
  GeoOptions geo;                       // tie to GPS
  int mosaic_every_n_frames = 3;        // blend every n-th tracked frame into the mosaic (keyframes always)
  int keyframe_min_inliers = 150;       // below this many background matches the frame becomes the keyframe
  double keyframe_min_overlap = 0.6;    // below this footprint overlap with the keyframe, likewise
  double keyframe_max_scale = 1.2;      // a scale change beyond [1/x, x] from the keyframe, likewise
  double recovery_view_scale = 1.6;     // when lost, the mosaic is searched over this many frame sizes around the last pose
  double recovery_min_painted = 0.25;   // fraction of that view the mosaic must cover to try
  int reregister_every_n_frames = 0;    // every n-th tracked frame is also registered against the mosaic at its
                                        // predicted place, which removes drift of the keyframe chain where the
                                        // mosaic holds earlier content (loops, overlapping strips); 0 = off
  bool reregister_scale = false;        // the re-registration also replaces the scale (height); false = position and
                                        // heading only (the mosaic is coarser than low frames: its scale is noisier)
  double reregister_max_shift = 0.15;   // a mosaic registration moving the frame centre by more than this fraction
                                        // of the frame width, or its scale by more than this fraction, is rejected
  // Evidence for a registration (real surveys: parallax, low texture, tilt).
  double min_spread = 0.0;              // background matches must span this fraction of the frame (convex hull area)
  bool guided_matching = false;         // when plain matching fails, match again inside a gate around the predicted
                                        // pose (GPS motion when tied to GPS, else the last frame-to-frame motion)
  double guide_gate = 0.12;             // gate radius as a fraction of the frame width (plus 3 GPS sigmas)
  double guide_turn = 0.0;              // deg: guided matching also tries the predicted heading turned by +-this
  double gps_max_disagreement = 0.35;   // a registration whose frame centre lands farther than this fraction of the
                                        // frame width (or 5 GPS sigmas, the larger) from the GPS position is rejected
  std::string scale_source = "similarity";  // the frame's scale (height) from "similarity": the least-squares fit to
                                        // the matches (eq. 3); "homography": the height ratio of the plane-induced
                                        // homography, h/h_key = 1 + n.R^T t/d (unbiased when the camera tilts: the
                                        // similarity then takes the scale of the overlap, not of the frame centre)
  std::string route_point = "centre";   // "centre": the route is the frame centre (principal point) on the ground;
                                        // "nadir": the point below the camera, from the ground-plane normal of the
                                        // homography to the keyframe (cameras without a gimbal tilt: the centre is
                                        // then h tan(tilt) away from the camera's position)
  int gps_check_below_inliers = 60;     // the GPS agreement test applies to registrations with fewer background matches
                                        // than this; stronger geometric evidence stands on its own (a GPS tie made
                                        // from a short or poor track must not veto a clear registration)
  bool reseat_only_new_ground = true;   // reseat only when the mosaic does not cover where the GPS puts the frame
                                        // (new ground: nothing to re-acquire against); else keep searching the mosaic
  bool reseat_by_gps = false;           // a frame no image registers is placed at its GPS position and becomes the
                                        // keyframe (reported LOST, not registered), so the next frame re-acquires
  int neighbour_frames = 0;             // registered frames whose features are kept (most recent first): a frame the
                                        // keyframe does not register is matched against the nearest of them (the
                                        // neighbour on the adjacent strip of a survey, the frame before a bad one)
  int neighbour_tries = 3;              // nearest kept frames (by predicted position) tried, within one frame width
  int num_threads = 2;                  // OpenCV threads (A-KAZE, matching, warping)
  bool async_mosaic = false;            // blend on a worker thread (real time: tracking never waits; a frame due while
                                        // the worker is busy replaces the queued one). false = blend inside ProcessFrame

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct GpsFix {
  int64_t utime = 0;                    // us
  bool valid = false;                   // has a horizontal fix
  double latitude = 0, longitude = 0;   // deg
  double altitude = 0;                  // m, ellipsoid
  double height_above_ground = std::numeric_limits<double>::quiet_NaN();  // m, NaN when unknown
  double horizontal_sigma = 2.0;        // m
  double vertical_sigma = 3.0;          // m
};

enum class TrackStatus { kCalibrating = 0, kTracking = 1, kLost = 2, kRecovered = 3 };
const char* ToString(TrackStatus status);

// The estimate after one frame (what UAV_STATE carries).
struct FrameState {
  int64_t utime = 0;
  int frame_index = -1;
  TrackStatus status = TrackStatus::kCalibrating;
  std::string message;                  // why, when not tracking
  double height = 0;                    // m, filtered
  double height_raw = 0;                // m, from the chain of scale changes alone
  double scale = 1.0;                   // lambda from the previous frame; > 1 = descending
  cv::Point2d route_px;                 // mosaic px of the frame centre
  cv::Point2d route_local;              // m, east/north (of the first GPS fix when tied, else of the first frame centre)
  double latitude = std::numeric_limits<double>::quiet_NaN();
  double longitude = std::numeric_limits<double>::quiet_NaN();
  bool gps_aided = false;               // tied to GPS and a fix is recent
  bool georeferenced = false;           // a mosaic -> ENU tie exists
  int num_matches = 0, num_inliers = 0, num_foreground = 0;
  bool keyframe = false;                // this frame became the keyframe
  bool reregistered = false;            // the pose came from a registration against the mosaic (periodic)
  bool guided = false;                  // registered by guided matching (GPS or motion prediction)
  bool reseated = false;                // not registered: placed at its GPS position to restart tracking
  double spread = 0;                    // convex-hull area of the background matches / frame area
  double tilt = 0;                      // rad, camera tilt from the ground normal (homography), 0 when not known
  bool mosaic_updated = false;          // blended into the mosaic (async_mosaic: queued for blending)
  double tracking_seconds = 0;          // s, features + matching + height
  double mosaic_seconds = 0;            // s, blending (0 when not blended or async_mosaic)
};

struct MosaickerSummary {
  int frames = 0, tracked = 0, lost = 0, recoveries = 0, keyframes = 0, blends = 0;
  int reregistrations = 0;              // frames whose pose came from a periodic registration against the mosaic
  int reregistrations_rejected = 0;     // such registrations that failed or disagreed too much with the chain
  int guided = 0;                       // frames registered by guided matching
  int gps_rejections = 0;               // registrations rejected because they disagreed with the GPS motion
  int reseats = 0;                      // frames placed by GPS after every registration failed
  std::string last_problem;
  Calibration calibration;
  double metres_per_pixel = 0;          // mosaic ground resolution
  bool georeferenced = false;
  double tie_rms = 0;                   // m, residual of the GPS tie
  int tie_pairs = 0;
  CanvasStats canvas;
  std::string BriefReport() const;
};

class UavMosaicker {
 public:
  explicit UavMosaicker(const MosaickerOptions& options);
  ~UavMosaicker();

  // One frame (BGR or gray, raw: undistorted here). Never throws on bad
  // input: an empty frame gives status LOST with a message.
  FrameState ProcessFrame(const cv::Mat& image, int64_t utime);
  void AddGps(const GpsFix& fix);

  // Downscaled mosaic (BGR) with the route drawn, longest side <= max_side.
  cv::Mat Preview(int max_side, bool draw_route = true) const;
  // Full mosaic as PNG (BGRA, alpha = covered) + world file `<stem>.pgw`
  // (lon/lat degrees, WGS84, linearised) when tied to GPS.
  bool WriteMosaic(const std::string& png_path, std::string* error);
  // Full mosaic as a north-up GeoTIFF in the flight's UTM zone (GDAL). Needs
  // the tie to GPS; false with one line in *error otherwise.
  bool WriteGeoTiff(const std::string& tif_path, std::string* error);
  // WGS84 lat/lon (deg, as x = lat, y = lon) of a mosaic pixel; false when not tied to GPS.
  bool MosaicToLatLon(const cv::Point2d& mosaic_px, cv::Point2d* lat_lon) const;

  MosaickerSummary summary() const;
  const Calibration& calibration() const { return calibration_; }
  double metres_per_pixel() const { return metres_per_pixel_; }
  // Local ENU east/north (m) of a mosaic pixel (best current estimate).
  cv::Point2d MosaicToLocal(const cv::Point2d& mosaic_px) const;
  // Forces calibration (e.g. from a tool that knows height and focal).
  void SetCalibration(const Calibration& calibration);

 private:
  struct Keyframe {
    FrameFeatures features;
    Similarity2 mosaic_from_frame;
    int64_t utime = 0;
    cv::Vec3d normal{0, 0, 1};          // ground-plane normal in its camera frame (scale_source homography)
  };
  struct TiePair {
    cv::Point2d mosaic_px;
    cv::Point2d enu;
  };
  cv::Mat Undistort(const cv::Mat& image);
  bool TryCalibrate(const cv::Mat& frame, FrameState* state);
  void StartMosaic(const cv::Mat& frame, const FrameFeatures& features, int64_t utime, FrameState* state);
  // The mosaic rendered around last_good_ over view_scale frame sizes (0 = recovery_view_scale).
  bool RegisterToMosaic(const cv::Mat& frame, const FrameFeatures& features, Similarity2* mosaic_from_frame,
                        MotionEstimate* motion, std::string* why, double view_scale = 0);
  // Periodic re-registration: *mosaic_from_frame (the chain's pose) replaced by
  // the registration against the mosaic rendered there, when that agrees.
  bool Reregister(const cv::Mat& frame, const FrameFeatures& features, Similarity2* mosaic_from_frame);
  struct Prediction {
    Similarity2 mosaic_from_frame;      // predicted pose of the new frame
    double gate_px = 0;                 // px of the frame, uncertainty of the prediction
    bool from_gps = false;              // GPS motion (else the last frame-to-frame motion)
    cv::Point2d gps_px;                 // mosaic px of the GPS position (from_gps)
    double gps_tolerance_px = 0;        // frame px, largest believable disagreement with the GPS
  };
  // Matches the frame against the kept registered frames nearest to where it is expected (neighbour_frames).
  bool RegisterToNeighbours(const FrameFeatures& features, const std::optional<Prediction>& prediction,
                            MotionEstimate* motion, Similarity2* mosaic_from_frame, const Keyframe** matched,
                            std::string* why);
  void KeepNeighbour(const FrameFeatures& features, const Similarity2& mosaic_from_frame, int64_t utime);
  // The pose of a frame at `utime` from the GPS (when tied and a fix is at
  // that time) or from constant motion (the last two registered frames were consecutive).
  std::optional<Prediction> Predict(int64_t utime, cv::Size size) const;
  // GPS course (rad, ENU, counter-clockwise from east) arriving at the fix
  // nearest to utime, from the fix before it; nullopt when not moving.
  std::optional<double> GpsCourseAt(int64_t utime) const;
  // Learns the heading of the camera relative to the GPS course from a registered frame.
  void UpdateYawOffset(const Similarity2& mosaic_from_frame, int64_t utime);
  // GPS east/north (m) of the fix nearest to utime within geo.max_time_gap.
  std::optional<cv::Point2d> GpsEnuAt(int64_t utime, double* sigma = nullptr) const;
  // The evidence test: support, spread, agreement with the GPS position.
  bool Evidence(const MotionEstimate& motion, const Similarity2& mosaic_from_frame, const std::optional<Prediction>& p,
                std::string* why);
  // Height ratio frame / keyframe and the ground normal in the frame from
  // the homography keyframe -> frame; false when no decomposition is plausible.
  // The ground plane of homography H (reference frame -> this frame): this frame's height relative to the
  // reference's and the ground normal in this frame's camera.
  bool PlaneFromHomography(const cv::Matx33d& H, const Keyframe& reference, double* height_ratio,
                           cv::Vec3d* normal) const;
  double KeyframeOverlap(const Similarity2& key_to_cur, cv::Size size) const;
  void PairPendingFixes();
  void RefitTie();
  void FillRoute(FrameState* state);
  // Blends now, or queues for the worker (async_mosaic). Returns false when not done/queued.
  bool BlendOrQueue(const cv::Mat& frame, const Similarity2& S, FrameState* state);
  void WorkerLoop();
  void FlushMosaic();  // waits until the worker has blended what is queued
  // The whole canvas (after FlushMosaic) as BGRA; TiledCanvas::Export.
  bool ExportCanvas(cv::Mat* bgra, double* scale, cv::Point2d* origin, std::string* error);

  MosaickerOptions options_;
  Calibration calibration_;
  bool calibrated_ = false;
  double focal_ = 0;                       // px
  double metres_per_pixel_ = 0;            // mosaic m/px
  std::unique_ptr<TiledCanvas> canvas_;
  HeightFilter height_filter_;
  cv::Mat map1_, map2_;
  cv::Size map_size_;
  PinholeCamera camera_;                   // scaled to the incoming frame size
  bool camera_scaled_warned_ = false;

  std::optional<Keyframe> keyframe_;
  std::deque<Keyframe> neighbours_;        // the last neighbour_frames registered frames (RegisterToNeighbours)
  Similarity2 last_good_;                  // mosaic_from_frame of the last tracked frame
  double last_scale_ = 0;                  // its similarity scale
  std::optional<cv::Point2d> yaw_offset_;  // mean (cos, sin) of frame heading minus GPS course (ENU), registered frames
  cv::Vec3d ground_normal_{0, 0, 1};       // ground-plane normal in the last registered frame's camera frame
  std::optional<Similarity2> prev_good_;   // mosaic_from_frame of the tracked frame before last_good_ (consecutive)
  double last_painted_ = 1.0;              // covered fraction of the last mosaic view searched (RegisterToMosaic)
  int last_good_index_ = -1;               // frame index of last_good_
  std::optional<cv::Point2d> last_good_enu_;  // m, GPS east/north at last_good_'s time (when a fix was there)
  bool lost_ = false;
  int frames_since_blend_ = 0;
  int frames_since_reregister_ = 0;
  FrameState last_state_;
  MosaickerSummary summary_;
  int frame_counter_ = 0;

  // GPS
  std::optional<GpsFix> origin_fix_;
  double last_hag_ = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> marker_sides_, marker_heights_;       // calibration sightings being averaged
  int64_t last_fix_utime_ = INT64_MIN / 2;
  std::deque<GpsFix> pending_fixes_;
  std::deque<GpsFix> recent_fixes_;                       // last fixes, for predictions
  std::deque<std::pair<int64_t, cv::Point2d>> history_;   // utime, route_px of tracked frames
  std::deque<TiePair> pairs_;
  std::optional<Similarity2> enu_from_flipped_;           // (x, -y) mosaic px -> ENU m
  std::optional<Similarity2> local_tie_;                  // the same over the last geo.predict_window pairs
  // The tie for predictions: the local one when there is one.
  const Similarity2* PredictionTie() const;
  // Similarity over pairs_[first..] when their GPS spread is at least min_spread.
  bool FitTie(size_t first, Similarity2* tie, double* rms) const;
  double tie_rms_ = 0;
  std::vector<cv::Point2d> route_;                        // for the preview

  // async_mosaic: one queued job, a worker thread, the canvas behind a mutex.
  struct BlendJob {
    cv::Mat frame;
    Similarity2 mosaic_from_frame;
  };
  mutable std::mutex canvas_mutex_;     // guards canvas_ content
  mutable std::mutex job_mutex_;
  std::condition_variable job_cv_;
  std::optional<BlendJob> job_;
  bool worker_busy_ = false, stop_worker_ = false;
  int64_t async_blends_ = 0, async_dropped_ = 0;  // guarded by job_mutex_
  std::thread worker_;
};

// Local east/north (m) of a lat/lon relative to an origin (flat earth).
cv::Point2d LatLonToEnu(double lat, double lon, double lat0, double lon0);
void EnuToLatLon(const cv::Point2d& enu, double lat0, double lon0, double* lat, double* lon);

}  // namespace vloc::mosaic
