// map_localizer: rover sites localised against an aerial map (SITE_POSE_FIX).
//   map_localizer --config config/procs/map_localizer.yaml [--map FILE] [--fix-every N] [--lcm-url URL]
#include <chrono>
#include <filesystem>
#include <iostream>
#include <thread>

#include "map_localizer_adapter.h"
#include "vloc/common/logging.h"
#include "vloc/lcm_io/process.h"

namespace {

// Waits up to `seconds` for `path` to appear (a map another process is
// still writing, e.g. vloc_render_map in the same group); false on a stop signal.
bool WaitForFile(const std::string& path, double seconds) {
  if (seconds <= 0 || std::filesystem::exists(path)) return true;
  LOG(INFO) << "map_localizer: waiting up to " << seconds << " s for the map " << path;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!std::filesystem::exists(path) && std::chrono::steady_clock::now() < deadline) {
    if (vloc::StopSignalPending()) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // let the writer finish the file
  return true;
}

}  // namespace

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
  vloc::maploc::MapRaster map;
  std::string error;
  try {
    navcam = vloc::LoadOptionsFile<vloc::NavcamModel>(options.navcam_config);
  } catch (const vloc::ConfigError& e) {
    std::cerr << "map_localizer: " << e.what() << "\n";
    return 1;
  }
  if (!WaitForFile(options.map_path, options.wait_for_map_s)) return 0;
  if (!vloc::maploc::LoadMapRaster(options.map_path, &map, &error, options.Georeference())) {
    std::cerr << "map_localizer: " << error << "\n";
    return 1;
  }
  LOG(INFO) << "map_localizer: map " << options.map_path << ": " << map.gray.cols << " x " << map.gray.rows << " at "
            << map.m_per_px << " m/px" << (map.has_height() ? " with heights" : "") << ", x from " << map.x_min
            << ", y up to " << map.y_max;
  vloc::MapLocalizerAdapter adapter(*setup->transport, options, navcam, std::move(map));
  LOG(INFO) << "map_localizer: waiting for " << options.stereo_channel << " and " << options.traverse_channel;
  const int rc = vloc::RunUntilSignal(*setup->transport, 200, [&] { adapter.OnIdle(); });
  LOG(INFO) << "map_localizer: " << adapter.StatusLine();
  return rc;
}
