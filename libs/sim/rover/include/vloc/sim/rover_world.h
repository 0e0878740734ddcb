#pragma once
// The whole simulated rover world in one object: terrain + traverse +
// Navcam renderer, built from one options struct (the same keys as the
// navcam/terrain/render/traverse sections of config/procs/sim_rover.yaml).
// Images rendered here are byte-identical to what sim_rover publishes.
//
//   vloc::sim::RoverWorldOptions options;
//   options.traverse.plan.sites_xy = {0, 0, 10, 0};   // two sites 10 m apart, 7 + 7 pairs
//   vloc::sim::RoverWorld world(options);              // builds terrain, simulates traverse
//   std::vector<vloc::StereoPair> site1 = world.RenderSite(1);
//   vloc::Pose3 truth = world.traverse().sites[1].world_from_body;

#include <Eigen/Core>

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/rover_data.h"
#include "vloc/sim/navcam_renderer.h"
#include "vloc/sim/rover_traverse.h"
#include "vloc/sim/terrain.h"

namespace vloc {
class OptionsReader;
}

namespace vloc::sim {

// How the light changes over the traverse (issue 16: the paper names dramatic changes of illumination between
// sites as what breaks cross-site matching). All zero = one fixed sun and exposure (the defaults).
struct LightingOptions {
  double azimuth_step_deg = 0.0;     // deg the sun's azimuth moves from one site to the next (a traverse over days)
  double elevation_step_deg = 0.0;   // deg its elevation moves per site (clamped to [min_elevation_deg, 89])
  double min_elevation_deg = 5.0;    // deg, lowest sun the steps may reach
  double exposure_jitter = 0.0;      // each site's gain is exposure_gain_dn x (1 + u), u uniform in +-this (auto-exposure)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct RoverWorldOptions {
  NavcamModel navcam;            // calibration (config/navcam.yaml)
  TerrainOptions terrain;        // the ground
  NavcamRenderOptions render;    // radiometry, noise, distortion
  TraverseOptions traverse;      // plan, panorama, motion, IMU, wheels
  LightingOptions lighting;      // sun and exposure changing between sites

  // Visits the sections `navcam`, `terrain`, `render`, `traverse`, `lighting`.
  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

class RoverWorld {
 public:
  // Throws std::invalid_argument (bad options, site off the terrain).
  explicit RoverWorld(const RoverWorldOptions& options);

  const RoverWorldOptions& options() const { return options_; }
  const Terrain& terrain() const { return *terrain_; }
  const SimulatedTraverse& traverse() const { return traverse_; }
  const NavcamRenderer& renderer() const { return *renderer_; }

  // The stereo pair of one exposure; noise seeded by (traverse seed, site, pair).
  StereoPair RenderExposure(const Exposure& exposure) const;
  // Every pair of one site's panorama, in pair order.
  std::vector<StereoPair> RenderSite(int site_id) const;
  // The sun (azimuth, elevation, deg) and gain factor of a site under `lighting`.
  Eigen::Vector2d SunAtSite(int site_id) const;
  double GainAtSite(int site_id) const;

 private:
  RoverWorldOptions options_;
  std::unique_ptr<Terrain> terrain_;
  SimulatedTraverse traverse_;
  std::unique_ptr<NavcamRenderer> renderer_;
  mutable std::mutex sun_mutex_;   // the terrain's sun is moved per site (shadows recomputed) while rendering it

  // Moves the terrain's sun to the site's; returns the lock held while the site's exposure renders.
  std::unique_lock<std::mutex> LightSite(int site_id) const;
};

}  // namespace vloc::sim
