// vloc_lcm_tunnel over a lossy link: two network namespaces ("vehicle",
// "ground") joined by a veth pair, one tunnel in each on its own ttl=0 bus,
// side by side with today's multicast (ttl=1) across the same link.
//   1. stereo pairs (2 MB) at 1/s at 0.1, 1 and 5 % loss: every pair arrives
//      through the tunnel, in order; multicast's arrivals are printed beside
//      it, with the tunnel's latency (median, max) and throughput;
//   2. a 30 s cut of the link: every pair and pose published meanwhile arrives
//      after the link returns, in order; the queue's high-water mark printed;
//   3. a 2 Mbit/s cap: every pose and status arrives, in order, their latency
//      printed; the images queue, and each is sent, queued or a counted drop.
// Loss by tc netem where the kernel has it, else nftables drops (no delay).
// Counts and order are asserted, never timings. Needs root; skips otherwise.
// VLOC_TUNNEL_FIGURE_PAIRS (default 20) sets the pairs per loss level (the
// README's figures: 100).

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <iostream>

#include "../tunnel/tunnel_bus.h"
#include "netns_link.h"
#include "vloc/lcm_io/process.h"
#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

using testing::BinPath;
using testing::InNetns;
using testing::InOrder;
using testing::NetnsLink;
using testing::Subprocess;
using testing::TunnelBus;
using testing::WaitOn;

const std::string kTunnelUrlV = "udpm://239.255.76.67:8221?ttl=0&recv_buf_size=33554432";
const std::string kTunnelUrlG = "udpm://239.255.76.67:8222?ttl=0&recv_buf_size=33554432";
const std::string kMulticastUrl = "udpm://239.255.76.67:8223?ttl=1&recv_buf_size=33554432";
constexpr size_t kPairBytes = 2000000;

double Now() { return TunnelBus::NowS(); }

int PairsPerLevel() {
  const char* v = std::getenv("VLOC_TUNNEL_FIGURE_PAIRS");
  return v && std::atoi(v) > 0 ? std::atoi(v) : 20;
}

// Median and max of the latencies (ms) of channel `c`, from publish times by index.
std::pair<double, double> Latency(const TunnelBus& bus, const std::string& c, const std::map<int64_t, double>& sent) {
  std::vector<double> ms;
  const auto& idx = bus.received.at(c);
  const auto& at = bus.arrival_s.at(c);
  for (size_t i = 0; i < idx.size(); ++i)
    if (sent.count(idx[i])) ms.push_back((at[i] - sent.at(idx[i])) * 1000);
  if (ms.empty()) return {0, 0};
  std::sort(ms.begin(), ms.end());
  return {ms[ms.size() / 2], ms.back()};
}

std::string Fixed(double v, int digits = 0) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

