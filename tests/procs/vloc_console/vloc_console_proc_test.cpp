// vloc_console as a real process on real sockets (LCM ports 7951-7956, HTTP
// on a free port it picks): it serves its own files and nothing else, it
// survives malformed HTTP / WebSocket input, a browser that disconnects and
// a client that does not read, it bridges LCM messages to the browsers, and
// only a client with the token may act (PROCMAN_ORDERS, MANUAL_TIE_POINTS).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <regex>

#include "raw_client.h"
#include "vloc/frontend_status_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/process.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/manual_tie_points_t.hpp"
#include "vloc/procman_order_t.hpp"
#include "vloc/procman_status_t.hpp"
#include "vloc/stereo_image_t.hpp"
#include "vloc/uav_state_t.hpp"
#include "vloc/testing/subprocess.h"
#include "vloc/traverse_t.hpp"
#include "vloc/tunnel_status_t.hpp"

namespace vloc {
namespace {

using nlohmann::json;
using testing::BinPath;
using testing::RawClient;
using testing::Subprocess;
using testing::TestLcmUrl;

// A running console and the HTTP port it chose.
struct Console {
  std::unique_ptr<Subprocess> process;
  int port = -1;
};

Console StartConsole(const std::string& lcm_url, std::vector<std::string> extra = {},
                     const std::string& config = "config/procs/vloc_console.yaml") {
  std::vector<std::string> argv = {BinPath("vloc_console"), "--config", config, "--port", "0", "--lcm-url", lcm_url};
  argv.insert(argv.end(), extra.begin(), extra.end());
  Console c;
  c.process = std::make_unique<Subprocess>(argv);
  if (!c.process->WaitForOutput(kReadyLine, 10)) return c;
  std::smatch m;
  const std::string& out = c.process->output();
  if (std::regex_search(out, m, std::regex("serving http://[^:]+:([0-9]+)/"))) c.port = std::stoi(m[1]);
  return c;
}

std::string Body(const std::string& response) {
  const size_t at = response.find("\r\n\r\n");
  return at == std::string::npos ? "" : response.substr(at + 4);
}

json Status(int port) { return json::parse(Body(RawClient::Get(port, "/api/status")), nullptr, false); }

// A web folder with a file, a subfolder, and links pointing out of it; a
// secret file beside it that must never be served.
std::filesystem::path MakeWebFolder() {
  const auto dir = std::filesystem::temp_directory_path() / "vloc_console_proc_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "web" / "sub");
  std::ofstream(dir / "web" / "index.html") << "<html>console index</html>";
  std::ofstream(dir / "web" / "sub" / "page.html") << "sub page";
  std::ofstream(dir / "web" / ".hidden") << "SECRET-HIDDEN";
  std::ofstream(dir / "secret.txt") << "SECRET-OUTSIDE";
  std::filesystem::create_symlink(dir / "secret.txt", dir / "web" / "link.txt");
  std::filesystem::create_directory_symlink(dir, dir / "web" / "up");
  return dir;
}

TEST(VlocConsole, ServesItsOwnFilesAndNothingElse) {
  const auto dir = MakeWebFolder();
  Console c = StartConsole(TestLcmUrl(7951), {"--web-root", (dir / "web").string()});
  ASSERT_GT(c.port, 0) << c.process->output();
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/")), 200);
  EXPECT_NE(RawClient::Get(c.port, "/").find("console index"), std::string::npos);
  EXPECT_NE(RawClient::Get(c.port, "/sub/page.html").find("sub page"), std::string::npos);
  for (const std::string& target : std::vector<std::string>{
           "/../secret.txt", "/sub/../../secret.txt", "/%2e%2e/secret.txt", "/%2E%2E%2Fsecret.txt",
           "/sub/%2e%2e/%2e%2e/secret.txt", "/..%2fsecret.txt", "/%252e%252e/secret.txt", "//etc/passwd", "/etc/passwd",
           "http://127.0.0.1/../secret.txt", "secret.txt", "/link.txt", "/up/secret.txt", "/.hidden", "/%2ehidden",
           "/index.html%00.png", "/%zz", "/sub\\..\\..\\secret.txt", "/" + std::string(5000, 'a')}) {
    const std::string r = RawClient::Get(c.port, target);
    const int status = RawClient::StatusOf(r);
    EXPECT_TRUE(status == 404 || status == 400) << target << " -> " << r.substr(0, 80);
    EXPECT_EQ(r.find("SECRET"), std::string::npos) << target;
    EXPECT_EQ(r.find("root:"), std::string::npos) << target;
  }
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/api/nothing")), 404);
  RawClient post(c.port);
  post.Send("POST /index.html HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 3\r\nConnection: close\r\n\r\nabc");
  const int post_status = RawClient::StatusOf(post.ReadAll(5));
  EXPECT_TRUE(post_status == 405 || post_status == 400) << post_status;
}

TEST(VlocConsole, SurvivesMalformedRequestsAndDisconnects) {
  Console c = StartConsole(TestLcmUrl(7952));
  ASSERT_GT(c.port, 0) << c.process->output();
  {  // garbage instead of HTTP, a header beyond any limit, a request cut short
    RawClient a(c.port), b(c.port), d(c.port);
    a.Send(std::string("\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03", 11) + std::string(300, '\xff') + "\r\n\r\n");
    b.Send("GET / HTTP/1.1\r\nX-Big: " + std::string(200000, 'x') + "\r\n\r\n");
    d.Send("GET /index.ht");
    a.ReadAll(1);
    b.ReadAll(1);
  }
  {  // a browser that asks for the page and leaves before reading it
    RawClient e(c.port);
    e.Send("GET /console.js HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
  }
  RawClient ws(c.port);
  ASSERT_TRUE(ws.Upgrade());
  ASSERT_TRUE(ws.WaitFor("\"hello\"", 5));
  ws.SendText("this is not json");
  auto reply = ws.WaitFor("\"reply\"", 5);
  ASSERT_TRUE(reply);
  EXPECT_NE(reply->find("not a JSON object"), std::string::npos);
  ws.SendText("[1,2,3]");
  EXPECT_TRUE(ws.WaitFor("not a JSON object", 5));
  ws.SendText(R"({"type":"order","host":"","target":"x","target_kind":"process","action":"explode"})");
  EXPECT_TRUE(ws.WaitFor("action start|stop|restart", 5));
  {  // WebSocket frames that break the protocol: unmasked, bad opcode, a huge declared length
    RawClient w1(c.port), w2(c.port), w3(c.port);
    ASSERT_TRUE(w1.Upgrade() && w2.Upgrade() && w3.Upgrade());
    w1.Send(std::string("\x81\x05hello", 7));
    w2.Send(std::string("\x83\x80\x01\x02\x03\x04", 6));
    w3.Send(std::string("\x81\xff\x7f\xff\xff\xff\xff\xff\xff\xff\x01\x02\x03\x04", 14));
    EXPECT_FALSE(w1.WaitFor("never", 2));
  }
  {  // more idle connections than allowed: a request is refused with 503, not queued without end
    std::vector<std::unique_ptr<RawClient>> crowd;
    for (int i = 0; i < 70; ++i) crowd.push_back(std::make_unique<RawClient>(c.port));
    EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/")), 503);
  }
  // Still serving, still answering.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (RawClient::StatusOf(RawClient::Get(c.port, "/")) != 200 && std::chrono::steady_clock::now() < until) {
  }
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/")), 200);
  ws.SendText(R"({"type":"auth"})");
  EXPECT_TRUE(ws.WaitFor("may_act", 5));
  const json s = Status(c.port);
  ASSERT_TRUE(s.is_object());
  EXPECT_GE(s["messages_bad"].get<int>(), 2);
  c.process->Signal(SIGTERM);
  EXPECT_EQ(c.process->WaitExit(10), 0) << c.process->output();
}

traverse_t Traverse(int num_sites, int64_t utime) {
  traverse_t t{};
  t.utime = utime;
  t.num_sites = num_sites;
  for (int i = 0; i < num_sites; ++i) {
    PoseWithCovariance p;
    p.pose.translation() = Eigen::Vector3d(10.0 * i, 0.1 * i, 0);
    p.covariance = Matrix6d::Identity() * 0.01;
    t.site_ids.push_back(i);
    t.poses.push_back(PoseToMessage(p, "world", "body"));
  }
  t.num_edges = num_sites;
  return t;
}

TEST(VlocConsole, DropsASlowClientAndKeepsServingOthers) {
  const std::string url = TestLcmUrl(7953);
  Console c = StartConsole(url);
  ASSERT_GT(c.port, 0) << c.process->output();
  std::string error;
  auto lcm = MakeLcmTransport(url, &error);
  ASSERT_TRUE(lcm) << error;
  RawClient slow(c.port);
  slow.SetReceiveBuffer(4096);
  ASSERT_TRUE(slow.Upgrade());  // ... and never reads again
  RawClient fast(c.port);
  ASSERT_TRUE(fast.Upgrade());
  const traverse_t big = Traverse(2000, 1);  // about 300 kB of JSON per message
  int64_t dropped = 0;
  for (int i = 0; i < 120 && dropped == 0; ++i) {
    ASSERT_TRUE(Publish(*lcm, "TRAVERSE", big));
    while (fast.NextText(0.05)) {
    }
    if (i % 10 == 9) dropped = Status(c.port).value("dropped_slow", 0);
  }
  EXPECT_GE(dropped, 1) << "a client that never reads must be dropped, not buffered without end";
  ASSERT_TRUE(Publish(*lcm, "TRAVERSE", Traverse(3, 42)));
  EXPECT_TRUE(fast.WaitFor("\"utime\":42", 10)) << "the reading client keeps receiving";
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/")), 200);
}

TEST(VlocConsole, BridgesWhatAnOperatorWatches) {
  const std::string url = TestLcmUrl(7954);
  Console c = StartConsole(url);
  ASSERT_GT(c.port, 0) << c.process->output();
  std::string error;
  auto lcm = MakeLcmTransport(url, &error);
  ASSERT_TRUE(lcm) << error;
  RawClient ws(c.port);
  ASSERT_TRUE(ws.Upgrade());
  ASSERT_TRUE(Publish(*lcm, "TRAVERSE", Traverse(4, 777)));
  auto t = ws.WaitFor("\"traverse\"", 5);
  ASSERT_TRUE(t);
  const json tj = json::parse(*t);
  ASSERT_EQ(tj["sites"].size(), 4u);
  EXPECT_NEAR(tj["sites"][3]["x"].get<double>(), 30.0, 1e-9);
  EXPECT_NEAR(tj["sites"][3]["cxx"].get<double>(), 0.01, 1e-12);
  frontend_status_t f{};
  f.previous_site_id = 2;
  f.current_site_id = 3;
  f.status = frontend_status_t::STATUS_LOW_TEXTURE;
  f.message = "flat sand";
  f.num_stages = 1;
  f.stage_names = {"prepare_images"};
  f.stage_counts = {28};
  f.stage_seconds = {0.5};
  ASSERT_TRUE(Publish(*lcm, "FRONTEND_STATUS", f));
  auto fs = ws.WaitFor("\"frontend_status\"", 5);
  ASSERT_TRUE(fs);
  EXPECT_EQ(json::parse(*fs)["status"], "low texture");
  procman_status_t p{};
  p.host = "rover";
  p.launcher_pid = 99;
  p.num_procs = 1;
  proc_status_t one{};
  one.name = "crosssite_ba";
  one.group = "rover_sim";
  one.state = proc_status_t::STATE_RUNNING;
  one.restarts = 2;
  one.rss_bytes = 1 << 20;
  p.procs = {one};
  ASSERT_TRUE(Publish(*lcm, "PROCMAN_STATUS", p));
  auto ps = ws.WaitFor("\"procman\"", 5);
  ASSERT_TRUE(ps);
  EXPECT_EQ(json::parse(*ps)["procs"][0]["restarts"], 2);
  // A tunnel end's link report (vloc_lcm_tunnel), with its channels; a newly opened page gets it too.
  tunnel_status_t tunnel{};
  tunnel.name = "rover", tunnel.peer_name = "ground", tunnel.endpoint = "tcp://10.0.0.2:7720";
  tunnel.connected = true, tunnel.queued_messages = 3, tunnel.dropped_queue_full = 2, tunnel.latency_samples = 4;
  tunnel.latency_median_ms = 30, tunnel.latency_max_ms = 94;
  tunnel_channel_status_t channel{};
  channel.channel = "NAVCAM_STEREO", channel.priority = tunnel_channel_status_t::PRIORITY_BULK, channel.dropped = 2;
  tunnel.num_channels = 1, tunnel.channels = {channel};
  ASSERT_TRUE(Publish(*lcm, "TUNNEL_STATUS", tunnel));
  auto ts = ws.WaitFor("\"tunnel\"", 5);
  ASSERT_TRUE(ts);
  const json link = json::parse(*ts);
  EXPECT_EQ(link["peer"], "ground");
  EXPECT_EQ(link["dropped"], 2);
  EXPECT_EQ(link["channels"][0]["priority"], "bulk");
  {
    RawClient later(c.port);
    ASSERT_TRUE(later.Upgrade());
    EXPECT_TRUE(later.WaitFor("\"tunnel\"", 5)) << "a page opened later gets the link too";
  }
  // A raw left image is announced and served as PNG; an image not kept is 404.
  stereo_image_t stereo{};
  stereo.site_id = 5;
  stereo.num_pairs = 1;
  for (image_t* image : {&stereo.left, &stereo.right}) {
    image->width = image->height = 16;
    image->encoding = image_t::ENCODING_GRAY8;
    image->data.assign(256, 77);
    image->size = 256;
  }
  ASSERT_TRUE(Publish(*lcm, "NAVCAM_STEREO", stereo));
  ASSERT_TRUE(ws.WaitFor("\"images\"", 5));
  const std::string png = RawClient::Get(c.port, "/api/image?site=5&pair=0");
  EXPECT_EQ(RawClient::StatusOf(png), 200);
  EXPECT_EQ(Body(png).substr(0, 4), "\x89PNG");
  EXPECT_EQ(RawClient::StatusOf(RawClient::Get(c.port, "/api/image?site=4&pair=0")), 404);
  // UAV: each state goes out live, the mosaic preview is served as sent.
  uav_state_t uav{};
  uav.frame_index = 41;
  uav.status = uav_state_t::STATUS_TRACKING;
  uav.height = 52.5;
  uav.latitude = uav.longitude = std::numeric_limits<double>::quiet_NaN();  // not georeferenced: null, not NaN
  ASSERT_TRUE(Publish(*lcm, "UAV_STATE", uav));
  auto us = ws.WaitFor("\"uav_state\"", 5);
  ASSERT_TRUE(us);
  EXPECT_EQ(json::parse(*us)["status"], "tracking");
  EXPECT_DOUBLE_EQ(json::parse(*us)["height"].get<double>(), 52.5);
  image_t mosaic{};
  mosaic.frame_id = "uav_mosaic";
  mosaic.width = mosaic.height = 2;
  mosaic.encoding = image_t::ENCODING_JPEG;
  mosaic.data = {0xff, 0xd8, 0xff, 0xe0, 1, 2, 3};
  mosaic.size = 7;
  ASSERT_TRUE(Publish(*lcm, "UAV_MOSAIC", mosaic));
  ASSERT_TRUE(ws.WaitFor("\"uav_mosaic\"", 5));
  EXPECT_EQ(Body(RawClient::Get(c.port, "/api/uav_mosaic")), std::string("\xff\xd8\xff\xe0\x01\x02\x03", 7));
  // A browser that connects later gets the whole picture first.
  RawClient late(c.port);
  ASSERT_TRUE(late.Upgrade());
  EXPECT_TRUE(late.WaitFor("\"utime\":777", 5));
  RawClient late2(c.port);
  ASSERT_TRUE(late2.Upgrade());
  EXPECT_TRUE(late2.WaitFor("flat sand", 5));
  RawClient late3(c.port);
  ASSERT_TRUE(late3.Upgrade());
  EXPECT_TRUE(late3.WaitFor("\"uav_history\"", 5)) << "the UAV route so far";
  // A corrupt message on a watched channel is skipped; the console goes on.
  const std::string junk(64, '\x7f');
  lcm->Publish("TRAVERSE", junk.data(), junk.size());
  ASSERT_TRUE(Publish(*lcm, "TRAVERSE", Traverse(2, 778)));
  EXPECT_TRUE(ws.WaitFor("\"utime\":778", 5));
}

// Runs `command` over a WebSocket and returns the reply.
json Command(RawClient& ws, json command) {
  static int id = 100;
  command["id"] = ++id;
  ws.SendText(command.dump());
  auto r = ws.WaitFor("\"id\":" + std::to_string(id), 5);
  return r ? json::parse(*r) : json();
}

TEST(VlocConsole, OnlyAClientWithTheTokenActs) {
  const std::string url = TestLcmUrl(7955);
  // Ten wrong tokens below are compared, not locked out (console_hostile_proc_test tests the lockout).
  const auto config = std::filesystem::temp_directory_path() / ("vloc_console_tokens_" + std::to_string(getpid()) + ".yaml");
  std::ifstream in("config/procs/vloc_console.yaml");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  text.replace(text.find("auth_free_failures: 3"), 21, "auth_free_failures: 20");
  std::ofstream(config) << text;
  Console c = StartConsole(url, {"--token", "s3cret"}, config.string());
  std::filesystem::remove(config);
  ASSERT_GT(c.port, 0) << c.process->output();
  std::string error;
  auto lcm = MakeLcmTransport(url, &error);
  ASSERT_TRUE(lcm) << error;
  std::vector<procman_order_t> orders;
  std::vector<manual_tie_points_t> ties;
  Subscribe<procman_order_t>(*lcm, "PROCMAN_ORDERS",
                             [&](const std::string&, const procman_order_t& m) { orders.push_back(m); });
  Subscribe<manual_tie_points_t>(*lcm, "MANUAL_TIE_POINTS",
                                 [&](const std::string&, const manual_tie_points_t& m) { ties.push_back(m); });
  RawClient ws(c.port);
  ASSERT_TRUE(ws.Upgrade());
  const json order = {{"type", "order"},
                      {"host", "rover"},
                      {"target", "crosssite_ba"},
                      {"target_kind", "process"},
                      {"action", "restart"}};
  const json tie = {{"type", "manual_tie"},
                    {"previous_site", 4},
                    {"current_site", 5},
                    {"points",
                     {{{"previous_pair", 1},
                       {"previous_u", 100.5},
                       {"previous_v", 200.25},
                       {"current_pair", 2},
                       {"current_u", 300},
                       {"current_v", 400}}}}};
  EXPECT_FALSE(Command(ws, {{"type", "auth"}})["may_act"].get<bool>());
  for (const json& bad_token : {json(nullptr), json("wrong"), json("s3cre"), json("s3cret!"), json(12)}) {
    json o = order, t = tie;
    if (!bad_token.is_null()) o["token"] = t["token"] = bad_token;
    EXPECT_FALSE(Command(ws, o)["ok"].get<bool>()) << bad_token;
    EXPECT_FALSE(Command(ws, t)["ok"].get<bool>()) << bad_token;
  }
  json o = order, t = tie;
  o["token"] = t["token"] = "s3cret";
  EXPECT_TRUE(Command(ws, o)["ok"].get<bool>());
  EXPECT_TRUE(Command(ws, t)["ok"].get<bool>());
  json nan_tie = t;
  nan_tie["points"][0]["current_u"] = -5;
  const json refused = Command(ws, nan_tie);
  EXPECT_FALSE(refused["ok"].get<bool>());
  EXPECT_NE(refused["error"].get<std::string>().find("current_u"), std::string::npos) << refused;
  json backwards = t;
  backwards["current_site"] = 3;
  EXPECT_FALSE(Command(ws, backwards)["ok"].get<bool>());
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while ((orders.empty() || ties.empty()) && std::chrono::steady_clock::now() < deadline) lcm->Handle(100);
  lcm->Handle(300);
  c.process->Drain();
  EXPECT_EQ(c.process->output().find("s3cret"), std::string::npos) << "the token never reaches the log";
  ASSERT_EQ(orders.size(), 1u) << "only the order with the token is sent";
  EXPECT_EQ(orders[0].target, "crosssite_ba");
  EXPECT_EQ(orders[0].host, "rover");
  EXPECT_EQ(int(orders[0].action), int(procman_order_t::ACTION_RESTART));
  ASSERT_EQ(ties.size(), 1u);
  EXPECT_EQ(ties[0].previous_site_id, 4);
  EXPECT_EQ(ties[0].current_site_id, 5);
  ASSERT_EQ(ties[0].num_points, 1);
  EXPECT_DOUBLE_EQ(ties[0].previous_v[0], 200.25);
  EXPECT_EQ(ties[0].current_pair[0], 2);
}

TEST(VlocConsole, WatchesOnlyWhenOpenToOtherMachinesWithoutAToken) {
  Console c = StartConsole(TestLcmUrl(7956), {"--bind", "0.0.0.0"});
  ASSERT_GT(c.port, 0) << c.process->output();
  RawClient ws(c.port);
  ASSERT_TRUE(ws.Upgrade());
  EXPECT_FALSE(Command(ws, {{"type", "auth"}})["may_act"].get<bool>());
  const json r =
      Command(ws, {{"type", "order"}, {"host", ""}, {"target", "x"}, {"target_kind", "process"}, {"action", "stop"}});
  EXPECT_FALSE(r["ok"].get<bool>());
  EXPECT_NE(r["error"].get<std::string>().find("only watches"), std::string::npos);
}

TEST(VlocConsole, BadSettingsGiveOneErrorLine) {
  const auto bad_ortho = std::filesystem::temp_directory_path() / "vloc_console_bad_ortho.yaml";
  std::ofstream(bad_ortho) << "orthoimage: {path: /nonexistent/ortho.png, m_per_px: 0.04}\n";
  for (const std::vector<std::string>& extra : {std::vector<std::string>{"--bind", "not-an-address"},
                                                {"--web-root", "/nonexistent/folder"},
                                                {"--port", "70000"},
                                                {"--config", bad_ortho.string()}}) {
    Subprocess p({BinPath("vloc_console"), "--config", "config/procs/vloc_console.yaml", "--lcm-url", TestLcmUrl(7956),
                  extra[0], extra[1]});
    EXPECT_EQ(p.WaitExit(10), 1) << extra[0];
    // One line naming the problem (the options echo above it is glog's INFO).
    const std::regex error_line("(^|\n)vloc_console: [^\n]*");
    const auto n =
        std::distance(std::sregex_iterator(p.output().begin(), p.output().end(), error_line), std::sregex_iterator());
    EXPECT_EQ(n, 1) << p.output();
  }
}

}  // namespace
}  // namespace vloc
