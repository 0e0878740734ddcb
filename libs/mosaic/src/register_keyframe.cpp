// Candidate 1: plain matching against the keyframe (registration.h).
#include "vloc/mosaic/registration.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {

Registration RegisterToKeyframe(const RegistrationInput& in, const MosaickerOptions& options) {
  Registration r;
  r.tried = true;
  r.source = RegistrationSource::kKeyframe;
  r.reference = in.keyframe;
  r.motion = EstimateMotion(in.keyframe->features, *in.features, options.matcher);
  if (!r.motion.ok) {
    r.why = "matching failed: " + r.motion.why;
    return r;
  }
  r.mosaic_from_frame = in.keyframe->mosaic_from_frame * r.motion.similarity.Inverse();
  r.ok = Evidence(r.motion, r.mosaic_from_frame, *in.prediction, in.principal_point, options, &r.why,
                  &r.gps_rejections);
  r.motion.ok = r.ok;
  return r;
}

}  // namespace vloc::mosaic
