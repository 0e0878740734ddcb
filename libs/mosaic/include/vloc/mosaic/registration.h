#pragma once
// Registering a frame into the mosaic: ranked, named candidates (STYLE 9,
// 10), each in a file named for it, each returning its result or why it
// failed. UavMosaicker::ProcessFrame tries them in order until one registers:
//
//   keyframe     register_keyframe.cpp    plain matching against the keyframe
//   guided       register_guided.cpp      matching inside a gate around the GPS / motion prediction
//   neighbours   register_neighbours.cpp  the kept registered frames nearest the prediction
//   finer        register_finer.cpp       the keyframe and the last frames with features at a finer level
//   mosaic       register_mosaic.cpp      the mosaic rendered around the prediction (after a loss)
//
// then, on success, RefineAgainstMosaic (register_mosaic.cpp: periodic
// re-registration against the mosaic) and, on failure, PlaceByGps
// (reseat_by_gps.cpp). Evidence (registration_evidence.cpp) is the test every
// candidate's registration must pass.

#include <opencv2/core.hpp>

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vloc/mosaic/frame_matcher.h"
#include "vloc/mosaic/geometry.h"
#include "vloc/mosaic/gps_tie.h"

namespace vloc::mosaic {

struct MosaickerOptions;
class MosaicBlender;

// A registered frame whose features are kept to register later frames against.
struct Keyframe {
  FrameFeatures features;
  Similarity2 mosaic_from_frame;
  int64_t utime = 0;
  int frame_index = -1;               // FrameState::frame_index: unique, unlike a time (which frame this is)
  cv::Vec3d normal{0, 0, 1};          // ground-plane normal in its camera frame (scale_source homography)
  cv::Mat image;                      // undistorted (the keyframe and recent frames only: RegisterAtFinerLevel)
  mutable std::shared_ptr<FrameFeatures> finer;  // features of image at fallback_downscale, found when first needed
};

// What a candidate may use to register the frame.
struct RegistrationInput {
  const cv::Mat* frame = nullptr;                 // undistorted
  const FrameFeatures* features = nullptr;        // of *frame
  cv::Point2d principal_point;                    // frame px
  const std::optional<Prediction>* prediction = nullptr;  // where the frame is expected (GPS or motion)
  Similarity2 last_good;                          // mosaic_from_frame of the last registered frame
  bool lost = false;                              // the previous frame was not registered
  double seconds_since_registered = 0;            // s since the last registered (or placed) frame; 0 before any
  const Keyframe* keyframe = nullptr;
  const std::deque<Keyframe>* neighbours = nullptr;  // kept registered frames (neighbour_frames)
  const std::deque<Keyframe>* recent = nullptr;      // the last registered frames with their images (fallback_frames)
  const MosaicBlender* mosaic = nullptr;
};

enum class RegistrationSource { kNone, kKeyframe, kNeighbour, kMosaic };

// One candidate's outcome.
struct Registration {
  bool tried = false;                  // the candidate applied (e.g. guided needs a prediction)
  bool ok = false;
  std::string why;                     // one clause, when tried and failed (the frame's message joins them with "; ")
  MotionEstimate motion;               // reference px -> frame px (the mosaic view's px for kMosaic)
  Similarity2 mosaic_from_frame;       // the frame's pose when ok
  RegistrationSource source = RegistrationSource::kNone;
  const Keyframe* reference = nullptr;  // the frame `motion` is relative to (kKeyframe, kNeighbour)
  int gps_rejections = 0;              // registrations the GPS test rejected
  double painted = 1.0;                // kMosaic: covered fraction of the mosaic view searched
};

// The evidence test: support spread over the frame (min_spread) and, below
// gps_check_below_inliers background matches, agreement with the GPS
// position. False with one clause appended to *why ("; "-separated).
bool Evidence(const MotionEstimate& motion, const Similarity2& mosaic_from_frame,
              const std::optional<Prediction>& prediction, const cv::Point2d& principal_point,
              const MosaickerOptions& options, std::string* why, int* gps_rejections);

// The frame was taken reseat_after_gap_s or more after the last registered
// one (a survey folder's next flight): it is searched for in the mosaic
// around its GPS position, and placed there on new ground, as after a loss.
bool NewFlight(const RegistrationInput& in, const MosaickerOptions& options);

// The candidates, in rank order.
Registration RegisterToKeyframe(const RegistrationInput& in, const MosaickerOptions& options);
Registration RegisterGuided(const RegistrationInput& in, const MosaickerOptions& options);
Registration RegisterToNeighbours(const RegistrationInput& in, const MosaickerOptions& options);
Registration RegisterAtFinerLevel(const RegistrationInput& in, const MosaickerOptions& options);
Registration RegisterToMosaicAfterLoss(const RegistrationInput& in, const MosaickerOptions& options);

// The mosaic rendered around `search` (mosaic_from_frame of where the frame
// is expected) over view_scale frame sizes, the frame registered to it.
Registration RegisterToMosaic(const cv::Mat& frame, const FrameFeatures& features, const MosaicBlender& mosaic,
                              const Similarity2& search, double view_scale, const MosaickerOptions& options);

// Periodic re-registration: `chain` (the pose from the keyframe chain)
// replaced by a registration against the mosaic rendered there, when that
// moves it by no more than reregister_max_shift. nullopt: rejected.
std::optional<Similarity2> RefineAgainstMosaic(const cv::Mat& frame, const FrameFeatures& features,
                                               const MosaicBlender& mosaic, const Similarity2& chain,
                                               const cv::Point2d& principal_point, const MosaickerOptions& options);

// reseat_by_gps (or reseat_after_gap_s, for a frame that long after the
// last registered one): a frame no candidate registers is placed at its GPS
// position when the mosaic holds nothing there (new ground: nothing to
// re-acquire against). The pose, or nullopt with *why.
std::optional<Similarity2> PlaceByGps(const RegistrationInput& in, const MosaickerOptions& options, std::string* why);

}  // namespace vloc::mosaic
