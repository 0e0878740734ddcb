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

#include <memory>
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

struct RoverWorldOptions {
  NavcamModel navcam;            // calibration (config/navcam.yaml)
  TerrainOptions terrain;        // the ground
  NavcamRenderOptions render;    // radiometry, noise, distortion
  TraverseOptions traverse;      // plan, panorama, motion, IMU, wheels

  // Visits the four sections `navcam`, `terrain`, `render`, `traverse`.
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
  // With the per-pixel depth of both images (CV_32F, camera z, 0 = none).
  RenderedPair RenderExposureWithDepth(const Exposure& exposure) const;
  // Every pair of one site's panorama, in pair order.
  std::vector<StereoPair> RenderSite(int site_id) const;

 private:
  RoverWorldOptions options_;
  std::unique_ptr<Terrain> terrain_;
  SimulatedTraverse traverse_;
  std::unique_ptr<NavcamRenderer> renderer_;
};

}  // namespace vloc::sim
