// map_localizer: rover sites localised against an aerial map (SITE_POSE_FIX).
//   map_localizer --config config/procs/map_localizer.yaml [--map FILE] [--fix-every N] [--lcm-url URL]
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>

#include "map_localizer_adapter.h"
#include "vloc/common/logging.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(
      argc, argv, {"map_localizer", {"map", "fix-every"}, true,
                   "--config config/procs/map_localizer.yaml [--map FILE] [--fix-every N] [--lcm-url URL]"});
  if (!setup) return 1;
  const auto loaded = vloc::LoadProcessOptions<vloc::MapLocalizerProcOptions>(
      *setup, [&](vloc::MapLocalizerProcOptions& o) {
        if (setup->args.Has("map")) o.map_path = setup->args.Get("map");
        if (setup->args.Has("fix-every")) o.fix_every = setup->args.GetInt("fix-every", o.fix_every);
      });
  if (!loaded) return 1;
  const vloc::MapLocalizerProcOptions& options = *loaded;
  vloc::NavcamModel navcam;
  try {
    navcam = vloc::LoadOptionsFile<vloc::NavcamModel>(options.navcam_config);
  } catch (const vloc::ConfigError& e) {
    std::cerr << "map_localizer: " << e.what() << "\n";
    return 1;
  }
  vloc::MapLocalizerAdapter adapter(*setup->transport, options, navcam);
  // A map that is there is read now (a bad one stops the process); one
  // still to come (a mosaic being flown, a map rendered by another process
  // of the group) is waited for up to wait_for_map_s while sites collect.
  if (options.wait_for_map_s <= 0 || std::filesystem::exists(options.map_path)) {
    std::string error;
    if (!adapter.LoadMap(&error)) {
      std::cerr << "map_localizer: " << error << "\n";
      return 1;
    }
    LOG(INFO) << "map_localizer: map " << options.map_path << ": " << adapter.MapDescription();
  } else {
    LOG(INFO) << "map_localizer: the map " << options.map_path << " is not there yet; sites wait for it up to "
              << options.wait_for_map_s << " s";
  }
  LOG(INFO) << "map_localizer: waiting for " << options.stereo_channel << " and " << options.traverse_channel;
  const auto map_deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(std::max(0.0, options.wait_for_map_s));
  bool no_map = false;
  const int rc = vloc::RunUntilSignal(*setup->transport, 200, [&] { adapter.OnIdle(); }, [&] {
    no_map = !adapter.HasMap() && std::chrono::steady_clock::now() > map_deadline;
    return no_map;
  });
  if (no_map) {
    std::cerr << "map_localizer: the map " << options.map_path << " did not appear within wait_for_map_s "
              << options.wait_for_map_s << " s\n";
    return 1;
  }
  LOG(INFO) << "map_localizer: " << adapter.StatusLine();
  return rc;
}
