// navcam_driver: replays recorded Navcam stereo pairs (a folder of images
// plus a YAML manifest, see navcam_manifest.h; or a folder of PDS3 products
// grouped by their labels, see navcam_pds.h) as NAVCAM_STEREO and
// ROVER_SITE, at the recorded pace (x speed) or as fast as possible.
//   navcam_driver --config config/procs/navcam_driver.yaml --manifest DATA/manifest.yaml [--speed 0]
//   navcam_driver --config config/procs/navcam_driver.yaml --pds DATA/pds_folder [--speed 0]
#include <filesystem>
#include <iostream>

#include "navcam_replay.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(argc, argv,
                                  {"navcam_driver", {"manifest", "pds", "speed"}, false,
                                   "[--config config/procs/navcam_driver.yaml] (--manifest FILE.yaml | --pds FOLDER) "
                                   "[--speed X] [--lcm-url URL]"});
  if (!setup) return 1;
  const auto loaded = vloc::LoadProcessOptions<vloc::NavcamDriverOptions>(*setup, [&](vloc::NavcamDriverOptions& o) {
    if (setup->args.Has("manifest")) {
      o.manifest = setup->args.Get("manifest");
      o.pds.clear();
    }
    if (setup->args.Has("pds")) {
      o.pds = setup->args.Get("pds");
      o.manifest.clear();
    }
    // A folder given as the manifest: PDS products without a manifest.
    if (!o.manifest.empty() && std::filesystem::is_directory(o.manifest)) std::swap(o.pds, o.manifest);
    if (setup->args.Has("speed")) o.speed = setup->args.GetDouble("speed", o.speed);
  });
  if (!loaded) return 1;
  const vloc::NavcamDriverOptions& options = *loaded;
  if (options.manifest.empty() && options.pds.empty()) {
    std::cerr << "navcam_driver: no manifest or PDS folder given (--manifest FILE.yaml, --pds FOLDER, or manifest: / "
                 "pds: in the config)\n";
    return 1;
  }
  vloc::NavcamManifest manifest;
  if (!options.pds.empty()) {
    vloc::NavcamPdsFolder folder = vloc::ReadNavcamPdsFolder(options.pds, options.pds_options);
    for (const vloc::NavcamPdsSite& site : folder.sites) LOG(INFO) << "navcam_driver: PDS " << site.Describe();
    manifest = std::move(folder.manifest);
  } else {
    manifest = vloc::ReadNavcamManifest(options.manifest);
  }
  for (const std::string& problem : manifest.problems) LOG(ERROR) << problem;
  if (!manifest.readable) return 1;
  vloc::ReplayPacer pacer(options.speed);
  const auto summary = vloc::ReplayNavcam(options, manifest, *setup->transport, pacer);
  LOG(INFO) << "navcam_driver: " << summary.sites << " sites, " << summary.pairs_published << " pairs published, "
            << summary.pairs_skipped << " skipped";
  return 0;
}
