// Periodic re-registration against the mosaic (reregister_every_n_frames) on
// a synthetic loop flight that returns over its start: the keyframe chain
// drifts, the mosaic still holds the start area as first seen, and
// registering frames to it there removes the drift. Vision only, no GPS.
// The camera wobbles (roll/pitch 0.015 rad, as a small UAV does): frames are
// then not exact similarities of the ground, which is what makes the chain drift.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include <opencv2/imgproc.hpp>

#include "synthetic_nadir.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {
namespace {

using testing::NadirCamera;
using testing::TruthPose;

// A circle of radius 45 m flown in 24 s, then 6 s more over the start area
// again; height 36 +- 4 m; the camera yaws +-0.3 rad.
constexpr double kLoopSeconds = 24.0, kFlightSeconds = 30.0, kFps = 6.0;
TruthPose Truth(double t) {
  const double w = 2 * M_PI / kLoopSeconds;
  TruthPose p;
  p.east = 45.0 * std::sin(w * t);
  p.north = 45.0 * (1 - std::cos(w * t));
  p.height = 36.0 + 4.0 * std::sin(w * t);
  p.yaw = 0.3 * std::sin(0.5 * w * t);
  return p;
}

// The nadir view tilted by roll/pitch (rad): ground px = M * K R K^-1 * view px.
cv::Mat RenderWobbling(const testing::SyntheticGround& g, const NadirCamera& cam, const TruthPose& p, double roll,
                       double pitch, double noise, uint64_t seed) {
  const cv::Matx23d M = testing::GroundFromView(g, cam, p.east, p.north, p.height, p.yaw);
  const cv::Matx33d G(M(0, 0), M(0, 1), M(0, 2), M(1, 0), M(1, 1), M(1, 2), 0, 0, 1);
  const cv::Matx33d K(cam.f, 0, cam.cx(), 0, cam.f, cam.cy(), 0, 0, 1);
  const cv::Matx33d Rx(1, 0, 0, 0, std::cos(pitch), -std::sin(pitch), 0, std::sin(pitch), std::cos(pitch));
  const cv::Matx33d Ry(std::cos(roll), 0, std::sin(roll), 0, 1, 0, -std::sin(roll), 0, std::cos(roll));
  const cv::Matx33d ground_from_view = G * K * Rx * Ry * K.inv();
  cv::Mat out;
  cv::warpPerspective(g.image, out, cv::Mat(ground_from_view), cam.size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                      cv::BORDER_REFLECT);
  cv::Mat noise_img(out.size(), CV_16SC3), o16;
  cv::RNG rng(seed);
  rng.fill(noise_img, cv::RNG::NORMAL, 0, noise);
  out.convertTo(o16, CV_16SC3);
  o16 += noise_img;
  o16.convertTo(out, CV_8UC3);
  return out;
}

struct RouteErrors {
  double distance = 0;      // m flown
  double worst = 0;         // m, whole flight
  double mean_return = 0;   // m, mean over the frames after the loop closes (t > kLoopSeconds)
  double height_rms = 0;    // fraction of the true height
  MosaickerSummary summary;
};

RouteErrors Fly(const testing::SyntheticGround& ground, int reregister_every) {
  const NadirCamera cam;
  MosaickerOptions o = testing::OptionsForCamera(cam, Truth(0).height);
  o.canvas.metres_per_pixel = 0.1;
  o.reregister_every_n_frames = reregister_every;
  UavMosaicker m(o);
  RouteErrors e;
  const TruthPose p0 = Truth(0);
  double se = 0;
  int n_return = 0;
  const int n = static_cast<int>(kFlightSeconds * kFps);
  for (int i = 0; i < n; ++i) {
    const double t = i / kFps;
    const TruthPose p = Truth(t);
    const cv::Mat frame =
        RenderWobbling(ground, cam, p, 0.015 * std::sin(2 * M_PI * t / 3.1), 0.015 * std::sin(2 * M_PI * t / 4.3 + 1), 3.0, i + 1);
    const FrameState s = m.ProcessFrame(frame, static_cast<int64_t>(t * 1e6));
    EXPECT_EQ(s.status, TrackStatus::kTracking) << "frame " << i << ": " << s.message;
    if (i > 0) e.distance += std::hypot(p.east - Truth((i - 1) / kFps).east, p.north - Truth((i - 1) / kFps).north);
    const double err = std::hypot(s.route_local.x - (p.east - p0.east), s.route_local.y - (p.north - p0.north));
    e.worst = std::max(e.worst, err);
    if (t > kLoopSeconds) {
      e.mean_return += err;
      ++n_return;
    }
    se += std::pow((s.height - p.height) / p.height, 2);
  }
  e.mean_return /= std::max(1, n_return);
  e.height_rms = std::sqrt(se / n);
  e.summary = m.summary();
  return e;
}

TEST(MosaickerReregistration, LoopFlightRouteErrorNotWorseAndUnderTarget) {
  const testing::SyntheticGround ground = testing::MakeGround(2600, 0.05, 77);
  const RouteErrors off = Fly(ground, 0), on = Fly(ground, 6);
  std::cout << "without re-registration: worst " << off.worst << " m, after the loop closes " << off.mean_return
            << " m (mean), height RMS " << 100 * off.height_rms << " %; " << off.summary.BriefReport() << "\n"
            << "with re-registration every 6 frames: worst " << on.worst << " m, after the loop closes "
            << on.mean_return << " m, height RMS " << 100 * on.height_rms << " %; " << on.summary.BriefReport()
            << "\n(distance " << on.distance << " m)\n";
  RecordProperty("route_error_after_loop_off_m", std::to_string(off.mean_return));
  RecordProperty("route_error_after_loop_on_m", std::to_string(on.mean_return));
  EXPECT_GT(on.summary.reregistrations, 10);
  EXPECT_EQ(on.summary.lost, 0);
  // Not worse where the flight returns over mapped ground (0.05 m slack: one mosaic pixel half).
  EXPECT_LE(on.mean_return, off.mean_return + 0.05);
  // Under the 1 % target over the whole flight, and height within 2 % RMS.
  EXPECT_LT(on.worst, 0.01 * on.distance);
  EXPECT_LT(on.height_rms, 0.02);
}

}  // namespace
}  // namespace vloc::mosaic
