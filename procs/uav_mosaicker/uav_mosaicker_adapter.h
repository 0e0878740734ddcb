#pragma once
// LCM adapter of the UAV mosaicker (libs/mosaic): UAV_CAMERA frames and
// UAV_GPS fixes in, UAV_STATE (every frame) and a JPEG UAV_MOSAIC preview
// (about once per second of message time) out. The full mosaic (PNG +
// .pgw world file when tied to GPS) is written on SIGUSR1, at shutdown and,
// with write_every_s, periodically once tied to GPS (each write replaces the
// files atomically: a live map for map_localizer).

#include <cstdint>
#include <memory>
#include <string>

#include "vloc/lcm_io/rate_limited_log.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/mosaic/uav_mosaicker.h"
#include "vloc/uav_state_t.hpp"

namespace vloc {

class OptionsReader;
struct image_t;
struct uav_gps_t;

struct UavMosaickerProcOptions {
  std::string camera_channel = "UAV_CAMERA";   // image_t in
  std::string gps_channel = "UAV_GPS";         // uav_gps_t in
  std::string state_channel = "UAV_STATE";     // uav_state_t out, one per frame
  std::string mosaic_channel = "UAV_MOSAIC";   // image_t out (JPEG preview)
  double preview_period = 1.0;                 // s of message time between previews (0 = none)
  int preview_max_side = 1024;                 // px, longest side of the preview
  int preview_jpeg_quality = 80;               // 1..100
  std::string output = "out/uav_mosaic.png";   // full mosaic, written on SIGUSR1 and at exit ("" = never)
  double write_every_s = 0.0;                  // s of message time: also write it this often once it is tied to
                                               // GPS (a live map for map_localizer; 0 = not)
  int camera_queue = 8;                        // frames queued before LCM drops the oldest (real time)
  int report_every_n_frames = 300;             // log a summary line every n frames
  mosaic::MosaickerOptions mosaicker;          // the algorithm

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

class UavMosaickerAdapter {
 public:
  UavMosaickerAdapter(const UavMosaickerProcOptions& options, Transport& transport);
  void Subscribe();
  // Writes the full mosaic to options.output (if set). Returns false on error (logged).
  bool WriteMosaic();
  const mosaic::UavMosaicker& mosaicker() const { return mosaicker_; }
  int64_t frames() const { return frames_; }
  // What the subscriptions received (undecodable frames included).
  std::string SubscriptionLine() const { return SubscriptionSummary({camera_stats_, gps_stats_}); }

 private:
  void OnFrame(const image_t& msg);
  void OnGps(const uav_gps_t& msg);
  void PublishPreview(int64_t utime);

  UavMosaickerProcOptions options_;
  Transport& transport_;
  mosaic::UavMosaicker mosaicker_;
  std::shared_ptr<SubscriptionStats> camera_stats_, gps_stats_;
  int64_t last_preview_utime_ = INT64_MIN / 2;
  int64_t last_write_utime_ = INT64_MIN / 2;
  int64_t frames_ = 0;
  int64_t undecodable_frames_ = 0;   // image bytes that are no image (counted as lost frames)
  RateLimitedLog undecodable_log_;
};

}  // namespace vloc
