// The altitude tags fused with the vision height (altitude_fusion.h).
#include "vloc/mosaic/altitude_fusion.h"

#include <cmath>
#include <limits>
#include <sstream>

#include "vloc/common/options.h"
#include "vloc/common/stats.h"

namespace vloc::mosaic {

void AltitudeFusionOptions::Visit(OptionsReader& r) {
  r.Optional("enabled", &enabled, "false: vision heights only");
  r.Optional("gps_altitude_sigma", &gps_altitude_sigma, "m, 1-sigma of an EXIF GPS altitude", Positive());
  r.Optional("relative_altitude_sigma", &relative_altitude_sigma, "m, 1-sigma of a DJI relative altitude", Positive());
  r.Optional("vision_survey_sigma", &vision_survey_sigma, "relative 1-sigma of a vision height over a survey",
             InOpen(0.0, 1.0));
  r.Optional("max_normalised_rms", &max_normalised_rms, "fuse when the normalised residual RMS is at most this",
             Positive());
  r.Child("filter", [this](OptionsReader& c) { filter.Visit(c); });
}

bool AltitudeFusionOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

const char* ToString(HeightSource source) {
  switch (source) {
    case HeightSource::kNone: return "none";
    case HeightSource::kVision: return "vision";
    case HeightSource::kAltitude: return "altitude";
    case HeightSource::kFused: return "vision+altitude";
  }
  return "none";
}

namespace {

bool Usable(double h) { return std::isfinite(h) && h > 0; }

// Vision heights alone: what the frames have when the tags are not fused.
AltitudeFusion VisionOnly(const std::vector<double>& vision_m, std::string why) {
  AltitudeFusion f;
  f.why = std::move(why);
  f.height_m.assign(vision_m.size(), std::numeric_limits<double>::quiet_NaN());
  f.source.assign(vision_m.size(), HeightSource::kNone);
  for (size_t i = 0; i < vision_m.size(); ++i)
    if (Usable(vision_m[i])) f.height_m[i] = vision_m[i], f.source[i] = HeightSource::kVision;
  return f;
}

// Ground level and the consistency of the tags with the vision heights.
void Consistency(const std::vector<double>& vision_m, const std::vector<double>& altitude_m, bool relative,
                 double altitude_sigma, const AltitudeFusionOptions& o, AltitudeFusion* f) {
  std::vector<double> offsets;
  for (size_t i = 0; i < vision_m.size(); ++i)
    if (Usable(vision_m[i]) && std::isfinite(altitude_m[i])) offsets.push_back(altitude_m[i] - vision_m[i]);
  f->pairs = static_cast<int>(offsets.size());
  if (offsets.empty()) return;
  f->ground_m = relative ? 0.0 : Median(offsets);
  double sum = 0;
  for (size_t i = 0; i < vision_m.size(); ++i) {
    if (!(Usable(vision_m[i]) && std::isfinite(altitude_m[i]))) continue;
    const double r = altitude_m[i] - f->ground_m - vision_m[i];
    const double v = o.vision_survey_sigma * vision_m[i];
    sum += r * r / (altitude_sigma * altitude_sigma + v * v);
  }
  f->normalised_rms = std::sqrt(sum / f->pairs);
}

}  // namespace

AltitudeFusion FuseAltitude(const std::vector<double>& seconds, const std::vector<double>& vision_m,
                            const std::vector<double>& altitude_m, bool relative, const AltitudeFusionOptions& o) {
  const size_t n = vision_m.size();
  if (!o.enabled) return VisionOnly(vision_m, "vision heights only (altitude_fusion.enabled: false)");
  if (seconds.size() != n || altitude_m.size() != n) return VisionOnly(vision_m, "vision heights only (no tags)");
  const double altitude_sigma = relative ? o.relative_altitude_sigma : o.gps_altitude_sigma;
  const char* tags = relative ? "DJI relative altitude" : "GPS altitude";
  AltitudeFusion probe;
  Consistency(vision_m, altitude_m, relative, altitude_sigma, o, &probe);
  std::ostringstream os;
  if (probe.pairs < 3) {
    os << "vision heights only: " << probe.pairs << " frames carry both a vision height and a " << tags
       << " (3 needed)";
    return VisionOnly(vision_m, os.str());
  }
  if (!(probe.normalised_rms <= o.max_normalised_rms)) {
    os << "vision heights only: the " << tags << " disagrees with them by " << probe.normalised_rms
       << " sigmas RMS (sigma " << altitude_sigma << " m and " << 100 * o.vision_survey_sigma
       << " % of the height; fused at <= " << o.max_normalised_rms << ")";
    AltitudeFusion f = VisionOnly(vision_m, os.str());
    f.ground_m = probe.ground_m, f.normalised_rms = probe.normalised_rms, f.pairs = probe.pairs;
    return f;
  }
  HeightFilterOptions fo = o.filter;
  fo.gps_use = "fused";
  fo.gps_height_sigma = altitude_sigma;
  HeightFilter filter(fo);
  AltitudeFusion f = probe;
  f.fused = true;
  f.height_m.assign(n, std::numeric_limits<double>::quiet_NaN());
  f.source.assign(n, HeightSource::kNone);
  for (size_t i = 0; i < n; ++i) {
    const int64_t utime = static_cast<int64_t>(std::llround(seconds[i] * 1e6));
    const double hag = std::isfinite(altitude_m[i]) ? altitude_m[i] - f.ground_m : std::nan("");
    const bool vision = Usable(vision_m[i]), altitude = Usable(hag);
    if (vision) filter.UpdateVision(vision_m[i], utime);
    if (!filter.initialized() && altitude) filter.Reset(hag, utime);
    else if (altitude) filter.UpdateGps(hag, utime);
    if (!vision && !altitude) continue;
    f.height_m[i] = filter.height();
    f.source[i] = vision && altitude ? HeightSource::kFused : vision ? HeightSource::kVision : HeightSource::kAltitude;
  }
  os << "vision heights fused with the " << tags << " (sigma " << altitude_sigma << " m"
     << (relative ? "" : ", ground level fitted at " + std::to_string(f.ground_m) + " m") << "; they agree to "
     << f.normalised_rms << " sigmas RMS over " << f.pairs << " frames)";
  f.why = os.str();
  return f;
}

}  // namespace vloc::mosaic
