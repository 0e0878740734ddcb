// vloc_lcm_tunnel as processes on one host: two LCM buses (loopback
// multicast on two ports, ttl=0) joined by two tunnels over TCP on
// 127.0.0.1 ("ground" binds, "vehicle" connects).
//   - channels both ways: every message arrives once, in order per channel,
//     intact; a message a tunnel republished is not sent back (no loops);
//     both tunnels report connected on TUNNEL_STATUS.
//   - either end SIGKILLed and restarted: what was published meanwhile on
//     the surviving end's bus arrives, complete and in order.
//   - a bad command line and garbage on the TCP port: one line, exit 1 /
//     the tunnel keeps working.
//   - both ends on one bus (a split group run whole on one machine): each
//     hears the other's reports directly and stops with one line, exit 1,
//     instead of forwarding every message round and round.
// Counts and order are asserted, never timings.

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <random>

#include "tunnel_bus.h"
#include "vloc/lcm_io/process.h"
#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

using testing::BinPath;
using testing::InOrder;
using testing::Subprocess;
using testing::TunnelBus;
using testing::WaitOn;

const std::string kUrlVehicle = testing::TestLcmUrl(8211);
const std::string kUrlGround = testing::TestLcmUrl(8212);
constexpr int kTcpPort = 18211;
constexpr double kDeadline = 90;  // s, generous: ctest -j2 on 2 loaded cores

std::unique_ptr<Subprocess> StartTunnel(const std::string& name) {
  std::vector<std::string> argv = {BinPath("vloc_lcm_tunnel"), "--config", "config/procs/vloc_lcm_tunnel.yaml",
                                   "--name", name};
  if (name == "ground") {
    argv.insert(argv.end(), {"--bind", "tcp://127.0.0.1:" + std::to_string(kTcpPort), "--lcm-url", kUrlGround});
  } else {
    argv.insert(argv.end(), {"--connect", "tcp://127.0.0.1:" + std::to_string(kTcpPort), "--lcm-url", kUrlVehicle});
  }
  auto p = std::make_unique<Subprocess>(argv);
  EXPECT_TRUE(p->WaitForOutput(kReadyLine, kDeadline)) << p->output();
  return p;
}

bool Connected(const TunnelBus& bus, const std::string& name) {
  const tunnel_status_t* s = bus.Status(name);
  return s && s->connected;
}

int64_t ReceivedBesidesStatus(const tunnel_status_t& s) {
  int64_t n = 0;
  for (const auto& c : s.channels)
    if (c.channel != "TUNNEL_STATUS") n += c.received;
  return n;
}

class TunnelProc : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(vehicle_bus.ok() && ground_bus.ok()); }
  bool Wait(const std::function<bool()>& done, const std::vector<Subprocess*>& procs) {
    return WaitOn({&vehicle_bus, &ground_bus}, procs, done, kDeadline);
  }
  // Both tunnels connected, each seen on its own bus.
  bool BothUp(Subprocess* v, Subprocess* g) {
    vehicle_bus.status.clear();
    ground_bus.status.clear();
    return Wait([&] { return Connected(vehicle_bus, "vehicle") && Connected(ground_bus, "ground"); }, {v, g});
  }
  // Publishes with a short handling pause, as a sensor would (LCM's own
  // receive buffers are not what is under test).
  void Send(TunnelBus& bus, const std::string& channel, int64_t first, int64_t count, size_t size) {
    for (int64_t i = first; i < first + count; ++i) {
      bus.Publish(channel, i, size);
      vehicle_bus.Handle(size > 100000 ? 10 : 1);
      ground_bus.Handle(0);
    }
  }
  TunnelBus vehicle_bus{kUrlVehicle};
  TunnelBus ground_bus{kUrlGround};
};

