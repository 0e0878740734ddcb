// sim_rover: the simulated lunar rover world (terrain, traverse, Navcam, IMU, wheels).
//   sim_rover [--config config/procs/sim_rover.yaml] [--speed X] [--sites N] [--revisit K] [--seed S]
//       --revisit K: one extra final site back at site K (loop closure; -1 = none)
//       --seed S: traverse.seed (another plan over the same terrain, other sensor noise; -1 = the config's)
//       publishes NAVCAM_STEREO, ROVER_SITE, IMU, WHEEL_ODOM, GT_POSE, SITE_POSE_GT over LCM
//       in real time (x speed; 0 = as fast as possible)
//   sim_rover ... --log FILE           writes the messages straight to an LCM log, as fast as it
//                                      can (event timestamps = message utimes)
//   sim_rover ... --render-sample DIR  saves the middle pair of site 0 as DIR/navcam_left.png,
//                                      DIR/navcam_right.png (and DIR/terrain_ortho.png) and exits
// See sim_rover_publisher.h for the channels and frames.
#include <glog/logging.h>

#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "sim_rover_publisher.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"


int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(argc, argv,
                                  {"sim_rover",
                                   {"log", "speed", "sites", "revisit", "seed", "render-sample"},
                                   false,
                                   "[--config config/procs/sim_rover.yaml] [--speed X] [--sites N] [--revisit K] [--seed S] "
                                   "[--log FILE | --render-sample DIR]",
                                   {"log", "render-sample"}});
  if (!setup) return 1;

  vloc::SimRoverOptions options;
  try {
    std::string echo;
    options = vloc::LoadOptions<vloc::SimRoverOptions>(
        setup->config, setup->config_path.empty() ? "defaults" : setup->config_path, &echo);
    if (setup->args.Has("speed")) options.speed = setup->args.GetDouble("speed", options.speed);
    if (setup->args.Has("sites")) {
      options.world.traverse.plan.num_sites = setup->args.GetInt("sites", options.world.traverse.plan.num_sites);
      if (!options.world.traverse.plan.sites_xy.empty())
        options.world.traverse.plan.sites_xy.resize(
            std::min<size_t>(options.world.traverse.plan.sites_xy.size(), 2 * std::max(1, options.world.traverse.plan.num_sites)));
      if (options.world.traverse.plan.revisit_site >= options.world.traverse.plan.num_sites) options.world.traverse.plan.revisit_site = -1;
    }
    if (setup->args.Has("revisit"))
      options.world.traverse.plan.revisit_site = setup->args.GetInt("revisit", options.world.traverse.plan.revisit_site);
    if (const int seed = setup->args.GetInt("seed", -1); seed >= 0) options.world.traverse.seed = static_cast<uint64_t>(seed);
    std::string error;
    if (!options.Check(&error)) throw vloc::ConfigError("command line: " + error);
    LOG(INFO) << "sim_rover options:\n"
              << echo << "\n(overrides: speed " << options.speed << ", sites " << options.world.traverse.plan.num_sites
              << ", revisit " << options.world.traverse.plan.revisit_site << ", seed " << options.world.traverse.seed << ")";
  } catch (const vloc::ConfigError& e) {
    std::cerr << "sim_rover: " << e.what() << "\n";
    return 1;
  }

  std::unique_ptr<vloc::sim::RoverWorld> world;
  try {
    world = std::make_unique<vloc::sim::RoverWorld>(options.world);
  } catch (const std::exception& e) {
    std::cerr << "sim_rover: " << e.what() << "\n";
    return 1;
  }
  const auto& s = world->terrain().summary();
  LOG(INFO) << "terrain: " << s.grid_vertices << "^2 vertices, " << s.num_craters << " craters, " << s.num_rocks
            << " rocks, heights " << s.min_height << " .. " << s.max_height << " m, built in " << s.build_seconds << " s";
  const auto& traverse = world->traverse();
  LOG(INFO) << "traverse: " << traverse.sites.size() << " sites, " << traverse.path_length_m << " m driven in "
            << traverse.duration_s << " s, " << traverse.exposures.size() << " stereo pairs";
  if (setup->args.Has("render-sample")) return vloc::WriteSimRoverSample(*world, setup->args.Get("render-sample"));

  vloc::SimRoverPublisher publisher(options, *world);
  if (setup->args.Has("log")) {
    std::string error;
    const std::string path = setup->args.Get("log");
    if (!vloc::WriteSimRoverLog(path, &publisher, &error)) {
      std::cerr << "sim_rover: " << error << "\n";
      return 1;
    }
    const auto& summary = publisher.summary();
    LOG(INFO) << "wrote " << path << ": " << summary.stereo_pairs << " stereo pairs, " << summary.site_events
              << " site events, " << summary.imu_samples << " IMU, " << summary.wheel_samples << " wheel, "
              << summary.gt_poses << " GT poses, " << summary.site_poses << " site poses; rendering took "
              << summary.render_seconds_total << " s";
    return 0;
  }
  return vloc::PublishSimRoverRealTime(*setup->transport, options.speed, &publisher);
}
