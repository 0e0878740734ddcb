// Dead reckoning against the simulator's ground truth (vloc::sim traverse):
// exact with ideal sensors; with the default noise, bias and slip, drifting
// like the simulator's own reference integration and within the covariance.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>

#include "vloc/common/options.h"
#include "vloc/deadreckoning/dead_reckoning.h"
#include "vloc/sim/rover_traverse.h"
#include "vloc/sim/terrain.h"
#include "vloc/testing/traverse_feed.h"

namespace vloc {
namespace {

const sim::Terrain& TestTerrain() {
  static const auto terrain = [] {
    sim::TerrainOptions options;
    options.resolution_m = 0.08;  // the traverse only needs heights
    return std::make_unique<sim::Terrain>(options);
  }();
  return *terrain;
}

DeadReckoningOptions OptionsFor(const sim::SimulatedTraverse& tr) {
  // The process's config, with the start heading of this traverse.
  YAML::Node root = LoadYamlFile("config/procs/dead_reckoning.yaml");
  DeadReckoningOptions o = LoadOptions<DeadReckoningOptions>(root["dead_reckoning"], "dead_reckoning");
  o.initial_yaw_rad = Heading(tr.ground_truth.front().world_from_body);
  o.initial_position = tr.ground_truth.front().world_from_body.translation();
  return o;
}

TEST(DeadReckoningSim, GravityMatchesSimulatorConfig) {
  YAML::Node sim = LoadYamlFile("config/procs/sim_rover.yaml");
  YAML::Node dr = LoadYamlFile("config/procs/dead_reckoning.yaml");
  ASSERT_TRUE(sim["traverse"]["imu"]["gravity_mps2"]);
  EXPECT_DOUBLE_EQ(sim["traverse"]["imu"]["gravity_mps2"].as<double>(),
                   dr["dead_reckoning"]["gravity_mps2"].as<double>());
}

TEST(DeadReckoningSim, IdealSensorsReproduceGroundTruth) {
  sim::TraverseOptions options;
  options.ideal_sensors = true;
  options.plan.num_sites = 6;
  const sim::SimulatedTraverse tr = sim::SimulateTraverse(TestTerrain(), options);
  DeadReckoning dr(OptionsFor(tr));
  const auto sites = testing::FeedTraverse(tr, dr);
  double worst_position = 0, worst_angle = 0;
  for (size_t k = 0; k < sites.size(); ++k) {
    const Pose3& gt = tr.sites[k].world_from_body;
    worst_position = std::max(worst_position, (sites[k].pose.translation() - gt.translation()).norm());
    worst_angle = std::max(worst_angle, LogSO3(gt.linear() * sites[k].pose.linear().transpose()).norm());
  }
  std::printf("ideal sensors, %zu sites over %.1f m: worst site position error %.5f m, attitude %.2e rad\n",
              sites.size(), tr.path_length_m, worst_position, worst_angle);
  EXPECT_LT(worst_position, 0.005 + 1e-4 * tr.path_length_m);
  EXPECT_LT(worst_angle, 1e-5);
  EXPECT_EQ(dr.stats().imu_dropped + dr.stats().wheel_dropped, 0);
}

TEST(DeadReckoningSim, DefaultNoiseDriftsWithinCovariance) {
  const sim::SimulatedTraverse tr = sim::SimulateTraverse(TestTerrain(), sim::TraverseOptions{});
  DeadReckoning dr(OptionsFor(tr));
  const auto sites = testing::FeedTraverse(tr, dr);
  int inside = 0;
  double final_drift = 0;
  for (size_t k = 1; k < sites.size(); ++k) {
    const Eigen::Vector3d e = tr.sites[k].world_from_body.translation() - sites[k].pose.translation();
    const Eigen::Matrix3d P = sites[k].covariance.block<3, 3>(0, 0);
    const double nees = e.dot(P.ldlt().solve(e));
    inside += nees < 11.34;  // chi2(3) 99 %
    final_drift = e.norm() / tr.sites[k].distance_from_start_m;
    if (k % 5 == 0 || k + 1 == sites.size()) {
      const Eigen::Matrix3d Rb = sites[k].pose.linear();
      const Eigen::Vector3d eb = Rb.transpose() * e;
      const Eigen::Matrix3d Pb = Rb.transpose() * P * Rb;
      std::printf("site %2zu: %.1f m driven, error %.3f m (%.1f %%), sigma %.3f m, NEES %.2f; body-frame error %.2f %.2f %.2f m, sigma %.2f %.2f %.2f m\n", k,
                  tr.sites[k].distance_from_start_m, e.norm(), 100 * final_drift, std::sqrt(P.trace()), nees,
                  eb.x(), eb.y(), eb.z(), std::sqrt(Pb(0,0)), std::sqrt(Pb(1,1)), std::sqrt(Pb(2,2)));
    }
  }
  // The simulator's noise and slip give a Yutu-like 5-15 % drift; the covariance
  // (8 % along-track scale sigma, gyro bias) should cover nearly every site.
  EXPECT_GE(final_drift, 0.03);
  EXPECT_LE(final_drift, 0.15);
  EXPECT_GE(inside, static_cast<int>(0.9 * (sites.size() - 1)));
}

}  // namespace
}  // namespace vloc
