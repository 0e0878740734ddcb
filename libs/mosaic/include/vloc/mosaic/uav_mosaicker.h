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
//
// ProcessFrame is a table of contents over one FrameWork (uav_mosaicker.cpp):
// decode and undistort, calibrate (CalibrationStep, first frames), detect,
// start the mosaic (first frame), predict (GpsTie), register (the ranked
// candidates of registration.h: keyframe, guided, neighbours, finer, mosaic; on
// failure PlaceByGps), refine against the mosaic, ground plane, height,
// keyframe, route and GPS tie, blend (MosaicBlender).

#include <opencv2/core.hpp>

#include <chrono>
#include <cstdint>
#include <deque>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/mosaic/calibration.h"
#include "vloc/mosaic/calibration_step.h"
#include "vloc/mosaic/frame_matcher.h"
#include "vloc/mosaic/geometry.h"
#include "vloc/mosaic/gps_tie.h"
#include "vloc/mosaic/height_filter.h"
#include "vloc/mosaic/height_graph.h"
#include "vloc/mosaic/lens_search.h"
#include "vloc/mosaic/mosaic_blender.h"
#include "vloc/mosaic/registration.h"
#include "vloc/mosaic/tiled_canvas.h"

namespace vloc {
class OptionsReader;
}

namespace vloc::mosaic {

struct MosaickerOptions {
  PinholeCamera camera;                 // intrinsics and distortion of the nadir camera
  CalibrationOptions calibration;       // sec. 2.1
  MatcherOptions matcher;               // sec. 2.2, eqs. 2-3
  HeightFilterOptions height_filter;    // smoothing of eqs. 4-5, GPS fusion option
  HeightGraphOptions height_graph;      // heights tied to earlier overlapping frames, not only the chain (stills)
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
  bool reseat_by_gps = false;           // a frame no image registers, where the mosaic holds nothing at its GPS
                                        // position (new ground), is placed there and becomes the keyframe (reported
                                        // LOST, not registered), so the next frame re-acquires
  double reseat_after_gap_s = 0;        // s: likewise for a frame taken this long after the last registered one (the
                                        // next flight of a survey folder: new ground, another start point), even
                                        // with reseat_by_gps false; 0 = off
  int neighbour_frames = 0;             // registered frames whose features are kept (most recent first): a frame the
                                        // keyframe does not register is matched against the nearest of them (the
                                        // neighbour on the adjacent strip of a survey, the frame before a bad one)
  double fallback_downscale = 0.0;      // a frame the candidates above miss at matcher.downscale is matched against the
                                        // keyframe again with features at this finer level (1 = full resolution: the
                                        // detector runs on a reduced level, the full one only when needed); 0 = off
  int fallback_frames = 2;              // the last registered frames also tried at the finer level (images kept)
  int neighbour_tries = 3;              // nearest kept frames (by predicted position) tried, within one frame width
  int num_threads = 2;                  // OpenCV threads (A-KAZE, matching, warping)
  bool async_mosaic = false;            // blend on a worker thread (real time: tracking never waits; a frame due while
                                        // the worker is busy replaces the queued one). false = blend inside ProcessFrame
  int async_mosaic_queue = 0;           // async_mosaic: 0 = as above (video); n > 0 = up to n frames wait, none dropped,
                                        // registration against the mosaic waits for them (stills: the same mosaic)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
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
  double features_seconds = 0;          // s, of which features (0 when the frame was prepared ahead: FramePreparer)
  double mosaic_seconds = 0;            // s, blending (0 when not blended or async_mosaic)
};

struct MosaickerSummary {
  int frames = 0, tracked = 0, lost = 0, recoveries = 0, keyframes = 0, blends = 0;
  int reregistrations = 0;              // frames whose pose came from a periodic registration against the mosaic
  int reregistrations_rejected = 0;     // such registrations that failed or disagreed too much with the chain
  int guided = 0;                       // frames registered by guided matching
  int gps_rejections = 0;               // registrations rejected because they disagreed with the GPS motion
  int reseats = 0;                      // frames placed by GPS after every registration failed
  int height_ties = 0;                  // height ties to earlier overlapping frames added (height_graph)
  int height_ties_dropped = 0;          // of the ties, dropped as outliers of the solution
  double height_tie_rms = 0;            // RMS of the kept links' and ties' residuals, in their sigmas
  std::string last_problem;
  Calibration calibration;
  double metres_per_pixel = 0;          // mosaic ground resolution
  bool georeferenced = false;
  double tie_rms = 0;                   // m, residual of the GPS tie
  int tie_pairs = 0;
  double blend_seconds = 0;             // s, blending (on the worker too)
  CanvasStats canvas;
  std::string BriefReport() const;
};

// A frame decoded, undistorted and with its features: what ProcessFrame does
// before registration, done ahead (e.g. on another thread while the previous
// frame registers) by a FramePreparer and handed to ProcessFrame.
struct PreparedFrame {
  bool usable = false;                  // 8-bit gray or BGR, not empty
  cv::Mat frame;                        // undistorted
  PinholeCamera camera;                 // the camera scaled to the frame size
  FrameFeatures features;
  double seconds = 0;                   // s, undistortion + features
};

// Prepares frames as the mosaicker with the same options would; one thread at a time.
class FramePreparer {
 public:
  explicit FramePreparer(const MosaickerOptions& options)
      : undistorter_(options.camera), matcher_(options.matcher) {}
  PreparedFrame Prepare(const cv::Mat& image);

 private:
  FrameUndistorter undistorter_;
  MatcherOptions matcher_;
};

class UavMosaicker {
 public:
  explicit UavMosaicker(const MosaickerOptions& options);
  ~UavMosaicker();

