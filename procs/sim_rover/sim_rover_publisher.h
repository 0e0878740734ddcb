#pragma once
// LCM adapter of the simulated rover: turns a SimulatedTraverse (and the
// Navcam images rendered at its exposures) into vloc messages, in time order.
//
// Channels (defaults):
//   NAVCAM_STEREO  stereo_image_t  one per exposure, PNG by default, utime = exposure time
//   ROVER_SITE     site_event_t    ARRIVED (when stopped), IMAGING_DONE, DEPARTED
//   IMU            imu_t           100 Hz, body frame (see vloc/sim/rover_traverse.h)
//   WHEEL_ODOM     wheel_odometry_t 20 Hz, cumulative distance incl. slip
//   GT_POSE        pose_t          10 Hz, frame "world", child "body": world_from_body truth
//   SITE_POSE_GT   site_pose_t     at each ARRIVED, source GROUND_TRUTH
// World: x east, y north, z up, origin at site 0 (heights shifted so the
// terrain is at z = 0 there). Body: x forward, y left, z up.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "vloc/lcm_io/transport.h"
#include "vloc/sim/rover_world.h"

namespace vloc {

class OptionsReader;

struct SimRoverOptions {
  std::string stereo_channel = "NAVCAM_STEREO";    // stereo_image_t
  std::string site_channel = "ROVER_SITE";         // site_event_t
  std::string imu_channel = "IMU";                 // imu_t
  std::string wheel_channel = "WHEEL_ODOM";        // wheel_odometry_t
  std::string gt_channel = "GT_POSE";              // pose_t
  std::string site_pose_channel = "SITE_POSE_GT";  // site_pose_t
  std::string image_encoding = "png";              // png, jpeg or gray8
  int jpeg_quality = 95;                           // 1..100 when image_encoding is jpeg
  double speed = 1.0;                              // real-time factor; 0 = as fast as possible
  double gt_rate_hz = 10.0;                        // Hz, GT_POSE rate (a divisor of the IMU rate)
  sim::RoverWorldOptions world;                    // sections navcam, terrain, render, traverse (top level)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct SimRoverSummary {
  int stereo_pairs = 0;
  int site_events = 0;
  int imu_samples = 0;
  int wheel_samples = 0;
  int gt_poses = 0;
  int site_poses = 0;
  double render_seconds_total = 0;  // wall time spent rendering
};

class SimRoverPublisher {
 public:
  // Receives one encoded message: channel, bytes, message utime.
  using Sink = std::function<void(const std::string& channel, const std::vector<uint8_t>& bytes, int64_t utime)>;

  // Both must outlive the publisher.
  SimRoverPublisher(const SimRoverOptions& options, const sim::RoverWorld& world);

  bool Done() const { return step_ >= traverse_.imu.size(); }
  int64_t NextUtime() const { return Done() ? 0 : traverse_.imu[step_].utime; }
  // Emits every message of the next IMU time step (events, site pose,
  // IMU, wheel, GT, then the stereo pair exposed at that time).
  void EmitNext(const Sink& sink);
  const SimRoverSummary& summary() const { return summary_; }

 private:
  const SimRoverOptions& options_;
  const sim::RoverWorld& world_;
  const sim::SimulatedTraverse& traverse_;
  size_t step_ = 0, event_ = 0, wheel_ = 0, exposure_ = 0;
  int gt_every_ = 10;
  SimRoverSummary summary_;
};

// Publishes every message on `transport` when the wall clock reaches its
// time / speed (speed 0: as fast as possible); stops early on SIGINT/SIGTERM.
// Returns the process exit code.
int PublishSimRoverRealTime(Transport& transport, double speed, SimRoverPublisher* publisher);

// Saves the middle pair of site 0 as DIR/navcam_left.png, DIR/navcam_right.png
// and a 40 m x 40 m orthoimage around it as DIR/terrain_ortho.png. Returns
// the process exit code (1 with one error line when a file cannot be written).
int WriteSimRoverSample(const sim::RoverWorld& world, const std::string& dir);

// Writes the whole traverse to an LCM log (event timestamps = message
// utimes). Returns false with one error line when the file cannot be written.
bool WriteSimRoverLog(const std::string& path, SimRoverPublisher* publisher, std::string* error);

}  // namespace vloc