class TunnelLink : public ::testing::Test {
 protected:
  void SetUp() override {
    if (geteuid() != 0) GTEST_SKIP() << "needs root (CAP_NET_ADMIN) to create network namespaces; run as root";
    link_ = std::make_unique<NetnsLink>("tl");
    std::string error;
    if (!link_->Create(&error))
      GTEST_SKIP() << "cannot create network namespaces (needs root / CAP_NET_ADMIN and iproute2): " << error;
    {
      InNetns in(link_->vehicle());
      ASSERT_TRUE(in.ok());
      v_tunnel_ = std::make_unique<TunnelBus>(kTunnelUrlV);
      v_mc_ = std::make_unique<TunnelBus>(kMulticastUrl);
    }
    {
      InNetns in(link_->ground());
      ASSERT_TRUE(in.ok());
      g_tunnel_ = std::make_unique<TunnelBus>(kTunnelUrlG);
      g_mc_ = std::make_unique<TunnelBus>(kMulticastUrl);
    }
    ASSERT_TRUE(v_tunnel_->ok() && v_mc_->ok() && g_tunnel_->ok() && g_mc_->ok());
    // Lost fragments hold the reassembly memory for ipfrag_time (30 s); as link_figures.sh does.
    testing::Shell("ip netns exec " + link_->ground() + " sysctl -qw net.ipv4.ipfrag_time=1");
  }
  void TearDown() override {
    for (auto* p : {vehicle_.get(), ground_.get()})
      if (p) {
        p->Signal(SIGTERM);
        p->WaitExit(20);
      }
  }
  void StartTunnels(double cap_mbps = 0) {
    const std::vector<std::string> common = {"--config", "config/procs/vloc_lcm_tunnel.yaml", "--bandwidth-cap-mbps",
                                             Fixed(cap_mbps, 3)};
    std::vector<std::string> g = {BinPath("vloc_lcm_tunnel"), "--name", "ground", "--bind", "tcp://10.218.0.2:7720",
                                  "--lcm-url", kTunnelUrlG};
    std::vector<std::string> v = {BinPath("vloc_lcm_tunnel"), "--name", "vehicle", "--connect",
                                  "tcp://10.218.0.2:7720", "--lcm-url", kTunnelUrlV};
    g.insert(g.end(), common.begin(), common.end());
    v.insert(v.end(), common.begin(), common.end());
    ground_ = std::make_unique<Subprocess>(link_->In(link_->ground(), g));
    vehicle_ = std::make_unique<Subprocess>(link_->In(link_->vehicle(), v));
    ASSERT_TRUE(ground_->WaitForOutput(kReadyLine, 60)) << ground_->output();
    ASSERT_TRUE(vehicle_->WaitForOutput(kReadyLine, 60)) << vehicle_->output();
    ASSERT_TRUE(Wait([&] {
      const auto* v = v_tunnel_->Status("vehicle");
      const auto* g = g_tunnel_->Status("ground");
      return v && g && v->connected && g->connected;
    }, 60)) << vehicle_->output() << ground_->output();
  }
  bool Wait(const std::function<bool()>& done, double timeout_s) {
    return WaitOn({v_tunnel_.get(), g_tunnel_.get(), v_mc_.get(), g_mc_.get()}, {vehicle_.get(), ground_.get()}, done,
                  timeout_s);
  }
  // Handles the buses until `t` (steady clock): the pace of a sensor.
  void Until(double t) {
    Wait([&] { return Now() >= t; }, 1e9);
  }
  void Publish(const std::string& channel, int64_t i, size_t size, bool multicast_too,
               std::map<int64_t, double>* sent) {
    (*sent)[i] = Now();
    v_tunnel_->Publish(channel, i, size);
    if (multicast_too) v_mc_->Publish(channel, i, size);
  }

  std::unique_ptr<NetnsLink> link_;
  std::unique_ptr<TunnelBus> v_tunnel_, g_tunnel_, v_mc_, g_mc_;
  std::unique_ptr<Subprocess> vehicle_, ground_;
};

