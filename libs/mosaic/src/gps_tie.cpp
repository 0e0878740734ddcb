#include "vloc/mosaic/gps_tie.h"

#include <glog/logging.h>

#include <algorithm>
#include <cmath>

#include "vloc/common/options.h"

namespace vloc::mosaic {

namespace {
constexpr double kEarthRadius = 6378137.0;
constexpr double kDeg = M_PI / 180.0;
}  // namespace

cv::Point2d LatLonToEnu(double lat, double lon, double lat0, double lon0) {
  return {(lon - lon0) * kDeg * kEarthRadius * std::cos(lat0 * kDeg), (lat - lat0) * kDeg * kEarthRadius};
}
void EnuToLatLon(const cv::Point2d& enu, double lat0, double lon0, double* lat, double* lon) {
  *lat = lat0 + enu.y / kEarthRadius / kDeg;
  *lon = lon0 + enu.x / (kEarthRadius * std::cos(lat0 * kDeg)) / kDeg;
}

void GeoOptions::Visit(OptionsReader& r) {
  r.Optional("min_fixes", &min_fixes, "fixes before the mosaic is tied to GPS", AtLeast(2));
  r.Optional("min_spread", &min_spread, "m, RMS spread of tied fixes", NonNegative());
  r.Optional("window_fixes", &window_fixes, "most recent pairs used in the tie");
  r.Optional("max_time_gap", &max_time_gap, "s, fix-to-frame pairing gap", Positive());
  r.Optional("gps_timeout", &gps_timeout, "s, after this without a fix the route is vision only", Positive());
  r.Optional("predict_window", &predict_window, "pairs of the local tie used for predictions (0 = the tie)",
             Is(0) || AtLeast(3));
  r.Relation("window_fixes", window_fixes >= min_fixes, "must be >= min_fixes");
}
bool GeoOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

bool GpsTie::AddFix(const GpsFix& fix) {
  if (!fix.valid || !std::isfinite(fix.latitude) || !std::isfinite(fix.longitude)) return false;
  if (!origin_fix_) origin_fix_ = fix;
  recent_fixes_.push_back(fix);
  if (!(recent_fixes_.back().horizontal_sigma > 0 && std::isfinite(recent_fixes_.back().horizontal_sigma)))
    recent_fixes_.back().horizontal_sigma = GpsFix().horizontal_sigma;  // unknown accuracy (NaN): the default
  while (recent_fixes_.size() > 64) recent_fixes_.pop_front();
  last_fix_utime_ = std::max(last_fix_utime_, fix.utime);
  pending_fixes_.push_back(fix);
  while (pending_fixes_.size() > 256) pending_fixes_.pop_front();
  PairPendingFixes();
  return true;
}

void GpsTie::AddRoutePoint(int64_t utime, const cv::Point2d& route_px) {
  history_.emplace_back(utime, route_px);
  while (history_.size() > 256) history_.pop_front();
}

cv::Point2d GpsTie::LastRoutePoint() const { return history_.empty() ? cv::Point2d(0, 0) : history_.back().second; }

const GpsFix* GpsTie::FixNear(int64_t utime) const {
  const GpsFix* fix = nullptr;
  const int64_t gap = static_cast<int64_t>(options_.max_time_gap * 1e6);
  for (const auto& f : recent_fixes_)
    if (std::llabs(f.utime - utime) <= gap && (!fix || std::llabs(f.utime - utime) < std::llabs(fix->utime - utime))) fix = &f;
  return fix;
}

std::optional<cv::Point2d> GpsTie::GpsEnuAt(int64_t utime, double* sigma) const {
  if (!origin_fix_) return std::nullopt;
  const GpsFix* fix = FixNear(utime);
  if (!fix) return std::nullopt;
  if (sigma) *sigma = fix->horizontal_sigma;
  return LatLonToEnu(fix->latitude, fix->longitude, origin_fix_->latitude, origin_fix_->longitude);
}

std::optional<double> GpsTie::GpsCourseAt(int64_t utime) const {
  if (!origin_fix_) return std::nullopt;
  const GpsFix* fix = FixNear(utime);
  const GpsFix* before = nullptr;
  for (const auto& f : recent_fixes_)
    if (fix && f.utime < fix->utime) before = &f;
  if (!fix || !before) return std::nullopt;
  const cv::Point2d d = LatLonToEnu(fix->latitude, fix->longitude, before->latitude, before->longitude);
  if (cv::norm(d) < 2 * fix->horizontal_sigma) return std::nullopt;
  return std::atan2(d.y, d.x);
}

// Heading of a frame's "up" (-y) in ENU = pi/2 - angle + tie angle (the tie maps (x, -y) mosaic px to ENU).
void GpsTie::UpdateYawOffset(const Similarity2& mosaic_from_frame, int64_t utime) {
  const Similarity2* tie = PredictionTie();
  if (!tie) return;
  const std::optional<double> course = GpsCourseAt(utime);
  if (!course) return;
  const double heading = M_PI / 2 - mosaic_from_frame.Angle() + tie->Angle();
  const cv::Point2d u(std::cos(heading - *course), std::sin(heading - *course));
  yaw_offset_ = yaw_offset_ ? 0.7 * *yaw_offset_ + 0.3 * u : u;
}

double GpsTie::PredictHeading(const GpsFix& fix, int64_t utime, const cv::Point2d& enu, double last_angle,
                              const Similarity2& tie) const {
  double angle = last_angle;
  const GpsFix* before = nullptr;
  const GpsFix* older = nullptr;
  for (const auto& f : recent_fixes_) {
    if (f.utime < fix.utime) {
      older = before;
      before = &f;
    }
  }
  const std::optional<double> course = GpsCourseAt(utime);
  if (course && yaw_offset_ && cv::norm(*yaw_offset_) > 0.5) {
    // The camera's heading relative to the course, learnt on registered frames (turns of a fixed wing).
    const double heading = *course + std::atan2(yaw_offset_->y, yaw_offset_->x);
    angle = M_PI / 2 + tie.Angle() - heading;
  } else if (before && older) {
    const cv::Point2d e0 = LatLonToEnu(older->latitude, older->longitude, origin_fix_->latitude, origin_fix_->longitude);
    const cv::Point2d e1 = LatLonToEnu(before->latitude, before->longitude, origin_fix_->latitude, origin_fix_->longitude);
    const cv::Point2d d0 = e1 - e0, d1 = enu - e1;
    if (cv::norm(d0) > 2 * fix.horizontal_sigma && cv::norm(d1) > 2 * fix.horizontal_sigma) {
      const double turn = std::atan2(d0.x * d1.y - d0.y * d1.x, d0.dot(d1));  // CCW in ENU = CW in mosaic px
      if (std::abs(turn) < M_PI / 3) angle -= turn;
    }
  }
  return angle;
}

std::optional<Prediction> GpsTie::Predict(int64_t utime, cv::Size size, const cv::Point2d& c, const LastPoses& poses,
                                          const PredictionGates& gates) const {
  const double scale = poses.last_good.Scale();
  const double width = static_cast<double>(size.width);
  // GPS: the fix nearest in time (within max_time_gap) mapped through the tie.
  const GpsFix* fix = FixNear(utime);
  const Similarity2* tie = PredictionTie();
  if (fix && tie && origin_fix_ && scale > 0) {
    const cv::Point2d enu = LatLonToEnu(fix->latitude, fix->longitude, origin_fix_->latitude, origin_fix_->longitude);
    const cv::Point2d flipped = tie->Inverse().Apply(enu);
    Prediction p;
    p.from_gps = true;
    p.gps_px = {flipped.x, -flipped.y};
    if (poses.last_good_enu) {
      // GPS motion since the last registered frame, from its registered centre
      // (the tie is a global fit: its local bias cancels in a difference).
      const Similarity2 lin{tie->a, tie->b, 0, 0};
      const cv::Point2d d = lin.Inverse().Apply(enu - *poses.last_good_enu);
      p.gps_px = poses.last_good.Apply(c) + cv::Point2d(d.x, -d.y);
    }
    // Heading: the last registered frame's, turned by the change of the GPS course.
    const double metres_per_frame_px = scale * std::abs(tie->Scale());
    const double angle = PredictHeading(*fix, utime, enu, poses.last_good.Angle(), *tie);
    p.mosaic_from_frame = Similarity2::FromScaleAngle(scale, angle, 0, 0);
    const cv::Point2d moved = p.mosaic_from_frame.Apply(c);
    p.mosaic_from_frame.tx = p.gps_px.x - moved.x;
    p.mosaic_from_frame.ty = p.gps_px.y - moved.y;
    const double sigma_px = fix->horizontal_sigma / std::max(1e-9, metres_per_frame_px);
    p.gate_px = gates.guide_gate * width + 3 * sigma_px;
    p.gps_tolerance_px = std::max(gates.gps_max_disagreement * width, 5 * sigma_px);
    return p;
  }
  // Constant motion: the last frame-to-frame motion once more.
  if (poses.prev_good) {
    Prediction p;
    p.mosaic_from_frame = poses.last_good * (poses.prev_good->Inverse() * poses.last_good);
    p.gate_px = 1.5 * gates.guide_gate * width;
    return p;
  }
  return std::nullopt;
}

std::optional<cv::Point2d> GpsTie::RouteAt(int64_t utime) const {
  const int64_t gap = static_cast<int64_t>(options_.max_time_gap * 1e6);
  for (size_t i = history_.size(); i-- > 0;) {
    if (history_[i].first > utime) continue;
    if (i + 1 < history_.size()) {
      const auto& a = history_[i];
      const auto& b = history_[i + 1];
      if (b.first - a.first <= 2 * gap) {
        const double w = b.first > a.first ? double(utime - a.first) / double(b.first - a.first) : 0.0;
        return a.second + w * (b.second - a.second);
      }
    } else if (utime - history_[i].first <= gap) {
      return history_[i].second;
    }
    return std::nullopt;
  }
  return std::nullopt;
}

void GpsTie::PairPendingFixes() {
  if (history_.empty() || !origin_fix_) return;
  bool added = false;
  while (!pending_fixes_.empty()) {
    const GpsFix& f = pending_fixes_.front();
    if (f.utime > history_.back().first) break;  // frames for this fix may still come
    if (const std::optional<cv::Point2d> p = RouteAt(f.utime)) {
      pairs_.push_back({*p, LatLonToEnu(f.latitude, f.longitude, origin_fix_->latitude, origin_fix_->longitude)});
      added = true;
    }
    pending_fixes_.pop_front();
  }
  while (static_cast<int>(pairs_.size()) > options_.window_fixes) pairs_.pop_front();
  if (added) RefitTie();
}

bool GpsTie::FitTie(size_t first, Similarity2* tie, double* rms) const {
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
  if (spread < options_.min_spread) return false;
  return FitSimilarity(from, to, tie, rms);
}

const Similarity2* GpsTie::PredictionTie() const {
  if (local_tie_) return &*local_tie_;
  return enu_from_flipped_ ? &*enu_from_flipped_ : nullptr;
}

void GpsTie::RefitTie() {
  if (static_cast<int>(pairs_.size()) < options_.min_fixes) return;
  Similarity2 T;
  double rms = 0;
  if (FitTie(0, &T, &rms)) {
    if (!enu_from_flipped_) LOG(INFO) << "mosaic tied to GPS: " << pairs_.size() << " fixes, rms " << rms << " m";
    enu_from_flipped_ = T;
    tie_rms_ = rms;
  }
  const int w = options_.predict_window;
  if (w > 0 && static_cast<int>(pairs_.size()) >= std::min(w, options_.min_fixes)) {
    Similarity2 L;
    const size_t first = pairs_.size() > static_cast<size_t>(w) ? pairs_.size() - w : 0;
    if (FitTie(first, &L, nullptr)) local_tie_ = L;
  }
}

cv::Point2d GpsTie::MosaicToLocal(const cv::Point2d& p, double metres_per_pixel) const {
  if (enu_from_flipped_) return enu_from_flipped_->Apply({p.x, -p.y});
  // Not tied: the first frame's image up is taken as north.
  return {p.x * metres_per_pixel, -p.y * metres_per_pixel};
}

bool GpsTie::MosaicToLatLon(const cv::Point2d& mosaic_px, cv::Point2d* lat_lon) const {
  if (!enu_from_flipped_ || !origin_fix_) return false;
  EnuToLatLon(enu_from_flipped_->Apply({mosaic_px.x, -mosaic_px.y}), origin_fix_->latitude, origin_fix_->longitude,
              &lat_lon->x, &lat_lon->y);
  return true;
}

}  // namespace vloc::mosaic
