// Each registration candidate of the mosaicker (registration.h) on
// synthetic nadir frames with known poses: the mosaic is the ground image
// itself (mosaic px = ground px), so every true mosaic_from_frame is known.
#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <optional>

#include "synthetic_nadir.h"
#include "vloc/mosaic/mosaic_blender.h"
#include "vloc/mosaic/registration.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {
namespace {

using testing::NadirCamera;

class RegistrationCandidates : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { ground_ = new testing::SyntheticGround(testing::MakeGround(2400, 0.05, 7)); }
  static void TearDownTestSuite() { delete ground_; }

  struct View {
    cv::Mat image;
    FrameFeatures features;
    Similarity2 mosaic_from_frame;  // truth: frame px -> ground px
  };
  static View Shoot(double east, double north, double yaw, int seed, double height = 40) {
    View v;
    v.image = testing::RenderNadir(*ground_, cam_, east, north, height, yaw, 2.0, seed);
    const cv::Matx23d M = testing::GroundFromView(*ground_, cam_, east, north, height, yaw);
    v.mosaic_from_frame = Similarity2{M(0, 0), M(1, 0), M(0, 2), M(1, 2)};
    v.features = ExtractFeatures(v.image, Options().matcher);
    return v;
  }
  static MosaickerOptions Options() {
    MosaickerOptions o = testing::OptionsForCamera(cam_, 40);
    o.guided_matching = true;
    o.min_spread = 0.02;
    return o;
  }
  static cv::Point2d Centre() { return {cam_.cx(), cam_.cy()}; }
  // Distance (ground px) between the frame centres of two poses.
  static double CentreError(const Similarity2& a, const Similarity2& b) {
    return cv::norm(a.Apply(Centre()) - b.Apply(Centre()));
  }
  // A registration input for `frame` against `key`, nothing else known.
  RegistrationInput Input(const View& frame, const Keyframe* key) {
    RegistrationInput in;
    in.frame = &frame.image;
    in.features = &frame.features;
    in.principal_point = Centre();
    in.prediction = &prediction_;
    in.keyframe = key;
    in.neighbours = &neighbours_;
    in.last_good = key ? key->mosaic_from_frame : Similarity2{};
    return in;
  }
  // A kept frame; its time doubles as its (unique) frame index.
  static Keyframe KeyOf(const View& v, int64_t utime = 0) {
    return Keyframe{v.features, v.mosaic_from_frame, utime, static_cast<int>(utime)};
  }
  // Five views 5 m apart along the east axis (seeds first_seed...) blended into `blender`.
  static void PaintStrip(MosaicBlender* blender, int first_seed) {
    blender->Start();
    for (int i = 0; i < 5; ++i) {
      const View v = Shoot(-10 + 5 * i, 0, 0, first_seed + i);
      ASSERT_TRUE(blender->Blend(v.image, v.mosaic_from_frame).done);
    }
  }
  // A GPS prediction `offset` (ground px) from `truth`, with a 200 px tolerance.
  static Prediction GpsPrediction(const Similarity2& truth, const Similarity2& offset) {
    Prediction p;
    p.from_gps = true;
    p.mosaic_from_frame = offset * truth;
    p.gps_px = p.mosaic_from_frame.Apply(Centre());
    p.gps_tolerance_px = 200;
    return p;
  }

  static testing::SyntheticGround* ground_;
  static NadirCamera cam_;
  std::optional<Prediction> prediction_;
  std::deque<Keyframe> neighbours_;
};
testing::SyntheticGround* RegistrationCandidates::ground_ = nullptr;
NadirCamera RegistrationCandidates::cam_;

