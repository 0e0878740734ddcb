// vloc_render_map: the simulated rover terrain as an aerial map (an orbiter's
// or an earlier UAV's view) under a sun of its own: a GeoTIFF (grey + height
// bands) or a PNG + world file, in the world frame (metres, x east, y north).
//   vloc_render_map --config config/procs/sim_rover.yaml --out map.tif [--res 0.2] [--sun-azimuth 60]
//                   [--sun-elevation 50] [--region x0,y0,x1,y1] [--terrain-seed N] [--rock-density D]
// --terrain-seed / --rock-density render another terrain (a wrong map) or
// another rock field (an older map) for the failure cases.
#include <cstdio>
#include <iostream>
#include <sstream>

#include "vloc/common/command_line.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/maploc/sim_aerial.h"
#include "vloc/sim/terrain.h"

namespace {

constexpr const char* kUsage =
    "usage: vloc_render_map --config config/procs/sim_rover.yaml --out map.tif|map.png [--res 0.2] "
    "[--sun-azimuth 60] [--sun-elevation 50] [--region x0,y0,x1,y1] [--terrain-seed N] [--rock-density D]";

bool ParseRegion(const std::string& text, vloc::sim::Region* region) {
  std::istringstream in(text);
  char c1, c2, c3;
  return static_cast<bool>(in >> region->x_min >> c1 >> region->y_min >> c2 >> region->x_max >> c3 >> region->y_max);
}

int Run(const vloc::CommandLine& args) {
  auto terrain_options = vloc::LoadOptionsFile<vloc::sim::TerrainOptions>(args.Get("config"), "terrain");
  if (args.Has("terrain-seed")) terrain_options.seed = std::stoull(args.Get("terrain-seed"));
  if (args.Has("rock-density")) terrain_options.rock_density = std::stod(args.Get("rock-density"));
  vloc::sim::Terrain terrain(terrain_options);
  vloc::maploc::AerialRenderOptions render;
  render.m_per_px = std::stod(args.Get("res", "0.2"));
  render.sun_azimuth_deg = std::stod(args.Get("sun-azimuth", "60"));
  render.sun_elevation_deg = std::stod(args.Get("sun-elevation", "50"));
  vloc::sim::Region region = terrain.Bounds();
  if (args.Has("region") && !ParseRegion(args.Get("region"), &region)) {
    std::cerr << "vloc_render_map: --region needs x0,y0,x1,y1 in metres\n";
    return 1;
  }
  const vloc::maploc::MapRaster map = vloc::maploc::RenderAerialMap(&terrain, region, render);
  const std::string out = args.Get("out");
  std::string error;
  const bool png = out.size() > 4 && out.substr(out.size() - 4) == ".png";
  if (!(png ? vloc::maploc::WriteMapPngWorld(map, out, &error) : vloc::maploc::WriteMapGeoTiff(map, out, &error))) {
    std::cerr << "vloc_render_map: " << error << "\n";
    return 1;
  }
  std::printf("wrote %s: %d x %d at %.3f m/px, x %.1f..%.1f, y %.1f..%.1f, sun %.0f/%.0f deg\n", out.c_str(),
              map.gray.cols, map.gray.rows, map.m_per_px, region.x_min, region.x_max, region.y_min, region.y_max,
              render.sun_azimuth_deg, render.sun_elevation_deg);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv,
                  {"config", "out", "res", "sun-azimuth", "sun-elevation", "region", "terrain-seed", "rock-density",
                   "help"},
                  &error)) {
    std::cerr << "vloc_render_map: " << error << "\n" << kUsage << "\n";
    return 1;
  }
  if (args.Has("help")) {
    std::cout << kUsage << "\n";
    return 0;
  }
  if (!args.Has("config") || !args.Has("out")) {
    std::cerr << "vloc_render_map: --config and --out are required\n" << kUsage << "\n";
    return 1;
  }
  try {
    return Run(args);
  } catch (const std::exception& e) {
    std::cerr << "vloc_render_map: " << e.what() << "\n";
    return 1;
  }
}
