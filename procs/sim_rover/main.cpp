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
#include <algorithm>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim_rover_publisher.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"


namespace {

// The command line's overrides (--speed, --sites, --revisit, --seed) applied to `o`.
void ApplyOverrides(const vloc::CommandLine& args, vloc::SimRoverOptions* o) {
  vloc::sim::TraversePlanOptions& plan = o->world.traverse.plan;
  if (args.Has("speed")) o->speed = args.GetDouble("speed", o->speed);
  if (args.Has("sites")) {
    plan.num_sites = args.GetInt("sites", plan.num_sites);
    if (!plan.sites_xy.empty())
      plan.sites_xy.resize(std::min<size_t>(plan.sites_xy.size(), 2 * std::max(1, plan.num_sites)));
    if (plan.revisit_site >= plan.num_sites) plan.revisit_site = -1;
  }
  if (args.Has("revisit")) plan.revisit_site = args.GetInt("revisit", plan.revisit_site);
  if (const int seed = args.GetInt("seed", -1); seed >= 0) o->world.traverse.seed = static_cast<uint64_t>(seed);
}

// The config with the command line's overrides, echoed to the log; nullopt after one error line.
std::optional<vloc::SimRoverOptions> LoadSimRoverOptions(const vloc::ProcessSetup& setup) {
  auto options = vloc::LoadProcessOptions<vloc::SimRoverOptions>(
      setup, [&](vloc::SimRoverOptions& o) { ApplyOverrides(setup.args, &o); });
  if (options) {
    const vloc::sim::TraversePlanOptions& plan = options->world.traverse.plan;
    LOG(INFO) << "(overrides: speed " << options->speed << ", sites " << plan.num_sites << ", revisit "
              << plan.revisit_site << ", seed " << options->world.traverse.seed << ")";
  }
  return options;
}

// The terrain and traverse, described in the log; null after one error line.
std::unique_ptr<vloc::sim::RoverWorld> BuildWorld(const vloc::sim::RoverWorldOptions& options) {
  std::unique_ptr<vloc::sim::RoverWorld> world;
  try {
    world = std::make_unique<vloc::sim::RoverWorld>(options);
  } catch (const std::exception& e) {
    std::cerr << "sim_rover: " << e.what() << "\n";
    return nullptr;
  }
  const auto& s = world->terrain().summary();
  LOG(INFO) << "terrain: " << s.grid_vertices << "^2 vertices, " << s.num_craters << " craters, " << s.num_rocks
            << " rocks, heights " << s.min_height << " .. " << s.max_height << " m, built in " << s.build_seconds << " s";
  const auto& traverse = world->traverse();
  LOG(INFO) << "traverse: " << traverse.sites.size() << " sites, " << traverse.path_length_m << " m driven in "
            << traverse.duration_s << " s, " << traverse.exposures.size() << " stereo pairs";
  return world;
}

// --log: every message straight to the LCM log at `path`; the process's exit code.
int WriteLog(const std::string& path, vloc::SimRoverPublisher* publisher) {
  std::string error;
  if (!vloc::WriteSimRoverLog(path, publisher, &error)) {
    std::cerr << "sim_rover: " << error << "\n";
    return 1;
  }
  const auto& summary = publisher->summary();
  LOG(INFO) << "wrote " << path << ": " << summary.stereo_pairs << " stereo pairs, " << summary.site_events
            << " site events, " << summary.imu_samples << " IMU, " << summary.wheel_samples << " wheel, "
            << summary.gt_poses << " GT poses, " << summary.site_poses << " site poses; rendering took "
            << summary.render_seconds_total << " s";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(argc, argv,
                                  {"sim_rover",
                                   {"log", "speed", "sites", "revisit", "seed", "render-sample"},
                                   false,
                                   "[--config config/procs/sim_rover.yaml] [--speed X] [--sites N] [--revisit K] [--seed S] "
                                   "[--log FILE | --render-sample DIR] [--lcm-url URL]",
                                   {"log", "render-sample"}});
  if (!setup) return 1;
  const std::optional<vloc::SimRoverOptions> options = LoadSimRoverOptions(*setup);
  if (!options) return 1;
  const std::unique_ptr<vloc::sim::RoverWorld> world = BuildWorld(options->world);
  if (!world) return 1;
  if (setup->args.Has("render-sample")) return vloc::WriteSimRoverSample(*world, setup->args.Get("render-sample"));
  vloc::SimRoverPublisher publisher(*options, *world);
  if (setup->args.Has("log")) return WriteLog(setup->args.Get("log"), &publisher);
  return vloc::PublishSimRoverRealTime(*setup->transport, options->speed, &publisher);
}
