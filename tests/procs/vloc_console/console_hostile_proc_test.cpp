// Hostile input over real LCM (ports 7961-7962) for what issue 19 added:
// vloc_console on every channel it watches, and feature_frontend on
// MANUAL_TIE_POINTS (random bytes, truncations, wrong types, extreme
// numbers, absurd lengths; vloc/testing/hostile.h). Afterwards each process
// is alive, still does its job, sent the browsers only valid JSON (no NaN)
// and the bus no non-finite number, and stops cleanly.
// Then the console as a network server (ports 7971-7974, issue 30): deep
// JSON, foreign Host and Origin, a welcome that must stay openable after a
// long run, pair indices beyond num_pairs, token guessing, launchers
// without end.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <thread>

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

// A console with the default config on its own LCM port, and its HTTP port.
struct ConsoleUnderTest {
  std::unique_ptr<Subprocess> process;
  int port = -1;
};

ConsoleUnderTest StartConsole(const std::string& url, const std::vector<std::string>& extra = {}) {
  std::vector<std::string> argv = {BinPath("vloc_console"), "--config", "config/procs/vloc_console.yaml",
                                   "--port", "0", "--lcm-url", url};
  argv.insert(argv.end(), extra.begin(), extra.end());
  ConsoleUnderTest c;
  c.process = std::make_unique<Subprocess>(argv);
  if (!c.process->WaitForOutput(kReadyLine, 10)) return c;
  std::smatch m;
  const std::string out = c.process->output();
  if (std::regex_search(out, m, std::regex("serving http://[^:]+:([0-9]+)/"))) c.port = std::stoi(m[1]);
  return c;
}

nlohmann::json ConsoleStatus(int port) {
  const std::string r = RawClient::Get(port, "/api/status");
  const size_t at = r.find("\r\n\r\n");
  return nlohmann::json::parse(at == std::string::npos ? "" : r.substr(at + 4), nullptr, false);
}

// Resident memory of a process, kB (VmRSS in /proc).
int64_t RssKb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stoll(line.substr(6));
  return -1;
}

// Every text message until `needle` arrives (inclusive), or all within the timeout.
std::vector<std::string> TextsUntil(RawClient& ws, const std::string& needle, double timeout_s) {
  std::vector<std::string> out;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < deadline) {
    auto m = ws.NextText(0.5);
    if (!m) continue;
    out.push_back(*m);
    if (m->find(needle) != std::string::npos) break;
  }
  return out;
}

int CountType(const std::vector<std::string>& texts, const std::string& type) {
  int n = 0;
  for (const std::string& t : texts) n += t.find("\"type\":\"" + type + "\"") != std::string::npos;
  return n;
}

TEST(ConsoleServerHostile, DeeplyNestedJsonIsRefusedNotParsed) {
  for (const bool with_token : {false, true}) {
    ConsoleUnderTest c = StartConsole(TestLcmUrl(7971), with_token ? std::vector<std::string>{"--token", "secret"}
                                                                   : std::vector<std::string>{});
    ASSERT_GT(c.port, 0) << c.process->output();
    RawClient ws(c.port);
    ASSERT_TRUE(ws.Upgrade());
    // 70,000 arrays deep (140 kB), then a 1 MB token nested the same way (the probe's SIGSEGVs).
    ws.SendText(std::string(70000, '[') + std::string(70000, ']'));
    auto reply = ws.WaitFor("\"reply\"", 10);
    ASSERT_TRUE(reply) << c.process->output();
    EXPECT_NE(reply->find("nested deeper than"), std::string::npos) << *reply;
    const int depth = 500000;
    ws.SendText("{\"type\":\"auth\",\"token\":" + std::string(depth, '[') + std::string(depth, ']') + "}");
    reply = ws.WaitFor("\"reply\"", 10);
    ASSERT_TRUE(reply) << c.process->output();
    EXPECT_NE(reply->find("nested deeper than"), std::string::npos) << *reply;
    // A string full of brackets is not nesting: answered as usual.
    ws.SendText("{\"type\":\"auth\",\"note\":\"" + std::string(1000, '[') + "\"}");
    EXPECT_TRUE(ws.WaitFor("may_act", 5));
    EXPECT_FALSE(c.process->WaitExit(0.1)) << c.process->output();
    c.process->Signal(SIGTERM);
    EXPECT_EQ(c.process->WaitExit(10), 0) << c.process->output();
  }
}

