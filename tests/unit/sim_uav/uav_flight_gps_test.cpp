// Flight plan, GPS and geodetic conversion of the simulated UAV.
#include <gtest/gtest.h>

#include <cmath>

#include "vloc/common/options.h"
#include "vloc/sim/uav_flight.h"
#include "vloc/sim/uav_geo.h"
#include "vloc/sim/uav_gps.h"
#include "vloc/sim/uav_world.h"

namespace vloc {
namespace {

TEST(UavFlight, DefaultPlanHoversOverMarkerThenFliesTwentyToEightyMetres) {
  const UavFlightOptions options;
  const UavFlight flight(options);
  // Calibration hover: over the take-off point at the calibration height.
  for (double t = 0; t <= options.calibration_hover; t += 0.5) {
    const UavState s = flight.StateAt(t);
    EXPECT_NEAR(s.position.x(), options.takeoff.x(), 1e-9);
    EXPECT_NEAR(s.position.y(), options.takeoff.y(), 1e-9);
    EXPECT_NEAR(s.position.z(), options.calibration_height, 1e-9);
  }
  const double dt = 1.0 / 30;
  const double start = options.calibration_hover + 1;
  double min_z = 1e9, max_z = -1e9, previous_yaw = flight.StateAt(start - dt).yaw;
  Eigen::Vector3d previous = flight.StateAt(start - dt).position;
  double max_yaw_step = 0, turned = 0;
  for (double t = start; t < flight.Duration(); t += dt) {
    const UavState s = flight.StateAt(t);
    min_z = std::min(min_z, s.position.z());
    max_z = std::max(max_z, s.position.z());
    // Continuity: never faster than the cruise speed (plus the curve's sampling error).
    EXPECT_LE((s.position - previous).norm(), options.speed * dt * 1.02 + 1e-6) << "t=" << t;
    max_yaw_step = std::max(max_yaw_step, std::abs(WrapAngle(s.yaw - previous_yaw)));
    turned += WrapAngle(s.yaw - previous_yaw);
    previous = s.position;
    previous_yaw = s.yaw;
  }
  EXPECT_GE(min_z, 15.0);
  EXPECT_LE(min_z, 21.0);
  EXPECT_NEAR(max_z, 80.0, 1.0);
  // A loop: the heading turns through a full circle, smoothly (< 3 deg per frame).
  EXPECT_GT(std::abs(turned), 1.8 * M_PI);
  EXPECT_LT(max_yaw_step, 3.0 * M_PI / 180);
  // Ends at the last waypoint.
  const auto& w = options.waypoints;
  const Eigen::Vector3d last(w[w.size() - 3], w[w.size() - 2], w[w.size() - 1]);
  EXPECT_LT((flight.StateAt(flight.Duration()).position - last).norm(), 1e-6);
  EXPECT_NEAR(flight.Duration(), options.calibration_hover + options.final_hover +
                                     flight.RouteLength() / options.speed + options.speed / options.acceleration,
              1e-6);
}

TEST(UavFlight, CameraLooksStraightDownWithImageTopForward) {
  UavFlightOptions options;
  options.wobble_amplitude = 0;
  const UavFlight flight(options);
  const double t = 20.0;
  const Pose3 world_from_camera = flight.WorldFromCamera(t);
  const Eigen::Vector3d optical_axis = world_from_camera.linear().col(2);
  EXPECT_NEAR(optical_axis.z(), -1.0, 1e-12);
  const double yaw = flight.StateAt(t).yaw;
  const Eigen::Vector3d image_up = -world_from_camera.linear().col(1);  // -camera y
  EXPECT_NEAR(image_up.x(), std::cos(yaw), 1e-12);
  EXPECT_NEAR(image_up.y(), std::sin(yaw), 1e-12);
}

TEST(UavFlight, RejectsBadWaypoints) {
  UavFlightOptions options;
  options.waypoints = {1, 2};
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("triples"), std::string::npos);
  EXPECT_THROW(UavFlight{options}, std::invalid_argument);
}

TEST(LocalTangentPlane, RoundTripAndScale) {
  const LocalTangentPlane plane(45.0, 9.0, 100.0);
  double lat, lon, alt, e, n, u;
  plane.ToGeodetic(300.0, -200.0, 50.0, &lat, &lon, &alt);
  plane.FromGeodetic(lat, lon, alt, &e, &n, &u);
  EXPECT_NEAR(e, 300.0, 1e-9);
  EXPECT_NEAR(n, -200.0, 1e-9);
  EXPECT_NEAR(u, 50.0, 1e-9);
  // One degree of latitude at 45 deg is 111.13 km.
  plane.ToGeodetic(0.0, 1000.0, 0.0, &lat, &lon, &alt);
  EXPECT_NEAR(1000.0 / (lat - 45.0), 111132.0, 20.0);
  plane.ToGeodetic(1000.0, 0.0, 0.0, &lat, &lon, &alt);
  EXPECT_NEAR(1000.0 / (lon - 9.0), 78847.0, 20.0);
}

TEST(UavGps, FiveHertzWithNoiseOfTheConfiguredSizeAndDropouts) {
  const UavFlight flight{UavFlightOptions()};
  UavGpsOptions options;
  options.dropouts = {30.0, 40.0};
  const UavGps gps(options, flight);
  EXPECT_EQ(gps.NumSamples(), static_cast<int>(std::floor(flight.Duration() * 5)) + 1);
  double sum2_e = 0, sum2_n = 0, sum2_h = 0;
  int fixes = 0, lost = 0;
  for (int k = 0; k < gps.NumSamples(); ++k) {
    const UavGpsSample& s = gps.Sample(k);
    EXPECT_EQ(s.utime, static_cast<int64_t>(std::llround(k * 200000.0)));
    const double t = k / 5.0;
    if (t >= 30.0 && t < 40.0) {
      EXPECT_FALSE(s.has_fix);
      EXPECT_TRUE(std::isnan(s.latitude));
      ++lost;
      continue;
    }
    ASSERT_TRUE(s.has_fix);
    double e, n, u;
    gps.plane().FromGeodetic(s.latitude, s.longitude, s.altitude, &e, &n, &u);
    EXPECT_LT((s.true_position - flight.StateAt(t).position).norm(), 1e-9);
    sum2_e += std::pow(e - s.true_position.x(), 2);
    sum2_n += std::pow(n - s.true_position.y(), 2);
    sum2_h += std::pow(s.height_above_ground - s.true_position.z(), 2);
    ++fixes;
  }
  EXPECT_EQ(lost, 50);
  // Correlated errors over ~100 s (~10 time constants): RMS within a factor ~2 of sigma.
  const double rms_e = std::sqrt(sum2_e / fixes), rms_n = std::sqrt(sum2_n / fixes), rms_h = std::sqrt(sum2_h / fixes);
  EXPECT_GT(rms_e, 0.4 * options.horizontal_sigma);
  EXPECT_LT(rms_e, 2.2 * options.horizontal_sigma);
  EXPECT_GT(rms_n, 0.4 * options.horizontal_sigma);
  EXPECT_LT(rms_n, 2.2 * options.horizontal_sigma);
  EXPECT_GT(rms_h, 0.3 * options.baro_sigma);
  EXPECT_LT(rms_h, 2.5 * options.baro_sigma);
  // At(t) returns the latest sample at or before t.
  EXPECT_EQ(gps.At(10.39).utime, 10200000);
}

TEST(UavWorldOptions, DefaultsPassAndConfigFileLoads) {
  std::string error;
  EXPECT_TRUE(UavWorldOptions().Check(&error)) << error;
  const auto options = LoadOptionsFile<UavWorldOptions>("config/procs/sim_uav.yaml", "world");
  EXPECT_EQ(options.camera.width, 1280);
  EXPECT_EQ(options.camera.height, 720);
  EXPECT_DOUBLE_EQ(options.fps, 30.0);
}

TEST(UavWorldOptions, UnknownKeyIsRejectedWithItsName) {
  YAML::Node node = YAML::Load("flight: {sped: 3}");
  try {
    LoadOptions<UavWorldOptions>(node, "test");
    FAIL() << "misspelled key accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("sped"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vloc
