#include "sim_rover_publisher.h"

#include <glog/logging.h>
#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <cmath>

#include "vloc/common/options.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"

namespace vloc {
namespace {

template <class Msg>
std::vector<uint8_t> Encode(const Msg& msg) {
  std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

}  // namespace

void SimRoverOptions::Visit(OptionsReader& r) {
  r.Optional("stereo_channel", &stereo_channel, "stereo_image_t channel");
  r.Optional("site_channel", &site_channel, "site_event_t channel");
  r.Optional("imu_channel", &imu_channel, "imu_t channel");
  r.Optional("wheel_channel", &wheel_channel, "wheel_odometry_t channel");
  r.Optional("gt_channel", &gt_channel, "pose_t channel, ground-truth world_from_body");
  r.Optional("site_pose_channel", &site_pose_channel, "site_pose_t channel, ground truth at arrival");
  r.Optional("image_encoding", &image_encoding, "png, jpeg or gray8");
  r.Optional("jpeg_quality", &jpeg_quality, "1..100");
  r.Optional("speed", &speed, "real-time factor; 0 = as fast as possible");
  r.Optional("gt_rate_hz", &gt_rate_hz, "Hz, GT_POSE rate");
  world.Visit(r);
}

bool SimRoverOptions::Check(std::string* error) const {
  try {
    const ImageEncoding e = ParseImageEncoding(image_encoding);
    if (e == ImageEncoding::kRgb8) return Fail(error, "image_encoding rgb8 does not fit gray Navcam images; use png, jpeg or gray8");
  } catch (const std::exception& ex) {
    return Fail(error, std::string("image_encoding: ") + ex.what());
  }
  if (jpeg_quality < 1 || jpeg_quality > 100) return Fail(error, "jpeg_quality must be in [1, 100]");
  if (!(speed >= 0)) return Fail(error, "speed must be >= 0 (0 = as fast as possible)");
  if (!(gt_rate_hz > 0 && gt_rate_hz <= world.traverse.imu.rate_hz)) return Fail(error, "gt_rate_hz must be in (0, imu rate]");
  for (const std::string* c : {&stereo_channel, &site_channel, &imu_channel, &wheel_channel, &gt_channel, &site_pose_channel})
    if (c->empty()) return Fail(error, "channel names must not be empty");
  return world.Check(error);
}

SimRoverPublisher::SimRoverPublisher(const SimRoverOptions& options, const sim::RoverWorld& world)
    : options_(options), world_(world), traverse_(world.traverse()) {
  gt_every_ = std::max(1, static_cast<int>(std::lround(options.world.traverse.imu.rate_hz / options.gt_rate_hz)));
}

void SimRoverPublisher::EmitNext(const Sink& sink) {
  if (Done()) return;
  const int64_t t = traverse_.imu[step_].utime;
  while (event_ < traverse_.events.size() && traverse_.events[event_].utime <= t) {
    const SiteEvent& event = traverse_.events[event_++];
    sink(options_.site_channel, Encode(SiteEventToMessage(event)), event.utime);
    ++summary_.site_events;
    if (event.event == SiteEventType::kArrived) {
      PoseWithCovariance pose;
      pose.utime = event.utime;
      pose.pose = traverse_.sites.at(event.site_id).world_from_body;
      sink(options_.site_pose_channel,
           Encode(SitePoseToMessage(event.site_id, site_pose_t::SOURCE_GROUND_TRUTH, pose)), event.utime);
      ++summary_.site_poses;
    }
  }
  sink(options_.imu_channel, Encode(ImuToMessage(traverse_.imu[step_])), t);
  ++summary_.imu_samples;
  while (wheel_ < traverse_.wheel.size() && traverse_.wheel[wheel_].utime <= t) {
    sink(options_.wheel_channel, Encode(WheelOdometryToMessage(traverse_.wheel[wheel_])), traverse_.wheel[wheel_].utime);
    ++wheel_;
    ++summary_.wheel_samples;
  }
  if (step_ % gt_every_ == 0) {
    PoseWithCovariance pose;
    pose.utime = t;
    pose.pose = traverse_.ground_truth[step_].world_from_body;
    sink(options_.gt_channel, Encode(PoseToMessage(pose, "world", "body")), t);
    ++summary_.gt_poses;
  }
  while (exposure_ < traverse_.exposures.size() && traverse_.exposures[exposure_].utime <= t) {
    const sim::Exposure& e = traverse_.exposures[exposure_++];
    const auto start = std::chrono::steady_clock::now();
    const StereoPair pair = world_.RenderExposure(e);
    summary_.render_seconds_total += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    stereo_image_t msg = StereoPairToMessage(pair, ParseImageEncoding(options_.image_encoding));
    sink(options_.stereo_channel, Encode(msg), e.utime);
    ++summary_.stereo_pairs;
    LOG(INFO) << "site " << e.site_id << " pair " << e.pair_index + 1 << "/" << e.num_pairs << " published";
  }
  ++step_;
}

bool WriteSimRoverLog(const std::string& path, SimRoverPublisher* publisher, std::string* error) {
  lcm::LogFile log(path, "w");
  if (!log.good()) return Fail(error, "cannot open LCM log " + path + " for writing (check the folder exists and is writable)");
  bool ok = true;
  const SimRoverPublisher::Sink sink = [&](const std::string& channel, const std::vector<uint8_t>& bytes, int64_t utime) {
    lcm::LogEvent event;
    event.eventnum = 0;
    event.timestamp = utime;
    event.channel = channel;
    event.datalen = static_cast<int32_t>(bytes.size());
    event.data = const_cast<uint8_t*>(bytes.data());
    if (log.writeEvent(&event) != 0) ok = false;
  };
  while (!publisher->Done() && ok) publisher->EmitNext(sink);
  if (!ok) return Fail(error, "writing LCM log " + path + " failed (disk full?)");
  return true;
}

}  // namespace vloc