TEST(ConsoleServerHostile, OnlyItsOwnHostAndOriginAreServed) {
  ConsoleUnderTest c = StartConsole(TestLcmUrl(7972));
  ASSERT_GT(c.port, 0) << c.process->output();
  const std::string self = "127.0.0.1:" + std::to_string(c.port);
  // DNS rebinding: a name that is not ours is refused, addresses and localhost are served.
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/", 5, "attacker.example")), 403);
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/api/status", 5, "attacker.example:8765")), 403);
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/", 5, self)), 200);
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/", 5, "localhost:" + std::to_string(c.port))), 200);
  {
    RawClient ws(c.port);
    EXPECT_FALSE(ws.Upgrade("/ws", "attacker.example"));
    EXPECT_NE(ws.handshake().find(" 403"), std::string::npos) << ws.handshake();
  }
  for (const std::string& origin : std::vector<std::string>{"http://attacker.example", "http://127.0.0.1:1", "null",
                                   "https://127.0.0.1:" + std::to_string(c.port) + ".attacker.example"}) {
    RawClient ws(c.port);
    EXPECT_FALSE(ws.Upgrade("/ws", self, "Origin: " + origin + "\r\n")) << origin;
    EXPECT_NE(ws.handshake().find(" 403"), std::string::npos) << origin << ": " << ws.handshake();
  }
  // The console's own page, and a client that is no browser, open it and may act on loopback.
  RawClient own(c.port), tool(c.port);
  ASSERT_TRUE(own.Upgrade("/ws", self, "Origin: http://" + self + "\r\n")) << own.handshake();
  ASSERT_TRUE(tool.Upgrade());
  own.SendText(R"({"type":"auth"})");
  EXPECT_TRUE(own.WaitFor("\"may_act\":true", 5));
  const nlohmann::json status = ConsoleStatus(c.port);
  ASSERT_TRUE(status.is_object());
  EXPECT_GE(status.value("hosts_refused", 0), 3);
  EXPECT_GE(status.value("origins_refused", 0), 4);
  c.process->Signal(SIGTERM);
  EXPECT_EQ(c.process->WaitExit(10), 0) << c.process->output();
}

TEST(ConsoleServerHostile, StateStaysBoundedAndANewPageCanAlwaysOpen) {
  const std::string url = TestLcmUrl(7973);
  ConsoleUnderTest c = StartConsole(url);
  ASSERT_GT(c.port, 0) << c.process->output();
  Bus bus(url, "NONE");
  // 100 TIE_POINTS of 1,000 points (the probe: the next page was dropped at connect, 8.3 MB unsent).
  for (int site = 1; site <= 100; ++site) {
    tie_points_t tp{};
    tp.previous_site_id = site - 1, tp.current_site_id = site;
    tp.previous_site_pose.pose = Pose(0), tp.current_site_pose_dr.pose = Pose(10);
    tie_point_t point{};
    point.num_observations = 4;
    point.observations.resize(4);
    for (int i = 0; i < 4; ++i) {
      tie_observation_t& o = point.observations[i];
      o.site_role = static_cast<int8_t>(i / 2), o.camera = static_cast<int8_t>(i % 2);
      o.u = 100 + i, o.v = 200 + i, o.sigma = 0.3;
    }
    tp.num_previous_pairs = tp.num_current_pairs = 1;
    tp.previous_mast_pan = tp.previous_mast_tilt = tp.current_mast_pan = tp.current_mast_tilt = {0.0};
    tp.num_points = 1000;
    tp.points.assign(1000, point);
    for (int i = 0; i < 1000; ++i) tp.points[i].id = i;
    bus.Send("TIE_POINTS", Bytes(tp));
    bus.Pump(5);
  }
  // One site's pair indices 0..999 with num_pairs 7 (the probe: 49 MB -> 1,056 MB).
  stereo_image_t st{};
  st.site_id = 1, st.num_pairs = 7;
  st.left = Image(image_t::ENCODING_GRAY8), st.right = st.left;
  st.left.width = st.left.height = 256, st.left.data.assign(256 * 256, 7), st.left.size = 256 * 256;
  for (int pair = 0; pair < 1000; ++pair) {
    st.pair_index = pair;
    bus.Send("NAVCAM_STEREO", Bytes(st));
    if (pair % 20 == 0) bus.Pump(5);
  }
  // 20,000 status messages from as many launchers (the probe: 5,064 kept).
  procman_status_t ps{};
  ps.num_procs = 0;
  for (int i = 0; i < 2000; ++i) {
    ps.host = "host" + std::to_string(i), ps.launcher_pid = i;
    bus.Send("PROCMAN_STATUS", Bytes(ps));
    if (i % 50 == 0) bus.Pump(5);
  }
  traverse_t done{};
  done.utime = 777, done.num_sites = 1, done.site_ids = {0}, done.poses = {Pose(0)};
  bus.Send("TRAVERSE", Bytes(done));
  RawClient watcher(c.port);
  ASSERT_TRUE(watcher.Upgrade());
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  bool traverse_seen = false;
  while (!traverse_seen && std::chrono::steady_clock::now() < deadline) {
    bus.Pump(20);
    bus.Send("TRAVERSE", Bytes(done));
    traverse_seen = watcher.WaitFor("\"utime\":777", 1).has_value();
  }
  ASSERT_TRUE(traverse_seen) << "the console did not take everything in";
  RawClient page(c.port);
  ASSERT_TRUE(page.Upgrade());
  const auto welcome = TextsUntil(page, "\"type\":\"traverse\"", 20);
  ASSERT_FALSE(welcome.empty());
  EXPECT_NE(welcome.front().find("\"hello\""), std::string::npos) << welcome.front().substr(0, 200);
  EXPECT_EQ(CountType(welcome, "traverse"), 1) << "the page was dropped before its picture arrived";
  EXPECT_LE(CountType(welcome, "tie_points"), 10);
  EXPECT_GE(CountType(welcome, "tie_points"), 1);
  EXPECT_LE(CountType(welcome, "procman"), 32);
  size_t bytes = 0;
  for (const std::string& t : welcome) bytes += t.size();
  EXPECT_LE(bytes, size_t(4) << 20);
  const nlohmann::json status = ConsoleStatus(c.port);
  ASSERT_TRUE(status.is_object());
  EXPECT_EQ(status.value("dropped_slow", -1), 0);
  // The pairs beyond num_pairs were refused, those below kept.
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/api/image?site=1&pair=6")), 200);
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/api/image?site=1&pair=7")), 404);
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/api/image?site=1&pair=999")), 404);
  std::cout << "welcome " << welcome.size() << " messages, " << bytes << " bytes; console RSS "
            << RssKb(c.process->pid()) << " kB\n";
  c.process->Signal(SIGTERM);
  EXPECT_EQ(c.process->WaitExit(10), 0) << c.process->output();
}

