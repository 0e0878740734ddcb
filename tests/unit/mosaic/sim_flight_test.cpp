// The mosaicker on the simulated UAV (libs/sim/uav, default world: textured
// ground, moving cars and people, ArUco marker under the take-off hover):
// the first 16 s of the default flight at 8 frames/s, vision only (no GPS).
// Targets: height RMS error <= 2 % of the true height, route error <= 1 % of
// the distance flown, no loss of track, moving objects rejected by eq. 2.
#include <gtest/gtest.h>

#include <cmath>

#include "vloc/common/options.h"
#include "vloc/mosaic/uav_mosaicker.h"
#include "vloc/sim/uav_world.h"

namespace vloc::mosaic {
namespace {

TEST(MosaickerSimFlight, ShortDefaultFlightMeetsTargets) {
  UavWorldOptions wo = LoadOptionsFile<UavWorldOptions>("config/procs/sim_uav.yaml", "world");
  wo.fps = 8.0;
  const UavWorld world(wo);
  MosaickerOptions o = LoadOptionsFile<MosaickerOptions>("config/procs/uav_mosaicker.yaml", "mosaicker");
  UavMosaicker m(o);
  const int frames = static_cast<int>(16.0 * wo.fps);
  double se = 0, dist = 0, worst_route = 0;
  int evaluated = 0, calibrating = 0, foreground = 0;
  bool started = false;
  double yaw0 = 0;
  Eigen::Vector2d start, prev;
  for (int i = 0; i < frames; ++i) {
    const double t = world.FrameTime(i);
    const FrameState s = m.ProcessFrame(world.RenderFrame(t), world.FrameUtime(i));
    const UavState truth = world.flight().StateAt(t);
    if (s.status == TrackStatus::kCalibrating) {
      ++calibrating;
      continue;
    }
    ASSERT_EQ(s.status, TrackStatus::kTracking) << "t " << t << ": " << s.message;
    const Eigen::Vector2d p = truth.position.head<2>();
    if (!started) {
      // Vision only: the mosaic takes the first frame's image top as north; the
      // truth heading of that frame (image top = forward) rotates it into the world.
      started = true;
      yaw0 = truth.yaw;
      start = prev = p;
    }
    dist += (p - prev).norm();
    prev = p;
    const double rot = yaw0 - M_PI / 2;
    const Eigen::Vector2d est(std::cos(rot) * s.route_local.x - std::sin(rot) * s.route_local.y,
                              std::sin(rot) * s.route_local.x + std::cos(rot) * s.route_local.y);
    worst_route = std::max(worst_route, (est - (p - start)).norm());
    se += std::pow((s.height - truth.position.z()) / truth.position.z(), 2);
    foreground += s.num_foreground;
    ++evaluated;
  }
  const double rms = std::sqrt(se / std::max(1, evaluated));
  std::cout << m.summary().calibration.Describe() << "\nheight RMS " << 100 * rms << " %, worst route error "
            << worst_route << " m over " << dist << " m (" << 100 * worst_route / dist << " %), foreground matches "
            << foreground << "; " << m.summary().BriefReport() << "\n";
  EXPECT_LE(calibrating, o.calibration.frames_to_average + 2);
  EXPECT_GT(evaluated, frames - 15);
  EXPECT_LT(rms, 0.02);
  EXPECT_GT(dist, 40.0);
  EXPECT_LT(worst_route, 0.01 * dist);
  EXPECT_EQ(m.summary().lost, 0);
}

}  // namespace
}  // namespace vloc::mosaic
