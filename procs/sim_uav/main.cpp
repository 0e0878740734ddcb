// sim_uav: a simulated small UAV with a nadir camera over textured ground.
//   sim_uav [--config config/procs/sim_uav.yaml] [--speed X] [--duration S] [--fps F] [--orthomap FILE.png] [--gps-sigma M]
//       publishes UAV_CAMERA, UAV_GPS, UAV_GT over LCM in real time (x speed; 0 = as fast as possible)
//   sim_uav ... --log FILE      writes the messages straight to an LCM log, as fast as it can
//   sim_uav ... --snapshot FILE.png [--at T]   saves the frame at T s (default 1) and exits
// See sim_uav_publisher.h for the channels and frames.
#include <opencv2/imgcodecs.hpp>

#include <iostream>
#include <string>
#include <vector>

#include "sim_uav_publisher.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"


int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(
      argc, argv,
      {"sim_uav",
       {"log", "duration", "fps", "speed", "snapshot", "at", "orthomap", "gps-sigma"},
       false,
       "[--config config/procs/sim_uav.yaml] [--speed X] [--duration S] [--fps F] [--orthomap FILE.png] [--gps-sigma M] "
       "[--log FILE] [--snapshot FILE.png --at T]",
       {"log", "snapshot"}});
  if (!setup) return 1;

  vloc::SimUavOptions options;
  try {
    std::string echo;
    options = vloc::LoadOptions<vloc::SimUavOptions>(setup->config, setup->config_path.empty() ? "defaults" : setup->config_path, &echo);
    if (setup->args.Has("duration")) options.duration = setup->args.GetDouble("duration", options.duration);
    if (setup->args.Has("fps")) options.world.fps = setup->args.GetDouble("fps", options.world.fps);
    if (setup->args.Has("speed")) options.speed = setup->args.GetDouble("speed", options.speed);
    if (setup->args.Has("orthomap")) options.world.orthomap.image = setup->args.Get("orthomap");
    if (setup->args.Has("gps-sigma"))
      options.world.gps.horizontal_sigma = setup->args.GetDouble("gps-sigma", options.world.gps.horizontal_sigma);
    std::string error;
    if (!options.Check(&error)) throw vloc::ConfigError("command line: " + error);
    LOG(INFO) << "sim_uav options:\n" << echo << "\n(overrides: duration " << options.duration << " s, fps "
              << options.world.fps << ", speed " << options.speed << ", orthomap image '"
              << options.world.orthomap.image << "', GPS horizontal sigma " << options.world.gps.horizontal_sigma << " m)";
  } catch (const vloc::ConfigError& e) {
    std::cerr << "sim_uav: " << e.what() << "\n";
    return 1;
  }

  std::unique_ptr<vloc::UavWorld> world;
  try {
    world = std::make_unique<vloc::UavWorld>(options.world);
  } catch (const std::exception& e) {
    std::cerr << "sim_uav: " << e.what() << "\n";
    return 1;
  }
  LOG(INFO) << "flight: " << world->flight().Duration() << " s, route " << world->flight().RouteLength() << " m, "
            << world->NumFrames() << " frames at " << options.world.fps << " fps";

  if (setup->args.Has("snapshot")) {
    const std::string path = setup->args.Get("snapshot");
    const double t = setup->args.GetDouble("at", 1.0);
    if (!cv::imwrite(path, world->RenderFrame(t))) {
      std::cerr << "sim_uav: cannot write snapshot " << path << " (check the folder exists and is writable)\n";
      return 1;
    }
    LOG(INFO) << "saved the frame at t = " << t << " s to " << path;
    return 0;
  }

  vloc::SimUavPublisher publisher(options, *world);
  if (setup->args.Has("log")) {
    std::string error;
    if (!vloc::WriteSimUavLog(setup->args.Get("log"), &publisher, &error)) {
      std::cerr << "sim_uav: " << error << "\n";
      return 1;
    }
    return 0;
  }
  return vloc::PublishSimUavRealTime(*setup->transport, options.speed, &publisher);
}
