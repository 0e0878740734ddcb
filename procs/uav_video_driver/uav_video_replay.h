#pragma once
// LCM adapter of uav_video_driver: publishes video frames on UAV_CAMERA
// (image_t, frame_id "uav_nadir") and telemetry fixes on UAV_GPS
// (uav_gps_t; FIX_NONE rows carry NaN position), merged in time order.
// Times: start_utime + the video clock (frame i at i / fps).

#include <cstdint>
#include <string>

#include "uav_video_input.h"
#include "vloc/lcm_io/replay_pacer.h"
#include "vloc/lcm_io/transport.h"

namespace vloc {

class OptionsReader;

struct UavVideoDriverOptions {
  std::string video;                      // video file, image pattern or folder (--video overrides)
  std::string telemetry_csv;              // optional telemetry CSV (--telemetry overrides)
  double fps = 0.0;                       // frames/s; 0 = the container's (30 for folders)
  double telemetry_time_offset = 0.0;     // s added to telemetry times to align them with the video
  int64_t start_utime = 0;                // microseconds of the first frame
  std::string camera_channel = "UAV_CAMERA";  // image_t
  std::string gps_channel = "UAV_GPS";        // uav_gps_t
  std::string frame_id = "uav_nadir";         // image_t.frame_id
  std::string encoding = "jpeg";              // jpeg, png, rgb8 or gray8
  int jpeg_quality = 90;                      // 1..100
  double speed = 1.0;                     // real-time factor; 0 = as fast as possible
  bool geotags = true;                    // folder of photos without a telemetry CSV: publish their EXIF GPS
  double geotag_horizontal_sigma = 3.0;   // m, horizontal sigma given to geotag fixes (EXIF has none)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct UavVideoReplaySummary {
  int frames_published = 0;
  int frames_skipped = 0;
  int fixes_published = 0;
};

UavVideoReplaySummary ReplayUavVideo(const UavVideoDriverOptions& options, UavVideoSource& video,
                                     const TelemetryCsv& telemetry, Transport& transport, ReplayPacer& pacer);

}  // namespace vloc
