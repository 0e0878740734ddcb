#include "vloc/lcm_io/convert_rover.h"

#include "vloc/lcm_io/convert_image.h"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <stdexcept>
#include <string>

namespace vloc {

namespace {

cv::Mat ToGray(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat gray;
  cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  return gray;
}

void RequireFinite(double v, const std::string& what) {
  if (!std::isfinite(v)) throw std::invalid_argument(what + " is not finite");
}

}  // namespace

stereo_image_t StereoPairToMessage(const StereoPair& pair, ImageEncoding encoding) {
  stereo_image_t msg;
  msg.utime = pair.utime;
  msg.site_id = pair.site_id;
  msg.pair_index = pair.pair_index;
  msg.num_pairs = pair.num_pairs;
  msg.mast_pan = pair.mast_pan;
  msg.mast_tilt = pair.mast_tilt;
  msg.left = ImageToMessage(pair.left, encoding, pair.utime, "navcam_left");
  msg.right = ImageToMessage(pair.right, encoding, pair.utime, "navcam_right");
  return msg;
}

StereoPair StereoPairFromMessage(const stereo_image_t& msg) { return StereoPairFromMessage(msg, ImageLimits()); }

void CheckStereoPairIndex(const stereo_image_t& msg) {
  const std::string who = "stereo pair " + std::to_string(msg.pair_index) + " of site " + std::to_string(msg.site_id);
  if (msg.site_id < 0) throw std::invalid_argument(who + ": negative site id");
  if (msg.num_pairs <= 0 || msg.num_pairs > kMaxPairsPerSite || msg.pair_index < 0 || msg.pair_index >= msg.num_pairs)
    throw std::invalid_argument(who + ": pair_index must be in [0, num_pairs) and num_pairs in [1, " +
                                std::to_string(kMaxPairsPerSite) + "] (num_pairs " + std::to_string(msg.num_pairs) +
                                ")");
}

StereoPair StereoPairFromMessage(const stereo_image_t& msg, const ImageLimits& limits) {
  CheckStereoPairIndex(msg);
  const std::string who = "stereo pair " + std::to_string(msg.pair_index) + " of site " + std::to_string(msg.site_id);
  RequireFinite(msg.mast_pan, who + ": mast_pan");
  RequireFinite(msg.mast_tilt, who + ": mast_tilt");
  StereoPair pair;
  pair.utime = msg.utime;
  pair.site_id = msg.site_id;
  pair.pair_index = msg.pair_index;
  pair.num_pairs = msg.num_pairs;
  pair.mast_pan = msg.mast_pan;
  pair.mast_tilt = msg.mast_tilt;
  try {
    pair.left = ToGray(ImageFromMessage(msg.left, limits));
    pair.right = ToGray(ImageFromMessage(msg.right, limits));
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(who + ": " + e.what());
  }
  if (pair.left.size() != pair.right.size())
    throw std::invalid_argument(who + ": left and right images differ in size");
  return pair;
}

imu_t ImuToMessage(const ImuSample& s) {
  imu_t msg;
  msg.utime = s.utime;
  for (int i = 0; i < 3; ++i) {
    msg.angular_velocity[i] = s.angular_velocity[i];
    msg.linear_acceleration[i] = s.linear_acceleration[i];
  }
  return msg;
}

ImuSample ImuFromMessage(const imu_t& msg) {
  ImuSample s;
  s.utime = msg.utime;
  for (int i = 0; i < 3; ++i) {
    s.angular_velocity[i] = msg.angular_velocity[i];
    s.linear_acceleration[i] = msg.linear_acceleration[i];
  }
  if (!s.angular_velocity.allFinite() || !s.linear_acceleration.allFinite())
    throw std::invalid_argument("IMU sample at " + std::to_string(msg.utime) + " us is not finite");
  return s;
}

wheel_odometry_t WheelOdometryToMessage(const WheelOdometrySample& s) {
  wheel_odometry_t msg;
  msg.utime = s.utime;
  msg.distance = s.distance;
  msg.speed = s.speed;
  return msg;
}

WheelOdometrySample WheelOdometryFromMessage(const wheel_odometry_t& msg) {
  RequireFinite(msg.distance, "wheel odometry distance");
  RequireFinite(msg.speed, "wheel odometry speed");
  return {msg.utime, msg.distance, msg.speed};
}

site_event_t SiteEventToMessage(const SiteEvent& e) {
  site_event_t msg;
  msg.utime = e.utime;
  msg.site_id = e.site_id;
  msg.event = static_cast<int8_t>(e.event);
  msg.num_pairs = e.num_pairs;
  return msg;
}

SiteEvent SiteEventFromMessage(const site_event_t& msg) {
  if (msg.event < 0 || msg.event > 2)
    throw std::invalid_argument("site event " + std::to_string(int(msg.event)) + " is not ARRIVED, IMAGING_DONE or DEPARTED");
  if (msg.site_id < 0) throw std::invalid_argument("site event with negative site id");
  if (msg.num_pairs < 0 || msg.num_pairs > kMaxPairsPerSite)
    throw std::invalid_argument("site event of site " + std::to_string(msg.site_id) + ": num_pairs " +
                                std::to_string(msg.num_pairs) + " outside [0, " + std::to_string(kMaxPairsPerSite) +
                                "]");
  return {msg.utime, msg.site_id, static_cast<SiteEventType>(msg.event), msg.num_pairs};
}

tie_points_t TiePointsToMessage(const TiePointSet& set) {
  tie_points_t msg;
  msg.utime = set.utime;
  msg.previous_site_id = set.previous_site_id;
  msg.current_site_id = set.current_site_id;
  msg.previous_site_pose = SitePoseToMessage(set.previous_site_id, site_pose_t::SOURCE_DEAD_RECKONING,
                                             set.previous_site_pose);
  msg.current_site_pose_dr = SitePoseToMessage(set.current_site_id, site_pose_t::SOURCE_DEAD_RECKONING,
                                               set.current_site_pose_dr);
  msg.num_previous_pairs = static_cast<int32_t>(set.previous_pointing.size());
  for (const auto& p : set.previous_pointing) {
    msg.previous_mast_pan.push_back(p.pan);
    msg.previous_mast_tilt.push_back(p.tilt);
  }
  msg.num_current_pairs = static_cast<int32_t>(set.current_pointing.size());
  for (const auto& p : set.current_pointing) {
    msg.current_mast_pan.push_back(p.pan);
    msg.current_mast_tilt.push_back(p.tilt);
  }
  msg.num_points = static_cast<int32_t>(set.points.size());
  for (const auto& tp : set.points) {
    tie_point_t m;
    m.id = tp.id;
    for (int i = 0; i < 3; ++i) {
      m.p_previous[i] = tp.p_previous[i];
      m.p_current[i] = tp.p_current[i];
    }
    m.weight = tp.weight;
    m.num_observations = static_cast<int32_t>(tp.observations.size());
    for (const auto& o : tp.observations) {
      tie_observation_t mo;
      mo.site_role = static_cast<int8_t>(o.site);
      mo.pair_index = o.pair_index;
      mo.camera = static_cast<int8_t>(o.camera);
      mo.u = o.uv.x();
      mo.v = o.uv.y();
      mo.sigma = o.sigma;
      m.observations.push_back(mo);
    }
    msg.points.push_back(std::move(m));
  }
  return msg;
}

TiePointSet TiePointsFromMessage(const tie_points_t& msg) {
  TiePointSet set;
  set.utime = msg.utime;
  set.previous_site_id = msg.previous_site_id;
  set.current_site_id = msg.current_site_id;
  set.previous_site_pose = PoseFromMessage(msg.previous_site_pose.pose);
  set.current_site_pose_dr = PoseFromMessage(msg.current_site_pose_dr.pose);
  for (int i = 0; i < msg.num_previous_pairs; ++i)
    set.previous_pointing.push_back({msg.previous_mast_pan[i], msg.previous_mast_tilt[i]});
  for (int i = 0; i < msg.num_current_pairs; ++i)
    set.current_pointing.push_back({msg.current_mast_pan[i], msg.current_mast_tilt[i]});
  for (const auto& m : msg.points) {
    TiePoint tp;
    tp.id = m.id;
    tp.p_previous = Eigen::Vector3d(m.p_previous[0], m.p_previous[1], m.p_previous[2]);
    tp.p_current = Eigen::Vector3d(m.p_current[0], m.p_current[1], m.p_current[2]);
    tp.weight = m.weight;
    for (const auto& mo : m.observations) {
      const int pairs = mo.site_role == tie_observation_t::SITE_PREVIOUS ? msg.num_previous_pairs : msg.num_current_pairs;
      if ((mo.site_role != 0 && mo.site_role != 1) || (mo.camera != 0 && mo.camera != 1) || mo.pair_index < 0 ||
          mo.pair_index >= pairs || !std::isfinite(mo.u) || !std::isfinite(mo.v) || !(mo.sigma > 0))
        throw std::invalid_argument("tie point " + std::to_string(m.id) +
                                    ": observation with bad site, camera, pair index, pixel or sigma");
      TieObservation o;
      o.site = static_cast<SiteRole>(mo.site_role);
      o.pair_index = mo.pair_index;
      o.camera = static_cast<CameraSide>(mo.camera);
      o.uv = Eigen::Vector2d(mo.u, mo.v);
      o.sigma = mo.sigma;
      tp.observations.push_back(o);
    }
    set.points.push_back(std::move(tp));
  }
  return set;
}

}  // namespace vloc