TEST_F(TunnelLink, EveryStereoPairArrivesAtEachLossLevel) {
  ASSERT_NO_FATAL_FAILURE(StartTunnels());
  const int n = PairsPerLevel();
  const int64_t first = 0;  // each level counts from 0 (what the buses heard is cleared between levels)
  for (double loss : {0.1, 1.0, 5.0}) {
    const std::string applied = link_->AddLoss(loss, 50);
    ASSERT_FALSE(applied.empty()) << link_->error();
    std::map<int64_t, double> sent;
    const double start = Now();
    for (int i = 0; i < n; ++i) {
      Until(start + i);  // 1 pair per second
      Publish("NAVCAM_STEREO", first + i, kPairBytes, true, &sent);
    }
    ASSERT_TRUE(Wait([&] { return g_tunnel_->Count("NAVCAM_STEREO") >= static_cast<size_t>(first + n); }, 300))
        << "tunnel delivered " << g_tunnel_->Count("NAVCAM_STEREO") - first << " of " << n << " at " << loss
        << " % loss\n"
        << vehicle_->output() << ground_->output();
    Until(Now() + 3);  // multicast stragglers
    std::vector<int64_t> got(g_tunnel_->received["NAVCAM_STEREO"].begin() + first,
                             g_tunnel_->received["NAVCAM_STEREO"].end());
    for (auto& g : got) g -= first;
    EXPECT_TRUE(InOrder(got, n)) << loss << " %";
    size_t multicast = 0;
    for (int64_t i : g_mc_->received["NAVCAM_STEREO"]) multicast += (i >= first && i < first + n);
    const auto [median, max] = Latency(*g_tunnel_, "NAVCAM_STEREO", sent);
    const double span = g_tunnel_->arrival_s["NAVCAM_STEREO"].back() - start;
    const tunnel_status_t* gs = g_tunnel_->Status("ground");
    const tunnel_status_t* vs = v_tunnel_->Status("vehicle");
    std::cout << "figure: loss " << loss << " % (" << applied << "): stereo pairs (2 MB) at 1/s, tunnel " << got.size()
              << " of " << n << ", multicast " << multicast << " of " << n << "; tunnel latency median "
              << Fixed(median) << " ms, max " << Fixed(max) << " ms; throughput "
              << Fixed(n * kPairBytes * 8 / span / 1e6, 1) << " Mbit/s; frames resent " << (vs ? vs->resent_frames : -1)
              << ", rejected " << (gs ? gs->rejected_frames : -1) << std::endl;
    EXPECT_EQ(g_tunnel_->corrupt, 0);
    link_->ClearLoss();
    for (TunnelBus* b : {v_tunnel_.get(), g_tunnel_.get(), v_mc_.get(), g_mc_.get()}) {
      b->received.clear();
      b->arrival_s.clear();
    }
  }
}

TEST_F(TunnelLink, AThirtySecondCutLosesNothingThatFitsTheQueues) {
  ASSERT_NO_FATAL_FAILURE(StartTunnels());
  std::map<int64_t, double> pairs_sent, poses_sent;
  const double start = Now();
  const double cut_at = start + 10, back_at = start + 40, end = start + 50;
  bool cut = false, back = false;
  int pairs = 0, poses = 0;
  while (Now() < end) {
    if (!cut && Now() >= cut_at) cut = link_->Cut();
    if (cut && !back && Now() >= back_at) {
      back = link_->Restore();
      ASSERT_TRUE(back);
    }
    if (Now() >= start + pairs) Publish("NAVCAM_STEREO", pairs++, kPairBytes, true, &pairs_sent);
    if (Now() >= start + poses * 0.2) Publish("DR_POSE", poses++, 500, true, &poses_sent);
    Wait([] { return true; }, 0);
  }
  ASSERT_TRUE(cut && back);
  double all_at = 0;
  ASSERT_TRUE(Wait([&] {
    all_at = Now();
    return g_tunnel_->Count("NAVCAM_STEREO") >= static_cast<size_t>(pairs) &&
           g_tunnel_->Count("DR_POSE") >= static_cast<size_t>(poses);
  }, 300)) << g_tunnel_->Count("NAVCAM_STEREO") << " of " << pairs << " pairs\n"
           << vehicle_->output() << ground_->output();
  EXPECT_TRUE(InOrder(g_tunnel_->received["NAVCAM_STEREO"], pairs));
  EXPECT_TRUE(InOrder(g_tunnel_->received["DR_POSE"], poses));
  Wait([&] { return v_tunnel_->Status("vehicle") && v_tunnel_->Status("vehicle")->queued_messages == 0; }, 10);
  const tunnel_status_t* vs = v_tunnel_->Status("vehicle");
  ASSERT_TRUE(vs);
  EXPECT_EQ(vs->dropped_queue_full, 0);
  std::cout << "figure: 30 s cut (pairs 2 MB at 1/s, poses at 5/s, " << Fixed(end - start) << " s): tunnel "
            << g_tunnel_->Count("NAVCAM_STEREO") << " of " << pairs << " pairs, " << g_tunnel_->Count("DR_POSE")
            << " of " << poses << " poses, in order; multicast " << g_mc_->Count("NAVCAM_STEREO") << " pairs, "
            << g_mc_->Count("DR_POSE") << " poses; queue high water " << Fixed(vs->queued_bytes_high_water / 1e6, 1)
            << " MB; all delivered " << Fixed(all_at - back_at, 1) << " s after the link returned; link up "
            << vs->connects << " times, frames resent " << vs->resent_frames << std::endl;
}

