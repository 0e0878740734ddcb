#pragma once
// The simulated terrain seen from above: an aerial orthoimage (and height
// map) at 10-50 cm/px under a sun of its own, as an orbiter or a UAV flying
// earlier would have seen it. Target vloc::maploc_sim (uses vloc::sim).
//
//   MapRaster map = RenderAerialMap(&terrain, {-50, -50, 50, 50}, {0.2, 60, 50});

#include "vloc/maploc/map_raster.h"
#include "vloc/sim/terrain.h"

namespace vloc::maploc {

struct AerialRenderOptions {
  double m_per_px = 0.2;            // m, map cell size
  double sun_azimuth_deg = 60.0;    // deg, ccw from east (the rover's default is 135)
  double sun_elevation_deg = 50.0;  // deg
  int supersample = 3;              // samples per cell side (area average)
  bool with_height = true;          // fill MapRaster::height
};

// Renders `region`; the terrain's sun is moved for the rendering and put back.
MapRaster RenderAerialMap(sim::Terrain* terrain, const sim::Region& region, const AerialRenderOptions& options);

}  // namespace vloc::maploc
