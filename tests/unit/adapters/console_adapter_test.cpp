// vloc_console's adapter in-process over MockTransport, with a ConsoleServer
// that is never started (no socket; Broadcast reaches no one): what the
// console keeps per channel and serves to a page that opens (Welcome, the
// /api replies), its bounds (sites, image sites, tie-point sites, UAV
// states, launchers, the welcome's bytes), and which browser commands it
// turns into PROCMAN_ORDERS / MANUAL_TIE_POINTS.
#include <gtest/gtest.h>

#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "console_adapter.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/manual_tie_points_t.hpp"
#include "vloc/procman_order_t.hpp"
#include "vloc/testing/rover_inputs.h"
#include "vloc/uav_state_t.hpp"

namespace vloc {
namespace {

using nlohmann::json;

struct Console {
  MockTransport bus;
  ConsoleServer server;
  ConsoleAdapter adapter;
  explicit Console(const ConsoleProcOptions& options) : server(options.server), adapter(bus, server, options) {
    adapter.Subscribe();
  }

  template <class Msg>
  void Send(const std::string& channel, const Msg& msg) {
    ASSERT_TRUE(Publish(bus, channel, msg));
    bus.HandleAll();
  }
  void Dr(int site) {
    PoseWithCovariance pose;
    pose.pose = MakePose(10.0 * site, 0, 0, 0, 0, 0);
    pose.covariance = Eigen::Matrix<double, 6, 6>::Identity() * 0.01;
    Send("SITE_POSE_DR", SitePoseToMessage(site, site_pose_t::SOURCE_DEAD_RECKONING, pose));
  }
  void Ties(int current_site) {
    tie_points_t t{};
    t.previous_site_id = current_site - 1;
    t.current_site_id = current_site;
    t.previous_site_pose.site_id = current_site - 1;
    t.current_site_pose_dr.site_id = current_site;
    t.previous_site_pose.pose.orientation[0] = t.current_site_pose_dr.pose.orientation[0] = 1;
    Send("TIE_POINTS", t);
  }
  void Launcher(const std::string& host) {
    procman_status_t s{};
    s.host = host;
    s.launcher_pid = 100;
    Send("PROCMAN_STATUS", s);
  }
  void UavState(int frame) {
    uav_state_t s{};
    s.frame_index = frame;
    s.status = uav_state_t::STATUS_TRACKING;
    s.height = 50;
    Send("UAV_STATE", s);
  }

