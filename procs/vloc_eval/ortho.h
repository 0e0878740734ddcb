#pragma once
// The map background of vloc_eval's plots: an orthoimage of the simulated
// terrain over the traverse's bounding box, with its ESRI world file.

#include <string>

#include "eval.h"

namespace vloc::eval {

struct OrthoOptions {
  std::string terrain_config;  // terrain YAML (config/sim/terrain.yaml) or a sim_rover config with a `terrain` section
  double m_per_px = 0.08;      // m per pixel of the orthoimage
  double margin_m = 12.0;      // m added around the sites' bounding box
  int max_side_px = 4000;      // px, m_per_px grows so no side exceeds this
};

// Builds the terrain of `options.terrain_config`, renders the box around
// every site position of `s` (ground truth and estimates, clipped to the
// terrain) and writes DIR/ortho.png (8-bit gray, north up) and DIR/ortho.pgw
// (world file: pixel size, rotation terms, centre of the top-left pixel in
// world x, y). Returns false with one error line naming the file and the fix.
bool WriteOrthoimage(const Summary& s, const OrthoOptions& options, const std::string& dir, std::string* error);

}  // namespace vloc::eval
