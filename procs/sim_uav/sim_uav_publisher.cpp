#include "sim_uav_publisher.h"

#include <opencv2/imgproc.hpp>

#include <glog/logging.h>
#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <thread>
#include <cmath>
#include <stdexcept>

#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/uav_gps_t.hpp"

namespace vloc {

void SimUavOptions::Visit(OptionsReader& r) {
  r.Optional("camera_channel", &camera_channel, "image_t channel", NonEmpty());
  r.Optional("gps_channel", &gps_channel, "uav_gps_t channel", NonEmpty());
  r.Optional("gt_channel", &gt_channel, "pose_t channel, world_from_body ground truth", NonEmpty());
  r.Optional("frame_id", &frame_id, "image_t.frame_id");
  r.Optional("encoding", &encoding, "image_t encoding", OneOf({"jpeg", "jpg", "png", "rgb8", "gray8"}));
  r.Optional("jpeg_quality", &jpeg_quality, "JPEG quality", InRange(1, 100));
  r.Optional("speed", &speed, "real-time factor, 0 = as fast as possible", NonNegative());
  r.Optional("duration", &duration, "s, 0 = whole flight plan", NonNegative());
  r.Optional("start_utime", &start_utime, "microseconds added to every message time");
  r.Child("world", [&](OptionsReader& c) { world.Visit(c); });
}

bool SimUavOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

SimUavPublisher::SimUavPublisher(const SimUavOptions& options, const UavWorld& world)
    : options_(options), world_(world), encoding_(ParseImageEncoding(options.encoding)) {
  const double plan = world_.flight().Duration();
  end_time_ = options_.duration > 0 ? std::min(options_.duration, plan) : plan;
}

bool SimUavPublisher::Done() const { return NextTime() > end_time_ + 1e-9; }

double SimUavPublisher::NextTime() const {
  const double tf = world_.FrameTime(next_frame_);
  const double tg = next_gps_ < world_.gps().NumSamples() ? world_.gps().SampleTime(next_gps_) : 1e300;
  return std::min(tf, tg);
}

std::future<SimUavPublisher::PreparedFrame> SimUavPublisher::PrepareFrame(int index) const {
  return std::async(std::launch::async, [this, index] {
    PreparedFrame out;
    const double t = world_.FrameTime(index);
    out.utime = options_.start_utime + world_.FrameUtime(index);
    const auto start = std::chrono::steady_clock::now();
    cv::Mat frame = world_.RenderFrame(t);
    out.render_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    if (encoding_ == ImageEncoding::kGray8) cv::cvtColor(frame, frame, cv::COLOR_BGR2GRAY);
    PoseWithCovariance truth;
    truth.utime = out.utime;
    truth.pose = world_.flight().WorldFromBody(t);
    out.truth = EncodeOrThrow(PoseToMessage(truth, "world", "uav_body"));
    out.image = EncodeOrThrow(ImageToMessage(frame, encoding_, out.utime, options_.frame_id, options_.jpeg_quality));
    return out;
  });
}

void SimUavPublisher::EmitNext(const Sink& sink) {
  const double tf = world_.FrameTime(next_frame_);
  const double tg = next_gps_ < world_.gps().NumSamples() ? world_.gps().SampleTime(next_gps_) : 1e300;
  if (tg < tf) {
    const UavGpsSample& s = world_.gps().Sample(next_gps_++);
    uav_gps_t msg;
    msg.utime = options_.start_utime + s.utime;
    msg.fix = s.has_fix ? uav_gps_t::FIX_3D : uav_gps_t::FIX_NONE;
    msg.latitude = s.latitude;
    msg.longitude = s.longitude;
    msg.altitude = s.altitude;
    msg.height_above_ground = s.height_above_ground;
    msg.horizontal_sigma = s.horizontal_sigma;
    msg.vertical_sigma = s.vertical_sigma;
    ++summary_.gps_fixes;
    if (!s.has_fix) ++summary_.gps_dropouts;
    sink(options_.gps_channel, EncodeOrThrow(msg), msg.utime);
    return;
  }
  // Frame i was rendered and encoded while frame i-1 was being published;
  // start frame i+1 now (rendering is a const, thread-safe UavWorld call).
  if (!pending_.valid()) pending_ = PrepareFrame(next_frame_);
  PreparedFrame frame = pending_.get();
  ++next_frame_;
  if (world_.FrameTime(next_frame_) <= end_time_ + 1e-9) pending_ = PrepareFrame(next_frame_);
  summary_.render_ms_total += frame.render_ms;
  ++summary_.frames;
  sink(options_.gt_channel, frame.truth, frame.utime);
  sink(options_.camera_channel, frame.image, frame.utime);
}

namespace {
void LogSummary(const char* what, const SimUavSummary& s) {
  LOG(INFO) << what << " " << s.frames << " frames, " << s.gps_fixes << " GPS messages (" << s.gps_dropouts
            << " without fix), mean render " << s.MeanRenderMs() << " ms";
}
}  // namespace

bool WriteSimUavLog(const std::string& path, SimUavPublisher* publisher, std::string* error) {
  lcm::LogFile log(path, "w");
  if (!log.good()) return Fail(error, "cannot open log " + path + " for writing (check the folder exists)");
  int64_t event_number = 0;
  while (!publisher->Done() && !StopSignalPending()) {
    publisher->EmitNext([&](const std::string& channel, const std::vector<uint8_t>& bytes, int64_t utime) {
      lcm::LogEvent event;
      event.eventnum = event_number++;
      event.timestamp = utime;
      event.channel = channel;
      event.datalen = static_cast<int32_t>(bytes.size());
      event.data = const_cast<uint8_t*>(bytes.data());
      log.writeEvent(&event);
    });
  }
  LogSummary(("wrote " + path + ":").c_str(), publisher->summary());
  return true;
}

int PublishSimUavRealTime(Transport& transport, double speed, SimUavPublisher* publisher) {
  const auto wall_start = std::chrono::steady_clock::now();
  const double first = publisher->NextTime();
  bool warned_late = false;
  auto on_idle = [&] {
    for (int burst = 0; burst < 8 && !publisher->Done(); ++burst) {
      const double t = publisher->NextTime();
      if (speed > 0) {
        const auto due = wall_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                          std::chrono::duration<double>((t - first) / speed));
        const auto now = std::chrono::steady_clock::now();
        if (now < due) {
          std::this_thread::sleep_until(std::min(due, now + std::chrono::milliseconds(20)));
          if (std::chrono::steady_clock::now() < due) return;
        } else if (!warned_late && now - due > std::chrono::seconds(1)) {
          warned_late = true;
          LOG(WARNING) << "rendering is more than 1 s behind real time; lower --fps or --speed";
        }
      }
      publisher->EmitNext([&](const std::string& channel, const std::vector<uint8_t>& bytes, int64_t) {
        transport.Publish(channel, bytes.data(), bytes.size());
      });
    }
  };
  const int code = RunUntilSignal(transport, 0, on_idle, [&] { return publisher->Done(); });
  LogSummary("published", publisher->summary());
  return code;
}

}  // namespace vloc