  // The page's messages of `type` in what a page opening now is sent.
  std::vector<json> Welcomed(const std::string& type) const {
    std::vector<json> out;
    for (const std::string& text : adapter.Welcome()) {
      json j = json::parse(text);
      if (j.value("type", "") == type) out.push_back(std::move(j));
    }
    return out;
  }
  // The `key` (site) of each of them, in the order sent.
  std::vector<int> WelcomedSites(const std::string& type, const std::string& key = "site") const {
    std::vector<int> sites;
    for (const json& j : Welcomed(type)) sites.push_back(j[key].get<int>());
    return sites;
  }
  json Hello() const { return json::parse(adapter.Welcome().front()); }
  // The reply to GET /api/<rest>?<query>; status 404 when the adapter has none.
  HttpReply Api(const std::string& rest, const std::map<std::string, std::string>& query = {}) {
    HttpReply reply;
    if (!adapter.OnApi(rest, query, &reply)) reply.status = 404;
    return reply;
  }
};

ConsoleProcOptions Defaults() {
  ConsoleProcOptions o;
  o.server.port = 0;
  return o;
}

TEST(ConsoleAdapter, KeepsThePosesOfTheNewestMaxSites) {
  ConsoleProcOptions o = Defaults();
  o.max_sites = 3;
  Console c(o);
  for (int site = 0; site < 5; ++site) c.Dr(site);
  c.Dr(4);  // a repeat replaces its copy
  EXPECT_EQ(c.WelcomedSites("site_pose"), (std::vector<int>{2, 3, 4}));
  EXPECT_EQ(c.Hello()["sites"], 3);
  EXPECT_EQ(c.Hello()["sites_not_sent"], 0);
}

TEST(ConsoleAdapter, ServesTheLeftImagesOfTheNewestImageSites) {
  ConsoleProcOptions o = Defaults();
  o.image_sites_kept = 2;
  Console c(o);
  for (int site = 0; site < 3; ++site)
    for (int k = 0; k < 2; ++k) c.Send("NAVCAM_STEREO", StereoPairToMessage(testing::TexturelessPair(site, k),
                                                                            site == 2 ? ImageEncoding::kJpeg
                                                                                      : ImageEncoding::kGray8));
  EXPECT_EQ(c.Api("image", {{"site", "0"}, {"pair", "0"}}).status, 404) << "site 0 is beyond image_sites_kept";
  const HttpReply raw = c.Api("image", {{"site", "1"}, {"pair", "1"}});
  EXPECT_EQ(raw.status, 200);
  EXPECT_EQ(raw.content_type, "image/png") << "raw pixels are served as PNG";
  EXPECT_EQ(raw.body.rfind("\x89PNG", 0), 0u);
  const HttpReply jpeg = c.Api("image", {{"site", "2"}, {"pair", "0"}});
  EXPECT_EQ(jpeg.content_type, "image/jpeg") << "JPEG bytes are served as they came";
  EXPECT_EQ(c.Api("image", {{"site", "2"}, {"pair", "2"}}).status, 404);
  EXPECT_EQ(c.Api("image", {{"site", "x"}}).status, 400);
  EXPECT_EQ(c.WelcomedSites("images"), (std::vector<int>{1, 2}));
  EXPECT_EQ(c.Welcomed("images").front()["pairs"].size(), 2u);
  // A pair index beyond num_pairs adds nothing.
  stereo_image_t beyond = StereoPairToMessage(testing::TexturelessPair(2, 0), ImageEncoding::kJpeg);
  beyond.pair_index = 7;
  c.Send("NAVCAM_STEREO", beyond);
  EXPECT_EQ(c.Api("image", {{"site", "2"}, {"pair", "7"}}).status, 404);
}

TEST(ConsoleAdapter, KeepsTheTiePointsOfTheNewestSites) {
  ConsoleProcOptions o = Defaults();
  o.tie_point_sites_kept = 2;
  Console c(o);
  for (int site = 1; site <= 4; ++site) c.Ties(site);
  EXPECT_EQ(c.WelcomedSites("tie_points", "current"), (std::vector<int>{3, 4}));
}

TEST(ConsoleAdapter, KeepsTheNewestUavStatesAndMosaic) {
  ConsoleProcOptions o = Defaults();
  o.max_uav_states = 4;
  Console c(o);
  for (int frame = 0; frame < 10; ++frame) c.UavState(frame);
  const std::vector<json> history = c.Welcomed("uav_history");
  ASSERT_EQ(history.size(), 1u);
  ASSERT_EQ(history[0]["states"].size(), 4u);
  EXPECT_EQ(history[0]["states"][0]["frame"], 6);
  EXPECT_EQ(c.Hello()["uav_states"], 4);
  // The mosaic preview: JPEG kept and served, anything else refused (the kept one stays).
  EXPECT_EQ(c.Api("uav_mosaic").status, 404);
  c.Send("UAV_MOSAIC", ImageToMessage(cv::Mat(16, 24, CV_8UC1, cv::Scalar(9)), ImageEncoding::kJpeg, 1, "mosaic"));
  const HttpReply jpeg = c.Api("uav_mosaic");
  EXPECT_EQ(jpeg.status, 200);
  c.Send("UAV_MOSAIC", ImageToMessage(cv::Mat(16, 24, CV_8UC1, cv::Scalar(9)), ImageEncoding::kPng, 2, "mosaic"));
  EXPECT_EQ(c.Api("uav_mosaic").body, jpeg.body);
  const std::vector<json> mosaic = c.Welcomed("uav_mosaic");
  ASSERT_EQ(mosaic.size(), 1u);
  EXPECT_EQ(mosaic[0]["seq"], 1);
  EXPECT_EQ(mosaic[0]["width"], 24);
}

TEST(ConsoleAdapter, KeepsTheProcessTablesOfMaxLaunchers) {
  ConsoleProcOptions o = Defaults();
  o.max_launchers = 2;
  Console c(o);
  c.Launcher("a");
  c.Launcher("b");
  c.Launcher("a");  // heard again: now b is the longest silent
  c.Launcher("c");
  std::vector<std::string> hosts;
  for (const json& j : c.Welcomed("procman")) hosts.push_back(j["host"]);
  EXPECT_EQ(hosts, (std::vector<std::string>{"a", "c"}));
}

TEST(ConsoleAdapter, WelcomeStaysWithinItsBytesNewestSitesFirst) {
  ConsoleProcOptions o = Defaults();
  o.welcome_max_bytes = 65536;
  Console c(o);
  for (int site = 0; site < 1000; ++site) c.Dr(site);
  size_t bytes = 0;
  for (const std::string& text : c.adapter.Welcome()) bytes += text.size();
  EXPECT_LE(bytes, 65536u + 200) << "the hello line is the only thing beyond the budget";
  const json hello = c.Hello();
  EXPECT_GT(hello["sites_not_sent"], 0);
  EXPECT_EQ(hello["sites"].get<int>() + hello["sites_not_sent"].get<int>(), 1000);
  EXPECT_EQ(c.WelcomedSites("site_pose").back(), 999);
}

TEST(ConsoleAdapter, ActsOnlyWhenAllowedAndOnWellFormedCommands) {
  Console c(Defaults());
  const json order = {{"type", "order"}, {"host", "rover"}, {"target", "crosssite_ba"},
                      {"target_kind", "process"}, {"action", "restart"}};
  EXPECT_FALSE(c.adapter.OnCommand(order, /*may_act=*/false)["ok"]);
  EXPECT_EQ(c.bus.Count("PROCMAN_ORDERS"), 0);
  EXPECT_FALSE(c.adapter.OnCommand({{"type", "shutdown"}}, true)["ok"]);
  json bad = order;
  bad["action"] = "kill";
  EXPECT_FALSE(c.adapter.OnCommand(bad, true)["ok"]);
  EXPECT_EQ(c.bus.Count("PROCMAN_ORDERS"), 0);

  EXPECT_TRUE(c.adapter.OnCommand(order, true)["ok"]);
  ASSERT_EQ(c.bus.Count("PROCMAN_ORDERS"), 1);
  procman_order_t sent;
  const std::vector<uint8_t>& bytes = *c.bus.Last("PROCMAN_ORDERS");
  ASSERT_TRUE(Decode(bytes.data(), bytes.size(), &sent));
  EXPECT_EQ(sent.host, "rover");
  EXPECT_EQ(sent.target, "crosssite_ba");
  EXPECT_EQ(sent.action, +procman_order_t::ACTION_RESTART);
  EXPECT_EQ(sent.target_kind, +procman_order_t::TARGET_PROCESS);

  json pick = {{"previous_pair", 0}, {"previous_u", 10}, {"previous_v", 20},
               {"current_pair", 1},  {"current_u", 30},  {"current_v", 40}};
  json ties = {{"type", "manual_tie"}, {"previous_site", 3}, {"current_site", 4}, {"points", {pick, pick}}};
  EXPECT_EQ(c.adapter.OnCommand(ties, true)["points"], 2);
  ASSERT_EQ(c.bus.Count("MANUAL_TIE_POINTS"), 1);
  ties["points"] = json::array();
  for (int i = 0; i <= Defaults().max_manual_points; ++i) ties["points"].push_back(pick);
  EXPECT_FALSE(c.adapter.OnCommand(ties, true)["ok"]) << "more picks than max_manual_points";
  EXPECT_EQ(c.bus.Count("MANUAL_TIE_POINTS"), 1);

  HttpReply status = c.Api("status");
  const json counts = json::parse(status.body);
  EXPECT_EQ(counts["orders_sent"], 1);
  EXPECT_EQ(counts["manual_sent"], 1);
  EXPECT_EQ(counts["refused"], 1) << "only the command refused for want of leave counts";
}

}  // namespace
}  // namespace vloc
