#pragma once
// LCM side of dead reckoning: IMU, WHEEL_ODOM and ROVER_SITE in; DR_POSE
// (pose_t, every publish_period_s of message time) and SITE_POSE_DR
// (site_pose_t, source DEAD_RECKONING, at every ARRIVED) out. Optionally
// the start position and heading from site 0's pose on start_pose_channel
// (e.g. SITE_POSE_GT in simulation, the lander's estimate on a mission).

#include <memory>
#include <string>

#include "vloc/deadreckoning/dead_reckoning.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"

namespace vloc {

struct DeadReckoningProcOptions {
  std::string imu_channel = "IMU";                 // imu_t in
  std::string wheel_channel = "WHEEL_ODOM";        // wheel_odometry_t in
  std::string site_channel = "ROVER_SITE";         // site_event_t in
  std::string pose_channel = "DR_POSE";            // pose_t out, periodic
  std::string site_pose_channel = "SITE_POSE_DR";  // site_pose_t out, per site
  std::string start_pose_channel = "";             // site_pose_t in: site 0's pose sets the start (empty = off)
  int queue_capacity = 1000;                       // messages a subscription may hold (IMU at 100 Hz)
  DeadReckoningOptions dead_reckoning;             // the estimator (map `dead_reckoning`)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

class DeadReckoningAdapter {
 public:
  DeadReckoningAdapter(Transport& transport, const DeadReckoningProcOptions& options);
  const DeadReckoning& estimator() const { return estimator_; }
  int64_t published_poses() const { return published_poses_; }
  int64_t published_sites() const { return published_sites_; }
  // One line of counts, for the log at exit.
  std::string StatusLine() const;

 private:
  void PublishReady();

  Transport& transport_;
  DeadReckoningProcOptions options_;
  DeadReckoning estimator_;
  std::shared_ptr<SubscriptionStats> imu_stats_, wheel_stats_, site_stats_, start_stats_;
  bool start_pose_set_ = false;
  int64_t published_poses_ = 0;
  int64_t published_sites_ = 0;
};

}  // namespace vloc
