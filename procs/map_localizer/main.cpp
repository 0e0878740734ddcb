// map_localizer: rover sites localised against an aerial map (SITE_POSE_FIX).
//   map_localizer --config config/procs/map_localizer.yaml [--map FILE] [--lcm-url URL]
#include <iostream>

#include "map_localizer_adapter.h"
#include "vloc/common/logging.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(
      argc, argv, {"map_localizer", {"map"}, true, "--config config/procs/map_localizer.yaml [--map FILE] [--lcm-url URL]"});
  if (!setup) return 1;
  const auto loaded = vloc::LoadProcessOptions<vloc::MapLocalizerProcOptions>(
      *setup, [&](vloc::MapLocalizerProcOptions& o) {
        if (setup->args.Has("map")) o.map_path = setup->args.Get("map");
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
  if (!vloc::maploc::LoadMapRaster(options.map_path, &map, &error,
                                   Eigen::Vector2d(options.map_offset_xy[0], options.map_offset_xy[1]))) {
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
