// The simulated rover traverse: ground truth, IMU and wheel odometry agree
// (ideal sensors reproduce the trajectory), noise and slip give a
// Yutu-like 5-15 % dead-reckoning drift, and the same seed gives the same data.
#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <cstdio>
#include <memory>

#include "vloc/sim/reference_dead_reckoning.h"
#include "vloc/sim/rover_traverse.h"
#include "vloc/sim/rover_world.h"
#include "vloc/sim/terrain.h"

namespace vloc::sim {
namespace {

// The default terrain at a coarser grid: the traverse only needs heights.
const Terrain& TestTerrain() {
  static const auto terrain = [] {
    TerrainOptions options;
    options.resolution_m = 0.08;
    return std::make_unique<Terrain>(options);
  }();
  return *terrain;
}

// DR position error at the last sample / path length.
double FinalDrift(const SimulatedTraverse& traverse) {
  const auto dr = IntegrateReferenceDeadReckoning(traverse.ground_truth.front().world_from_body, traverse.imu,
                                                  traverse.wheel);
  const Eigen::Vector3d error =
      dr.back().world_from_body.translation() - traverse.ground_truth.back().world_from_body.translation();
  return error.norm() / traverse.path_length_m;
}

// The whole simulated world's defaults pass their bounds (Navcam, terrain,
// render, traverse plan/panorama/motion/IMU/wheels, lighting), and a broken
// one is named with its path.
TEST(SimTraverse, WorldDefaultsPassTheirBounds) {
  RoverWorldOptions options;
  std::string error;
  EXPECT_TRUE(options.Check(&error)) << error;
  options.traverse.wheels.rate_hz = options.traverse.imu.rate_hz + 1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_EQ(error, "traverse.wheels.rate_hz: must not exceed imu.rate_hz");
  options = RoverWorldOptions();
  options.traverse.plan.margin_m = 1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_EQ(error, "traverse.plan.margin_m = 1: must be >= 3");
}

TEST(SimTraverse, IdealSensorsReproduceGroundTruth) {
  TraverseOptions options;
  options.ideal_sensors = true;
  const SimulatedTraverse traverse = SimulateTraverse(TestTerrain(), options);
  ASSERT_EQ(traverse.sites.size(), 20u);
  ASSERT_EQ(traverse.imu.size(), traverse.ground_truth.size());
  const auto dr = IntegrateReferenceDeadReckoning(traverse.ground_truth.front().world_from_body, traverse.imu,
                                                  traverse.wheel);
  ASSERT_EQ(dr.size(), traverse.ground_truth.size());
  double worst_position = 0, worst_angle = 0;
  for (size_t k = 0; k < dr.size(); k += 10) {
    const Pose3& gt = traverse.ground_truth[k].world_from_body;
    worst_position = std::max(worst_position, (dr[k].world_from_body.translation() - gt.translation()).norm());
    worst_angle = std::max(worst_angle, LogSO3(gt.linear().transpose() * dr[k].world_from_body.linear()).norm());
  }
  std::printf("ideal sensors over %.1f m: worst position error %.4f m, worst attitude error %.2e rad\n",
              traverse.path_length_m, worst_position, worst_angle);
  // Only discretisation error remains: wheel distance interpolated at 20 Hz.
  EXPECT_LT(worst_position, 0.01 + 1e-4 * traverse.path_length_m);
  EXPECT_LT(worst_angle, 1e-6);
  EXPECT_GT(traverse.path_length_m, 19 * 5.0 * 0.95);
}

TEST(SimTraverse, NoisySensorsDriftFiveToFifteenPercent) {
  const SimulatedTraverse traverse = SimulateTraverse(TestTerrain(), TraverseOptions{});
  const double drift = FinalDrift(traverse);
  std::printf("default traverse: %.1f m in %.0f s, dead-reckoning drift %.2f %% of distance\n",
              traverse.path_length_m, traverse.duration_s, 100 * drift);
  EXPECT_GE(drift, 0.05);
  EXPECT_LE(drift, 0.15);
}

TEST(SimTraverse, DriftStaysInBandForOtherSeeds) {
  for (uint64_t seed : {2u, 3u}) {
    TraverseOptions options;
    options.seed = seed;
    const double drift = FinalDrift(SimulateTraverse(TestTerrain(), options));
    std::printf("seed %lu: drift %.2f %%\n", static_cast<unsigned long>(seed), 100 * drift);
    EXPECT_GE(drift, 0.05) << "seed " << seed;
    EXPECT_LE(drift, 0.15) << "seed " << seed;
  }
}

TEST(SimTraverse, SameSeedSameData) {
  TraverseOptions options;
  options.plan.num_sites = 4;
  const SimulatedTraverse a = SimulateTraverse(TestTerrain(), options);
  const SimulatedTraverse b = SimulateTraverse(TestTerrain(), options);
  ASSERT_EQ(a.imu.size(), b.imu.size());
  ASSERT_EQ(a.wheel.size(), b.wheel.size());
  for (size_t k = 0; k < a.imu.size(); ++k) {
    ASSERT_EQ(a.imu[k].utime, b.imu[k].utime);
    ASSERT_EQ(a.imu[k].angular_velocity, b.imu[k].angular_velocity) << k;
    ASSERT_EQ(a.imu[k].linear_acceleration, b.imu[k].linear_acceleration) << k;
    ASSERT_TRUE(a.ground_truth[k].world_from_body.matrix() == b.ground_truth[k].world_from_body.matrix());
  }
  for (size_t k = 0; k < a.wheel.size(); ++k) ASSERT_EQ(a.wheel[k].distance, b.wheel[k].distance);
  options.seed = 2;
  const SimulatedTraverse c = SimulateTraverse(TestTerrain(), options);
  EXPECT_NE(c.sites.back().world_from_body.translation(), a.sites.back().world_from_body.translation());
}

TEST(SimTraverse, SitesEventsAndExposuresFollowThePlan) {
  TraverseOptions options;
  options.plan.num_sites = 5;
  options.panorama.backward_pair = true;
  const SimulatedTraverse traverse = SimulateTraverse(TestTerrain(), options);
  ASSERT_EQ(traverse.sites.size(), 5u);
  EXPECT_EQ(traverse.exposures.size(), 5u * 8u);
  // Site 0 at the world origin, on the ground.
  EXPECT_NEAR(traverse.sites[0].world_from_body.translation().head<2>().norm(), 0.0, 1e-9);
  EXPECT_NEAR(traverse.sites[0].world_from_body.translation().z(), 0.0, 0.1);
  for (size_t i = 1; i < traverse.sites.size(); ++i) {
    const double leg = (traverse.sites[i].planned_xy - traverse.sites[i - 1].planned_xy).norm();
    EXPECT_GE(leg, options.plan.spacing_min_m - 1e-9);
    EXPECT_LE(leg, options.plan.spacing_max_m + 1e-9);
    // Arrived close to the plan (side-slip and slope shorten the leg a little).
    EXPECT_LT((traverse.sites[i].world_from_body.translation().head<2>() - traverse.sites[i].planned_xy).norm(),
              0.05 * leg + 0.05);
  }
  // Events: ARRIVED, IMAGING_DONE (, DEPARTED) per site, in time order.
  ASSERT_EQ(traverse.events.size(), 5u * 3u - 1u);
  for (size_t k = 0; k < traverse.events.size(); ++k) {
    EXPECT_EQ(static_cast<int>(traverse.events[k].event), static_cast<int>(k % 3));
    EXPECT_EQ(traverse.events[k].site_id, static_cast<int>(k / 3));
    if (k > 0) {
      EXPECT_GT(traverse.events[k].utime, traverse.events[k - 1].utime);
    }
  }
  // Exposures while stopped, between ARRIVED and IMAGING_DONE; last one backward. Every exposure of a site at
  // the site's pose, attitude included: the front end and the BA take one body pose per site, so a rover still
  // settling while it images would put a pointing error into the images that no algorithm should explain (it
  // showed as pairs whose matches sat 1-2 px off the truth, uniformly in each image, at every range).
  for (const SiteVisit& site : traverse.sites) {
    for (const Exposure& e : site.exposures)
      EXPECT_LT(LogSO3(site.world_from_body.linear().transpose() * e.world_from_body.linear()).norm(), 1e-12)
          << "site " << site.site_id << " pair " << e.pair_index;
    ASSERT_EQ(site.exposures.size(), 8u);
    EXPECT_NEAR(site.exposures.back().mast_pan, M_PI, 1e-12);
    EXPECT_NEAR(site.exposures[0].mast_pan, 3 * 26.0 * M_PI / 180, 1e-12);
    for (const Exposure& e : site.exposures) {
      EXPECT_GT(e.utime, site.arrived_utime);
      EXPECT_LT(e.utime, site.imaging_done_utime);
      EXPECT_LT((e.world_from_body.translation() - site.world_from_body.translation()).norm(), 1e-6);
    }
  }
}

TEST(SimTraverse, AccelerometerReadsGravityAtRestAndFollowsSlope) {
  TraverseOptions options;
  options.ideal_sensors = true;
  options.plan.num_sites = 3;
  options.imu.gravity_mps2 = 1.62;
  const SimulatedTraverse traverse = SimulateTraverse(TestTerrain(), options);
  for (const SiteVisit& site : traverse.sites) {
    const Exposure& e = site.exposures.back();
    size_t k = 0;
    while (traverse.imu[k].utime < e.utime) ++k;
    const Eigen::Vector3d expected = e.world_from_body.linear().transpose() * Eigen::Vector3d(0, 0, 1.62);
    EXPECT_LT((traverse.imu[k].linear_acceleration - expected).norm(), 1e-4);
    EXPECT_LT(traverse.imu[k].angular_velocity.norm(), 1e-5);
  }
  // Somewhere along the way the rover pitches and rolls with the ground.
  double max_tilt = 0;
  for (const auto& gt : traverse.ground_truth) {
    const Eigen::Vector3d rpy = RollPitchYawFromRotation(gt.world_from_body.linear());
    max_tilt = std::max({max_tilt, std::abs(rpy.x()), std::abs(rpy.y())});
  }
  EXPECT_GT(max_tilt, 0.2 * M_PI / 180);
  EXPECT_LT(max_tilt, 25 * M_PI / 180);
}

// The body origin (centre of the wheel contacts) stays on the ground: its
// height follows the mean terrain height under the rover.
TEST(SimTraverse, RoverFollowsTheTerrain) {
  TraverseOptions options;
  options.plan.num_sites = 6;
  const SimulatedTraverse traverse = SimulateTraverse(TestTerrain(), options);
  std::vector<double> gaps;
  for (size_t k = 0; k < traverse.ground_truth.size(); k += 50) {
    const Pose3& pose = traverse.ground_truth[k].world_from_body;
    double ground = 0;
    int n = 0;
    for (double fx : {-0.6, 0.0, 0.6}) {
      for (double fy : {-0.5, 0.5}) {
        const Eigen::Vector3d contact = pose * Eigen::Vector3d(fx, fy, 0);
        ground += TestTerrain().Height(contact.x(), contact.y());
        ++n;
      }
    }
    gaps.push_back(std::abs(pose.translation().z() - ground / n));
  }
  std::sort(gaps.begin(), gaps.end());
  std::printf("body height above the mean contact height: median %.3f m, max %.3f m\n", gaps[gaps.size() / 2],
              gaps.back());
  EXPECT_LT(gaps[gaps.size() / 2], 0.03);
  EXPECT_LT(gaps.back(), 0.15);
}

TEST(SimTraverse, RevisitReturnsToTheEarlierSite) {
  TraverseOptions options;
  options.ideal_sensors = true;
  options.plan.num_sites = 4;
  options.plan.revisit_site = 1;
  const SimulatedTraverse traverse = SimulateTraverse(TestTerrain(), options);
  ASSERT_EQ(traverse.sites.size(), 5u);
  const SiteVisit& last = traverse.sites.back();
  EXPECT_EQ(last.revisit_of, 1);
  const Pose3& original = traverse.sites[1].world_from_body;
  EXPECT_LT((last.world_from_body.translation() - original.translation()).norm(), 0.3);
  EXPECT_LT(std::abs(WrapAngle(Heading(last.world_from_body) - Heading(original))), 1e-3);
}

TEST(SimTraverse, RejectsBadOptions) {
  TraverseOptions options;
  options.plan.spacing_min_m = 12;
  options.plan.spacing_max_m = 6;
  EXPECT_THROW(SimulateTraverse(TestTerrain(), options), std::invalid_argument);
  TraverseOptions off_field;
  off_field.plan.sites_xy = {0, 0, 500, 0};
  EXPECT_THROW(SimulateTraverse(TestTerrain(), off_field), std::invalid_argument);
}

}  // namespace
}  // namespace vloc::sim
