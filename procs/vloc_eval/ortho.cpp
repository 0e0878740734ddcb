#include "ortho.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <opencv2/imgcodecs.hpp>

#include "vloc/common/options.h"
#include "vloc/common/stopwatch.h"
#include "vloc/sim/terrain.h"

namespace vloc::eval {

bool WriteOrthoimage(const Summary& s, const OrthoOptions& o, const std::string& dir, std::string* error) {
  if (s.sites.empty()) return Fail(error, "no sites with ground truth: no orthoimage to render");
  if (!(o.m_per_px > 0) || !(o.margin_m >= 0) || o.max_side_px < 16)
    return Fail(error, "orthoimage: m_per_px must be > 0, margin_m >= 0, max_side_px >= 16");
  sim::TerrainOptions terrain_options;
  try {
    const YAML::Node root = LoadYamlFile(o.terrain_config);
    terrain_options = LoadOptionsFile<sim::TerrainOptions>(o.terrain_config, root["terrain"] ? "terrain" : "");
  } catch (const std::exception& e) {
    return Fail(error, std::string(e.what()) + " (--terrain takes config/sim/terrain.yaml or a sim_rover config)");
  }
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
  auto extend = [&](bool has, const Pose3& p) {
    if (!has) return;
    x0 = std::min(x0, p.translation().x());
    x1 = std::max(x1, p.translation().x());
    y0 = std::min(y0, p.translation().y());
    y1 = std::max(y1, p.translation().y());
  };
  for (const SiteRow& r : s.sites) {
    extend(true, r.gt);
    extend(r.has_dr, r.dr);
    extend(r.has_visual, r.visual);
    extend(r.has_opt, r.opt);
  }
  sim::Region region{x0 - o.margin_m, y0 - o.margin_m, x1 + o.margin_m, y1 + o.margin_m};
  region.x_min = std::max(region.x_min, terrain_options.origin_x_m);
  region.y_min = std::max(region.y_min, terrain_options.origin_y_m);
  region.x_max = std::min(region.x_max, terrain_options.origin_x_m + terrain_options.size_m);
  region.y_max = std::min(region.y_max, terrain_options.origin_y_m + terrain_options.size_m);
  if (!(region.x_max > region.x_min) || !(region.y_max > region.y_min))
    return Fail(error, "the traverse lies outside the terrain of " + o.terrain_config + " (wrong terrain config?)");
  const double side = std::max(region.x_max - region.x_min, region.y_max - region.y_min);
  const double m_per_px = std::max(o.m_per_px, side / o.max_side_px);

  const auto start = std::chrono::steady_clock::now();
  cv::Mat image;
  try {
    const sim::Terrain terrain(terrain_options);
    image = terrain.RenderOrthoimage(region, m_per_px);
  } catch (const std::exception& e) {
    return Fail(error, o.terrain_config + ": " + e.what());
  }
  const double seconds = SecondsSince(start);
  const std::string png = dir + "/ortho.png", pgw = dir + "/ortho.pgw";
  if (!cv::imwrite(png, image)) return Fail(error, "cannot write " + png + " (check the folder is writable)");
  std::ofstream f(pgw);
  f << std::setprecision(12) << m_per_px << "\n0\n0\n" << -m_per_px << "\n"
    << region.x_min + 0.5 * m_per_px << "\n" << region.y_max - 0.5 * m_per_px << "\n";
  if (!f) return Fail(error, "cannot write " + pgw + " (check the folder is writable)");
  std::cerr << "vloc_eval: orthoimage " << image.cols << " x " << image.rows << " px at " << m_per_px
            << " m/px of x " << region.x_min << " .. " << region.x_max << ", y " << region.y_min << " .. "
            << region.y_max << " m (terrain built and rendered in " << std::fixed << std::setprecision(1)
            << seconds << " s)\n";
  return true;
}

}  // namespace vloc::eval
