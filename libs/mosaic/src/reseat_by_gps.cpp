// After every candidate failed (reseat_by_gps): the frame placed at its GPS
// position with the heading and scale of the prediction, when the mosaic
// holds nothing there to re-acquire against (registration.h).
#include "vloc/mosaic/mosaic_blender.h"
#include "vloc/mosaic/registration.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {

bool NewFlight(const RegistrationInput& in, const MosaickerOptions& options) {
  return options.reseat_after_gap_s > 0 && in.seconds_since_registered >= options.reseat_after_gap_s;
}

std::optional<Similarity2> PlaceByGps(const RegistrationInput& in, const MosaickerOptions& options, std::string* why) {
  const bool new_flight = NewFlight(in, options);
  if (!options.reseat_by_gps && !new_flight) return std::nullopt;
  const std::optional<Prediction>& prediction = *in.prediction;
  if (!prediction || !prediction->from_gps) return std::nullopt;
  // New ground: the mosaic covers less than recovery_min_painted of the view at the GPS position.
  const double k = options.recovery_view_scale;
  const cv::Size frame_size = in.features->size;
  const cv::Size view_size(static_cast<int>(frame_size.width * k), static_cast<int>(frame_size.height * k));
  const cv::Point2d offset((view_size.width - frame_size.width) / 2.0, (view_size.height - frame_size.height) / 2.0);
  cv::Mat view, mask;
  const double painted =
      in.mosaic ? in.mosaic->Render(prediction->mosaic_from_frame * Similarity2{1, 0, -offset.x, -offset.y}, view_size,
                                    &view, &mask)
                : 0.0;
  if (painted >= options.recovery_min_painted) return std::nullopt;  // mapped ground: keep searching the mosaic
  *why = "placed at its GPS position, tracking restarts from this frame";
  if (new_flight && !options.reseat_by_gps)
    *why = "a new flight (" + std::to_string(static_cast<int>(in.seconds_since_registered)) +
           " s after the last registered photo): " + *why;
  return prediction->mosaic_from_frame;
}

}  // namespace vloc::mosaic
