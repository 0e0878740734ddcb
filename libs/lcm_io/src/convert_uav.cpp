#include "vloc/lcm_io/convert_uav.h"

#include <cmath>

namespace vloc {

uav_state_t StateToMessage(const mosaic::FrameState& s) {
  uav_state_t m;
  m.utime = s.utime;
  m.frame_index = s.frame_index;
  m.status = static_cast<int8_t>(s.status);
  m.message = s.message;
  m.height = s.height;
  m.height_raw = s.height_raw;
  m.scale = s.scale;
  m.route_px[0] = s.route_px.x;
  m.route_px[1] = s.route_px.y;
  m.route_local[0] = s.route_local.x;
  m.route_local[1] = s.route_local.y;
  m.latitude = s.latitude;
  m.longitude = s.longitude;
  m.gps_aided = s.gps_aided ? 1 : 0;
  m.num_matches = s.num_matches;
  m.num_inliers = s.num_inliers;
  m.num_foreground = s.num_foreground;
  m.tracking_seconds = s.tracking_seconds;
  return m;
}

mosaic::GpsFix GpsFromMessage(const uav_gps_t& msg) {
  mosaic::GpsFix f;
  f.utime = msg.utime;
  f.valid = msg.fix != uav_gps_t::FIX_NONE && std::isfinite(msg.latitude) && std::isfinite(msg.longitude);
  f.latitude = msg.latitude;
  f.longitude = msg.longitude;
  f.altitude = msg.altitude;
  f.height_above_ground = msg.height_above_ground;
  f.horizontal_sigma = msg.horizontal_sigma;
  f.vertical_sigma = msg.vertical_sigma;
  return f;
}

}  // namespace vloc
