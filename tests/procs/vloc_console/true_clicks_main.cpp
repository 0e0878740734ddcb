// vloc_true_clicks: prints, as the console's manual_tie JSON, the picks a
// careful operator would make for a simulated site pair (true_clicks.h).
// For the browser test, which clicks them on the page.
//   vloc_true_clicks --config config/sim/rover_two_sites.yaml --previous 0 --current 1 [--count 12]
#include <iostream>
#include <nlohmann/json.hpp>

#include "true_clicks.h"
#include "vloc/common/command_line.h"

int main(int argc, char** argv) {
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv, {"config", "previous", "current", "count"}, &error)) {
    std::cerr << "vloc_true_clicks: " << error << "\n";
    return 1;
  }
  try {
    const vloc::sim::RoverWorld world(
        vloc::testing::WorldOptionsOf(args.Get("config", "config/sim/rover_two_sites.yaml")));
    vloc::testing::ClickOptions o;
    o.count = args.GetInt("count", o.count);
    const auto ties = vloc::testing::TrueClicks(world, args.GetInt("previous", 0), args.GetInt("current", 1), o);
    nlohmann::json points = nlohmann::json::array();
    for (const vloc::ManualTie& t : ties)
      points.push_back({{"previous_pair", t.previous_pair},
                        {"previous_u", t.previous_px.x()},
                        {"previous_v", t.previous_px.y()},
                        {"current_pair", t.current_pair},
                        {"current_u", t.current_px.x()},
                        {"current_v", t.current_px.y()}});
    std::cout << nlohmann::json{{"points", points}}.dump() << "\n";
  } catch (const std::exception& e) {
    std::cerr << "vloc_true_clicks: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
