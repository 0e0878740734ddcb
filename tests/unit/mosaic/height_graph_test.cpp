// The height graph (height_graph.h): a chain alone is kept as chained; ties
// across the strips of a survey bound the chain's random walk; a gross tie is
// dropped. The height-tie step of the mosaicker on a synthetic two-strip
// survey: ties made, every height within 2 % of the truth.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <vector>

#include "synthetic_nadir.h"
#include "vloc/mosaic/height_graph.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {
namespace {

constexpr double kLinkSigma = 0.02;  // log: one height ratio (seneca's links against the GPS altitude: 2.5 %)

// A lawnmower survey of `strips` strips of `per_strip` frames: true log heights, and the graph of its noisy
// registration chain plus (with_ties) one tie from each frame to the frame beside it on the previous strip.
struct Survey {
  std::vector<double> truth;
  HeightGraph graph;
};

Survey FlySurvey(int strips, int per_strip, bool with_ties, uint64_t seed) {
  cv::RNG rng(seed);
  Survey s;
  const int n = strips * per_strip;
  for (int i = 0; i < n; ++i) s.truth.push_back(std::log(60.0) + 0.05 * std::sin(0.3 * i));
  double chained = s.truth[0];
  s.graph.AddFrame(0, chained);
  for (int i = 1; i < n; ++i) {
    const double link = s.truth[i] - s.truth[i - 1] + rng.gaussian(kLinkSigma);
    chained += link;
    s.graph.AddFrame(i, chained);
    s.graph.AddTie(i - 1, i, link, kLinkSigma);
  }
  if (with_ties) {
    for (int i = per_strip; i < n; ++i) {
      const int strip = i / per_strip, along = i % per_strip;
      const int beside = (strip - 1) * per_strip + (per_strip - 1 - along);  // strips alternate direction
      s.graph.AddTie(beside, i, s.truth[i] - s.truth[beside] + rng.gaussian(kLinkSigma), kLinkSigma);
    }
  }
  return s;
}

double RmsError(const Survey& s, bool solved) {
  double sum = 0;
  for (size_t i = 0; i < s.truth.size(); ++i) {
    const double x = solved ? *s.graph.LogScale(static_cast<int64_t>(i)) : s.graph.ChainedLogScale(static_cast<int64_t>(i));
    sum += (x - s.truth[i]) * (x - s.truth[i]);
  }
  return std::sqrt(sum / s.truth.size());
}

TEST(HeightGraph, ChainAloneIsKeptAsChained) {
  Survey s = FlySurvey(4, 10, /*with_ties=*/false, 3);
  ASSERT_TRUE(s.graph.Solve());
  for (int i = 0; i < 40; ++i) EXPECT_NEAR(*s.graph.LogScale(i), s.graph.ChainedLogScale(i), 1e-9) << "frame " << i;
  EXPECT_EQ(s.graph.dropped(), 0);
}

TEST(HeightGraph, TiesAcrossStripsBoundTheChainsDrift) {
  // 8 strips of 20 frames, links and ties of 2 %: the chain walks to ~2 % x sqrt(80) ~ 18 % RMS; tied to the
  // strip beside, every frame is a few links from the anchor through the grid (measured, 20 seeds: 13.9 -> 2.6 %).
  double chain = 0, tied = 0;
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    Survey s = FlySurvey(8, 20, /*with_ties=*/true, seed);
    ASSERT_TRUE(s.graph.Solve());
    chain += RmsError(s, /*solved=*/false) / 20;
    tied += RmsError(s, /*solved=*/true) / 20;
  }
  std::cout << "log-height RMS over 20 surveys: chain " << 100 * chain << " %, tied " << 100 * tied << " %\n";
  EXPECT_LT(tied, 0.5 * chain);
  EXPECT_LT(tied, 4 * kLinkSigma);
}

TEST(HeightGraph, AGrossTieIsDroppedAndTheRestHold) {
  HeightGraph g;
  for (int i = 0; i < 10; ++i) g.AddFrame(i, 0.01 * i);
  for (int i = 1; i < 10; ++i) g.AddTie(i - 1, i, 0.01, kLinkSigma);
  g.AddTie(2, 8, 0.06 + 0.3, kLinkSigma);  // 30 % off: a wrong match
  g.AddTie(1, 7, 0.06, kLinkSigma);
  ASSERT_TRUE(g.Solve());
  EXPECT_EQ(g.dropped(), 1);
  for (int i = 0; i < 10; ++i) EXPECT_NEAR(*g.LogScale(i), 0.01 * i, 1e-6) << "frame " << i;
}

