// sim_uav: a simulated small UAV with a nadir camera over textured ground.
//   sim_uav [--config config/procs/sim_uav.yaml] [--speed X] [--duration S] [--fps F] [--orthomap FILE.png] [--gps-sigma M]
//       publishes UAV_CAMERA, UAV_GPS, UAV_GT over LCM in real time (x speed; 0 = as fast as possible)
//   sim_uav ... --log FILE      writes the messages straight to an LCM log, as fast as it can
//   sim_uav ... --snapshot FILE.png [--at T]   saves the frame at T s (default 1) and exits
// See sim_uav_publisher.h for the channels and frames.
#include <opencv2/imgcodecs.hpp>

#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim_uav_publisher.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"


namespace {

// The config with the command line's overrides, echoed to the log; nullopt after one error line.
std::optional<vloc::SimUavOptions> LoadSimUavOptions(const vloc::ProcessSetup& setup) {
  const vloc::CommandLine& args = setup.args;
  auto options = vloc::LoadProcessOptions<vloc::SimUavOptions>(setup, [&](vloc::SimUavOptions& o) {
    if (args.Has("duration")) o.duration = args.GetDouble("duration", o.duration);
    if (args.Has("fps")) o.world.fps = args.GetDouble("fps", o.world.fps);
    if (args.Has("speed")) o.speed = args.GetDouble("speed", o.speed);
    if (args.Has("orthomap")) o.world.orthomap.image = args.Get("orthomap");
    if (args.Has("gps-sigma")) o.world.gps.horizontal_sigma = args.GetDouble("gps-sigma", o.world.gps.horizontal_sigma);
  });
  if (options)
    LOG(INFO) << "(overrides: duration " << options->duration << " s, fps " << options->world.fps << ", speed "
              << options->speed << ", orthomap image '" << options->world.orthomap.image
              << "', GPS horizontal sigma " << options->world.gps.horizontal_sigma << " m)";
  return options;
}

// The world and its flight, described in the log; null after one error line.
std::unique_ptr<vloc::UavWorld> BuildWorld(const vloc::UavWorldOptions& options) {
  std::unique_ptr<vloc::UavWorld> world;
  try {
    world = std::make_unique<vloc::UavWorld>(options);
  } catch (const std::exception& e) {
    std::cerr << "sim_uav: " << e.what() << "\n";
    return nullptr;
  }
  LOG(INFO) << "flight: " << world->flight().Duration() << " s, route " << world->flight().RouteLength() << " m, "
            << world->NumFrames() << " frames at " << options.fps << " fps";
  return world;
}

// --snapshot: the frame at `t` s saved to `path`; the process's exit code.
int WriteSnapshot(const vloc::UavWorld& world, const std::string& path, double t) {
  if (!cv::imwrite(path, world.RenderFrame(t))) {
    std::cerr << "sim_uav: cannot write snapshot " << path << " (check the folder exists and is writable)\n";
    return 1;
  }
  LOG(INFO) << "saved the frame at t = " << t << " s to " << path;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(
      argc, argv,
      {"sim_uav",
       {"log", "duration", "fps", "speed", "snapshot", "at", "orthomap", "gps-sigma"},
       false,
       "[--config config/procs/sim_uav.yaml] [--speed X] [--duration S] [--fps F] [--orthomap FILE.png] [--gps-sigma M] "
       "[--log FILE] [--snapshot FILE.png --at T] [--lcm-url URL]",
       {"log", "snapshot"}});
  if (!setup) return 1;
  const std::optional<vloc::SimUavOptions> options = LoadSimUavOptions(*setup);
  if (!options) return 1;
  const std::unique_ptr<vloc::UavWorld> world = BuildWorld(options->world);
  if (!world) return 1;
  if (setup->args.Has("snapshot"))
    return WriteSnapshot(*world, setup->args.Get("snapshot"), setup->args.GetDouble("at", 1.0));
  vloc::SimUavPublisher publisher(*options, *world);
  if (setup->args.Has("log")) {
    std::string error;
    if (!vloc::WriteSimUavLog(setup->args.Get("log"), &publisher, &error)) {
      std::cerr << "sim_uav: " << error << "\n";
      return 1;
    }
    return 0;
  }
  return vloc::PublishSimUavRealTime(*setup->transport, options->speed, &publisher);
}