TEST_F(TunnelProc, CarriesChannelsBothWaysInOrderWithoutLoops) {
  auto ground = StartTunnel("ground");
  auto vehicle = StartTunnel("vehicle");
  ASSERT_TRUE(BothUp(vehicle.get(), ground.get())) << vehicle->output() << ground->output();

  // vehicle -> ground: IMU-like (normal), images (bulk, 1 MB), poses (urgent);
  // ground -> vehicle: orders; both ways: PROCMAN_STATUS.
  for (int i = 0; i < 20; ++i) {
    Send(vehicle_bus, "T_IMU", i * 10, 10, 200);
    Send(vehicle_bus, "NAVCAM_STEREO", i, 1, 1 << 20);
    Send(vehicle_bus, "DR_POSE", i, 1, 500);
    Send(vehicle_bus, "PROCMAN_STATUS", i, 1, 300);
    Send(ground_bus, "PROCMAN_ORDERS", i, 1, 100);
    Send(ground_bus, "PROCMAN_STATUS", 1000 + i, 1, 300);
  }
  ASSERT_TRUE(Wait(
      [&] {
        return ground_bus.Count("T_IMU") >= 200 && ground_bus.Count("NAVCAM_STEREO") >= 20 &&
               ground_bus.Count("DR_POSE") >= 20 && vehicle_bus.Count("PROCMAN_ORDERS") >= 20 &&
               ground_bus.Count("PROCMAN_STATUS") >= 40 && vehicle_bus.Count("PROCMAN_STATUS") >= 40;
      },
      {vehicle.get(), ground.get()}))
      << vehicle->output() << ground->output();
  // Each tunnel has heard (and skipped) the echo of all it republished, and
  // reported it: only then can a loop be ruled out by counting.
  const size_t from_vehicle = 200 + 20 + 20 + 20, from_ground = 20 + 20;
  ASSERT_TRUE(Wait(
      [&] {
        const tunnel_status_t* g = ground_bus.Status("ground");
        const tunnel_status_t* v = vehicle_bus.Status("vehicle");
        return g && v && g->echoes_skipped >= static_cast<int64_t>(from_vehicle) &&
               v->echoes_skipped >= static_cast<int64_t>(from_ground) && g->queued_messages == 0 &&
               v->queued_messages == 0 && g->in_flight_bytes == 0 && v->in_flight_bytes == 0;
      },
      {vehicle.get(), ground.get()}))
      << vehicle->output() << ground->output();
  EXPECT_TRUE(InOrder(ground_bus.received["T_IMU"], 200));
  EXPECT_TRUE(InOrder(ground_bus.received["NAVCAM_STEREO"], 20));
  EXPECT_TRUE(InOrder(ground_bus.received["DR_POSE"], 20));
  EXPECT_TRUE(InOrder(vehicle_bus.received["PROCMAN_ORDERS"], 20));
  EXPECT_EQ(ground_bus.corrupt + vehicle_bus.corrupt, 0);
  // No loops: each bus holds its own 20 PROCMAN_STATUS and the other's 20, once each.
  EXPECT_EQ(ground_bus.Count("PROCMAN_STATUS"), 40u);
  EXPECT_EQ(vehicle_bus.Count("PROCMAN_STATUS"), 40u);
  EXPECT_EQ(vehicle_bus.Count("T_IMU"), 200u);
  EXPECT_EQ(vehicle_bus.Count("NAVCAM_STEREO"), 20u);
  EXPECT_EQ(ground_bus.Count("PROCMAN_ORDERS"), 20u);
  const tunnel_status_t& g = *ground_bus.Status("ground");
  const tunnel_status_t& v = *vehicle_bus.Status("vehicle");
  // Republished per channel (the other tunnel's TUNNEL_STATUS crosses too, and is not counted here).
  EXPECT_EQ(ReceivedBesidesStatus(v), static_cast<int64_t>(from_ground));
  EXPECT_EQ(ReceivedBesidesStatus(g), static_cast<int64_t>(from_vehicle));
  EXPECT_EQ(v.dropped_queue_full + g.dropped_queue_full + v.rejected_frames + g.rejected_frames, 0);
  EXPECT_EQ(g.peer_name, "vehicle");
  EXPECT_EQ(v.peer_name, "ground");
  std::cout << "tunnel status (ground): received " << g.received_messages << ", echoes skipped " << g.echoes_skipped
            << ", latency median " << g.latency_median_ms << " ms, channels " << g.num_channels << "\n";
  ground->Signal(SIGTERM);
  vehicle->Signal(SIGTERM);
  EXPECT_EQ(ground->WaitExit(30), 0);
  EXPECT_EQ(vehicle->WaitExit(30), 0);
  EXPECT_NE(vehicle->output().find("vehicle: sent "), std::string::npos) << vehicle->output();
}

TEST_F(TunnelProc, EitherEndRestartsAndNothingQueuedIsLost) {
  auto ground = StartTunnel("ground");
  auto vehicle = StartTunnel("vehicle");
  ASSERT_TRUE(BothUp(vehicle.get(), ground.get())) << vehicle->output() << ground->output();
  Send(vehicle_bus, "T_IMU", 0, 10, 200);
  ASSERT_TRUE(Wait(
      [&] {
        const tunnel_status_t* v = vehicle_bus.Status("vehicle");
        return ground_bus.Count("T_IMU") >= 10 && v && v->sent_messages >= 10 && v->in_flight_bytes == 0;
      },
      {vehicle.get(), ground.get()}));

  // The ground end dies; the vehicle queues what its bus carries meanwhile.
  ground.reset();  // SIGKILL
  Send(vehicle_bus, "T_IMU", 10, 30, 200);
  Send(vehicle_bus, "NAVCAM_STEREO", 0, 5, 1 << 20);
  ground = StartTunnel("ground");
  ASSERT_TRUE(Wait([&] { return ground_bus.Count("T_IMU") >= 40 && ground_bus.Count("NAVCAM_STEREO") >= 5; },
                   {vehicle.get(), ground.get()}))
      << vehicle->output() << ground->output();
  EXPECT_TRUE(InOrder(ground_bus.received["T_IMU"], 40));
  EXPECT_TRUE(InOrder(ground_bus.received["NAVCAM_STEREO"], 5));

  // The vehicle end dies; the ground queues the orders meanwhile.
  vehicle.reset();
  Send(ground_bus, "PROCMAN_ORDERS", 0, 10, 100);
  vehicle = StartTunnel("vehicle");
  ASSERT_TRUE(Wait([&] { return vehicle_bus.Count("PROCMAN_ORDERS") >= 10; }, {vehicle.get(), ground.get()}))
      << vehicle->output() << ground->output();
  EXPECT_TRUE(InOrder(vehicle_bus.received["PROCMAN_ORDERS"], 10));
  EXPECT_EQ(ground_bus.corrupt + vehicle_bus.corrupt, 0) << ::testing::PrintToString(ground_bus.corrupt_channels)
                                                        << ::testing::PrintToString(vehicle_bus.corrupt_channels);
}

