// config/groups/rover_split_tunnel.yaml run as written: the rover group
// split across two network namespaces ("vehicle", "ground") joined by a veth
// pair that loses 5 % of its packets, each on its own ttl=0 LCM bus (nothing
// crosses by multicast), one vloc_launch per namespace, the two buses joined
// by the file's vloc_lcm_tunnel pair (ground binds, vehicle connects).
//
//   1. one host: config/groups/rover_split.yaml whole in the ground
//      namespace -> the reference traverse;
//   2. split over the lossy link, the vehicle started first: its simulator
//      waits for the ground's front end, BA and graph (depends_on across
//      hosts, through PROCMAN_STATUS carried by the tunnels) and starts once
//      the ground runs them; the traverse completes on the ground and equals
//      the reference; each launcher sees the other; an order sent on the
//      ground's bus (PROCMAN_ORDERS) restarts a vehicle process; every
//      message the vehicle recorded on the channels it publishes is in the
//      ground's log too (every stereo pair), and no tunnel dropped anything.
// Loss by tc netem where the kernel has it, else nftables drops (no delay).
// Counts and results are asserted, never timings. Needs root; skips
// otherwise. Two 2-site traverses of 4 stereo pairs per site (~2.3 min on
// 2 cores, ~3.2 min beside multihost_proc_test under ctest -j2).

#include <gtest/gtest.h>

#include <iostream>

#include "netns_link.h"
#include "split_traverse.h"