TEST_F(RegistrationCandidates, KeyframeRegistersAnOverlappingFrameAndSaysWhyNotABlankOne) {
  const View a = Shoot(0, 0, 0.1, 1), b = Shoot(6, 2, 0.15, 2);
  const Keyframe key = KeyOf(a);
  const Registration r = RegisterToKeyframe(Input(b, &key), Options());
  ASSERT_TRUE(r.ok) << r.why;
  EXPECT_EQ(r.source, RegistrationSource::kKeyframe);
  EXPECT_EQ(r.reference, &key);
  EXPECT_LT(CentreError(r.mosaic_from_frame, b.mosaic_from_frame), 1.5);
  EXPECT_NEAR(r.mosaic_from_frame.Scale(), b.mosaic_from_frame.Scale(), 0.01 * b.mosaic_from_frame.Scale());

  View blank = b;
  blank.image = cv::Mat(cam_.size, CV_8UC3, cv::Scalar::all(90));
  blank.features = ExtractFeatures(blank.image, Options().matcher);
  const Registration f = RegisterToKeyframe(Input(blank, &key), Options());
  EXPECT_TRUE(f.tried);
  EXPECT_FALSE(f.ok);
  EXPECT_EQ(f.why.rfind("matching failed: ", 0), 0u) << f.why;
}

TEST_F(RegistrationCandidates, GuidedNeedsAPredictionAndRegistersInsideItsGate) {
  const View a = Shoot(0, 0, 0.0, 3), b = Shoot(10, -3, 0.05, 4);
  const Keyframe key = KeyOf(a);
  EXPECT_FALSE(RegisterGuided(Input(b, &key), Options()).tried);  // no prediction
  MosaickerOptions no_guide = Options();
  no_guide.guided_matching = false;
  Prediction p;
  p.mosaic_from_frame = Similarity2{1, 0, 8, -4} * b.mosaic_from_frame;  // a few px off the truth
  p.gate_px = 40;
  prediction_ = p;
  EXPECT_FALSE(RegisterGuided(Input(b, &key), no_guide).tried);
  const Registration r = RegisterGuided(Input(b, &key), Options());
  ASSERT_TRUE(r.tried);
  ASSERT_TRUE(r.ok) << r.why;
  EXPECT_TRUE(r.motion.guided);
  EXPECT_LT(CentreError(r.mosaic_from_frame, b.mosaic_from_frame), 1.5);
}

TEST_F(RegistrationCandidates, EvidenceRejectsAWeakRegistrationFarFromTheGpsButNotAStrongOne) {
  const View a = Shoot(0, 0, 0.0, 5), b = Shoot(6, 0, 0.0, 6);
  const Keyframe key = KeyOf(a);
  Prediction p;
  p.from_gps = true;
  p.mosaic_from_frame = b.mosaic_from_frame;
  p.gps_px = b.mosaic_from_frame.Apply(Centre()) + cv::Point2d(200, 0);  // the GPS says 200 ground px east
  p.gps_tolerance_px = 50;
  prediction_ = p;
  MosaickerOptions o = Options();
  const Registration plain = RegisterToKeyframe(Input(b, &key), o);
  ASSERT_TRUE(plain.motion.num_background > 0);
  // Below gps_check_below_inliers the GPS vetoes it; above, the matches stand on their own.
  o.gps_check_below_inliers = plain.motion.num_background + 1;
  const Registration vetoed = RegisterToKeyframe(Input(b, &key), o);
  EXPECT_FALSE(vetoed.ok);
  EXPECT_EQ(vetoed.gps_rejections, 1);
  EXPECT_NE(vetoed.why.find("from the GPS position"), std::string::npos) << vetoed.why;
  o.gps_check_below_inliers = plain.motion.num_background;
  const Registration kept = RegisterToKeyframe(Input(b, &key), o);
  EXPECT_TRUE(kept.ok) << kept.why;
  EXPECT_EQ(kept.gps_rejections, 0);
}

