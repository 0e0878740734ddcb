#pragma once
// A simulated traverse fed to dead reckoning as the process would get it.
// Header-only; the test links vloc::deadreckoning and vloc::sim.

#include <cstdint>
#include <functional>
#include <vector>

#include "vloc/deadreckoning/dead_reckoning.h"
#include "vloc/sim/rover_traverse.h"

namespace vloc::testing {

// Feeds the traverse's site events, wheel and IMU samples to `dr` in time
// order (an event before a sample of the same time, a wheel sample before
// an IMU one); `after_imu` runs after each IMU sample (e.g. to set the start
// pose once there is attitude). Returns the pose at every arrival, by site.
inline std::vector<PoseWithCovariance> FeedTraverse(const sim::SimulatedTraverse& tr, DeadReckoning& dr,
                                                    const std::function<void()>& after_imu = {}) {
  std::vector<PoseWithCovariance> sites(tr.sites.size());
  size_t i = 0, w = 0, e = 0;
  while (i < tr.imu.size() || w < tr.wheel.size() || e < tr.events.size()) {
    const int64_t ti = i < tr.imu.size() ? tr.imu[i].utime : INT64_MAX;
    const int64_t tw = w < tr.wheel.size() ? tr.wheel[w].utime : INT64_MAX;
    const int64_t te = e < tr.events.size() ? tr.events[e].utime : INT64_MAX;
    if (te < ti && te < tw) {
      dr.AddSiteEvent(tr.events[e++]);
    } else if (tw <= ti) {
      dr.AddWheel(tr.wheel[w++]);
    } else {
      dr.AddImu(tr.imu[i++]);
      if (after_imu) after_imu();
    }
    for (const auto& [site, pose] : dr.PopSitePoses())
      if (site >= 0 && site < static_cast<int>(sites.size())) sites[site] = pose;
    while (dr.PopPeriodicPose()) {
    }
  }
  return sites;
}

}  // namespace vloc::testing