namespace vloc {
namespace {

using namespace testing;  // split_traverse.h, netns_link.h

// One bus per host, kept on it (ttl=0): only the tunnels cross the link.
const std::string kUrl = "udpm://239.255.76.67:7983?ttl=0&recv_buf_size=33554432";
const std::string kGroundAddress = "10.218.0.2";  // NetnsLink's ground end
constexpr int kSites = 2;
constexpr double kLossPercent = 5.0;
// The channels the vehicle publishes and the ground uses or records.
const char* const kVehicleChannels[] = {"NAVCAM_STEREO", "ROVER_SITE", "IMU",    "WHEEL_ODOM",
                                        "GT_POSE",       "SITE_POSE_GT", "SITE_POSE_DR", "DR_POSE"};

class SplitTunnel : public SplitLinkTest {
 protected:
  void SetUp() override { SetUpLink("st", kUrl); }
};

TEST_F(SplitTunnel, SplitTraverseOverALossyLinkMatchesOneHost) {
  const size_t kVehicleProcs = 4, kGroundProcs = 5;  // each with its tunnel

  // --- 1. rover_split.yaml whole on one host (the ground namespace): the reference.
  std::optional<traverse_t> reference;
  std::map<int, site_pose_t> reference_gt;
  {
    SCOPED_TRACE("one host");
    Subprocess whole = LaunchIn(*link_, link_->ground(), "", dir_ + "/one_host", kSites,
                                {"config/groups/rover_split.yaml", kUrl});
    ASSERT_TRUE(bus_->WaitFor([&] { return bus_->TraverseComplete(kSites); }, 150, {&whole}))
        << "no complete traverse on one host\n" << whole.output();
    reference = bus_->traverse;
    reference_gt = bus_->gt;
    StopLauncher(whole, "one-host launcher");
  }

  // --- 2. rover_split_tunnel.yaml split over a lossy link, the vehicle first.
  bus_->Reset();
  const std::string applied = link_->AddLoss(kLossPercent, 0);
  ASSERT_FALSE(applied.empty()) << "neither tc netem nor nftables could add loss: " << link_->error();
  std::cout << "[split_tunnel] link: " << applied << "\n";
  const std::string group = "config/groups/rover_split_tunnel.yaml";
  const std::string ground_dir = dir_ + "/ground", vehicle_dir = dir_ + "/vehicle";
  Subprocess vehicle = LaunchIn(*link_, link_->vehicle(), "vehicle", vehicle_dir, kSites,
                                {group, kUrl, {"VLOC_TUNNEL_PEER=" + kGroundAddress}});
  // Alone, the vehicle's simulator waits for the ground's processes.
  ASSERT_TRUE(vehicle.WaitForOutput("feature_frontend (host ground)", 30)) << vehicle.output();
  Subprocess ground = LaunchIn(*link_, link_->ground(), "ground", ground_dir, kSites, {group, kUrl});
  ASSERT_TRUE(bus_->WaitFor([&] { return bus_->TraverseComplete(kSites); }, 200, {&ground, &vehicle}))
      << "no complete traverse split across a tunnel\nground:\n" << ground.output() << "\nvehicle:\n"
      << vehicle.output();

  // The vehicle's launcher reached the ground's bus through the tunnel, and each saw the other.
  ASSERT_TRUE(bus_->status.count("vehicle") && bus_->status.count("ground"));
  EXPECT_EQ(bus_->status["vehicle"].procs.size(), kVehicleProcs);
  EXPECT_EQ(bus_->status["ground"].procs.size(), kGroundProcs);
  EXPECT_NE(ground.output().find("peers: launcher 'vehicle'"), std::string::npos) << ground.output();
  EXPECT_NE(vehicle.output().find("peers: launcher 'ground'"), std::string::npos) << vehicle.output();

  // The same traverse as on one host.
  ExpectSameTraverse("split_tunnel", *bus_->traverse, bus_->gt, *reference, reference_gt);

  // An order from the ground's bus restarts a vehicle process (PROCMAN_ORDERS crosses).
  {
    SCOPED_TRACE("order across the tunnel");
    const proc_status_t* dr = bus_->Proc("vehicle", "dead_reckoning", vehicle.pid());
    ASSERT_TRUE(dr && dr->pid > 0);
    const int old_pid = dr->pid;
    ASSERT_TRUE(bus_->Order("vehicle", "dead_reckoning", procman_order_t::ACTION_RESTART));
    ASSERT_TRUE(bus_->WaitFor(
        [&] {
          const proc_status_t* p = bus_->Proc("vehicle", "dead_reckoning", vehicle.pid());
          return p && p->state == proc_status_t::STATE_RUNNING && p->pid > 0 && p->pid != old_pid;
        },
        30, {&ground, &vehicle}))
        << vehicle.output();
  }

  // The simulator ends; then the vehicle's tunnel has nothing left to send.
  ASSERT_TRUE(bus_->WaitFor(
      [&] {
        const proc_status_t* sim = bus_->Proc("vehicle", "sim_rover", vehicle.pid());
        return sim && sim->state == proc_status_t::STATE_EXITED;
      },
      120, {&ground, &vehicle}))
      << vehicle.output();
  const auto drained = [&] {
    if (!bus_->tunnels.count("vehicle") || !bus_->tunnels.count("ground")) return false;
    const tunnel_status_t& v = bus_->tunnels["vehicle"];
    return v.connected && v.queued_messages == 0 && v.in_flight_bytes == 0;
  };
  bus_->tunnels.clear();  // a report from after the simulator's end
  ASSERT_TRUE(bus_->WaitFor(drained, 60, {&ground, &vehicle})) << vehicle.output();
  bus_->WaitFor([] { return false; }, 2, {&ground, &vehicle});  // the loggers write what arrived
  const tunnel_status_t v_tunnel = bus_->tunnels["vehicle"], g_tunnel = bus_->tunnels["ground"];
  StopLauncher(vehicle, "vehicle launcher");
  StopLauncher(ground, "ground launcher");
  link_->ClearLoss();

  // Everything the vehicle published crossed: counted from both hosts' logs.
  const LogCounts sent = CountLog(vehicle_dir + "/rover_vehicle.lcmlog");
  const LogCounts received = CountLog(ground_dir + "/rover_ground.lcmlog");
  std::string report;
  const int lost = ReportLink("[split_tunnel] " + applied + ", vehicle -> ground through the tunnel:", sent, received,
                              &report);
  std::cout << report;
  ASSERT_EQ(sent.pairs.size(), static_cast<size_t>(kSites)) << report;
  EXPECT_EQ(lost, 0) << report;
  for (const char* ch : kVehicleChannels) {
    const int s = sent.messages.count(ch) ? sent.messages.at(ch) : 0;
    const int r = received.messages.count(ch) ? received.messages.at(ch) : 0;
    EXPECT_GT(s, 0) << ch;
    EXPECT_EQ(r, s) << ch << "\n" << report;
  }
  for (const tunnel_status_t* t : {&v_tunnel, &g_tunnel}) {
    std::cout << "[split_tunnel] tunnel " << t->name << ": sent " << t->sent_messages << " messages, received "
              << t->received_messages << ", frames resent " << t->resent_frames << ", rejected " << t->rejected_frames
              << ", queue high water " << t->queued_bytes_high_water / 1e6 << " MB, connects " << t->connects
              << ", dropped " << t->dropped_queue_full + t->dropped_too_large + t->dropped_too_many_channels << "\n";
    EXPECT_EQ(t->dropped_queue_full + t->dropped_too_large + t->dropped_too_many_channels, 0) << t->name;
    EXPECT_EQ(t->rejected_frames, 0) << t->name;
  }
}

}  // namespace
}  // namespace vloc