TEST_F(RegistrationCandidates, NeighboursTryTheNearestKeptFramesNotTheKeyframe) {
  const View key_view = Shoot(-20, 0, 0.0, 7), near = Shoot(0, 6, 0.0, 8), far = Shoot(60, 40, 0.0, 9);
  const View b = Shoot(3, 8, 0.02, 10);
  const Keyframe key = KeyOf(key_view, 100);
  EXPECT_FALSE(RegisterToNeighbours(Input(b, &key), Options()).tried);  // none kept
  neighbours_ = {KeyOf(far, 1), KeyOf(near, 2), key};
  RegistrationInput in = Input(b, &key);
  in.last_good = near.mosaic_from_frame;  // expected near `near` (no prediction)
  const Registration r = RegisterToNeighbours(in, Options());
  ASSERT_TRUE(r.ok) << r.why;
  EXPECT_EQ(r.source, RegistrationSource::kNeighbour);
  ASSERT_NE(r.reference, nullptr);
  EXPECT_EQ(r.reference->utime, 2);
  EXPECT_LT(CentreError(r.mosaic_from_frame, b.mosaic_from_frame), 1.5);
}

TEST_F(RegistrationCandidates, MosaicSearchIsCentredOnThePoseItIsGiven) {
  MosaickerOptions o = Options();
  MosaicBlender blender(o.canvas, false);
  PaintStrip(&blender, 20);
  const View b = Shoot(2, 1, 0.1, 30);
  // Searched around the truth: registered; around a pose 2 km away: nothing painted there.
  const Registration r = RegisterToMosaic(b.image, b.features, blender, b.mosaic_from_frame, 1.6, o);
  ASSERT_TRUE(r.ok) << r.why;
  EXPECT_EQ(r.source, RegistrationSource::kMosaic);
  EXPECT_LT(CentreError(r.mosaic_from_frame, b.mosaic_from_frame), 2.0);
  const Registration away =
      RegisterToMosaic(b.image, b.features, blender, Similarity2{1, 0, 40000, 0} * b.mosaic_from_frame, 1.6, o);
  EXPECT_FALSE(away.ok);
  EXPECT_LT(away.painted, o.recovery_min_painted);
  EXPECT_EQ(away.why.rfind("mosaic covers only", 0), 0u) << away.why;

  // After a loss only, searched at the GPS prediction when there is one, else at last_good.
  RegistrationInput in = Input(b, nullptr);
  in.mosaic = &blender;
  in.last_good = Similarity2{1, 0, 40000, 0} * b.mosaic_from_frame;
  EXPECT_FALSE(RegisterToMosaicAfterLoss(in, o).tried);
  in.lost = true;
  EXPECT_FALSE(RegisterToMosaicAfterLoss(in, o).ok);
  prediction_ = GpsPrediction(b.mosaic_from_frame, Similarity2{1, 0, 15, -10});
  const Registration at_gps = RegisterToMosaicAfterLoss(in, o);
  ASSERT_TRUE(at_gps.ok) << at_gps.why;
  EXPECT_LT(CentreError(at_gps.mosaic_from_frame, b.mosaic_from_frame), 2.0);

  // Refinement: a chain pose off by 20 ground px is pulled back; one off by 3 frames is rejected.
  const Similarity2 drifted = Similarity2{1, 0, 20, 0} * b.mosaic_from_frame;
  const std::optional<Similarity2> refined = RefineAgainstMosaic(b.image, b.features, blender, drifted, Centre(), o);
  ASSERT_TRUE(refined.has_value());
  EXPECT_LT(CentreError(*refined, b.mosaic_from_frame), 2.0);
  EXPECT_DOUBLE_EQ(refined->Scale(), drifted.Scale());  // reregister_scale false: the chain's scale
  const Similarity2 elsewhere = Similarity2{1, 0, 3 * 640 * b.mosaic_from_frame.Scale(), 0} * b.mosaic_from_frame;
  EXPECT_FALSE(RefineAgainstMosaic(b.image, b.features, blender, elsewhere, Centre(), o).has_value());
}

