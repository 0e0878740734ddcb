// navcam_driver: replays recorded Navcam stereo pairs (a folder of images
// plus a YAML manifest, see navcam_manifest.h) as NAVCAM_STEREO and
// ROVER_SITE, at the recorded pace (x speed) or as fast as possible.
//   navcam_driver --config config/procs/navcam_driver.yaml --manifest DATA/manifest.yaml [--speed 0]
#include <iostream>

#include "navcam_replay.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(argc, argv,
                                  {"navcam_driver", {"manifest", "speed"}, false,
                                   "[--config config/procs/navcam_driver.yaml] --manifest FILE.yaml [--speed X]"});
  if (!setup) return 1;
  vloc::NavcamDriverOptions options;
  try {
    std::string echo;
    options = vloc::LoadOptions<vloc::NavcamDriverOptions>(setup->config, setup->config_path, &echo);
    if (setup->args.Has("manifest")) options.manifest = setup->args.Get("manifest");
    if (setup->args.Has("speed")) options.speed = setup->args.GetDouble("speed", options.speed);
    LOG(INFO) << "navcam_driver options:\n" << echo << "\n(effective manifest " << options.manifest << ", speed "
              << options.speed << ")";
  } catch (const vloc::ConfigError& e) {
    std::cerr << "navcam_driver: " << e.what() << "\n";
    return 1;
  }
  if (options.manifest.empty()) {
    std::cerr << "navcam_driver: no manifest given (--manifest FILE.yaml or manifest: in the config)\n";
    return 1;
  }
  const vloc::NavcamManifest manifest = vloc::ReadNavcamManifest(options.manifest);
  for (const std::string& problem : manifest.problems) LOG(ERROR) << problem;
  if (!manifest.readable) return 1;
  vloc::ReplayPacer pacer(options.speed);
  const auto summary = vloc::ReplayNavcam(options, manifest, *setup->transport, pacer);
  LOG(INFO) << "navcam_driver: " << summary.sites << " sites, " << summary.pairs_published << " pairs published, "
            << summary.pairs_skipped << " skipped";
  return 0;
}