TEST_F(TunnelProc, BadCommandLineOneLineAndGarbageOnTheLinkSurvived) {
  Subprocess bad({BinPath("vloc_lcm_tunnel"), "--lcm-url", kUrlGround});
  EXPECT_EQ(bad.WaitExit(30), 1);
  EXPECT_NE(bad.output().find("no endpoint"), std::string::npos) << bad.output();

  auto ground = StartTunnel("ground");
  // Random bytes, a ZMTP greeting cut short and a huge frame header on raw TCP connections.
  std::mt19937 rng(11);
  for (int c = 0; c < 20; ++c) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(kTcpPort);
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0) {
      std::vector<uint8_t> junk(1 + rng() % 4000);
      for (auto& b : junk) b = static_cast<uint8_t>(rng());
      if (c % 3 == 1) junk = {0xff, 0, 0, 0, 0, 0, 0, 0, 1, 0x7f, 3, 0};  // ZMTP signature, cut
      if (c % 3 == 2) junk = {0xff, 0, 0, 0, 0, 0, 0, 0, 1, 0x7f, 3, 0, 'N', 'U', 'L', 'L', 0, 0, 0, 0, 0, 0, 0, 0,
                              0,    0, 0, 0, 0, 0, 0, 0, 0, 0,    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
                              0,    0, 0, 0, 0, 0, 0, 0, 0, 0,    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 0xff, 0xff,
                              0xff, 0xff, 0xff, 0xff, 0xff, 0xff};
      [[maybe_unused]] ssize_t n = write(fd, junk.data(), junk.size());
    }
    close(fd);
  }
  auto vehicle = StartTunnel("vehicle");
  ASSERT_TRUE(BothUp(vehicle.get(), ground.get())) << vehicle->output() << ground->output();
  Send(vehicle_bus, "T_IMU", 0, 20, 200);
  ASSERT_TRUE(Wait([&] { return ground_bus.Count("T_IMU") >= 20; }, {vehicle.get(), ground.get()}))
      << ground->output();
  EXPECT_TRUE(InOrder(ground_bus.received["T_IMU"], 20));
}

TEST(TunnelLoop, BothEndsOnOneBusStopWithOneLine) {
  const std::string url = testing::TestLcmUrl(8213);
  const std::string port = std::to_string(kTcpPort + 2);
  Subprocess ground({BinPath("vloc_lcm_tunnel"), "--config", "config/procs/vloc_lcm_tunnel.yaml", "--name", "ground",
                     "--bind", "tcp://127.0.0.1:" + port, "--lcm-url", url});
  Subprocess vehicle({BinPath("vloc_lcm_tunnel"), "--config", "config/procs/vloc_lcm_tunnel.yaml", "--name", "vehicle",
                      "--connect", "tcp://127.0.0.1:" + port, "--lcm-url", url});
  const std::string line = "publishes on this tunnel's own bus";
  // Either end may notice first; the other then loses its peer and keeps waiting for it.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(kDeadline);
  int noticed = 0;
  while (noticed == 0 && std::chrono::steady_clock::now() < deadline) {
    ground.Drain();
    vehicle.Drain();
    for (Subprocess* p : {&ground, &vehicle})
      if (p->WaitExit(0.1).has_value() && p->output().find(line) != std::string::npos) ++noticed;
  }
  ASSERT_GE(noticed, 1) << ground.output() << "\n----\n" << vehicle.output();
  for (Subprocess* p : {&ground, &vehicle}) {
    if (p->output().find(line) == std::string::npos) continue;
    EXPECT_EQ(p->WaitExit(1).value_or(-1), 1) << p->output();
    const std::string& out = p->output();
    EXPECT_EQ(out.find(line), out.rfind(line)) << "one line, not one per report: " << out;
  }
}

}  // namespace
}  // namespace vloc
