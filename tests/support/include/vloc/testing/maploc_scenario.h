#pragma once
// A simulated rover world and an aerial map of it for the map-localization
// tests and benchmark: the Navcam at half size (512 x 512, f = 594.5 px) to
// keep rendering and stereo fast, the map rendered from a terrain built with
// the same options (or changed ones: an older or a wrong map) under another
// sun. Link vloc::maploc_sim.
#include <memory>
#include <random>
#include <vector>

#include "vloc/maploc/sim_aerial.h"
#include "vloc/sim/rover_world.h"

namespace vloc::testing {

struct MaplocScenarioOptions {
  std::vector<double> sites_xy = {0, 0, 8, 2, 16, 0, 24, 4, 32, 0, 40, -4};  // m, x0 y0 x1 y1 ...
  int num_sites = 0;              // > 0: a random plan of this many sites instead of sites_xy
  uint64_t seed = 1;              // traverse seed (plan, sensors)
  double terrain_size_m = 80.0;   // m, square terrain ...
  double terrain_origin_x_m = -20.0, terrain_origin_y_m = -40.0;  // m, ... its south-west corner
  double map_m_per_px = 0.2;      // m, aerial map cell size
  double map_sun_azimuth_deg = 60.0, map_sun_elevation_deg = 50.0;  // the map's sun (the rover's: 135, 30)
  int image_size = 512;           // px, Navcam side (f scaled with it)
};

inline sim::RoverWorldOptions MaplocWorldOptions(const MaplocScenarioOptions& s) {
  sim::RoverWorldOptions o;
  o.terrain.size_m = s.terrain_size_m;
  o.terrain.origin_x_m = s.terrain_origin_x_m;
  o.terrain.origin_y_m = s.terrain_origin_y_m;
  const double scale = s.image_size / 1024.0;
  for (PinholeCamera* c : {&o.navcam.rig.left, &o.navcam.rig.right}) {
    c->width = c->height = s.image_size;
    c->fx = c->fy = 1189.0 * scale;
    c->cx = c->cy = 0.5 * s.image_size - 0.5;
  }
  o.traverse.seed = s.seed;
  if (s.num_sites > 0) {
    o.traverse.plan.num_sites = s.num_sites;
    o.traverse.plan.margin_m = 15.0;
  } else {
    o.traverse.plan.sites_xy = s.sites_xy;
  }
  return o;
}

// The map of `terrain_options`' terrain over its whole extent.
inline maploc::MapRaster RenderMapOf(const sim::TerrainOptions& terrain_options, const MaplocScenarioOptions& s) {
  sim::Terrain terrain(terrain_options);
  const sim::Region bounds = terrain.Bounds();
  maploc::AerialRenderOptions render;
  render.m_per_px = s.map_m_per_px;
  render.sun_azimuth_deg = s.map_sun_azimuth_deg;
  render.sun_elevation_deg = s.map_sun_elevation_deg;
  return maploc::RenderAerialMap(&terrain, bounds, render);
}

// The predicted pose: truth plus Gaussian noise of the given sigmas, with that covariance.
inline PoseWithCovariance NoisyPrior(const Pose3& truth, double sigma_xy_m, double sigma_heading_rad, std::mt19937* rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  const Eigen::Vector3d rpy = RollPitchYawFromRotation(truth.linear());
  PoseWithCovariance p;
  p.pose = MakePose(truth.translation().x() + sigma_xy_m * n(*rng), truth.translation().y() + sigma_xy_m * n(*rng),
                    truth.translation().z(), rpy.x(), rpy.y(), rpy.z() + sigma_heading_rad * n(*rng));
  Vector6d d;
  d << sigma_xy_m * sigma_xy_m, sigma_xy_m * sigma_xy_m, 0.01, 1e-6, 1e-6, sigma_heading_rad * sigma_heading_rad;
  p.covariance = d.asDiagonal();
  return p;
}

}  // namespace vloc::testing