TEST_F(RegistrationCandidates, PlaceByGpsOnlyOnNewGroundAndOnlyWhenAsked) {
  MosaickerOptions o = Options();
  MosaicBlender blender(o.canvas, false);
  blender.Start();
  const View mapped = Shoot(0, 0, 0, 40);
  ASSERT_TRUE(blender.Blend(mapped.image, mapped.mosaic_from_frame).done);
  const View b = Shoot(0, 0, 0, 41);
  RegistrationInput in = Input(b, nullptr);
  in.mosaic = &blender;
  Prediction p;
  p.from_gps = true;
  p.mosaic_from_frame = Similarity2{1, 0, 30000, 0} * b.mosaic_from_frame;  // new ground
  prediction_ = p;
  std::string why;
  EXPECT_FALSE(PlaceByGps(in, o, &why).has_value());  // reseat_by_gps off
  o.reseat_by_gps = true;
  const std::optional<Similarity2> placed = PlaceByGps(in, o, &why);
  ASSERT_TRUE(placed.has_value());
  EXPECT_LT(CentreError(*placed, p.mosaic_from_frame), 1e-9);
  EXPECT_NE(why.find("GPS position"), std::string::npos);
  prediction_->mosaic_from_frame = b.mosaic_from_frame;  // mapped ground: keep searching the mosaic instead
  EXPECT_FALSE(PlaceByGps(in, o, &why).has_value());
  prediction_->from_gps = false;  // a motion prediction never places a frame
  prediction_->mosaic_from_frame = Similarity2{1, 0, 30000, 0} * b.mosaic_from_frame;
  EXPECT_FALSE(PlaceByGps(in, o, &why).has_value());
}

// reseat_after_gap_s: a frame long after the last registered one (a folder's
// next flight) is searched for in the mosaic at its GPS position without a
// loss before it, and placed there on new ground even with reseat_by_gps off.
TEST_F(RegistrationCandidates, ANewFlightIsSearchedInTheMosaicAndPlacedByGps) {
  MosaickerOptions o = Options();
  MosaicBlender blender(o.canvas, false);
  PaintStrip(&blender, 70);
  const View b = Shoot(2, 1, 0.1, 80);
  RegistrationInput in = Input(b, nullptr);
  in.mosaic = &blender;
  in.last_good = Similarity2{1, 0, 40000, 0} * b.mosaic_from_frame;
  prediction_ = GpsPrediction(b.mosaic_from_frame, Similarity2{1, 0, 15, -10});
  in.seconds_since_registered = 900;  // 15 minutes later, not lost
  EXPECT_FALSE(NewFlight(in, o));     // off by default
  EXPECT_FALSE(RegisterToMosaicAfterLoss(in, o).tried);
  o.reseat_after_gap_s = 60;
  ASSERT_TRUE(NewFlight(in, o));
  const Registration r = RegisterToMosaicAfterLoss(in, o);
  ASSERT_TRUE(r.ok) << r.why;
  EXPECT_LT(CentreError(r.mosaic_from_frame, b.mosaic_from_frame), 2.0);
  in.seconds_since_registered = 59;  // the same flight: no search without a loss
  EXPECT_FALSE(RegisterToMosaicAfterLoss(in, o).tried);

  in.seconds_since_registered = 900;
  prediction_->mosaic_from_frame = Similarity2{1, 0, 30000, 0} * b.mosaic_from_frame;  // new ground
  std::string why;
  ASSERT_FALSE(o.reseat_by_gps);
  const std::optional<Similarity2> placed = PlaceByGps(in, o, &why);
  ASSERT_TRUE(placed.has_value());
  EXPECT_EQ(why.rfind("a new flight (900 s after the last registered photo): placed at its GPS position", 0), 0u) << why;
  in.seconds_since_registered = 59;
  EXPECT_FALSE(PlaceByGps(in, o, &why).has_value());
}

