// Hostile input over real LCM (ports 7961-7962) for what issue 19 added:
// vloc_console on every channel it watches, and feature_frontend on
// MANUAL_TIE_POINTS (random bytes, truncations, wrong types, extreme
// numbers, absurd lengths; vloc/testing/hostile.h). Afterwards each process
// is alive, still does its job, sent the browsers only valid JSON (no NaN)
// and the bus no non-finite number, and stops cleanly.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <regex>

#include "../hostile/hostile_bus.h"
#include "raw_client.h"
#include "vloc/frontend_status_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/localization_t.hpp"
#include "vloc/manual_tie_points_t.hpp"
#include "vloc/procman_status_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/stereo_image_t.hpp"
#include "vloc/tie_points_t.hpp"
#include "vloc/traverse_t.hpp"
#include "vloc/uav_state_t.hpp"

namespace vloc {
namespace {

using testing::BinPath;
using testing::Bus;
using testing::HostileMessage;
using testing::RawClient;
using testing::Subprocess;
using testing::TestLcmUrl;

constexpr int kPerChannel = 60;

template <class Msg>
std::vector<uint8_t> Bytes(const Msg& m) {
  std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

pose_t Pose(double x) {
  PoseWithCovariance p;
  p.pose.translation().x() = x;
  p.covariance = Matrix6d::Identity() * 0.01;
  return PoseToMessage(p, "world", "body");
}

image_t Image(int8_t encoding) {
  image_t i{};
  i.frame_id = "navcam_left";
  i.width = i.height = 8;
  i.encoding = encoding;
  i.data.assign(64, 100);
  i.size = 64;
  return i;
}

// One valid message per channel the console watches: {channel, type, bytes}.
std::vector<std::tuple<std::string, std::string, std::vector<uint8_t>>> ConsoleTemplates() {
  traverse_t t{};
  t.num_sites = 2, t.site_ids = {0, 1}, t.poses = {Pose(0), Pose(10)};
  site_pose_t s{};
  s.site_id = 1, s.source = site_pose_t::SOURCE_DEAD_RECKONING, s.pose = Pose(10);
  localization_t l{};
  l.site_id = 1, l.pose = Pose(10), l.relative_pose = Pose(10), l.message = "ok";
  frontend_status_t f{};
  f.current_site_id = 1, f.num_stages = 1, f.stage_names = {"prepare_images"}, f.stage_counts = {1},
  f.stage_seconds = {0.1};
  tie_points_t tp{};
  tp.current_site_id = 1, tp.previous_site_pose.pose = Pose(0), tp.current_site_pose_dr.pose = Pose(10);
  tie_point_t point{};
  point.num_observations = 1;
  point.observations.resize(1);
  tp.num_points = 1, tp.points = {point};
  procman_status_t ps{};
  proc_status_t one{};
  one.name = "x";
  ps.host = "h", ps.num_procs = 1, ps.procs = {one};
  uav_state_t u{};
  u.message = "tracking";
  stereo_image_t st{};
  st.site_id = 1, st.num_pairs = 1, st.left = Image(image_t::ENCODING_GRAY8), st.right = Image(image_t::ENCODING_GRAY8);
  return {{"TRAVERSE", "traverse_t", Bytes(t)},
          {"SITE_POSE_DR", "site_pose_t", Bytes(s)},
          {"SITE_POSE_VISUAL", "localization_t", Bytes(l)},
          {"FRONTEND_STATUS", "frontend_status_t", Bytes(f)},
          {"TIE_POINTS", "tie_points_t", Bytes(tp)},
          {"PROCMAN_STATUS", "procman_status_t", Bytes(ps)},
          {"UAV_STATE", "uav_state_t", Bytes(u)},
          {"UAV_MOSAIC", "image_t", Bytes(Image(image_t::ENCODING_JPEG))},
          {"NAVCAM_STEREO", "stereo_image_t", Bytes(st)}};
}

std::vector<std::vector<uint8_t>> OthersThan(
    const std::string& type, const std::vector<std::tuple<std::string, std::string, std::vector<uint8_t>>>& all) {
  std::vector<std::vector<uint8_t>> out;
  for (const auto& [channel, t, bytes] : all)
    if (t != type) out.push_back(bytes);
  return out;
}

// Reads every message the browser has been sent; false at the first that is not valid JSON.
bool AllJson(RawClient& ws, int* count, std::string* bad) {
  while (auto text = ws.NextText(0.02)) {
    ++*count;
    if (nlohmann::json::parse(*text, nullptr, false).is_discarded()) return (*bad = text->substr(0, 200), false);
  }
  return true;
}

TEST(ConsoleHostile, ConsoleSurvivesEveryWatchedChannelAndSendsOnlyJson) {
  const std::string url = TestLcmUrl(7961);
  Subprocess console(
      {BinPath("vloc_console"), "--config", "config/procs/vloc_console.yaml", "--port", "0", "--lcm-url", url});
  ASSERT_TRUE(console.WaitForOutput(kReadyLine, 10)) << console.output();
  std::smatch m;
  const std::string out = console.output();
  ASSERT_TRUE(std::regex_search(out, m, std::regex("serving http://[^:]+:([0-9]+)/")));
  const int port = std::stoi(m[1]);
  RawClient ws(port);
  ASSERT_TRUE(ws.Upgrade());
  Bus bus(url, "NONE");
  const auto templates = ConsoleTemplates();
  int sent = 0, received = 0;
  std::string bad;
  for (const auto& [channel, type, bytes] : templates) {
    for (const HostileMessage& h :
         testing::MakeHostileMessages(channel, type, bytes, OthersThan(type, templates), kPerChannel)) {
      bus.Send(channel, h.bytes);
      ++sent;
      console.Drain();
      ASSERT_TRUE(AllJson(ws, &received, &bad)) << "after " << h.name << ": not JSON: " << bad;
    }
  }
  bus.Pump(1000);
  ASSERT_TRUE(AllJson(ws, &received, &bad)) << bad;
  EXPECT_FALSE(console.WaitExit(0.1)) << console.output();
  std::cout << sent << " hostile messages, " << received << " JSON messages to the browser\n";
  // Still doing its job: a good traverse reaches the browser, a new browser gets the page.
  traverse_t good{};
  good.utime = 4242, good.num_sites = 1, good.site_ids = {0}, good.poses = {Pose(0)};
  bus.Send("TRAVERSE", Bytes(good));
  EXPECT_TRUE(ws.WaitFor("\"utime\":4242", 5));
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(port, "/")), 200);
  console.Signal(SIGTERM);
  EXPECT_EQ(console.WaitExit(10), 0) << console.output();
}

TEST(ConsoleHostile, FrontendSurvivesHostileManualTiePoints) {
  const std::string url = TestLcmUrl(7962);
  Bus bus(url, "(FRONTEND_STATUS|TIE_POINTS)");
  Subprocess frontend(
      {BinPath("feature_frontend"), "--config", "config/procs/feature_frontend.yaml", "--lcm-url", url});
  bus.Watch(&frontend);
  ASSERT_TRUE(frontend.WaitForOutput(kReadyLine, 20)) << frontend.output();
  manual_tie_points_t t{};
  t.source = "hostile";
  t.previous_site_id = 0, t.current_site_id = 1, t.num_points = 2;
  t.previous_pair = {0, 1}, t.previous_u = {10, 20}, t.previous_v = {30, 40};
  t.current_pair = {0, 1}, t.current_u = {50, 60}, t.current_v = {70, 80};
  const auto templ = Bytes(t);
  std::vector<std::vector<uint8_t>> others;
  for (const auto& [channel, type, bytes] : ConsoleTemplates()) others.push_back(bytes);
  int sent = 0;
  for (const HostileMessage& h :
       testing::MakeHostileMessages("MANUAL_TIE_POINTS", "manual_tie_points_t", templ, others, kPerChannel))
    bus.Send("MANUAL_TIE_POINTS", h.bytes), ++sent;
  bus.Send("MANUAL_TIE_POINTS", templ);
  ASSERT_TRUE(bus.PumpUntilQuiet(1.0, 20));
  EXPECT_FALSE(frontend.WaitExit(0.1)) << frontend.output();
  // No site images are held: every readable set is answered MISSING_INPUT, none published as tie points.
  const auto statuses = testing::DecodeAll<frontend_status_t>(bus.got(), "FRONTEND_STATUS");
  ASSERT_GE(statuses.size(), 1u);
  for (const auto& s : statuses) EXPECT_EQ(int(s.status), int(frontend_status_t::STATUS_MISSING_INPUT)) << s.message;
  EXPECT_EQ(bus.Count("TIE_POINTS"), 0);
  std::string first;
  EXPECT_EQ(bus.NonFinite(&first), 0) << first;
  std::cout << sent << " hostile manual tie messages, " << statuses.size() << " answered MISSING_INPUT\n";
  frontend.Signal(SIGTERM);
  EXPECT_EQ(frontend.WaitExit(20), 0) << frontend.output();
}

}  // namespace
}  // namespace vloc