TEST(HeightGraph, UnknownFramesAndTiesAreIgnored) {
  HeightGraph g;
  g.AddFrame(5, 1.0);
  g.AddTie(5, 6, 0.1, kLinkSigma);  // frame 6 unknown
  g.AddFrame(6, std::nan(""));      // not finite: not added
  EXPECT_EQ(g.ties(), 0);
  EXPECT_EQ(g.frames(), 1);
  EXPECT_FALSE(g.LogScale(6).has_value());
  ASSERT_TRUE(g.Solve());
  EXPECT_NEAR(*g.LogScale(5), 1.0, 1e-9);
}

// A survey flown photo by photo as the mosaicker solves it: each frame added with its link and its tie to the strip
// before, then a Solve. `live` gets each frame's solution at its own photo.
HeightGraph FlyLive(int strips, int per_strip, int window, uint64_t seed, std::vector<double>* truth,
                    std::vector<double>* live) {
  cv::RNG rng(seed);
  HeightGraphOptions o;
  o.window = window;
  HeightGraph g(o);
  const int n = strips * per_strip;
  truth->clear();
  live->clear();
  for (int i = 0; i < n; ++i) truth->push_back(std::log(60.0) + 0.05 * std::sin(0.3 * i));
  double chained = (*truth)[0];
  g.AddFrame(0, chained);
  live->push_back(chained);
  for (int i = 1; i < n; ++i) {
    const double link = (*truth)[i] - (*truth)[i - 1] + rng.gaussian(kLinkSigma);
    chained += link;
    g.AddFrame(i, chained);
    g.AddTie(i - 1, i, link, kLinkSigma);
    if (i >= per_strip) {
      const int beside = (i / per_strip - 1) * per_strip + (per_strip - 1 - i % per_strip);
      g.AddTie(beside, i, (*truth)[i] - (*truth)[beside] + rng.gaussian(kLinkSigma), kLinkSigma);
    }
    EXPECT_TRUE(g.Solve());
    live->push_back(*g.LogScale(i));
  }
  return g;
}

// A survey longer than the window: each photo's solve moves only the newest `window` frames (its cost bounded),
// the live heights are as good as with every frame solved, and SolveAll gives the full least squares at the end.
// Measured, 5 surveys of 16 strips x 20 frames: live RMS against the truth 4.03 % with a window of 120 frames (6
// strips), 4.06 % with every frame solved; a window of 3 strips is too short (4.61 %).
TEST(HeightGraph, AWindowBoundsEachSolveAndSolveAllIsTheWholeSolution) {
  double rms_window = 0, rms_full = 0;
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    std::vector<double> truth, live_full, live_window;
    HeightGraph full = FlyLive(16, 20, /*window=*/0, seed, &truth, &live_full);
    HeightGraph windowed = FlyLive(16, 20, /*window=*/120, seed, &truth, &live_window);
    EXPECT_FALSE(full.Windowed());
    EXPECT_TRUE(windowed.Windowed());
    for (size_t i = 0; i < truth.size(); ++i) {
      rms_window += (live_window[i] - truth[i]) * (live_window[i] - truth[i]) / (5.0 * truth.size());
      rms_full += (live_full[i] - truth[i]) * (live_full[i] - truth[i]) / (5.0 * truth.size());
    }
    ASSERT_TRUE(windowed.SolveAll());
    for (int i = 0; i < 320; ++i) EXPECT_NEAR(*windowed.LogScale(i), *full.LogScale(i), 1e-9) << "frame " << i;
  }
  rms_window = std::sqrt(rms_window), rms_full = std::sqrt(rms_full);
  std::cout << "live log-height RMS, 5 surveys of 320 frames: window 120 " << 100 * rms_window << " %, all frames "
            << 100 * rms_full << " %\n";
  EXPECT_LT(rms_window, 1.1 * rms_full);
  // A window as large as the survey never holds a frame: the same solves as no window.
  std::vector<double> truth, live_full, live_large;
  FlyLive(16, 20, /*window=*/0, 1, &truth, &live_full);
  HeightGraph large = FlyLive(16, 20, /*window=*/320, 1, &truth, &live_large);
  EXPECT_FALSE(large.Windowed());
  EXPECT_EQ(live_large, live_full);
}

