// vloc_console's message <-> JSON layer (procs/vloc_console/console_json.cpp):
// each tie point's residual under the BA's relative pose, null for numbers
// JSON cannot hold, and the browser's commands checked field by field.
#include "console_json.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "vloc/lcm_io/convert.h"

namespace vloc {
namespace {

using nlohmann::json;

tie_points_t TwoPoints() {
  tie_points_t m{};
  m.previous_site_id = 3;
  m.current_site_id = 4;
  for (int k = 0; k < 2; ++k) {
    tie_point_t p{};
    p.id = k;
    // p_previous = p_current + (10, 0, 0) for point 0; off by 0.3 m in y for point 1.
    p.p_current[0] = 5.0 + k, p.p_current[1] = 1.0, p.p_current[2] = -1.5;
    p.p_previous[0] = 15.0 + k, p.p_previous[1] = 1.0 + 0.3 * k, p.p_previous[2] = -1.5;
    tie_observation_t o{};
    o.site_role = tie_observation_t::SITE_PREVIOUS, o.camera = tie_observation_t::CAMERA_LEFT, o.pair_index = 2;
    o.u = 100 + k, o.v = 200;
    p.observations.push_back(o);
    o.camera = tie_observation_t::CAMERA_RIGHT;
    p.observations.push_back(o);
    o.site_role = tie_observation_t::SITE_CURRENT, o.camera = tie_observation_t::CAMERA_LEFT, o.pair_index = 5;
    o.u = 300, o.v = 400 + k;
    p.observations.push_back(o);
    p.num_observations = 3;
    m.points.push_back(p);
  }
  m.num_points = 2;
  return m;
}

TEST(ConsoleJson, TiePointResidualsUnderTheRelativePose) {
  Pose3 previous_from_current = Pose3::Identity();
  previous_from_current.translation() = Eigen::Vector3d(10, 0, 0);
  const json j = TiePointsJson(TwoPoints(), previous_from_current);
  ASSERT_EQ(j["points"].size(), 2u);
  EXPECT_NEAR(j["points"][0]["residual_m"].get<double>(), 0.0, 1e-12);
  EXPECT_NEAR(j["points"][1]["residual_m"].get<double>(), 0.3, 1e-12);
  EXPECT_EQ(j["points"][1]["previous"]["pair"], 2);
  EXPECT_EQ(j["points"][1]["current"]["v"], 401.0);
  EXPECT_FALSE(TiePointsJson(TwoPoints(), std::nullopt)["points"][0].contains("residual_m"));
}

TEST(ConsoleJson, NonFiniteNumbersBecomeNull) {
  uav_state_t u{};
  u.latitude = std::numeric_limits<double>::quiet_NaN();
  u.height = std::numeric_limits<double>::infinity();
  const json j = UavStateJson(u);
  EXPECT_TRUE(j["height"].is_null());
  EXPECT_NO_THROW(json::parse(j.dump()));
}

json Pick() {
  return {{"previous_pair", 1}, {"previous_u", 10.5}, {"previous_v", 20},
          {"current_pair", 2},  {"current_u", 30},    {"current_v", 40}};
}

TEST(ConsoleJson, ManualTiesAreCheckedFieldByField) {
  manual_tie_points_t t;
  std::string error;
  json c = {{"previous_site", 0}, {"current_site", 1}, {"points", {Pick(), Pick()}}};
  ASSERT_TRUE(ManualTiesFromJson(c, 7, 200, &t, &error)) << error;
  EXPECT_EQ(t.num_points, 2);
  EXPECT_EQ(t.utime, 7);
  EXPECT_DOUBLE_EQ(t.previous_u[1], 10.5);
  EXPECT_EQ(t.source, "vloc_console");
  struct Case {
    const char* what;
    json command;
    const char* says;
  };
  json nan_pick = Pick(), pair_text = Pick(), fractional_pair = Pick();
  nan_pick["current_u"] = -1;
  pair_text["previous_pair"] = "1";
  fractional_pair["current_pair"] = 1.5;
  for (const Case& k : std::vector<Case>{
           {"negative px", {{"previous_site", 0}, {"current_site", 1}, {"points", {nan_pick}}}, "current_u"},
           {"pair as text", {{"previous_site", 0}, {"current_site", 1}, {"points", {pair_text}}}, "previous_pair"},
           {"fractional pair", {{"previous_site", 0}, {"current_site", 1}, {"points", {fractional_pair}}}, "integer"},
           {"backwards", {{"previous_site", 2}, {"current_site", 1}, {"points", {Pick()}}}, "after"},
           {"no points", {{"previous_site", 0}, {"current_site", 1}, {"points", json::array()}}, "1 to 200"},
           {"no site", {{"current_site", 1}, {"points", {Pick()}}}, "previous_site"}}) {
    manual_tie_points_t bad;
    EXPECT_FALSE(ManualTiesFromJson(k.command, 7, 200, &bad, &error)) << k.what;
    EXPECT_NE(error.find(k.says), std::string::npos) << k.what << ": " << error;
  }
  json many = {{"previous_site", 0}, {"current_site", 1}, {"points", json::array()}};
  for (int i = 0; i < 3; ++i) many["points"].push_back(Pick());
  EXPECT_FALSE(ManualTiesFromJson(many, 7, 2, &t, &error));
}

TEST(ConsoleJson, OrdersNameAKnownActionAndKind) {
  procman_order_t o;
  std::string error;
  ASSERT_TRUE(OrderFromJson({{"host", ""}, {"target", "crosssite_ba"}, {"target_kind", "group"}, {"action", "stop"}}, 5,
                            &o, &error))
      << error;
  EXPECT_EQ(int(o.target_kind), int(procman_order_t::TARGET_GROUP));
  EXPECT_EQ(int(o.action), int(procman_order_t::ACTION_STOP));
  EXPECT_FALSE(
      OrderFromJson({{"host", ""}, {"target", ""}, {"target_kind", "process"}, {"action", "stop"}}, 5, &o, &error));
  EXPECT_FALSE(
      OrderFromJson({{"host", ""}, {"target", "x"}, {"target_kind", "thing"}, {"action", "stop"}}, 5, &o, &error));
  EXPECT_FALSE(OrderFromJson({{"target", "x"}, {"target_kind", "process"}, {"action", "stop"}}, 5, &o, &error));
  EXPECT_NE(error.find("host"), std::string::npos);
}

}  // namespace
}  // namespace vloc
