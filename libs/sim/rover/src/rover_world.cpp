#include "vloc/sim/rover_world.h"

#include <stdexcept>

#include "vloc/common/options.h"
#include "vloc/sim/noise.h"

namespace vloc::sim {

void RoverWorldOptions::Visit(OptionsReader& r) {
  r.Child("navcam", [&](OptionsReader& c) { navcam.Visit(c); });
  r.Child("terrain", [&](OptionsReader& c) { terrain.Visit(c); });
  r.Child("render", [&](OptionsReader& c) { render.Visit(c); });
  r.Child("traverse", [&](OptionsReader& c) { traverse.Visit(c); });
}

bool RoverWorldOptions::Check(std::string* error) const {
  return navcam.Check(error) && terrain.Check(error) && render.Check(error) && traverse.Check(error);
}

RoverWorld::RoverWorld(const RoverWorldOptions& options) : options_(options) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument(error);
  terrain_ = std::make_unique<Terrain>(options_.terrain);
  traverse_ = SimulateTraverse(*terrain_, options_.traverse);
  renderer_ = std::make_unique<NavcamRenderer>(*terrain_, options_.navcam, options_.render);
}

RenderedPair RoverWorld::RenderExposureWithDepth(const Exposure& e) const {
  const uint64_t seed = Hash3(options_.traverse.seed, static_cast<uint64_t>(e.site_id), static_cast<uint64_t>(e.pair_index));
  return renderer_->RenderPair(e.world_from_body, e.mast_pan, e.mast_tilt, seed, true);
}

StereoPair RoverWorld::RenderExposure(const Exposure& e) const {
  const uint64_t seed = Hash3(options_.traverse.seed, static_cast<uint64_t>(e.site_id), static_cast<uint64_t>(e.pair_index));
  const RenderedPair rendered = renderer_->RenderPair(e.world_from_body, e.mast_pan, e.mast_tilt, seed, false);
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
