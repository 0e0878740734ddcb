// The rover group split across two machines, as two network namespaces
// ("vehicle" and "ground") joined by a veth pair, on one LCM bus with
// ttl=1: config/groups/rover_split.yaml run by one vloc_launch per
// namespace (--host vehicle / --host ground) against the same file run
// whole on one host.
//
//   1. one host: the whole file in the ground namespace -> reference traverse
//   2. split, clean link (the vehicle started first: its simulator waits
//      for the ground's processes): the traverse arrives complete and equals the
//      reference; dead_reckoning SIGKILLed on the vehicle is restarted by
//      the vehicle's launcher and seen restarted from the ground; the link
//      cut at the ground end: each launcher logs the other LOST within
//      --lost-after + 1 s, and back once the link returns; both stop.
//   3. split, lossy link (5 % loss, 20 ms delay): what the vehicle sent and
//      the ground did not receive is named per channel and, for images,
//      per site and pair; small messages still arrive; the ground's
//      traverse holds the sites whose poses arrived; nothing hangs.
// Skips (GTEST_SKIP) where namespaces cannot be made (not root). Runs three
// 2-site simulated traverses of 4 stereo pairs per site (~2.5 min on 2 cores).

#include <gtest/gtest.h>
#include <signal.h>

#include <iostream>
#include <sstream>

#include "netns_link.h"
#include "split_traverse.h"

