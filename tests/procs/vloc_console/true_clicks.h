#pragma once
// What a careful operator would click, from the simulator's truth: ground
// points seen in a left image of both sites (terrain ray casts from the true
// site poses, occlusion checked from the second site), as raw pixels, with
// a seeded click error. The same world sim_rover builds from its config.

#include <Eigen/Geometry>
#include <random>
#include <string>
#include <vector>

#include "vloc/common/options.h"
#include "vloc/crosssite/frontend.h"
#include "vloc/sim/rover_world.h"

namespace vloc::testing {

// The simulated world of a sim_rover config (its navcam, terrain, render,
// traverse and lighting sections).
inline sim::RoverWorldOptions WorldOptionsOf(const std::string& sim_config) {
  const YAML::Node all = LoadYamlFile(sim_config);
  YAML::Node world;
  for (const char* key : {"navcam", "terrain", "render", "traverse", "lighting"})
    if (all[key]) world[key] = all[key];
  std::string echo;
  return LoadOptions<sim::RoverWorldOptions>(world, sim_config, &echo);
}

struct ClickOptions {
  int count = 12;               // picks wanted
  double grid_px = 48;          // px, spacing of the candidate pixels in the previous images
  double margin_px = 40;        // px, kept from the image borders
  double max_range_m = 20;      // m, farther ground is not picked
  double click_sigma_px = 1.0;  // px, 1-sigma error of a click (each axis)
  unsigned seed = 19;
};

// World point seen at raw pixel `px` of the left camera at `exposure`; false when the ray misses.
inline bool GroundAt(const sim::RoverWorld& w, const sim::Exposure& e, const Eigen::Vector2d& px, double max_range,
                     Eigen::Vector3d* p_world, Eigen::Vector3d* centre) {
  const NavcamModel& n = w.options().navcam;
  const Pose3 world_from_left = e.world_from_body * n.mast.BodyFromLeft(e.mast_pan, e.mast_tilt, n.rig);
  const Eigen::Vector3d dir = (world_from_left.linear() * n.rig.left.Ray(n.rig.left.Undistort(px))).normalized();
  *centre = world_from_left.translation();
  const auto hit = w.terrain().Raycast(*centre, dir, max_range);
  if (!hit) return false;
  *p_world = hit->point;
  return true;
}

// Where `p_world` appears in the left image of `exposure`, if seen there unoccluded.
inline bool SeenAt(const sim::RoverWorld& w, const sim::Exposure& e, const Eigen::Vector3d& p_world, double margin,
                   Eigen::Vector2d* px) {
  const NavcamModel& n = w.options().navcam;
  const Pose3 world_from_left = e.world_from_body * n.mast.BodyFromLeft(e.mast_pan, e.mast_tilt, n.rig);
  const auto raw = n.rig.left.Project(world_from_left.inverse() * p_world);
  if (!raw || !n.rig.left.InImage(*raw, margin)) return false;
  const Eigen::Vector3d centre = world_from_left.translation(), d = p_world - centre;
  const auto hit = w.terrain().Raycast(centre, d.normalized(), d.norm() + 1.0);
  if (!hit || std::abs(hit->range - d.norm()) > 0.05) return false;
  *px = *raw;
  return true;
}

// Up to o.count picks for the site pair, spread over the candidates (seeded).
inline std::vector<ManualTie> TrueClicks(const sim::RoverWorld& w, int previous, int current, const ClickOptions& o) {
  const auto& prev = w.traverse().sites.at(previous).exposures;
  const auto& cur = w.traverse().sites.at(current).exposures;
  const auto& cam = w.options().navcam.rig.left;
  std::vector<ManualTie> all;
  for (const sim::Exposure& ep : prev)
    for (double v = o.margin_px; v < cam.height - o.margin_px; v += o.grid_px)
      for (double u = o.margin_px; u < cam.width - o.margin_px; u += o.grid_px) {
        Eigen::Vector3d p, centre;
        if (!GroundAt(w, ep, {u, v}, o.max_range_m, &p, &centre)) continue;
        for (const sim::Exposure& ec : cur) {
          Eigen::Vector2d at;
          if (!SeenAt(w, ec, p, o.margin_px, &at)) continue;
          all.push_back({ep.pair_index, {u, v}, ec.pair_index, at});
          break;
        }
      }
  std::mt19937 rng(o.seed);
  std::shuffle(all.begin(), all.end(), rng);
  all.resize(std::min<size_t>(all.size(), static_cast<size_t>(o.count)));
  std::normal_distribution<double> click(0.0, o.click_sigma_px);
  for (ManualTie& t : all) t.current_px += Eigen::Vector2d(click(rng), click(rng));
  return all;
}

}  // namespace vloc::testing
