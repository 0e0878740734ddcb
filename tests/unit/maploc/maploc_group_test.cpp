// The rover_sim_map group: rover_sim's processes plus the map renderer and
// map_localizer, the simulator started after map_localizer, the map path
// in the log folder, its name overridable by VLOC_MAP_NAME. The cooperative
// run's two groups: uav_coop's mosaic (in the log folder) is rover_coop's map.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>

#include "vloc/launch/group_file.h"

namespace vloc::launch {
namespace {

const ProcessSpec& Find(const GroupFile& file, const std::string& name) {
  const auto it = std::find_if(file.processes.begin(), file.processes.end(),
                               [&](const ProcessSpec& p) { return p.name == name; });
  if (it == file.processes.end()) throw std::runtime_error("no process " + name);
  return *it;
}

TEST(RoverSimMapGroup, ParsesWithTheMapLocalizerBeforeTheSimulator) {
  // The launcher's variables, as vloc_launch sets them, from this test's environment.
  setenv("VLOC_BIN", "/b", 1);
  setenv("VLOC_ROOT", "/r", 1);
  setenv("VLOC_LCM_URL", "udpm://239.255.76.67:7667?ttl=0", 1);
  setenv("VLOC_LOG_DIR", "/logs", 1);
  unsetenv("VLOC_MAP_NAME");
  const GroupFile file = ParseGroupFile("config/groups/rover_sim_map.yaml");
  EXPECT_EQ(file.Groups(), std::vector<std::string>{"rover_sim_map"});
  const ProcessSpec& localizer = Find(file, "map_localizer");
  EXPECT_EQ(localizer.command, "/b/map_localizer");
  EXPECT_EQ(localizer.args.back(), "/logs/sim_map_20cm.tif");
  EXPECT_EQ(Find(file, "render_map").args[3], "/logs/sim_map_20cm.tif");
  const auto& sim_deps = Find(file, "sim_rover").depends_on;
  EXPECT_NE(std::find(sim_deps.begin(), sim_deps.end(), "map_localizer"), sim_deps.end());
  setenv("VLOC_MAP_NAME", "orbital.tif", 1);
  EXPECT_EQ(Find(ParseGroupFile("config/groups/rover_sim_map.yaml"), "map_localizer").args.back(),
            "/logs/orbital.tif");
}

TEST(CoopGroups, TheUavGroupsMosaicIsTheRoverGroupsMap) {
  setenv("VLOC_BIN", "/b", 1);
  setenv("VLOC_ROOT", "/r", 1);
  setenv("VLOC_LCM_URL", "udpm://239.255.76.67:7667?ttl=0", 1);
  setenv("VLOC_LOG_DIR", "/logs", 1);
  for (const char* v : {"VLOC_COOP_MAP_NAME", "VLOC_FIX_EVERY", "VLOC_SIM_UAV_CONFIG", "VLOC_UAV_GPS_SIGMA"}) unsetenv(v);
  const GroupFile uav = ParseGroupFile("config/groups/uav_coop.yaml");
  EXPECT_EQ(uav.Groups(), std::vector<std::string>{"uav_coop"});
  const auto& mosaicker = Find(uav, "uav_mosaicker").args;
  EXPECT_NE(std::find(mosaicker.begin(), mosaicker.end(), "/logs/uav_mosaic.png"), mosaicker.end());
  EXPECT_NE(std::find(mosaicker.begin(), mosaicker.end(), "config/procs/uav_mosaicker_coop.yaml"), mosaicker.end());
  const auto& sim = Find(uav, "sim_uav").args;
  EXPECT_NE(std::find(sim.begin(), sim.end(), "/logs/coop_orthomap.png"), sim.end());
  EXPECT_NE(std::find(sim.begin(), sim.end(), "config/procs/sim_uav_coop.yaml"), sim.end());
  const GroupFile rover = ParseGroupFile("config/groups/rover_coop.yaml");
  const auto& localizer = Find(rover, "map_localizer").args;
  EXPECT_NE(std::find(localizer.begin(), localizer.end(), "/logs/uav_mosaic.png"), localizer.end());
  EXPECT_NE(std::find(localizer.begin(), localizer.end(), "config/procs/map_localizer_coop.yaml"), localizer.end());
  const auto& sim_deps = Find(rover, "sim_rover").depends_on;
  EXPECT_NE(std::find(sim_deps.begin(), sim_deps.end(), "map_localizer"), sim_deps.end());
  // The two groups share a log folder: no process name (hence <name>.log) in both.
  for (const ProcessSpec& p : uav.processes)
    EXPECT_THROW(Find(rover, p.name), std::runtime_error) << p.name << " is in both groups";
}

}  // namespace
}  // namespace vloc::launch
