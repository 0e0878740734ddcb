// crosssite_ba: cross-site bundle adjustment of each new site.
//   crosssite_ba --config config/procs/crosssite_ba.yaml [--state-dir DIR] [--lcm-url URL]
#include <iostream>

#include "crosssite_ba_adapter.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup =
      vloc::SetupProcess(argc, argv, {"crosssite_ba", {"state-dir"}, true,
                                      "--config config/procs/crosssite_ba.yaml [--state-dir DIR] [--lcm-url URL]"});
  if (!setup) return 1;
  const auto loaded = vloc::LoadProcessOptions<vloc::CrossSiteBaProcOptions>(*setup);
  if (!loaded) return 1;
  const vloc::CrossSiteBaProcOptions& options = *loaded;
  vloc::NavcamModel navcam;
  try {
    std::string navcam_echo;
    navcam = vloc::LoadOptionsFile<vloc::NavcamModel>(options.navcam_config, "", &navcam_echo);
    LOG(INFO) << "Navcam (" << options.navcam_config << "):\n" << navcam_echo;
  } catch (const vloc::ConfigError& e) {
    std::cerr << "crosssite_ba: " << e.what() << "\n";
    return 1;
  }
  vloc::CrossSiteBaAdapter adapter(*setup->transport, options, navcam);
  std::string note, error;
  const std::string state_path = vloc::ResolveStatePath(options.state_path, setup->args, &note);
  if (!note.empty()) LOG(WARNING) << "crosssite_ba: " << note;
  if (!adapter.Restore(state_path, &error)) {
    std::cerr << "crosssite_ba: " << error << "\n";
    return 1;
  }
  LOG(INFO) << "crosssite_ba: waiting for " << options.tie_points_channel;
  const int rc = vloc::RunUntilSignal(*setup->transport, 200);
  LOG(INFO) << "crosssite_ba: " << adapter.StatusLine();
  return rc;
}
