#include "vloc/sim/rover_world.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "vloc/common/options.h"
#include "vloc/sim/noise.h"

namespace vloc::sim {

void LightingOptions::Visit(OptionsReader& r) {
  r.Optional("azimuth_step_deg", &azimuth_step_deg, "deg the sun's azimuth moves per site", Finite());
  r.Optional("elevation_step_deg", &elevation_step_deg, "deg the sun's elevation moves per site", Finite());
  r.Optional("min_elevation_deg", &min_elevation_deg, "deg, lowest sun", InRange(1, 89));
  r.Optional("exposure_jitter", &exposure_jitter, "site gain varies by +-this fraction", InRightOpen(0, 0.9));
}

bool LightingOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

void RoverWorldOptions::Visit(OptionsReader& r) {
  r.Child("navcam", [&](OptionsReader& c) { navcam.Visit(c); });
  r.Child("terrain", [&](OptionsReader& c) { terrain.Visit(c); });
  r.Child("render", [&](OptionsReader& c) { render.Visit(c); });
  r.Child("traverse", [&](OptionsReader& c) { traverse.Visit(c); });
  r.Child("lighting", [&](OptionsReader& c) { lighting.Visit(c); });
}

bool RoverWorldOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

RoverWorld::RoverWorld(const RoverWorldOptions& options) : options_(options) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument(error);
  terrain_ = std::make_unique<Terrain>(options_.terrain);
  traverse_ = SimulateTraverse(*terrain_, options_.traverse);
  renderer_ = std::make_unique<NavcamRenderer>(*terrain_, options_.navcam, options_.render);
}

Eigen::Vector2d RoverWorld::SunAtSite(int site_id) const {
  const TerrainOptions& t = options_.terrain;
  const LightingOptions& l = options_.lighting;
  const double elevation = std::clamp(t.sun_elevation_deg + site_id * l.elevation_step_deg, l.min_elevation_deg, 89.0);
  return {t.sun_azimuth_deg + site_id * l.azimuth_step_deg, elevation};
}

double RoverWorld::GainAtSite(int site_id) const {
  const double jitter = options_.lighting.exposure_jitter;
  if (jitter <= 0) return 1.0;
  const double u = 2.0 * HashToUnit(Hash3(options_.traverse.seed, static_cast<uint64_t>(site_id), 0x6A1EULL)) - 1.0;
  return 1.0 + jitter * u;
}

std::unique_lock<std::mutex> RoverWorld::LightSite(int site_id) const {
  std::unique_lock<std::mutex> lock(sun_mutex_);
  const Eigen::Vector2d sun = SunAtSite(site_id);
  terrain_->SetSun(sun.x(), sun.y());
  return lock;
}

StereoPair RoverWorld::RenderExposure(const Exposure& e) const {
  const uint64_t seed = Hash3(options_.traverse.seed, static_cast<uint64_t>(e.site_id), static_cast<uint64_t>(e.pair_index));
  RenderedPair rendered;
  {
    const auto lit = LightSite(e.site_id);
    rendered = renderer_->RenderPair(e.world_from_body, e.mast_pan, e.mast_tilt, seed, false, GainAtSite(e.site_id));
  }
  StereoPair pair;
  pair.utime = e.utime;
  pair.site_id = e.site_id;
  pair.pair_index = e.pair_index;
  pair.num_pairs = e.num_pairs;
  pair.mast_pan = e.mast_pan;
  pair.mast_tilt = e.mast_tilt;
  pair.left = rendered.left.image;
  pair.right = rendered.right.image;
  return pair;
}

std::vector<StereoPair> RoverWorld::RenderSite(int site_id) const {
  if (site_id < 0 || site_id >= static_cast<int>(traverse_.sites.size()))
    throw std::invalid_argument("RenderSite: site " + std::to_string(site_id) + " does not exist (traverse has " +
                                std::to_string(traverse_.sites.size()) + " sites)");
  std::vector<StereoPair> pairs;
  for (const Exposure& e : traverse_.sites[site_id].exposures) pairs.push_back(RenderExposure(e));
  return pairs;
}

}  // namespace vloc::sim