TEST(ConsoleServerHostile, TokenGuessesAreLockedOut) {
  ConsoleUnderTest c = StartConsole(TestLcmUrl(7974), {"--token", "abc"});
  ASSERT_GT(c.port, 0) << c.process->output();
  RawClient ws(c.port);
  ASSERT_TRUE(ws.Upgrade());
  int wrong = 0, locked = 0;
  for (int i = 0; i < 200; ++i) {
    ws.SendText("{\"type\":\"auth\",\"token\":\"g" + std::to_string(i) + "\"}");
    auto reply = ws.WaitFor("\"reply\"", 5);
    ASSERT_TRUE(reply) << c.process->output();
    if (reply->find("too many wrong tokens") != std::string::npos)
      ++locked;
    else if (reply->find("\"may_act\":false") != std::string::npos)
      ++wrong;
  }
  // Three free guesses, a fourth that starts the lockout, then none compared for at least 1 s.
  EXPECT_EQ(wrong + locked, 200);
  EXPECT_LE(wrong, 10) << "guesses were compared at full speed";
  // Guess on until the sixth compared guess (a 4 s lockout), then the right token: not even compared.
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (wrong < 6 && std::chrono::steady_clock::now() < give_up) {
    ws.SendText(R"({"type":"auth","token":"guess"})");
    auto reply = ws.WaitFor("\"reply\"", 5);
    ASSERT_TRUE(reply);
    if (reply->find("too many wrong tokens") == std::string::npos) ++wrong;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_EQ(wrong, 6);
  ws.SendText(R"({"type":"auth","token":"abc"})");
  auto reply = ws.WaitFor("\"reply\"", 5);
  ASSERT_TRUE(reply);
  EXPECT_NE(reply->find("too many wrong tokens"), std::string::npos) << "the right token during a lockout: " << *reply;
  const nlohmann::json status = ConsoleStatus(c.port);
  ASSERT_TRUE(status.is_object());
  EXPECT_EQ(status.value("auth_failures", -1), wrong);
  EXPECT_GE(status.value("auth_locked_out", -1), locked + 1);
  // After the lockout the right token is taken again.
  bool accepted = false;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!accepted && std::chrono::steady_clock::now() < deadline) {
    ws.SendText(R"({"type":"auth","token":"abc"})");
    reply = ws.WaitFor("\"reply\"", 5);
    accepted = reply && reply->find("\"may_act\":true") != std::string::npos;
    if (!accepted) std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  EXPECT_TRUE(accepted) << "the right token after the lockout";
  std::cout << wrong << " wrong tokens compared, " << locked << " refused unread\n";
  c.process->Signal(SIGTERM);
  EXPECT_EQ(c.process->WaitExit(10), 0) << c.process->output();
}

}  // namespace
}  // namespace vloc
