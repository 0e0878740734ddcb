#pragma once
// Inputs of uav_video_driver (no LCM here):
//  - UavVideoSource: frames from a video file or image-sequence pattern
//    (anything cv::VideoCapture opens, e.g. flight.mp4 or frames/%05d.png) or
//    from a folder of images (sorted by name; an unreadable image is
//    reported in one line and skipped). Frame i is at i / fps seconds, or,
//    for a folder of photos whose EXIF capture times increase (and no fps
//    forced), at its capture time after the first photo's.
//  - UavVideoSource::GeotagTelemetry: the folder's EXIF GPS (and DJI XMP
//    relative altitude as height above ground) as telemetry fixes at the
//    photos' times, for geotagged surveys without a telemetry CSV.
//  - ReadTelemetryCsv: GPS telemetry, header row with named columns:
//      time (s, video clock: 0 = first frame) or utime (us),
//      latitude (deg), longitude (deg), altitude (m),
//      optional: height_above_ground (m), fix (0 none, 1 2-D, 2 3-D),
//                horizontal_sigma (m), vertical_sigma (m)
//    A row with fix 0 may leave latitude/longitude/altitude empty. A row
//    with a non-number or a value out of range is skipped with one line.

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <cstdint>
#include <string>
#include <vector>

namespace vloc {

struct TelemetryCsv;

class UavVideoSource {
 public:
  enum class Status { kFrame, kSkipped, kEnd };

  // `fps` > 0 overrides the container's frame rate. False with one line in
  // *error when nothing can be opened.
  bool Open(const std::string& path, double fps, std::string* error);
  double fps() const { return fps_; }
  // kFrame: *frame (BGR) and *utime (us since the first frame) are set.
  // kSkipped: an unreadable image of a folder, described in *problem.
  Status Next(cv::Mat* frame, int64_t* utime, std::string* problem);
  // Folder mode: true when the frame times are the photos' EXIF capture times.
  bool exif_times() const { return !file_utimes_.empty(); }

  // Folder mode: one fix per geotagged photo at the photo's frame time
  // (horizontal_sigma m, as EXIF carries no accuracy). *how says how many
  // photos were tagged and whether they carry a relative altitude.
  TelemetryCsv GeotagTelemetry(double horizontal_sigma, std::string* how) const;

 private:
  cv::VideoCapture capture_;
  std::vector<std::string> files_;  // folder mode
  std::vector<int64_t> file_utimes_;  // folder mode: EXIF capture times since the first photo (empty = i / fps)
  size_t next_file_ = 0;
  int64_t index_ = 0;
  double fps_ = 30.0;
};

struct TelemetryFix {
  int64_t utime = 0;               // microseconds, video clock
  int fix = 2;                     // 0 none, 1 2-D, 2 3-D
  double latitude = 0, longitude = 0, altitude = 0;  // deg, deg, m (NaN without fix)
  double height_above_ground = 0;  // m, NaN when not in the file
  double horizontal_sigma = 0;     // m, NaN when not in the file
  double vertical_sigma = 0;       // m, NaN when not in the file
};

struct TelemetryCsv {
  std::vector<TelemetryFix> fixes;
  std::vector<std::string> problems;
  bool readable = false;
};

// `time_offset` (s) is added to every time to align telemetry with the video.
TelemetryCsv ReadTelemetryCsv(const std::string& path, double time_offset);

}  // namespace vloc
