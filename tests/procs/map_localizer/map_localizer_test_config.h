#pragma once
// map_localizer's process tests: the maploc scenario's 512 x 512 Navcam as a
// calibration file, and the process config naming it and the map.
#include <filesystem>
#include <fstream>
#include <string>

namespace vloc::testing {

// Writes navcam.yaml and map_localizer.yaml into `dir`; returns the config's path.
inline std::string WriteMapLocalizerConfigs(const std::filesystem::path& dir, const std::string& map_path) {
  std::ofstream(dir / "navcam.yaml") << R"(rig:
  left:  {width: 512, height: 512, fx: 594.5, fy: 594.5, cx: 255.5, cy: 255.5}
  right: {width: 512, height: 512, fx: 594.5, fy: 594.5, cx: 255.5, cy: 255.5}
  right_in_left_translation: [0.27, 0.0, 0.0]
  right_in_left_rpy: [0.0, 0.0, 0.0]
mast:
  mast_head: [0.0, 0.0, 1.5]
  camera_offset: 0.0
)";
  std::ofstream(dir / "map_localizer.yaml") << "navcam_config: " << (dir / "navcam.yaml").string() << "\n"
                                            << "map_path: " << map_path << "\n";
  return (dir / "map_localizer.yaml").string();
}

}  // namespace vloc::testing