namespace vloc {
namespace {

using namespace testing;  // split_traverse.h: GroundBus, LaunchIn, CountLog, ReportLink, ...
using Clock = SplitClock;

// ttl=1: the multicast crosses the link (one hop); ttl=0 would stay on each host.
const std::string kUrl = "udpm://239.255.76.67:7981?ttl=1&recv_buf_size=33554432";
constexpr double kLostAfter = 3.0;  // s, --lost-after of both launchers
// s, hang guard of a whole traverse: 66-152 s on this 2-core machine alone or at load 3, 303 s at load 8;
// 150 s failed once at load 9 (the suite ten times under load). Not a timing assertion.
constexpr double kTraverseGuardS = 480;

// A vloc_launch in a namespace, running rover_split.yaml (its part of it
// for a non-empty host).
Subprocess Launch(const NetnsLink& link, const std::string& ns, const std::string& host, const std::string& log_dir,
                  int sites) {
  return LaunchIn(link, ns, host, log_dir, sites, {"config/groups/rover_split.yaml", kUrl});
}

void Stop(Subprocess& launcher, const std::string& what) { StopLauncher(launcher, what); }

class MultiHost : public SplitLinkTest {
 protected:
  void SetUp() override { SetUpLink("vl18", kUrl); }
};

TEST_F(MultiHost, SplitGroupMatchesOneHostSurvivesKillCutAndLoss) {
  constexpr int kSites = 2;
  const size_t kVehicleProcs = 3, kGroundProcs = 4;

  // --- 1. The whole file on one host (the ground namespace): the reference.
  std::optional<traverse_t> reference;
  std::map<int, site_pose_t> reference_gt;
  {
    SCOPED_TRACE("one host");
    Subprocess whole = Launch(*link_, link_->ground(), "", dir_ + "/one_host", kSites);
    ASSERT_TRUE(bus_->WaitFor([&] { return bus_->TraverseComplete(kSites); }, kTraverseGuardS, {&whole}))
        << "no complete traverse on one host\n" << whole.output();
    reference = bus_->traverse;
    reference_gt = bus_->gt;
    Stop(whole, "one-host launcher");
  }

  // --- 2. Split over a clean link. The vehicle first: its simulator waits
  // for the ground's processes (remote depends_on) until the ground runs them.
  bus_->Reset();
  const std::string ground_dir = dir_ + "/split/ground", vehicle_dir = dir_ + "/split/vehicle";
  Subprocess vehicle = Launch(*link_, link_->vehicle(), "vehicle", vehicle_dir, kSites);
  ASSERT_TRUE(bus_->WaitFor(
      [&] {
        const proc_status_t* dr = bus_->Proc("vehicle", "dead_reckoning", vehicle.pid());
        return dr && dr->state == proc_status_t::STATE_RUNNING;
      },
      20, {&vehicle}))
      << vehicle.output();
  bus_->WaitFor([] { return false; }, 1.5, {&vehicle});
  const proc_status_t* waiting = bus_->Proc("vehicle", "sim_rover", vehicle.pid());
  ASSERT_TRUE(waiting);
  EXPECT_EQ(int{waiting->state}, int{proc_status_t::STATE_STARTING}) << vehicle.output();
  EXPECT_NE(vehicle.output().find("feature_frontend (host ground)"), std::string::npos) << vehicle.output();
  Subprocess ground = Launch(*link_, link_->ground(), "ground", ground_dir, kSites);
  ASSERT_TRUE(bus_->WaitFor([&] { return bus_->TraverseComplete(kSites); }, kTraverseGuardS, {&ground, &vehicle}))
      << "no complete traverse split across hosts\nground:\n" << ground.output() << "\nvehicle:\n" << vehicle.output();
  // Each launcher names its host and runs only its part.
  ASSERT_TRUE(bus_->status.count("vehicle"));
  EXPECT_EQ(bus_->status["vehicle"].procs.size(), kVehicleProcs);
  EXPECT_EQ(bus_->status["ground"].procs.size(), kGroundProcs);
  EXPECT_NE(ground.output().find("peers: launcher 'vehicle'"), std::string::npos) << ground.output();
  EXPECT_NE(vehicle.output().find("peers: launcher 'ground'"), std::string::npos) << vehicle.output();

  // The same traverse as on one host: same inputs, same processes.
  ExpectSameTraverse("multihost", *bus_->traverse, bus_->gt, *reference, reference_gt);

  // A process killed on the vehicle: restarted there, seen from the ground.
  {
    SCOPED_TRACE("kill on the vehicle");
    const proc_status_t* dr = bus_->Proc("vehicle", "dead_reckoning", vehicle.pid());
    ASSERT_TRUE(dr && dr->pid > 0);
    const int old_pid = dr->pid;
    ASSERT_EQ(kill(old_pid, SIGKILL), 0);
    ASSERT_TRUE(bus_->WaitFor(
        [&] {
          const proc_status_t* p = bus_->Proc("vehicle", "dead_reckoning", vehicle.pid());
          return p && p->state == proc_status_t::STATE_RUNNING && p->pid != old_pid && p->restarts == 1;
        },
        15, {&ground, &vehicle}))
        << vehicle.output();
    ASSERT_TRUE(bus_->WaitFor(
        [&] { return ground.output().find("process 'dead_reckoning' BACKOFF -> RUNNING") != std::string::npos ||
                     ground.output().find("process 'dead_reckoning' RUNNING -> RUNNING") != std::string::npos; },
        5, {&ground, &vehicle}))
        << ground.output();
    EXPECT_NE(ground.output().find("launcher 'vehicle': process 'dead_reckoning'"), std::string::npos);
  }

  // The link cut for a while: each side names the other LOST, then back.
  {
    SCOPED_TRACE("link cut");
    const int vehicle_reports_before = bus_->status_count["vehicle"];
    const auto cut = Clock::now();
    ASSERT_TRUE(link_->Cut());
    std::optional<double> ground_noticed, vehicle_noticed;
    bus_->WaitFor(
        [&] {
          if (!ground_noticed && ground.output().find("launcher 'vehicle' (pid") != std::string::npos &&
              ground.output().find(") LOST: no report for") != std::string::npos)
            ground_noticed = Since(cut);
          if (!vehicle_noticed && vehicle.output().find(") LOST: no report for") != std::string::npos)
            vehicle_noticed = Since(cut);
          return ground_noticed && vehicle_noticed;
        },
        kLostAfter + 5, {&ground, &vehicle});
    ASSERT_TRUE(ground_noticed) << ground.output();
    ASSERT_TRUE(vehicle_noticed) << vehicle.output();
    std::cout << "[multihost] lost launcher noticed after " << *ground_noticed << " s (ground) and "
              << *vehicle_noticed << " s (vehicle); --lost-after " << kLostAfter << " s\n";
    EXPECT_LE(*ground_noticed, kLostAfter + 1.5);
    EXPECT_LE(*vehicle_noticed, kLostAfter + 1.5);
    bus_->WaitFor([] { return false; }, 2, {&ground, &vehicle});  // cut for ~6 s in all
    ASSERT_TRUE(link_->Restore());
    ASSERT_TRUE(bus_->WaitFor(
        [&] {
          return ground.output().find("launcher 'vehicle' is back after") != std::string::npos &&
                 vehicle.output().find("launcher 'ground' is back after") != std::string::npos &&
                 bus_->status_count["vehicle"] > vehicle_reports_before + 1;
        },
        15, {&ground, &vehicle}))
        << "ground:\n" << ground.output() << "\nvehicle:\n" << vehicle.output();
    // The ground's PROCMAN_PEERS: the vehicle alive again, lost once.
    ASSERT_TRUE(bus_->WaitFor(
        [&] {
          if (!bus_->peers.count("ground")) return false;
          for (const auto& p : bus_->peers["ground"].peers)
            if (p.host == "vehicle" && p.state == procman_peer_t::STATE_ALIVE && p.times_lost == 1) return true;
          return false;
        },
        5, {&ground, &vehicle}));
  }
  Stop(vehicle, "vehicle launcher");
  Stop(ground, "ground launcher");
  std::string report;
  const int lost_clean = ReportLink("[multihost] clean link, vehicle -> ground:", CountLog(vehicle_dir + "/rover_vehicle.lcmlog"),
                                    CountLog(ground_dir + "/rover_ground.lcmlog"), &report);
  std::cout << report;
  EXPECT_EQ(lost_clean, 0) << report;

  // --- 3. Split over a lossy link.
  bus_->Reset();
  const std::string applied = link_->AddLoss(5.0, 20.0);
  ASSERT_FALSE(applied.empty()) << "neither tc netem nor nftables could add loss: " << link_->error();
  std::cout << "[multihost] lossy link: " << applied << "\n";
  constexpr int kLossySites = 2;
  const std::string lossy_ground = dir_ + "/lossy/ground", lossy_vehicle = dir_ + "/lossy/vehicle";
  Subprocess ground2 = Launch(*link_, link_->ground(), "ground", lossy_ground, kLossySites);
  ASSERT_TRUE(bus_->WaitFor([&] { return bus_->AllRunning("ground", kGroundProcs, ground2.pid()); }, 20, {&ground2}));
  Subprocess vehicle2 = Launch(*link_, link_->vehicle(), "vehicle", lossy_vehicle, kLossySites);
  // The vehicle's simulator ends; its status still crosses (small messages).
  ASSERT_TRUE(bus_->WaitFor(
      [&] {
        const proc_status_t* sim = bus_->Proc("vehicle", "sim_rover", vehicle2.pid());
        return sim && sim->state == proc_status_t::STATE_EXITED;
      },
      150, {&ground2, &vehicle2}))
      << vehicle2.output();
  bus_->WaitFor([] { return false; }, 3, {&ground2, &vehicle2});  // the last small messages
  const std::optional<traverse_t> lossy_traverse = bus_->traverse;
  Stop(vehicle2, "vehicle launcher (lossy)");
  Stop(ground2, "ground launcher (lossy)");
  link_->ClearLoss();

  const LogCounts sent = CountLog(lossy_vehicle + "/rover_vehicle.lcmlog");
  const LogCounts received = CountLog(lossy_ground + "/rover_ground.lcmlog");
  const int lost = ReportLink("[multihost] 5 % loss, vehicle -> ground:", sent, received, &report);
  std::cout << report;
  ASSERT_EQ(sent.pairs.size(), static_cast<size_t>(kLossySites));
  // Images are fragmented into ~700 IP packets each: at 5 % loss nearly all
  // are lost, and each one lost is named above by site and pair.
  EXPECT_GT(lost, 0) << report;
  // Single-packet messages mostly arrive (5 % +- a few per cent).
  for (const char* ch : {"IMU", "WHEEL_ODOM", "GT_POSE"}) {
    const double s = sent.messages.count(ch) ? sent.messages.at(ch) : 0;
    const double r = received.messages.count(ch) ? received.messages.at(ch) : 0;
    EXPECT_GT(s, 0) << ch;
    EXPECT_GT(r, 0.85 * s) << ch << ": " << r << " of " << s << "\n" << report;
    EXPECT_LT(r, s) << ch << ": no loss at all? " << applied;
  }
  // The ground still has a traverse of the sites whose poses arrived.
  ASSERT_TRUE(lossy_traverse.has_value()) << ReadFile(lossy_ground + "/traverse_graph.log");
  EXPECT_GE(lossy_traverse->num_sites, 1);
  std::cout << "[multihost] lossy traverse: " << lossy_traverse->num_sites << " sites, "
            << lossy_traverse->num_visual_edges << " visual edges\n";
  // The front end names the sites it could not use (in its log) instead of waiting for them.
  const std::string frontend_log = ReadFile(lossy_ground + "/feature_frontend.log");
  std::cout << "[multihost] feature_frontend on the lossy link:\n";
  std::istringstream lines(frontend_log);
  for (std::string line; std::getline(lines, line);)
    if (line.find("site") != std::string::npos || line.find("subscri") != std::string::npos)
      std::cout << "  " << line << "\n";
}

}  // namespace
}  // namespace vloc