  // One frame (BGR or gray, raw: undistorted here). Never throws on bad
  // input: an empty frame gives status LOST with a message.
  FrameState ProcessFrame(const cv::Mat& image, int64_t utime);
  // The same for a frame prepared ahead (FramePreparer with these options): same result.
  FrameState ProcessFrame(PreparedFrame frame, int64_t utime);
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
  // A registered frame's height (m) from the height graph as solved now (all
  // ties so far), by its FrameState::frame_index; none when height_graph.ties
  // is 0 or the frame is not in the graph.
  std::optional<double> AdjustedHeight(int frame_index) const;
  // The height graph solved over every frame, when its solves have held older frames fixed (a survey longer than
  // height_graph.window): the final heights. Nothing otherwise.
  void FinishHeights();
  // From now on every height link and tie is kept with its matched points, for SearchRadialDistortion
  // (lens_search.h); null before this is called.
  void KeepHeightObservations() { observations_.emplace(); }
  const HeightObservations* height_observations() const { return observations_ ? &*observations_ : nullptr; }
  // Waits until queued blends are done (async_mosaic).
  void FlushMosaic() { blender_.Flush(); }
  // Forces calibration (e.g. from a tool that knows height and focal).
  void SetCalibration(const Calibration& calibration);

 private:
  // One frame on its way through ProcessFrame.
  struct FrameWork {
    int64_t utime = 0;
    std::chrono::steady_clock::time_point t0;
    cv::Mat frame;                          // undistorted
    FrameFeatures features;
    bool detected = false;                  // features already there (prepared ahead)
    std::optional<Prediction> prediction;   // where the frame is expected (GPS or motion)
    Registration registration;              // the candidate that registered it (or the keyframe attempt's counts)
    const char* registered_by = nullptr;    // that candidate's name ("keyframe", ...), null when none did
    std::string why;                        // the failed candidates' reasons, "; "-separated
    bool reregistered = false;              // the pose was refined against the mosaic
    bool plane_ok = false;                  // the ground plane came from the homography
    bool was_lost = false;                  // the previous frame was not registered
    bool new_keyframe = false;
    FrameState state;
  };
  // A ranked registration candidate (registration.h).
  struct Candidate {
    const char* name;                                   // for messages and the summary
    Registration (*run)(const RegistrationInput&, const MosaickerOptions&);
    int MosaickerSummary::*registered_count;            // bumped when it registers a frame (nullptr: none)
  };
  static const std::vector<Candidate>& Candidates();

  // The steps of ProcessFrame, in order.
  FrameState Process(FrameWork* w);
  FrameWork BeginFrame(int64_t utime);
  bool Decode(const cv::Mat& image, FrameWork* w);
  bool RejectUnusable(FrameWork* w);
  bool Calibrate(FrameWork* w);
  void Detect(FrameWork* w);
  void StartMosaic(FrameWork* w);
  void PredictPose(FrameWork* w);
  bool Register(FrameWork* w);
  void RefinePose(FrameWork* w);
  void MarkLost(FrameWork* w);
  void MarkRegistered(FrameWork* w);
  void EstimateGroundPlane(FrameWork* w);
  void TieHeights(FrameWork* w);  // height_ties.cpp
  void EstimateHeight(FrameWork* w);
  void UpdateKeyframe(FrameWork* w);
  void TieRouteToGps(FrameWork* w);
  void Blend(FrameWork* w);
  FrameState Finish(FrameWork* w);

  RegistrationInput InputFor(const FrameWork& w) const;
  std::vector<const Keyframe*> FramesToTie(const FrameWork& w) const;
  std::optional<HeightObservation> HeightRatioTo(const Keyframe& earlier, const FrameWork& w) const;
  HeightObservation RegistrationLink(const FrameWork& w, double log_ratio) const;
  std::optional<double> GraphScale(int frame_index) const;
  cv::Point2d PrincipalPoint() const;
  // The keyframe's image, for the finer-level candidate (fallback_downscale).
  void KeepImageForFinerLevel(const cv::Mat& frame);
  void KeepNeighbour(const FrameFeatures& features, const Similarity2& mosaic_from_frame, int64_t utime, int frame_index);
  void FillRoute(FrameState* state);

  MosaickerOptions options_;
  Calibration calibration_;
  bool calibrated_ = false;
  double focal_ = 0;                       // px
  double metres_per_pixel_ = 0;            // mosaic m/px
  CalibrationStep calibration_step_;
  FrameUndistorter undistorter_;
  HeightFilter height_filter_;
  HeightGraph heights_;                    // log scales of the registered frames and their ties (height_graph.ties)
  std::optional<HeightObservations> observations_;  // the graph's links and ties with their points (when kept)
  GpsTie gps_;
  MosaicBlender blender_;

  std::optional<Keyframe> keyframe_;
  std::deque<Keyframe> neighbours_;        // the last neighbour_frames registered frames (RegisterToNeighbours)
  std::deque<Keyframe> recent_;            // the last fallback_frames registered frames with images (RegisterAtFinerLevel)
  LastPoses last_;                         // the last registered frames' poses (predictions start there)
  double last_scale_ = 0;                  // the last registered frame's similarity scale
  cv::Vec3d ground_normal_{0, 0, 1};       // ground-plane normal in the last registered frame's camera frame
  int last_good_index_ = -1;               // frame index of last_.last_good
  int64_t last_good_utime_ = 0;            // us, its time
  bool lost_ = false;
  int frames_since_blend_ = 0;
  int frames_since_reregister_ = 0;
  FrameState last_state_;
  MosaickerSummary summary_;
  int frame_counter_ = 0;
  double last_hag_ = std::numeric_limits<double>::quiet_NaN();  // m, latest GPS height above ground
  std::vector<cv::Point2d> route_;         // for the preview
};

}  // namespace vloc::mosaic