TEST_F(TunnelLink, UnderA2MbitCapPosesAndStatusKeepMovingWhileImagesQueue) {
  ASSERT_NO_FATAL_FAILURE(StartTunnels(2.0));
  std::map<int64_t, double> pairs_sent, poses_sent, status_sent;
  const double start = Now(), end = start + 20;
  int pairs = 0, poses = 0, statuses = 0;
  while (Now() < end) {
    if (Now() >= start + pairs) Publish("NAVCAM_STEREO", pairs++, kPairBytes, false, &pairs_sent);
    if (Now() >= start + poses * 0.2) Publish("DR_POSE", poses++, 500, false, &poses_sent);
    if (Now() >= start + statuses) Publish("FRONTEND_STATUS", statuses++, 300, false, &status_sent);
    Wait([] { return true; }, 0);
  }
  ASSERT_TRUE(Wait([&] {
    return g_tunnel_->Count("DR_POSE") >= static_cast<size_t>(poses) &&
           g_tunnel_->Count("FRONTEND_STATUS") >= static_cast<size_t>(statuses);
  }, 120)) << vehicle_->output() << ground_->output();
  EXPECT_TRUE(InOrder(g_tunnel_->received["DR_POSE"], poses));
  EXPECT_TRUE(InOrder(g_tunnel_->received["FRONTEND_STATUS"], statuses));
  // Every image is accounted for: sent, still queued, or dropped (counted), per the vehicle's report after the last.
  const double last = Now();
  ASSERT_TRUE(Wait([&] {
    const tunnel_status_t* v = v_tunnel_->Status("vehicle");
    return v && v->utime > 0 && TunnelBus::NowS() > last + 1.5;
  }, 30));
  const tunnel_status_t* vs = v_tunnel_->Status("vehicle");
  int64_t sent = 0, queued = 0, dropped = 0;
  for (const auto& c : vs->channels)
    if (c.channel == "NAVCAM_STEREO") sent = c.sent, queued = c.queued_messages, dropped = c.dropped;
  EXPECT_EQ(sent + queued + dropped, pairs);
  const auto& got = g_tunnel_->received["NAVCAM_STEREO"];
  EXPECT_TRUE(std::is_sorted(got.begin(), got.end()));
  const auto [pose_med, pose_max] = Latency(*g_tunnel_, "DR_POSE", poses_sent);
  const auto [st_med, st_max] = Latency(*g_tunnel_, "FRONTEND_STATUS", status_sent);
  const auto [img_med, img_max] = Latency(*g_tunnel_, "NAVCAM_STEREO", pairs_sent);
  std::cout << "figure: 2 Mbit/s cap, 20 s of pairs (2 MB) at 1/s + poses at 5/s + status at 1/s: poses " << poses
            << " of " << poses << ", latency median " << Fixed(pose_med) << " ms, max " << Fixed(pose_max)
            << " ms; status " << statuses << " of " << statuses << ", median " << Fixed(st_med) << " ms, max "
            << Fixed(st_max) << " ms; images: " << got.size() << " of " << pairs << " arrived (latency median "
            << Fixed(img_med / 1000, 1) << " s, max " << Fixed(img_max / 1000, 1) << " s), " << queued
            << " queued, " << dropped << " dropped; tunnel sent " << Fixed(vs->tx_bytes_per_s * 8 / 1e6, 2)
            << " Mbit/s" << std::endl;
}

}  // namespace
}  // namespace vloc
