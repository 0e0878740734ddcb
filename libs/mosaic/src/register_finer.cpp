// Candidate 4 (fallback_downscale): the keyframe again, plain then guided,
// with the features of both frames at a finer level than matcher.downscale.
// The detector runs on a reduced level for speed; the few frames that level
// misses (low texture) get the full one (registration.h).
#include <memory>

#include "vloc/mosaic/registration.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {

namespace {

// Plain, then guided, against one reference at the finer level.
Registration AgainstAtFinerLevel(const RegistrationInput& in, const FrameFeatures& features, const Keyframe& reference,
                                 const MosaickerOptions& finer) {
  if (!reference.finer)
    reference.finer = std::make_shared<FrameFeatures>(ExtractFeatures(reference.image, finer.matcher));
  const Keyframe key{*reference.finer, reference.mosaic_from_frame, reference.utime, reference.frame_index,
                     reference.normal};
  RegistrationInput at_finer = in;
  at_finer.features = &features;
  at_finer.keyframe = &key;
  Registration r = RegisterToKeyframe(at_finer, finer);
  if (!r.ok) {
    Registration guided = RegisterGuided(at_finer, finer);
    if (guided.tried) {
      const int rejections = r.gps_rejections + guided.gps_rejections;
      const std::string why = r.why + "; " + guided.why;
      if (guided.ok || guided.motion.num_matches > r.motion.num_matches) r = std::move(guided);
      r.gps_rejections = rejections;
      if (!r.ok) r.why = why;
    }
  }
  r.reference = &reference;
  return r;
}

}  // namespace

// The keyframe, then the recent registered frames newest first.
Registration RegisterAtFinerLevel(const RegistrationInput& in, const MosaickerOptions& options) {
  if (!(options.fallback_downscale > 0) || !in.keyframe || in.keyframe->image.empty() || !in.frame) return {};
  MosaickerOptions finer = options;
  finer.matcher.downscale = options.fallback_downscale;
  finer.matcher.detect_width = 0;
  const FrameFeatures features = ExtractFeatures(*in.frame, finer.matcher);
  std::vector<const Keyframe*> references{in.keyframe};
  if (in.recent)
    for (auto it = in.recent->rbegin(); it != in.recent->rend(); ++it)
      if (it->frame_index != in.keyframe->frame_index && !it->image.empty()) references.push_back(&*it);
  Registration result;
  int rejections = 0;
  std::string why;
  for (const Keyframe* reference : references) {
    Registration r = AgainstAtFinerLevel(in, features, *reference, finer);
    rejections += r.gps_rejections;
    if (r.ok || !result.tried || r.motion.num_matches > result.motion.num_matches) result = std::move(r);
    if (result.ok) break;
    why += (why.empty() ? "" : "; ") + result.why;
  }
  result.gps_rejections = rejections;
  if (!result.ok)
    result.why = "at the finer level (" + std::to_string(options.fallback_downscale) + ", " +
                 std::to_string(references.size()) + " frames): " + why;
  return result;
}

}  // namespace vloc::mosaic
