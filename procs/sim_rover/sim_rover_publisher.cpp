#include "sim_rover_publisher.h"

#include <glog/logging.h>
#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <thread>

#include "vloc/common/options.h"
#include "vloc/common/stopwatch.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/process.h"
#include "vloc/lcm_io/typed.h"

namespace vloc {
void SimRoverOptions::Visit(OptionsReader& r) {
  r.Optional("stereo_channel", &stereo_channel, "stereo_image_t channel", NonEmpty());
  r.Optional("site_channel", &site_channel, "site_event_t channel", NonEmpty());
  r.Optional("imu_channel", &imu_channel, "imu_t channel", NonEmpty());
  r.Optional("wheel_channel", &wheel_channel, "wheel_odometry_t channel", NonEmpty());
  r.Optional("gt_channel", &gt_channel, "pose_t channel, ground-truth world_from_body", NonEmpty());
  r.Optional("site_pose_channel", &site_pose_channel, "site_pose_t channel, ground truth at arrival", NonEmpty());
  r.Optional("image_encoding", &image_encoding, "stereo image encoding (rgb8 does not fit the grey Navcam)",
             OneOf({"png", "jpeg", "jpg", "gray8"}));
  r.Optional("jpeg_quality", &jpeg_quality, "JPEG quality", InRange(1, 100));
  r.Optional("speed", &speed, "real-time factor; 0 = as fast as possible", NonNegative());
  r.Optional("gt_rate_hz", &gt_rate_hz, "Hz, GT_POSE rate", Positive());
  world.Visit(r);
  r.Relation("gt_rate_hz", gt_rate_hz <= world.traverse.imu.rate_hz, "must be <= the IMU rate (traverse.imu.rate_hz)");
}

bool SimRoverOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

SimRoverPublisher::SimRoverPublisher(const SimRoverOptions& options, const sim::RoverWorld& world)
    : options_(options), world_(world), traverse_(world.traverse()) {
  gt_every_ = std::max(1, static_cast<int>(std::lround(options.world.traverse.imu.rate_hz / options.gt_rate_hz)));
}

void SimRoverPublisher::EmitNext(const Sink& sink) {
  if (Done()) return;
  const int64_t t = traverse_.imu[step_].utime;
  while (event_ < traverse_.events.size() && traverse_.events[event_].utime <= t) {
    const SiteEvent& event = traverse_.events[event_++];
    sink(options_.site_channel, EncodeOrThrow(SiteEventToMessage(event)), event.utime);
    ++summary_.site_events;
    if (event.event == SiteEventType::kArrived) {
      PoseWithCovariance pose;
      pose.utime = event.utime;
      pose.pose = traverse_.sites.at(event.site_id).world_from_body;
      sink(options_.site_pose_channel,
           EncodeOrThrow(SitePoseToMessage(event.site_id, site_pose_t::SOURCE_GROUND_TRUTH, pose)), event.utime);
      ++summary_.site_poses;
    }
  }
  sink(options_.imu_channel, EncodeOrThrow(ImuToMessage(traverse_.imu[step_])), t);
  ++summary_.imu_samples;
  while (wheel_ < traverse_.wheel.size() && traverse_.wheel[wheel_].utime <= t) {
    sink(options_.wheel_channel, EncodeOrThrow(WheelOdometryToMessage(traverse_.wheel[wheel_])), traverse_.wheel[wheel_].utime);
    ++wheel_;
    ++summary_.wheel_samples;
  }
  if (step_ % gt_every_ == 0) {
    PoseWithCovariance pose;
    pose.utime = t;
    pose.pose = traverse_.ground_truth[step_].world_from_body;
    sink(options_.gt_channel, EncodeOrThrow(PoseToMessage(pose, "world", "body")), t);
    ++summary_.gt_poses;
  }
  while (exposure_ < traverse_.exposures.size() && traverse_.exposures[exposure_].utime <= t) {
    const sim::Exposure& e = traverse_.exposures[exposure_++];
    const auto start = std::chrono::steady_clock::now();
    const StereoPair pair = world_.RenderExposure(e);
    summary_.render_seconds_total += SecondsSince(start);
    stereo_image_t msg = StereoPairToMessage(pair, ParseImageEncoding(options_.image_encoding));
    sink(options_.stereo_channel, EncodeOrThrow(msg), e.utime);
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

int WriteSimRoverSample(const sim::RoverWorld& world, const std::string& dir) {
  const sim::SimulatedTraverse& traverse = world.traverse();
  const sim::Terrain& terrain = world.terrain();
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  const auto& exposures = traverse.sites.front().exposures;
  const sim::Exposure& e = exposures[exposures.size() / 2];
  const auto start = std::chrono::steady_clock::now();
  const StereoPair pair = world.RenderExposure(e);
  const double seconds = SecondsSince(start);
  const Eigen::Vector3d p = e.world_from_body.translation();
  const cv::Mat ortho = terrain.RenderOrthoimage({p.x() - 10, p.y() - 20, p.x() + 30, p.y() + 20}, 0.04);
  for (const auto& [name, image] : {std::pair<std::string, cv::Mat>{"navcam_left.png", pair.left},
                                    {"navcam_right.png", pair.right},
                                    {"terrain_ortho.png", ortho}}) {
    const std::string path = dir + "/" + name;
    if (!cv::imwrite(path, image)) {
      std::cerr << "sim_rover: cannot write " << path << " (check the folder is writable)\n";
      return 1;
    }
  }
  std::cout << "sim_rover: wrote " << dir << "/navcam_left.png, navcam_right.png (site 0, pair " << e.pair_index
            << ", pan " << e.mast_pan * 180 / M_PI << " deg, tilt " << e.mast_tilt * 180 / M_PI << " deg, "
            << pair.left.cols << "x" << pair.left.rows << ", pair rendered in " << seconds
            << " s) and terrain_ortho.png (40 m x 40 m, 4 cm/px)\n";
  return 0;
}

int PublishSimRoverRealTime(Transport& transport, double speed, SimRoverPublisher* publisher) {
  const auto wall_start = std::chrono::steady_clock::now();
  const int64_t sim_start = publisher->NextUtime();
  const SimRoverPublisher::Sink sink = [&](const std::string& channel, const std::vector<uint8_t>& bytes, int64_t) {
    if (!transport.Publish(channel, bytes.data(), bytes.size()))
      LOG(ERROR) << "channel " << channel << ": publish of " << bytes.size() << " bytes failed";
  };
  while (!publisher->Done()) {
    if (StopSignalPending()) {
      LOG(INFO) << "stop signal received, shutting down";
      return 0;
    }
    if (speed > 0) {
      const auto due = wall_start + std::chrono::microseconds(
                                        static_cast<int64_t>((publisher->NextUtime() - sim_start) / speed));
      // Sleep in short slices so a stop signal is seen promptly.
      while (std::chrono::steady_clock::now() < due) {
        if (StopSignalPending()) return 0;
        std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(
            due - std::chrono::steady_clock::now(), std::chrono::milliseconds(50)));
      }
    }
    publisher->EmitNext(sink);
    transport.Handle(0);
  }
  LOG(INFO) << "traverse finished";
  return 0;
}

}  // namespace vloc
