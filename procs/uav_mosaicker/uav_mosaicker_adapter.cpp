#include "uav_mosaicker_adapter.h"

#include <glog/logging.h>

#include <cmath>

#include "vloc/common/options.h"
#include "vloc/image_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_uav.h"
#include "vloc/uav_gps_t.hpp"

namespace vloc {

void UavMosaickerProcOptions::Visit(OptionsReader& r) {
  r.Optional("camera_channel", &camera_channel, "image_t in", NonEmpty());
  r.Optional("gps_channel", &gps_channel, "uav_gps_t in");
  r.Optional("state_channel", &state_channel, "uav_state_t out", NonEmpty());
  r.Optional("mosaic_channel", &mosaic_channel, "image_t out, JPEG preview");
  r.Optional("preview_period", &preview_period, "s between previews, 0 = none", NonNegative());
  r.Optional("preview_max_side", &preview_max_side, "px", AtLeast(64));
  r.Optional("preview_jpeg_quality", &preview_jpeg_quality, "1..100", InRange(1, 100));
  r.Optional("output", &output, "full mosaic PNG path, written on SIGUSR1 and at exit");
  r.Optional("write_every_s", &write_every_s, "s of message time between periodic writes once tied to GPS (0 = none)",
             NonNegative());
  r.Optional("camera_queue", &camera_queue, "frames queued before the oldest is dropped", AtLeast(1));
  r.Optional("report_every_n_frames", &report_every_n_frames, "summary log period", AtLeast(1));
  r.Child("mosaicker", [&](OptionsReader& c) { mosaicker.Visit(c); });
}

bool UavMosaickerProcOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

UavMosaickerAdapter::UavMosaickerAdapter(const UavMosaickerProcOptions& options, Transport& transport)
    : options_(options), transport_(transport), mosaicker_(options.mosaicker) {}

void UavMosaickerAdapter::Subscribe() {
  camera_stats_ = vloc::Subscribe<image_t>(
      transport_, options_.camera_channel, [this](const std::string&, const image_t& m) { OnFrame(m); },
      options_.camera_queue);
  if (!options_.gps_channel.empty())
    gps_stats_ = vloc::Subscribe<uav_gps_t>(
        transport_, options_.gps_channel, [this](const std::string&, const uav_gps_t& m) { OnGps(m); }, 200);
}

void UavMosaickerAdapter::OnGps(const uav_gps_t& msg) { mosaicker_.AddGps(GpsFromMessage(msg)); }

void UavMosaickerAdapter::OnFrame(const image_t& msg) {
  cv::Mat image;
  try {
    image = ImageFromMessage(msg);
  } catch (const std::exception& e) {
    ++undecodable_frames_;
    if (undecodable_log_.ShouldLog())
      LOG(ERROR) << "channel " << options_.camera_channel << ": frame not decodable (" << e.what()
                 << "); counted as a lost frame (" << undecodable_frames_ << " so far)" << undecodable_log_.Suppressed();
  }
  const mosaic::FrameState state = mosaicker_.ProcessFrame(image, msg.utime);
  Publish(transport_, options_.state_channel, StateToMessage(state));
  ++frames_;
  if (state.status == mosaic::TrackStatus::kLost || state.status == mosaic::TrackStatus::kRecovered)
    LOG(INFO) << "frame " << state.frame_index << " " << mosaic::ToString(state.status) << ": " << state.message;
  if (frames_ % options_.report_every_n_frames == 0)
    LOG(INFO) << "uav_mosaicker: height " << state.height << " m, route " << state.route_local.x << ", "
              << state.route_local.y << " m; " << mosaicker_.summary().BriefReport();
  if (options_.preview_period > 0 && !options_.mosaic_channel.empty() &&
      msg.utime - last_preview_utime_ >= static_cast<int64_t>(options_.preview_period * 1e6))
    PublishPreview(msg.utime);
  if (options_.write_every_s > 0 && state.georeferenced &&
      msg.utime - last_write_utime_ >= static_cast<int64_t>(options_.write_every_s * 1e6)) {
    last_write_utime_ = msg.utime;
    WriteMosaic();
  }
}

void UavMosaickerAdapter::PublishPreview(int64_t utime) {
  const cv::Mat preview = mosaicker_.Preview(options_.preview_max_side);
  if (preview.empty()) return;
  last_preview_utime_ = utime;
  Publish(transport_, options_.mosaic_channel,
          ImageToMessage(preview, ImageEncoding::kJpeg, utime, "uav_mosaic", options_.preview_jpeg_quality));
}

bool UavMosaickerAdapter::WriteMosaic() {
  if (options_.output.empty()) return true;
  std::string error;
  if (!mosaicker_.WriteMosaic(options_.output, &error)) {
    LOG(ERROR) << "uav_mosaicker: mosaic not written: " << error;
    return false;
  }
  LOG(INFO) << "uav_mosaicker: mosaic written to " << options_.output << "; " << mosaicker_.summary().BriefReport();
  return true;
}

}  // namespace vloc
