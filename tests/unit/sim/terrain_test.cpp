// The simulated terrain: deterministic, craters and rocks where they were
// placed, ray casting lands on the surface, shadows away from the sun.
#include <gtest/gtest.h>

#include <cmath>

#include "vloc/sim/noise.h"
#include "vloc/sim/terrain.h"

namespace vloc::sim {
namespace {

TerrainOptions SmallTerrain() {
  TerrainOptions options;
  options.size_m = 40.0;
  options.origin_x_m = -20.0;
  options.origin_y_m = -20.0;
  options.crater_density = 2.0;
  options.crater_max_diameter_m = 8.0;
  return options;
}

TEST(SimTerrain, DefaultsPassCheck) {
  std::string error;
  EXPECT_TRUE(TerrainOptions{}.Check(&error)) << error;
  TerrainOptions bad;
  bad.resolution_m = 0;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_THROW(Terrain{bad}, std::invalid_argument);
}

TEST(SimTerrain, SameSeedSameHeightsOtherSeedOther) {
  const Terrain a(SmallTerrain()), b(SmallTerrain());
  TerrainOptions other_options = SmallTerrain();
  other_options.seed = 2;
  const Terrain other(other_options);
  ASSERT_EQ(a.vertices_per_side(), 1001);
  int differing = 0;
  for (int j = 0; j < a.vertices_per_side(); j += 7) {
    for (int i = 0; i < a.vertices_per_side(); i += 7) {
      ASSERT_EQ(a.VertexHeight(i, j), b.VertexHeight(i, j));
      differing += a.VertexHeight(i, j) != other.VertexHeight(i, j);
    }
  }
  EXPECT_GT(differing, 1000);
  EXPECT_EQ(a.Albedo(1.2345, -3.21, 0.0), b.Albedo(1.2345, -3.21, 0.0));
  EXPECT_NEAR(a.Height(0, 0), 0.0, 1e-6);
}

TEST(SimTerrain, CratersAreBowlsWithRaisedRims) {
  const Terrain terrain(SmallTerrain());
  ASSERT_FALSE(terrain.craters().empty());
  // Overlapping craters and relief can hide a single rim: most must show.
  int checked = 0, bowls = 0, rims = 0;
  for (const Crater& c : terrain.craters()) {
    if (c.diameter < 2.0 || !terrain.Contains(c.centre.x() - c.diameter, c.centre.y()) ||
        !terrain.Contains(c.centre.x() + c.diameter, c.centre.y()))
      continue;
    const double floor = terrain.Height(c.centre.x(), c.centre.y());
    double rim = 0, outside = 0;
    for (int k = 0; k < 8; ++k) {
      const double a = k * M_PI / 4;
      rim += terrain.Height(c.centre.x() + 0.5 * c.diameter * std::cos(a), c.centre.y() + 0.5 * c.diameter * std::sin(a)) / 8;
      outside += terrain.Height(c.centre.x() + 0.75 * c.diameter * std::cos(a), c.centre.y() + 0.75 * c.diameter * std::sin(a)) / 8;
    }
    bowls += floor < rim - 0.5 * c.depth;
    rims += rim > outside;
    ++checked;
  }
  ASSERT_GT(checked, 3);
  EXPECT_GE(bowls, 0.8 * checked);
  EXPECT_GE(rims, 0.7 * checked);
}

TEST(SimTerrain, RocksStandAboveTheGround) {
  const Terrain terrain(SmallTerrain());
  int checked = 0;
  for (const Rock& rock : terrain.rocks()) {
    if (rock.diameter < 0.3 || !terrain.Contains(rock.centre.x(), rock.centre.y())) continue;
    const double top = terrain.Height(rock.centre.x(), rock.centre.y());
    const double around = terrain.Height(rock.centre.x() + rock.diameter, rock.centre.y());
    EXPECT_GT(top - around, 0.3 * rock.height) << "rock of " << rock.diameter << " m";
    ++checked;
  }
  EXPECT_GT(checked, 0);
}

TEST(SimTerrain, RaycastHitsTheSurface) {
  const Terrain terrain(SmallTerrain());
  int hits = 0;
  for (int k = 0; k < 200; ++k) {
    const double az = 0.1 * k, el = -(0.05 + 0.004 * k);
    const Eigen::Vector3d origin(0.3 * std::cos(0.7 * k), 0.3 * std::sin(0.7 * k), 1.6);
    const Eigen::Vector3d dir(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    const auto hit = terrain.Raycast(origin, dir, 100.0);
    if (!hit) continue;
    ++hits;
    EXPECT_NEAR(hit->point.z(), terrain.Height(hit->point.x(), hit->point.y()), 1e-4);
    // Nothing in front of the hit: sample the ray before it.
    for (double t = 0.05; t < hit->range - 0.05; t += 0.05) {
      const Eigen::Vector3d q = origin + t * dir;
      ASSERT_GT(q.z(), terrain.Height(q.x(), q.y()) - 1e-4) << "ray " << k << " passed under the surface at t=" << t;
    }
  }
  EXPECT_GT(hits, 150);
  // Looking up: no hit.
  EXPECT_FALSE(terrain.Raycast(Eigen::Vector3d(0, 0, 1.5), Eigen::Vector3d(0, 0.6, 0.8), 100.0));
}

TEST(SimTerrain, CraterWallFacingAwayFromTheSunIsShadowed) {
  TerrainOptions options = SmallTerrain();
  options.sun_elevation_deg = 15;
  const Terrain terrain(options);
  const Eigen::Vector2d sun(terrain.SunDirection().x(), terrain.SunDirection().y());
  int checked = 0;
  for (const Crater& c : terrain.craters()) {
    if (c.diameter < 2.0 || c.depth / c.diameter < 0.1 || !terrain.Contains(c.centre.x() - c.diameter, c.centre.y() - c.diameter) ||
        !terrain.Contains(c.centre.x() + c.diameter, c.centre.y() + c.diameter))
      continue;
    // Just inside the sun-ward rim: in the rim's shadow. Opposite wall: lit.
    const Eigen::Vector2d near_wall = c.centre + 0.38 * c.diameter * sun.normalized();
    const Eigen::Vector2d far_wall = c.centre - 0.38 * c.diameter * sun.normalized();
    EXPECT_LT(terrain.SunVisibility(near_wall.x(), near_wall.y()), 0.5);
    EXPECT_GT(terrain.SunVisibility(far_wall.x(), far_wall.y()), 0.5);
    EXPECT_GT(terrain.Radiance(far_wall.x(), far_wall.y(), 0.01), terrain.Radiance(near_wall.x(), near_wall.y(), 0.01));
    ++checked;
  }
  EXPECT_GT(checked, 0);
}

TEST(SimTerrain, AlbedoHasTextureAtEveryScaleAndStaysRegolithLike) {
  const Terrain terrain(SmallTerrain());
  // Standard deviation of albedo over a 10 x 10 patch at spacing `step`, band-limited to `step`.
  auto spread = [&](double step) {
    double sum = 0, sum2 = 0;
    for (int j = 0; j < 10; ++j) {
      for (int i = 0; i < 10; ++i) {
        const double a = terrain.Albedo(3.0 + i * step, 2.0 + j * step, step);
        sum += a;
        sum2 += a * a;
      }
    }
    return std::sqrt(std::max(0.0, sum2 / 100 - (sum / 100) * (sum / 100))) / (sum / 100);
  };
  // Texture seen at 2 m (1.7 mm pixels) and at 20 m (2 cm pixels).
  EXPECT_GT(spread(0.0017), 0.01);
  EXPECT_GT(spread(0.02), 0.01);
  EXPECT_LT(spread(0.02), 0.5);
  const cv::Mat ortho = terrain.RenderOrthoimage({-5, -5, 5, 5}, 0.05);
  EXPECT_EQ(ortho.cols, 200);
  EXPECT_EQ(ortho.rows, 200);
  cv::Scalar mean, stddev;
  cv::meanStdDev(ortho, mean, stddev);
  EXPECT_GT(mean[0], 60);
  EXPECT_LT(mean[0], 220);
  EXPECT_GT(stddev[0], 3);
}

TEST(SimNoise, GradientMatchesFiniteDifferences) {
  for (int k = 0; k < 50; ++k) {
    const double x = 0.37 * k - 3.1, y = 0.91 * k + 0.2, h = 1e-6;
    double gx, gy;
    const double v = GradientNoiseWithGradient(x, y, 7, &gx, &gy);
    EXPECT_NEAR(v, GradientNoise(x, y, 7), 1e-12);
    EXPECT_NEAR(gx, (GradientNoise(x + h, y, 7) - GradientNoise(x - h, y, 7)) / (2 * h), 1e-5);
    EXPECT_NEAR(gy, (GradientNoise(x, y + h, 7) - GradientNoise(x, y - h, 7)) / (2 * h), 1e-5);
  }
}

}  // namespace
}  // namespace vloc::sim
