// Candidate 4 (after a loss) and the periodic refinement: the frame
// registered against the mosaic rendered where it is expected (registration.h).
#include <opencv2/imgproc.hpp>

#include <cmath>

#include "vloc/mosaic/mosaic_blender.h"
#include "vloc/mosaic/registration.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {

namespace {

// Features of the view, without those on the border of its painted area (artificial corners).
FrameFeatures PaintedFeatures(const cv::Mat& view, cv::Mat mask, const MatcherOptions& options) {
  FrameFeatures vf = ExtractFeatures(view, options);
  cv::erode(mask, mask, cv::Mat(), cv::Point(-1, -1), 6);
  FrameFeatures kept;
  kept.size = vf.size;
  for (size_t i = 0; i < vf.points.size(); ++i) {
    const cv::Point p(cvRound(vf.points[i].x), cvRound(vf.points[i].y));
    if (p.inside(cv::Rect(0, 0, mask.cols, mask.rows)) && mask.at<uchar>(p)) {
      kept.points.push_back(vf.points[i]);
      kept.descriptors.push_back(vf.descriptors.row(static_cast<int>(i)));
    }
  }
  return kept;
}

}  // namespace

Registration RegisterToMosaic(const cv::Mat& frame, const FrameFeatures& features, const MosaicBlender& mosaic,
                              const Similarity2& search, double view_scale, const MosaickerOptions& options) {
  Registration r;
  r.tried = true;
  r.source = RegistrationSource::kMosaic;
  const double k = view_scale;
  const cv::Size view_size(static_cast<int>(frame.cols * k), static_cast<int>(frame.rows * k));
  const cv::Point2d offset((view_size.width - frame.cols) / 2.0, (view_size.height - frame.rows) / 2.0);
  // view px v -> frame px v - offset -> mosaic via the search pose.
  const Similarity2 mosaic_from_view = search * Similarity2{1, 0, -offset.x, -offset.y};
  cv::Mat view, mask;
  r.painted = mosaic.Render(mosaic_from_view, view_size, &view, &mask);
  if (r.painted < options.recovery_min_painted) {
    r.why = "mosaic covers only " + std::to_string(r.painted) + " of the search area";
    return r;
  }
  const FrameFeatures kept = PaintedFeatures(view, mask, options.matcher);
  r.motion = EstimateMotion(kept, features, options.matcher);
  if (!r.motion.ok && options.guided_matching) {
    // Guided: the view was rendered where the frame is expected (view px - offset = frame px).
    MotionPrior prior;
    prior.to_from_from = Similarity2{1, 0, -offset.x, -offset.y};
    prior.gate_px = options.guide_gate * frame.cols + offset.x;
    MotionEstimate guided = EstimateMotion(kept, features, options.matcher, &prior);
    if (guided.ok) r.motion = guided;
  }
  if (!r.motion.ok) {
    r.why = "against the mosaic: " + r.motion.why;
    return r;
  }
  r.mosaic_from_frame = mosaic_from_view * r.motion.similarity.Inverse();
  r.ok = true;
  return r;
}

Registration RegisterToMosaicAfterLoss(const RegistrationInput& in, const MosaickerOptions& options) {
  if (!(in.lost || NewFlight(in, options)) || !in.mosaic || !in.mosaic->started()) return {};
  // Search where the GPS says the frame is, else around the last registered pose.
  const std::optional<Prediction>& prediction = *in.prediction;
  const Similarity2 search = prediction && prediction->from_gps ? prediction->mosaic_from_frame : in.last_good;
  Registration r = RegisterToMosaic(*in.frame, *in.features, *in.mosaic, search, options.recovery_view_scale, options);
  if (r.ok) {
    r.ok = Evidence(r.motion, r.mosaic_from_frame, prediction, in.principal_point, options, &r.why,
                    &r.gps_rejections);
  }
  return r;
}

std::optional<Similarity2> RefineAgainstMosaic(const cv::Mat& frame, const FrameFeatures& features,
                                               const MosaicBlender& mosaic, const Similarity2& chain,
                                               const cv::Point2d& c, const MosaickerOptions& options) {
  // Render the mosaic around the pose of the chain and register the frame to it.
  const Registration r = RegisterToMosaic(frame, features, mosaic, chain, 1.0 + 2 * options.reregister_max_shift, options);
  if (!r.ok) return std::nullopt;
  Similarity2 S = r.mosaic_from_frame;
  // Accept only a correction the size of drift, not a different place.
  const double shift_frames = cv::norm(S.Apply(c) - chain.Apply(c)) / (chain.Scale() * frame.cols);
  const double scale_change = std::abs(S.Scale() / chain.Scale() - 1.0);
  if (shift_frames > options.reregister_max_shift || scale_change > options.reregister_max_shift ||
      r.motion.num_background < options.matcher.min_inliers)
    return std::nullopt;
  if (!options.reregister_scale) {
    // Position and heading from the mosaic, scale (height) from the chain: the
    // mosaic is often coarser than the frame, its scale the less precise.
    Similarity2 kept = Similarity2::FromScaleAngle(chain.Scale(), S.Angle(), 0, 0);
    const cv::Point2d target = S.Apply(c), moved = kept.Apply(c);
    kept.tx = target.x - moved.x;
    kept.ty = target.y - moved.y;
    S = kept;
  }
  return S;
}

}  // namespace vloc::mosaic
