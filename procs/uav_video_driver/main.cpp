// uav_video_driver: replays a UAV video (file, image pattern or folder of
// images) and optional telemetry CSV (uav_video_input.h) on UAV_CAMERA and
// UAV_GPS, at the recorded pace (x speed) or as fast as possible.
//   uav_video_driver --config config/procs/uav_video_driver.yaml --video flight.mp4 [--telemetry gps.csv] [--speed 0]
// A folder of geotagged photos without --telemetry publishes their EXIF GPS
// (and DJI relative altitude) on UAV_GPS at their EXIF capture times.
#include <iostream>

#include "uav_video_replay.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(
      argc, argv,
      {"uav_video_driver", {"video", "telemetry", "speed", "fps"}, false,
       "[--config config/procs/uav_video_driver.yaml] --video FILE|PATTERN|FOLDER [--telemetry CSV] [--speed X] "
       "[--fps F] [--lcm-url URL]"});
  if (!setup) return 1;
  const auto loaded = vloc::LoadProcessOptions<vloc::UavVideoDriverOptions>(*setup, [&](vloc::UavVideoDriverOptions& o) {
    if (setup->args.Has("video")) o.video = setup->args.Get("video");
    if (setup->args.Has("telemetry")) o.telemetry_csv = setup->args.Get("telemetry");
    if (setup->args.Has("speed")) o.speed = setup->args.GetDouble("speed", o.speed);
    if (setup->args.Has("fps")) o.fps = setup->args.GetDouble("fps", o.fps);
  });
  if (!loaded) return 1;
  const vloc::UavVideoDriverOptions& options = *loaded;
  vloc::UavVideoSource video;
  std::string error;
  if (options.video.empty() || !video.Open(options.video, options.fps, &error)) {
    std::cerr << "uav_video_driver: " << (options.video.empty() ? "no video given (--video FILE)" : error) << "\n";
    return 1;
  }
  vloc::TelemetryCsv telemetry;
  if (!options.telemetry_csv.empty()) telemetry = vloc::ReadTelemetryCsv(options.telemetry_csv, options.telemetry_time_offset);
  if (options.telemetry_csv.empty() && options.geotags) {
    std::string how;
    vloc::TelemetryCsv tags = video.GeotagTelemetry(options.geotag_horizontal_sigma, &how);
    if (tags.readable) {
      LOG(INFO) << "GPS from the photos' geotags: " << how;
      telemetry = std::move(tags);
    }
  }
  for (const auto& p : telemetry.problems) LOG(ERROR) << p;
  vloc::ReplayPacer pacer(options.speed);
  const auto summary = vloc::ReplayUavVideo(options, video, telemetry, *setup->transport, pacer);
  LOG(INFO) << "uav_video_driver: published " << summary.frames_published << " frames ("
            << (video.exif_times() ? std::string("at their EXIF capture times") : std::to_string(video.fps()) + " fps") << "), " << summary.fixes_published << " GPS fixes; skipped " << summary.frames_skipped
            << " frames and " << telemetry.problems.size() << " telemetry rows";
  return 0;
}