TEST_F(RegistrationCandidates, FinerLevelTriesTheKeyframeThenTheRecentFramesWithFinerFeatures) {
  const View a = Shoot(0, 0, 0.0, 60), last = Shoot(4, 0, 0.0, 61), b = Shoot(8, 1, 0.05, 62);
  MosaickerOptions o = Options();
  o.matcher.downscale = 0.3;
  Keyframe key = KeyOf(a, 1);
  EXPECT_FALSE(RegisterAtFinerLevel(Input(b, &key), o).tried);  // fallback_downscale 0: off
  o.fallback_downscale = 1.0;
  EXPECT_FALSE(RegisterAtFinerLevel(Input(b, &key), o).tried);  // no keyframe image kept
  key.image = a.image;
  const Registration r = RegisterAtFinerLevel(Input(b, &key), o);
  ASSERT_TRUE(r.ok) << r.why;
  EXPECT_EQ(r.reference, &key);
  ASSERT_TRUE(key.finer != nullptr);  // the keyframe's finer features, kept for the next frame
  EXPECT_GT(key.finer->points.size(), ExtractFeatures(a.image, o.matcher).points.size());
  EXPECT_LT(CentreError(r.mosaic_from_frame, b.mosaic_from_frame), 1.0);
  // A keyframe that does not overlap: the recent frame registers it.
  Keyframe far = KeyOf(Shoot(300, 300, 0.0, 63), 2);
  far.image = Shoot(300, 300, 0.0, 63).image;
  std::deque<Keyframe> recent{Keyframe{last.features, last.mosaic_from_frame, 3, 3, {0, 0, 1}, last.image}};
  RegistrationInput in = Input(b, &far);
  in.recent = &recent;
  const Registration via_recent = RegisterAtFinerLevel(in, o);
  ASSERT_TRUE(via_recent.ok) << via_recent.why;
  EXPECT_EQ(via_recent.reference, &recent.front());
  EXPECT_LT(CentreError(via_recent.mosaic_from_frame, b.mosaic_from_frame), 1.0);
}

TEST_F(RegistrationCandidates, DetectWidthCapsTheDetectorsFrame) {
  MatcherOptions wide = Options().matcher, capped = wide;
  wide.downscale = 0.5;
  capped.downscale = 1.0;
  capped.detect_width = cam_.size.width / 2;
  const View v = Shoot(0, 0, 0, 70);
  const FrameFeatures a = ExtractFeatures(v.image, wide), b = ExtractFeatures(v.image, capped);
  ASSERT_EQ(a.points.size(), b.points.size());
  for (size_t i = 0; i < a.points.size(); ++i) ASSERT_EQ(a.points[i], b.points[i]);
}

// The whole mosaicker with reseat_by_gps: the aircraft jumps to unmapped
// ground (frames 20-24 rendered 150 m away, GPS following), the first of them
// is placed by GPS and LOST, the next ones register against it.
TEST_F(RegistrationCandidates, MosaickerReseatsOnNewGroundAndTracksOnFromThere) {
  MosaickerOptions o = Options();
  o.reseat_by_gps = true;
  o.geo.min_spread = 3.0;
  o.canvas.metres_per_pixel = 0.1;
  UavMosaicker m(o);
  int reseated = -1, tracked_after = 0;
  for (int i = 0; i < 26; ++i) {
    const double east = i < 20 ? -20 + 1.0 * i : 150 + 1.0 * (i - 20), north = 0;
    GpsFix fix;
    fix.utime = i * 200000;
    fix.valid = true;
    fix.horizontal_sigma = 0.5;
    EnuToLatLon({east, north}, 45.0, 7.0, &fix.latitude, &fix.longitude);
    m.AddGps(fix);
    const FrameState s = m.ProcessFrame(Shoot(east, north, 0, 50 + i).image, fix.utime);
    if (s.reseated && reseated < 0) reseated = i;
    if (i > 20 && s.status != TrackStatus::kLost) ++tracked_after;
    if (i == 20) EXPECT_EQ(s.status, TrackStatus::kLost) << s.message;
  }
  EXPECT_EQ(reseated, 20);
  EXPECT_EQ(m.summary().reseats, 1);
  EXPECT_EQ(tracked_after, 5);
}

}  // namespace
}  // namespace vloc::mosaic
