// vloc_lcm_tunnel's adapter in-process: two ends, each over its own
// MockTransport bus, joined by their ZeroMQ link over a Unix socket (ipc://,
// in the test's own TMPDIR; no network). What crosses (the channels a side
// sends and the other receives, once, never echoed back), the status each
// end reports, and the loop it refuses: both ends on one bus. Every wait has
// a guard; nothing is timed.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "tunnel_adapter.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/tunnel_status_t.hpp"

namespace vloc {
namespace {

// The Unix socket of a test's link (removed by ~Tunnel).
std::string SocketFile(const std::string& name) {
  return ::testing::TempDir() + "/tunnel_" + std::to_string(getpid()) + "_" + name;
}

tunnel::TunnelOptions End(const std::string& name, const std::string& socket, bool bind) {
  tunnel::TunnelOptions o;
  o.name = name;
  (bind ? o.bind : o.connect) = socket;
  o.status_period_s = 0.05;
  return o;
}

// Both ends started, their links on threads of their own, stopped and
// joined at the end of the test.
struct Tunnel {
  std::vector<std::unique_ptr<TunnelAdapter>> ends;
  std::vector<MockTransport*> buses;
  std::atomic<bool> stop{false};
  std::vector<std::thread> links;
  std::string socket_file;

  explicit Tunnel(const std::string& name) : socket_file(SocketFile(name)) {}
  std::string endpoint() const { return "ipc://" + socket_file; }

  void Add(MockTransport& bus, const tunnel::TunnelOptions& options) {
    ends.push_back(std::make_unique<TunnelAdapter>(bus, options));
    buses.push_back(&bus);
    std::string error;
    ASSERT_TRUE(ends.back()->Start(&error)) << error;
    TunnelAdapter* end = ends.back().get();
    links.emplace_back([this, end] { end->RunLink(stop); });
  }
  // Handles the buses until `done` holds; false after the guard (60 s).
  bool HandleUntil(const std::function<bool()>& done) {
    const auto guard = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!done()) {
      if (std::chrono::steady_clock::now() > guard) return false;
      for (MockTransport* bus : buses) bus->HandleAll();
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return true;
  }
  ~Tunnel() {
    stop = true;
    for (std::thread& t : links) t.join();
    ends.clear();
    std::remove(socket_file.c_str());
  }
};

site_pose_t SitePose(int site) {
  PoseWithCovariance pose;
  pose.pose = MakePose(site, 2, 3, 0, 0, 0.1);
  pose.covariance = Eigen::Matrix<double, 6, 6>::Identity();
  return SitePoseToMessage(site, site_pose_t::SOURCE_DEAD_RECKONING, pose);
}

// The newest status report of end `name` heard on `bus`.
struct StatusOf {
  tunnel_status_t last{};  // zeroed: lcm-gen leaves a default-constructed message's numbers uninitialised
  int reports = 0;
  std::shared_ptr<SubscriptionStats> stats;
  StatusOf(Transport& bus, const std::string& name) {
    stats = Subscribe<tunnel_status_t>(bus, "TUNNEL_STATUS", [this, name](const std::string&, const tunnel_status_t& m) {
      if (m.name != name) return;
      last = m;
      ++reports;
    });
  }
};

TEST(TunnelAdapter, CarriesEachMessageAcrossOnceAndNeverBack) {
  MockTransport vehicle, ground;
  StatusOf ground_status(ground, "ground");
  Tunnel t("carry");
  const std::string socket = t.endpoint();
  t.Add(ground, End("ground", socket, /*bind=*/true));
  t.Add(vehicle, End("vehicle", socket, /*bind=*/false));
  ASSERT_TRUE(Publish(vehicle, "SITE_POSE_DR", SitePose(4)));
  ASSERT_TRUE(t.HandleUntil([&] { return ground.Count("SITE_POSE_DR") == 1; }));
  // The ground end heard its own copy and did not send it back.
  ASSERT_TRUE(t.HandleUntil([&] { return ground_status.last.echoes_skipped >= 1; }));
  // Several more reports each way: long enough for an echo to have come back.
  const int reports = ground_status.reports;
  ASSERT_TRUE(t.HandleUntil([&] { return ground_status.reports >= reports + 5; }));
  EXPECT_EQ(vehicle.Count("SITE_POSE_DR"), 1) << "republished on the bus it came from";
  EXPECT_EQ(ground.Count("SITE_POSE_DR"), 1);
  site_pose_t received;
  ASSERT_TRUE(Decode(ground.Last("SITE_POSE_DR")->data(), ground.Last("SITE_POSE_DR")->size(), &received));
  EXPECT_EQ(received.site_id, 4);
  EXPECT_EQ(received.pose.position[0], 4);
  EXPECT_EQ(ground_status.last.peer_name, "vehicle");
  EXPECT_TRUE(ground_status.last.connected);
  EXPECT_FALSE(t.ends[0]->LoopDetected());
  EXPECT_FALSE(t.ends[1]->LoopDetected());
}

TEST(TunnelAdapter, OnlyTheChannelsOneSideSendsAndTheOtherReceivesCross) {
  MockTransport vehicle, ground;
  StatusOf ground_status(ground, "ground");
  Tunnel t("filter");
  const std::string socket = t.endpoint();
  tunnel::TunnelOptions g = End("ground", socket, true);
  g.receive_channels = {"SITE_POSE_.*", "TUNNEL_STATUS"};
  tunnel::TunnelOptions v = End("vehicle", socket, false);
  v.send_channels = {"SITE_POSE_.*", "IMU", "TUNNEL_STATUS"};
  t.Add(ground, g);
  t.Add(vehicle, v);
  ASSERT_TRUE(Publish(vehicle, "IMU", SitePose(1)));           // sent, refused by the ground
  ASSERT_TRUE(Publish(vehicle, "WHEEL_ODOM", SitePose(2)));    // not sent
  ASSERT_TRUE(Publish(vehicle, "SITE_POSE_DR", SitePose(3)));  // crosses
  ASSERT_TRUE(t.HandleUntil([&] { return ground.Count("SITE_POSE_DR") == 1; }));
  ASSERT_TRUE(t.HandleUntil([&] { return ground_status.last.refused_from_peer >= 1; }));
  EXPECT_EQ(ground_status.last.refused_from_peer, 1) << "the IMU message only";
  EXPECT_EQ(ground.Count("IMU"), 0);
  EXPECT_EQ(ground.Count("WHEEL_ODOM"), 0);
}

TEST(TunnelAdapter, BothEndsOnOneBusIsALoop) {
  MockTransport bus;
  Tunnel t("loop");
  const std::string socket = t.endpoint();
  t.Add(bus, End("ground", socket, true));
  t.Add(bus, End("vehicle", socket, false));
  ASSERT_TRUE(t.HandleUntil([&] { return t.ends[0]->LoopDetected() || t.ends[1]->LoopDetected(); }));
  const int which = t.ends[0]->LoopDetected() ? 0 : 1;
  EXPECT_NE(t.ends[which]->LoopProblem().find("publishes on this tunnel's own bus"), std::string::npos)
      << t.ends[which]->LoopProblem();
}

}  // namespace
}  // namespace vloc
