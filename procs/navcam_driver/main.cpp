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
  const auto loaded = vloc::LoadProcessOptions<vloc::NavcamDriverOptions>(*setup, [&](vloc::NavcamDriverOptions& o) {
    if (setup->args.Has("manifest")) o.manifest = setup->args.Get("manifest");
    if (setup->args.Has("speed")) o.speed = setup->args.GetDouble("speed", o.speed);
  });
  if (!loaded) return 1;
  const vloc::NavcamDriverOptions& options = *loaded;
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
