#pragma once
// LCM adapter of the simulated UAV: turns UavWorld frames, GPS fixes and
// ground truth into vloc messages, in time order.
//
// Channels (defaults):
//   UAV_CAMERA  image_t    frame_id "uav_nadir", JPEG by default, utime = exposure time
//   UAV_GPS     uav_gps_t  at world.gps.rate; FIX_NONE with NaN fields inside a drop-out
//   UAV_GT      pose_t     frame_id "world", child_frame_id "uav_body": world_from_body of
//                          the UAV at each frame time. World: x east, y north, z up with
//                          the ground at z = 0, so position[2] is the height above ground.
//                          Body: x forward, y left, z up; the nadir camera is at the body
//                          origin with body_from_camera = UavBodyFromCamera() (image top =
//                          forward), so world_from_camera = world_from_body * that.

#include <cstdint>
#include <functional>
#include <future>
#include <string>
#include <vector>

#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/sim/uav_world.h"

namespace vloc {

class OptionsReader;

struct SimUavOptions {
  std::string camera_channel = "UAV_CAMERA";  // image_t
  std::string gps_channel = "UAV_GPS";        // uav_gps_t
  std::string gt_channel = "UAV_GT";          // pose_t world_from_body
  std::string frame_id = "uav_nadir";         // image_t.frame_id
  std::string encoding = "jpeg";              // jpeg, png, rgb8 or gray8
  int jpeg_quality = 90;                      // 1..100
  double speed = 1.0;                         // real-time factor; 0 = as fast as possible
  double duration = 0.0;                      // s, 0 = the whole flight plan
  int64_t start_utime = 0;                    // microseconds added to every message time
  UavWorldOptions world;                      // the simulated world and flight

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// What a run produced.
struct SimUavSummary {
  int frames = 0;
  int gps_fixes = 0;       // messages on the GPS channel (with or without fix)
  int gps_dropouts = 0;    // of which without fix
  double render_ms_total = 0;
  double MeanRenderMs() const { return frames > 0 ? render_ms_total / frames : 0.0; }
};

class SimUavPublisher {
 public:
  // Receives one encoded message: channel, bytes, message utime.
  using Sink = std::function<void(const std::string& channel, const std::vector<uint8_t>& bytes, int64_t utime)>;

  SimUavPublisher(const SimUavOptions& options, const UavWorld& world);

  bool Done() const;
  // Simulation time (s since flight start) of the next event.
  double NextTime() const;
  // Renders/encodes the next event (a frame with its ground truth, or a GPS
  // fix) and hands its messages to `sink`.
  void EmitNext(const Sink& sink);
  const SimUavSummary& summary() const { return summary_; }

 private:
  // A frame's encoded messages, rendered ahead on a worker thread.
  struct PreparedFrame {
    int64_t utime = 0;
    double render_ms = 0;
    std::vector<uint8_t> truth, image;
  };
  std::future<PreparedFrame> PrepareFrame(int index) const;

  SimUavOptions options_;
  const UavWorld& world_;
  std::future<PreparedFrame> pending_;
  ImageEncoding encoding_;
  double end_time_ = 0;
  int next_frame_ = 0, next_gps_ = 0;
  SimUavSummary summary_;
};

// Writes every event straight to an LCM log (event timestamps = message
// utime), as fast as rendering allows. False with one error line.
bool WriteSimUavLog(const std::string& path, SimUavPublisher* publisher, std::string* error);

// Publishes each event at start + t / speed (speed 0: no waiting) until the
// flight ends or SIGINT/SIGTERM. Returns the exit code.
int PublishSimUavRealTime(Transport& transport, double speed, SimUavPublisher* publisher);

}  // namespace vloc
