#include "uav_video_replay.h"

#include <glog/logging.h>

#include <opencv2/imgproc.hpp>

#include "vloc/common/options.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/uav_gps_t.hpp"

namespace vloc {

void UavVideoDriverOptions::Visit(OptionsReader& r) {
  r.Optional("video", &video, "video file, image pattern (frames/%05d.png) or folder of images");
  r.Optional("telemetry_csv", &telemetry_csv, "optional telemetry CSV");
  r.Optional("fps", &fps, "frames/s, 0 = from the video (30 for folders)", NonNegative());
  r.Optional("telemetry_time_offset", &telemetry_time_offset, "s added to telemetry times");
  r.Optional("start_utime", &start_utime, "microseconds of the first frame");
  r.Optional("camera_channel", &camera_channel, "image_t channel");
  r.Optional("gps_channel", &gps_channel, "uav_gps_t channel");
  r.Optional("frame_id", &frame_id, "image_t.frame_id");
  r.Optional("encoding", &encoding, "image_t encoding", OneOf({"jpeg", "jpg", "png", "rgb8", "gray8"}));
  r.Optional("jpeg_quality", &jpeg_quality, "JPEG quality", InRange(1, 100));
  r.Optional("speed", &speed, "real-time factor, 0 = as fast as possible", NonNegative());
  r.Optional("geotags", &geotags, "publish the EXIF GPS of a folder of photos (no telemetry CSV)");
  r.Optional("geotag_horizontal_sigma", &geotag_horizontal_sigma, "m, sigma of geotag fixes", Positive());
}

bool UavVideoDriverOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

UavVideoReplaySummary ReplayUavVideo(const UavVideoDriverOptions& options, UavVideoSource& video,
                                     const TelemetryCsv& telemetry, Transport& transport, ReplayPacer& pacer) {
  UavVideoReplaySummary summary;
  const ImageEncoding encoding = ParseImageEncoding(options.encoding);
  cv::Mat frame;
  int64_t frame_utime = 0;
  std::string problem;
  auto advance = [&] {
    while (true) {
      const auto status = video.Next(&frame, &frame_utime, &problem);
      if (status == UavVideoSource::Status::kFrame) return true;
      if (status == UavVideoSource::Status::kEnd) return false;
      LOG(ERROR) << problem;
      ++summary.frames_skipped;
    }
  };
  bool have_frame = advance();
  size_t g = 0;
  while (have_frame || g < telemetry.fixes.size()) {
    const bool take_gps = g < telemetry.fixes.size() && (!have_frame || telemetry.fixes[g].utime <= frame_utime);
    const int64_t utime = options.start_utime + (take_gps ? telemetry.fixes[g].utime : frame_utime);
    if (!pacer.WaitFor(utime)) break;
    if (take_gps) {
      const TelemetryFix& f = telemetry.fixes[g++];
      uav_gps_t msg;
      msg.utime = utime;
      msg.fix = static_cast<int8_t>(f.fix);
      msg.latitude = f.latitude;
      msg.longitude = f.longitude;
      msg.altitude = f.altitude;
      msg.height_above_ground = f.height_above_ground;
      msg.horizontal_sigma = f.horizontal_sigma;
      msg.vertical_sigma = f.vertical_sigma;
      Publish(transport, options.gps_channel, msg);
      ++summary.fixes_published;
    } else {
      if (encoding == ImageEncoding::kGray8) cv::cvtColor(frame, frame, cv::COLOR_BGR2GRAY);
      Publish(transport, options.camera_channel,
              ImageToMessage(frame, encoding, utime, options.frame_id, options.jpeg_quality));
      ++summary.frames_published;
      have_frame = advance();
    }
  }
  return summary;
}

}  // namespace vloc