// Two strips flown east then west 12 m apart at 28-32 m (640 x 360 px, f 500 px: 38 x 22 m on the ground), a
// frame every 12 m: each frame of the second strip overlaps the first strip's frames beside it by about 40 %.
TEST(HeightTies, SecondStripIsTiedToTheFirstAndHeightsHold) {
  const testing::SyntheticGround ground = testing::MakeGround(3200, 0.05, 33);
  const testing::NadirCamera cam;
  std::vector<testing::TruthPose> poses;
  for (int strip = 0; strip < 2; ++strip)
    for (int k = 0; k < 8; ++k) {
      const int along = strip == 0 ? k : 7 - k;
      const double h = 30.0 + 2.0 * std::sin(0.7 * (strip * 8 + k));
      poses.push_back({-42.0 + 12.0 * along, -6.0 + 12.0 * strip, h, 0.0});
    }
  MosaickerOptions o = testing::OptionsForCamera(cam, poses[0].height);
  o.canvas.metres_per_pixel = 0.12;
  o.neighbour_frames = 30;
  o.height_graph.ties = 2;
  UavMosaicker m(o);
  std::vector<FrameState> states;
  for (size_t i = 0; i < poses.size(); ++i) {
    const auto& p = poses[i];
    states.push_back(m.ProcessFrame(testing::RenderNadir(ground, cam, p.east, p.north, p.height, p.yaw, 2.0, i + 1),
                                    static_cast<int64_t>(i) * 3000000));
  }
  EXPECT_GE(m.summary().height_ties, 8) << m.summary().BriefReport();
  int checked = 0;
  for (size_t i = 1; i < states.size(); ++i) {
    if (states[i].status != TrackStatus::kTracking) continue;
    const std::optional<double> h = m.AdjustedHeight(states[i].frame_index);
    ASSERT_TRUE(h.has_value()) << "frame " << i;
    EXPECT_NEAR(*h / poses[i].height, 1.0, 0.02) << "frame " << i;
    ++checked;
  }
  EXPECT_GE(checked, 14);
  MosaickerOptions off = o;
  off.height_graph.ties = 0;
  UavMosaicker chain_only(off);
  chain_only.ProcessFrame(testing::RenderNadir(ground, cam, poses[0].east, poses[0].north, poses[0].height, 0, 2.0, 1), 0);
  EXPECT_FALSE(chain_only.AdjustedHeight(0).has_value());
}

// A bad clock: two frames with one time. The graph knows frames by their index, not their time: nothing is
// confused with the other frame, every height finite and near the truth.
TEST(HeightTies, ARepeatedFrameTimeConfusesNoFrame) {
  const testing::SyntheticGround ground = testing::MakeGround(3200, 0.05, 34);
  const testing::NadirCamera cam;
  MosaickerOptions o = testing::OptionsForCamera(cam, 30.0);
  o.canvas.metres_per_pixel = 0.12;
  o.neighbour_frames = 30;
  o.height_graph.ties = 2;
  UavMosaicker m(o);
  const std::vector<int64_t> utimes = {0, 3000000, 6000000, 6000000, 9000000};
  const std::vector<double> heights = {30.0, 31.0, 32.0, 27.0, 30.0};  // the repeated time 5 m lower
  for (size_t i = 0; i < utimes.size(); ++i) {
    const double east = -20.0 + 8.0 * i;
    const FrameState s =
        m.ProcessFrame(testing::RenderNadir(ground, cam, east, 0.0, heights[i], 0.0, 2.0, i + 1), utimes[i]);
    if (i == 0) continue;
    ASSERT_EQ(s.status, TrackStatus::kTracking) << "frame " << i;
    ASSERT_TRUE(std::isfinite(s.height)) << "frame " << i;
    EXPECT_NEAR(s.height_raw / heights[i], 1.0, 0.03) << "frame " << i;
  }
  for (int i = 1; i < 5; ++i) EXPECT_NEAR(*m.AdjustedHeight(i) / heights[i], 1.0, 0.03) << "frame " << i;
  EXPECT_EQ(m.summary().tracked, 5);
}

}  // namespace
}  // namespace vloc::mosaic
