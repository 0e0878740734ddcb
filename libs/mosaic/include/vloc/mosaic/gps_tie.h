#pragma once
// The mosaic's tie to GPS and the prediction of where the next frame lands.
//
//   GpsTie tie(options.geo);
//   tie.AddFix(fix);                          // whenever a fix arrives
//   tie.AddRoutePoint(utime, route_px);       // each registered frame's route point
//   tie.PairPendingFixes();                   // pairs fixes with the route, refits the tie
//   std::optional<Prediction> p = tie.Predict(utime, frame_size, last_poses, ...);
//
// The tie is a similarity from (x, -y) mosaic px to local east/north metres of
// the first fix, fitted to the fixes paired with the route (interpolated at
// the fix times). A local tie over the last geo.predict_window pairs serves
// predictions (robust to a chain whose scale drifts).

#include <opencv2/core.hpp>

#include <cstdint>
#include <deque>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "vloc/mosaic/geometry.h"

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

struct GpsFix {
  int64_t utime = 0;                    // us
  bool valid = false;                   // has a horizontal fix
  double latitude = 0, longitude = 0;   // deg
  double altitude = 0;                  // m, ellipsoid
  double height_above_ground = std::numeric_limits<double>::quiet_NaN();  // m, NaN when unknown
  double horizontal_sigma = 2.0;        // m
  double vertical_sigma = 3.0;          // m
};

// Where a frame is expected in the mosaic.
struct Prediction {
  Similarity2 mosaic_from_frame;      // predicted pose of the new frame
  double gate_px = 0;                 // px of the frame, uncertainty of the prediction
  bool from_gps = false;              // GPS motion (else the last frame-to-frame motion)
  cv::Point2d gps_px;                 // mosaic px of the GPS position (from_gps)
  double gps_tolerance_px = 0;        // frame px, largest believable disagreement with the GPS
};

// The poses a prediction starts from: the last registered frame's, the one
// before it when the two were consecutive frames, and the GPS position at the
// last one's time.
struct LastPoses {
  Similarity2 last_good;                     // mosaic_from_frame of the last registered frame
  std::optional<Similarity2> prev_good;      // of the registered frame before it (consecutive frames only)
  std::optional<cv::Point2d> last_good_enu;  // m, GPS east/north at last_good's time
};

// How far a prediction may be off (MosaickerOptions::guide_gate, gps_max_disagreement).
struct PredictionGates {
  double guide_gate = 0.12;            // fraction of the frame width (plus 3 GPS sigmas)
  double gps_max_disagreement = 0.35;  // fraction of the frame width (or 5 GPS sigmas)
};

class GpsTie {
 public:
  explicit GpsTie(const GeoOptions& options) : options_(options) {}

  // A fix without a valid horizontal position is ignored (returns false).
  bool AddFix(const GpsFix& fix);
  // The route point (mosaic px) of a registered frame at utime.
  void AddRoutePoint(int64_t utime, const cv::Point2d& route_px);
  // The route point last added ((0, 0) before any).
  cv::Point2d LastRoutePoint() const;
  // Pairs the fixes received so far with the route (interpolated at the fix
  // time) and refits the tie when pairs were added.
  void PairPendingFixes();

  // The pose of a frame at `utime` from the GPS (when tied and a fix is at
  // that time) or from constant motion (prev_good set); nullopt otherwise.
  // `principal_point`: frame px of the principal point.
  std::optional<Prediction> Predict(int64_t utime, cv::Size size, const cv::Point2d& principal_point,
                                    const LastPoses& poses, const PredictionGates& gates) const;
  // Learns the heading of the camera relative to the GPS course from a registered frame.
  void UpdateYawOffset(const Similarity2& mosaic_from_frame, int64_t utime);
  // GPS east/north (m) of the fix nearest to utime within geo.max_time_gap.
  std::optional<cv::Point2d> GpsEnuAt(int64_t utime, double* sigma = nullptr) const;
  // GPS course (rad, ENU, counter-clockwise from east) arriving at the fix
  // nearest to utime, from the fix before it; nullopt when not moving.
  std::optional<double> GpsCourseAt(int64_t utime) const;

  bool tied() const { return enu_from_flipped_.has_value(); }
  // (x, -y) mosaic px -> ENU m (tied() only).
  const std::optional<Similarity2>& enu_from_flipped() const { return enu_from_flipped_; }
  const std::optional<GpsFix>& origin() const { return origin_fix_; }
  int64_t last_fix_utime() const { return last_fix_utime_; }
  double tie_rms() const { return tie_rms_; }
  int tie_pairs() const { return static_cast<int>(pairs_.size()); }
  // Local ENU east/north (m) of a mosaic pixel: through the tie, else the
  // first frame's image up taken as north at metres_per_pixel.
  cv::Point2d MosaicToLocal(const cv::Point2d& mosaic_px, double metres_per_pixel) const;
  // WGS84 lat/lon (deg, as x = lat, y = lon) of a mosaic pixel; false when not tied.
  bool MosaicToLatLon(const cv::Point2d& mosaic_px, cv::Point2d* lat_lon) const;

 private:
  struct TiePair {
    cv::Point2d mosaic_px;
    cv::Point2d enu;
  };
  // The fix nearest to utime within geo.max_time_gap, or null.
  const GpsFix* FixNear(int64_t utime) const;
  // The tie for predictions: the local one when there is one.
  const Similarity2* PredictionTie() const;
  // Similarity over pairs_[first..] when their GPS spread is at least min_spread.
  bool FitTie(size_t first, Similarity2* tie, double* rms) const;
  void RefitTie();
  // The route point at a fix's time, interpolated between registered frames.
  std::optional<cv::Point2d> RouteAt(int64_t utime) const;
  // The predicted heading (mosaic angle) at a fix: the GPS course and the learnt yaw offset, else the last
  // registered frame's heading turned by the change of course.
  double PredictHeading(const GpsFix& fix, int64_t utime, const cv::Point2d& enu, double last_angle,
                        const Similarity2& tie) const;

  GeoOptions options_;
  std::optional<GpsFix> origin_fix_;
  int64_t last_fix_utime_ = INT64_MIN / 2;
  std::deque<GpsFix> pending_fixes_;
  std::deque<GpsFix> recent_fixes_;                       // last fixes, for predictions
  std::deque<std::pair<int64_t, cv::Point2d>> history_;   // utime, route_px of registered frames
  std::deque<TiePair> pairs_;
  std::optional<Similarity2> enu_from_flipped_;           // (x, -y) mosaic px -> ENU m
  std::optional<Similarity2> local_tie_;                  // the same over the last geo.predict_window pairs
  std::optional<cv::Point2d> yaw_offset_;  // mean (cos, sin) of frame heading minus GPS course (ENU), registered frames
  double tie_rms_ = 0;
};

// Local east/north (m) of a lat/lon relative to an origin (flat earth).
cv::Point2d LatLonToEnu(double lat, double lon, double lat0, double lon0);
void EnuToLatLon(const cv::Point2d& enu, double lat0, double lon0, double* lat, double* lon);

}  // namespace vloc::mosaic
