#pragma once
// The photos' altitude tags fused with the vision height (issue 31): the
// paper's height from the affine scale stays the measurement; the tags, when
// they agree with it within both uncertainties, hold its drift.
//
//   AltitudeFusion f = FuseAltitude(seconds, vision_m, altitude_m, relative, options);
//   if (f.fused) use(f.height_m[i]);   else std::cout << f.why;     // one line: why the tags were not used
//
// Altitude tags: the DJI relative altitude (XMP, height above the take-off
// point: the ground at take-off) or the EXIF GPS altitude (above sea level:
// the ground level is fitted, the median of altitude - vision height).
// Consistency: the residuals altitude - ground - vision height, each divided
// by its sigma sqrt(altitude_sigma^2 + (vision_survey_sigma h)^2), must have
// an RMS <= max_normalised_rms, or the tags are not fused (a camera GPS
// whose altitude climbs 113 m while the photos keep their scale). Fusion:
// HeightFilter in "fused" mode, frame by frame in time order: the vision
// height measures log h + bias (bias a random walk), the altitude measures
// log h. Each frame says which measurements made its height.

#include <string>
#include <vector>

#include "vloc/mosaic/height_filter.h"

namespace vloc {
class OptionsReader;
}

namespace vloc::mosaic {

struct AltitudeFusionOptions {
  bool enabled = true;                   // false: vision heights only
  double gps_altitude_sigma = 3.0;       // m, 1-sigma of an EXIF GPS altitude (camera GPS, vertical)
  double relative_altitude_sigma = 0.5;  // m, 1-sigma of a DJI relative altitude (barometric)
  double vision_survey_sigma = 0.06;     // relative 1-sigma of a vision height over a survey (drift included): the
                                         // consistency test's allowance, not the filter's per-frame sigma
  double max_normalised_rms = 3.0;       // the tags are fused when the normalised residual RMS is at most this
  HeightFilterOptions filter;            // gps_use is forced to "fused"; gps_height_sigma is the altitude's sigma

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

enum class HeightSource { kNone, kVision, kAltitude, kFused };
const char* ToString(HeightSource source);

struct AltitudeFusion {
  bool fused = false;                    // the tags were consistent and used
  std::string why;                       // one line: what was used, or why the tags were not
  double ground_m = 0;                   // ground level subtracted from the altitude (0 for relative altitude)
  double normalised_rms = 0;             // consistency of altitude and vision (<= max_normalised_rms to fuse)
  int pairs = 0;                         // frames with both a vision height and an altitude
  std::vector<double> height_m;          // per frame: fused, else vision, else NaN
  std::vector<HeightSource> source;      // per frame: what made height_m
};

// seconds: capture times (increasing); vision_m: vision heights (NaN when the
// frame is not registered); altitude_m: altitude tags (NaN when none);
// relative: the tags are heights above take-off (DJI), else above sea level.
AltitudeFusion FuseAltitude(const std::vector<double>& seconds, const std::vector<double>& vision_m,
                            const std::vector<double>& altitude_m, bool relative, const AltitudeFusionOptions& options);

}  // namespace vloc::mosaic
