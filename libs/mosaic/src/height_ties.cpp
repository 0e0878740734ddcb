// The height-tie step of ProcessFrame (height_graph.h): the registered frame
// joins the height graph by its registration and by ties to the kept earlier
// frames that overlap it most (the adjacent strip of a survey), each matched
// inside a gate around where the mosaic poses put it; the frame's height is
// then the graph's solution.
#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {

void UavMosaicker::TieHeights(FrameWork* w) {
  const HeightGraphOptions& o = options_.height_graph;
  if (o.ties <= 0) return;
  const Registration& r = w->registration;
  const double log_s = std::log(r.mosaic_from_frame.Scale());
  const int key = w->state.frame_index;
  heights_.AddFrame(key, log_s);
  if (observations_) observations_->frames.emplace_back(key, log_s);
  std::vector<HeightObservation> measured;
  if (r.reference && r.source != RegistrationSource::kMosaic)
    measured.push_back(RegistrationLink(*w, log_s - std::log(r.reference->mosaic_from_frame.Scale())));
  for (const Keyframe* n : FramesToTie(*w)) {
    const double chained = log_s - std::log(n->mosaic_from_frame.Scale());
    std::optional<HeightObservation> tie = HeightRatioTo(*n, *w);
    if (!tie || std::abs(tie->log_ratio - chained) > o.max_disagreement) continue;
    measured.push_back(std::move(*tie));
    ++summary_.height_ties;
  }
  for (HeightObservation& m : measured) {
    heights_.AddTie(m.from, m.to, m.log_ratio, o.SigmaFor(m.support));
    if (observations_) observations_->pairs.push_back(std::move(m));
  }
  heights_.Solve();
  summary_.height_ties_dropped = heights_.dropped();
  summary_.height_tie_rms = heights_.ResidualRms();
}

// The registration's own height ratio as a link of the graph; its points
// when the ratio came from the ground plane (scale_source homography).
HeightObservation UavMosaicker::RegistrationLink(const FrameWork& w, double log_ratio) const {
  const Registration& r = w.registration;
  HeightObservation link{r.reference->frame_index, w.state.frame_index, log_ratio, r.motion.num_background,
                         r.reference->normal};
  if (observations_ && w.plane_ok && options_.scale_source == "homography") {
    link.from_px = r.motion.from_background;
    link.to_px = r.motion.to_background;
  }
  return link;
}

// The kept frames (not the registration's reference) covering at least
// min_overlap of this frame by their mosaic poses, most overlap first.
std::vector<const Keyframe*> UavMosaicker::FramesToTie(const FrameWork& w) const {
  const Registration& r = w.registration;
  const Similarity2 frame_from_mosaic = r.mosaic_from_frame.Inverse();
  std::vector<std::pair<double, const Keyframe*>> overlapping;
  for (const Keyframe& n : neighbours_) {
    // (The kept frames are earlier ones: this frame joins them after its height.)
    if ((r.reference && n.frame_index == r.reference->frame_index) || !heights_.Has(n.frame_index)) continue;
    const double overlap = OverlapFraction(frame_from_mosaic * n.mosaic_from_frame, w.frame.size());
    if (overlap >= options_.height_graph.min_overlap) overlapping.emplace_back(overlap, &n);
  }
  std::sort(overlapping.begin(), overlapping.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  const size_t ties = static_cast<size_t>(options_.height_graph.ties);
  if (overlapping.size() > ties) overlapping.resize(ties);
  std::vector<const Keyframe*> frames;
  for (const auto& [overlap, n] : overlapping) frames.push_back(n);
  return frames;
}

// log(h_frame / h_earlier) of the plane homography from the earlier frame,
// matched inside a gate around the mosaic poses' prediction; none when the
// match or the decomposition fails. Its points are kept only when the
// observations are (KeepHeightObservations).
std::optional<HeightObservation> UavMosaicker::HeightRatioTo(const Keyframe& earlier, const FrameWork& w) const {
  MotionPrior prior;
  prior.to_from_from = w.registration.mosaic_from_frame.Inverse() * earlier.mosaic_from_frame;
  prior.gate_px = options_.guide_gate * w.frame.cols;
  MotionEstimate m = EstimateMotion(earlier.features, w.features, options_.matcher, &prior);
  if (!m.ok) return std::nullopt;
  const std::optional<PlaneRatio> plane = PlaneFromHomography(m.homography, undistorter_.camera().K(), earlier.normal);
  if (!plane) return std::nullopt;
  HeightObservation tie{earlier.frame_index, w.state.frame_index, std::log(plane->height_ratio), m.num_background,
                        earlier.normal};
  if (observations_) {
    tie.from_px = std::move(m.from_background);
    tie.to_px = std::move(m.to_background);
  }
  return tie;
}

// The frame's scale (mosaic px per frame px) as the height graph solves it; none when ties are off or the frame is
// not in the graph (then its registration's scale stands).
std::optional<double> UavMosaicker::GraphScale(int frame_index) const {
  if (options_.height_graph.ties <= 0) return std::nullopt;
  const std::optional<double> solved = heights_.LogScale(frame_index);
  if (!solved) return std::nullopt;
  return std::exp(*solved);
}

void UavMosaicker::FinishHeights() {
  if (!heights_.Windowed() || !heights_.SolveAll()) return;
  summary_.height_ties_dropped = heights_.dropped();
  summary_.height_tie_rms = heights_.ResidualRms();
}

std::optional<double> UavMosaicker::AdjustedHeight(int frame_index) const {
  const std::optional<double> scale = GraphScale(frame_index);
  if (!scale || !calibrated_) return std::nullopt;
  return *scale * metres_per_pixel_ * focal_;
}

}  // namespace vloc::mosaic
