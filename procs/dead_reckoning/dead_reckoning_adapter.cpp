#include "dead_reckoning_adapter.h"

#include <sstream>

#include "vloc/common/options.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"

namespace vloc {

void DeadReckoningProcOptions::Visit(OptionsReader& r) {
  r.Optional("imu_channel", &imu_channel, "imu_t in", NonEmpty());
  r.Optional("wheel_channel", &wheel_channel, "wheel_odometry_t in", NonEmpty());
  r.Optional("site_channel", &site_channel, "site_event_t in", NonEmpty());
  r.Optional("pose_channel", &pose_channel, "pose_t out, periodic", NonEmpty());
  r.Optional("site_pose_channel", &site_pose_channel, "site_pose_t out, per site", NonEmpty());
  r.Optional("start_pose_channel", &start_pose_channel, "site_pose_t in: site 0 sets the start; empty = off");
  r.Optional("queue_capacity", &queue_capacity, "messages per subscription queue", AtLeast(1));
  r.Child("dead_reckoning", [&](OptionsReader& c) { dead_reckoning.Visit(c); });
}

bool DeadReckoningProcOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

DeadReckoningAdapter::DeadReckoningAdapter(Transport& transport, const DeadReckoningProcOptions& options)
    : transport_(transport), options_(options), estimator_(options.dead_reckoning) {
  imu_stats_ = Subscribe<imu_t>(
      transport_, options_.imu_channel,
      [this](const std::string&, const imu_t& msg) {
        estimator_.AddImu(ImuFromMessage(msg));
        PublishReady();
      },
      options_.queue_capacity);
  wheel_stats_ = Subscribe<wheel_odometry_t>(
      transport_, options_.wheel_channel,
      [this](const std::string&, const wheel_odometry_t& msg) {
        estimator_.AddWheel(WheelOdometryFromMessage(msg));
        PublishReady();
      },
      options_.queue_capacity);
  site_stats_ = Subscribe<site_event_t>(
      transport_, options_.site_channel,
      [this](const std::string&, const site_event_t& msg) {
        estimator_.AddSiteEvent(SiteEventFromMessage(msg));
        PublishReady();
      },
      options_.queue_capacity);
  if (!options_.start_pose_channel.empty()) {
    start_stats_ = Subscribe<site_pose_t>(
        transport_, options_.start_pose_channel,
        [this](const std::string&, const site_pose_t& msg) {
          if (msg.site_id != 0 || start_pose_set_) return;
          start_pose_set_ = estimator_.SetStartPose(PoseFromMessage(msg.pose).pose);
          if (!start_pose_set_) start_pose_set_ = true;  // too late: do not try again
        },
        options_.queue_capacity);
  }
}

void DeadReckoningAdapter::PublishReady() {
  while (auto pose = estimator_.PopPeriodicPose()) {
    if (Publish(transport_, options_.pose_channel, PoseToMessage(*pose, "world", "body"))) ++published_poses_;
  }
  for (const auto& [site, pose] : estimator_.PopSitePoses()) {
    if (Publish(transport_, options_.site_pose_channel,
                SitePoseToMessage(site, site_pose_t::SOURCE_DEAD_RECKONING, pose))) {
      ++published_sites_;
      LOG(INFO) << "site " << site << ": dead-reckoning pose (" << pose.pose.translation().transpose()
                << ") m, heading " << Heading(pose.pose) << " rad, position sigma "
                << std::sqrt(pose.covariance.block<3, 3>(0, 0).trace()) << " m after "
                << estimator_.stats().distance_m << " m";
    }
  }
}

std::string DeadReckoningAdapter::StatusLine() const {
  const DeadReckoningStats& s = estimator_.stats();
  std::ostringstream o;
  o << "imu used " << s.imu_used << ", dropped " << s.imu_dropped << ", gaps " << s.imu_gaps << "; wheel used "
    << s.wheel_used << ", dropped " << s.wheel_dropped << ", odometer resets " << s.odometer_resets
    << "; gravity updates " << s.gravity_updates << "; restarts " << s.resets << "; duplicate arrivals "
    << s.site_events_dropped << "; implausible samples rejected " << s.implausible << ", time outliers "
    << s.time_outliers << "; distance " << s.distance_m << " m; published " << published_poses_
    << " poses, " << published_sites_ << " site poses; "
    << SubscriptionSummary({imu_stats_, wheel_stats_, site_stats_, start_stats_});
  return o.str();
}

}  // namespace vloc
