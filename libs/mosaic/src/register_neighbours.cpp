// Candidate 3: the kept registered frames nearest to where the frame is
// expected (neighbour_frames, neighbour_tries): the neighbour on the adjacent
// strip of a survey, the frame before a bad one (registration.h).
#include <algorithm>
#include <utility>
#include <vector>

#include "vloc/mosaic/registration.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {

Registration RegisterToNeighbours(const RegistrationInput& in, const MosaickerOptions& options) {
  Registration r;
  if (in.neighbours->empty()) return r;
  r.tried = true;
  r.source = RegistrationSource::kNeighbour;
  // Where the frame centre is expected in the mosaic, and how far a frame that overlaps it can be.
  const cv::Point2d c = in.principal_point;
  const std::optional<Prediction>& prediction = *in.prediction;
  const Similarity2& expected = prediction ? prediction->mosaic_from_frame : in.last_good;
  const cv::Point2d at = expected.Apply(c);
  const double reach = expected.Scale() * in.features->size.width;
  std::vector<std::pair<double, const Keyframe*>> near;
  for (const auto& n : *in.neighbours) {
    if (in.keyframe && n.frame_index == in.keyframe->frame_index) continue;  // tried already
    const double d = cv::norm(n.mosaic_from_frame.Apply(c) - at);
    if (d < reach) near.emplace_back(d, &n);
  }
  std::sort(near.begin(), near.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  if (near.size() > static_cast<size_t>(options.neighbour_tries)) near.resize(options.neighbour_tries);
  std::string tried;
  for (const auto& [d, n] : near) {
    MotionEstimate m = EstimateMotion(n->features, *in.features, options.matcher);
    std::string reason = m.ok ? "" : m.why;
    if (m.ok) {
      const Similarity2 S = n->mosaic_from_frame * m.similarity.Inverse();
      if (Evidence(m, S, prediction, c, options, &reason, &r.gps_rejections)) {
        r.ok = true;
        r.motion = m;
        r.mosaic_from_frame = S;
        r.reference = n;
        return r;
      }
    }
    tried = reason;
  }
  if (!near.empty()) r.why = std::to_string(near.size()) + " earlier frames nearby: " + tried;
  return r;
}

}  // namespace vloc::mosaic
