// Candidate 2: matching against the keyframe inside a gate around the
// predicted pose (GPS motion when tied to GPS, else the last frame-to-frame
// motion): only candidates near where a feature should land compete
// (registration.h). Needs guided_matching and a prediction.
#include "vloc/mosaic/registration.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {

Registration RegisterGuided(const RegistrationInput& in, const MosaickerOptions& options) {
  Registration r;
  if (!options.guided_matching || !*in.prediction) return r;
  const Prediction& prediction = **in.prediction;
  r.tried = true;
  r.source = RegistrationSource::kKeyframe;
  r.reference = in.keyframe;
  // The predicted pose, rebuilt from its scale and heading about the principal point.
  const cv::Point2d c = in.principal_point;
  Similarity2 P = Similarity2::FromScaleAngle(prediction.mosaic_from_frame.Scale(),
                                              prediction.mosaic_from_frame.Angle(), 0, 0);
  const cv::Point2d at = prediction.mosaic_from_frame.Apply(c), moved = P.Apply(c);
  P.tx = at.x - moved.x;
  P.ty = at.y - moved.y;
  MotionPrior prior;
  prior.to_from_from = P.Inverse() * in.keyframe->mosaic_from_frame;
  prior.gate_px = prediction.gate_px;
  r.motion = EstimateMotion(in.keyframe->features, *in.features, options.matcher, &prior);
  std::string why = r.motion.ok ? "" : r.motion.why;
  if (r.motion.ok) {
    r.mosaic_from_frame = in.keyframe->mosaic_from_frame * r.motion.similarity.Inverse();
    r.ok = Evidence(r.motion, r.mosaic_from_frame, prediction, c, options, &why, &r.gps_rejections);
    r.motion.ok = r.ok;
  }
  if (!r.ok) r.why = "guided by the " + std::string(prediction.from_gps ? "GPS" : "last motion") + ": " + why;
  return r;
}

}  // namespace vloc::mosaic
