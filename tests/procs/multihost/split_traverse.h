#pragma once
// Test support for the rover group split across two network namespaces
// (NetnsLink): a vloc_launch per namespace running a group file (its part
// of it with --host, all of it without), what the ground's bus hears
// (traverse, ground truth, launcher status, tunnel status), the recorded
// logs counted per channel and stereo pair, and a split traverse compared
// site by site with the one-host traverse. Header-only; used by
// multihost_proc_test (one multicast bus across the link) and
// split_tunnel_proc_test (a ttl=0 bus per namespace joined by vloc_lcm_tunnel).

#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "netns_link.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/procman_order_t.hpp"
#include "vloc/procman_peers_t.hpp"
#include "vloc/procman_status_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/stereo_image_t.hpp"
#include "vloc/testing/subprocess.h"
#include "vloc/traverse_t.hpp"
#include "vloc/tunnel_status_t.hpp"

namespace vloc::testing {

using SplitClock = std::chrono::steady_clock;

inline double Since(SplitClock::time_point t) {
  return std::chrono::duration<double>(SplitClock::now() - t).count();
}

inline std::string SourceDir() {
  const char* dir = std::getenv("VLOC_SOURCE_DIR");
  return dir ? dir : VLOC_SOURCE_DIR;
}

inline std::string BinDir() {
  const std::string launch = BinPath("vloc_launch");
  return launch.substr(0, launch.rfind('/'));
}

inline std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// What the test hears on the ground's side of the bus.
class GroundBus {
 public:
  explicit GroundBus(const std::string& url) {
    std::string error;
    transport_ = MakeLcmTransport(url, &error);
    EXPECT_TRUE(transport_) << error;
    if (!transport_) return;
    Subscribe<traverse_t>(*transport_, "TRAVERSE", [this](const std::string&, const traverse_t& m) { traverse = m; }, 100);
    Subscribe<site_pose_t>(*transport_, "SITE_POSE_GT",
                           [this](const std::string&, const site_pose_t& m) { gt[m.site_id] = m; }, 100);
    Subscribe<procman_status_t>(
        *transport_, "PROCMAN_STATUS",
        [this](const std::string&, const procman_status_t& m) {
          status[m.host] = m;
          ++status_count[m.host];
        },
        100);
    Subscribe<procman_peers_t>(*transport_, "PROCMAN_PEERS",
                               [this](const std::string&, const procman_peers_t& m) { peers[m.host] = m; }, 100);
    Subscribe<tunnel_status_t>(*transport_, "TUNNEL_STATUS",
                               [this](const std::string&, const tunnel_status_t& m) { tunnels[m.name] = m; }, 100);
  }
  // Forgets what was heard, after handling what is still queued (the
  // previous run's last messages), so that it cannot pass for the next run's.
  void Reset() {
    WaitFor([] { return false; }, 1.0, {});
    traverse.reset();
    gt.clear();
    status.clear();
    status_count.clear();
    peers.clear();
    tunnels.clear();
  }
  // Handles messages (draining the launchers' output) until `done` or the timeout.
  bool WaitFor(const std::function<bool()>& done, double timeout_s, const std::vector<Subprocess*>& drain) {
    const auto start = SplitClock::now();
    while (Since(start) < timeout_s) {
      if (transport_) transport_->Handle(100);
      for (Subprocess* p : drain) p->Drain();
      if (done()) return true;
    }
    return false;
  }
  // `name` in the newest status of the launcher of `host` with pid
  // `launcher_pid` (a stopped launcher's last reports may still be queued).
  const proc_status_t* Proc(const std::string& host, const std::string& name, int launcher_pid) const {
    auto it = status.find(host);
    if (it == status.end() || it->second.launcher_pid != launcher_pid) return nullptr;
    for (const auto& p : it->second.procs)
      if (p.name == name) return &p;
    return nullptr;
  }
  bool AllRunning(const std::string& host, size_t count, int launcher_pid) const {
    auto it = status.find(host);
    if (it == status.end() || it->second.launcher_pid != launcher_pid || it->second.procs.size() != count)
      return false;
    for (const auto& p : it->second.procs)
      if (p.state != proc_status_t::STATE_RUNNING) return false;
    return true;
  }
  // An order on PROCMAN_ORDERS from this side of the bus (as the console sends it).
  bool Order(const std::string& host, const std::string& process, int8_t action) {
    procman_order_t order;
    order.utime = 0;
    order.host = host;
    order.target = process;
    order.target_kind = procman_order_t::TARGET_PROCESS;
    order.action = action;
    return transport_ && Publish(*transport_, "PROCMAN_ORDERS", order);
  }
  bool TraverseComplete(int sites) const {
    return traverse && traverse->num_sites == sites && traverse->num_visual_edges == sites - 1;
  }

  std::optional<traverse_t> traverse;
  std::map<int, site_pose_t> gt;
  std::map<std::string, procman_status_t> status;
  std::map<std::string, int> status_count;
  std::map<std::string, procman_peers_t> peers;
  std::map<std::string, tunnel_status_t> tunnels;  // by tunnel name

 private:
  std::unique_ptr<Transport> transport_;
};

// config/procs/sim_rover.yaml with 4 stereo pairs per site instead of 7
// (rendering dominates the run time), its includes made absolute.
inline std::string ShortSimConfig(const std::string& dir) {
  std::string text = ReadFile(SourceDir() + "/config/procs/sim_rover.yaml");
  auto replace = [&](const std::string& from, const std::string& to) {
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
  };
  replace("num_pairs: 7", "num_pairs: 4");
  replace("include: ../navcam.yaml", "include: " + SourceDir() + "/config/navcam.yaml");
  replace("include: ../sim/terrain.yaml", "include: " + SourceDir() + "/config/sim/terrain.yaml");
  std::filesystem::create_directories(dir);
  const std::string path = dir + "/sim_rover_4pairs.yaml";
  std::ofstream(path) << text;
  return path;
}

// What one launcher runs: a group file (config/groups/...) on a bus.
struct SplitRun {
  std::string group;                 // path below the source folder
  std::string url;                   // --lcm-url
  std::vector<std::string> env = {};  // beyond VLOC_ROOT, VLOC_BIN and VLOC_SIM_*
};

// A vloc_launch in namespace `ns` running `run.group` (its part of it for a
// non-empty host), a simulated traverse of `sites` sites of 4 pairs each.
inline Subprocess LaunchIn(const NetnsLink& link, const std::string& ns, const std::string& host,
                           const std::string& log_dir, int sites, const SplitRun& run) {
  std::vector<std::string> argv = {BinPath("vloc_launch"), "--config", SourceDir() + "/" + run.group, "--lcm-url",
                                   run.url, "--log-dir", log_dir, "--lost-after", "3"};
  if (!host.empty()) argv.insert(argv.end(), {"--host", host});
  std::filesystem::create_directories(log_dir);
  std::vector<std::string> env = {"VLOC_ROOT=" + SourceDir(), "VLOC_BIN=" + BinDir(),
                                  "VLOC_SIM_SITES=" + std::to_string(sites), "VLOC_SIM_SPEED=30",
                                  "VLOC_SIM_CONFIG=" + ShortSimConfig(log_dir)};
  env.insert(env.end(), run.env.begin(), run.env.end());
  return Subprocess(link.In(ns, argv), env);
}

// SIGTERM, then the launcher must have stopped everything and exited.
inline void StopLauncher(Subprocess& launcher, const std::string& what) {
  launcher.Signal(SIGTERM);
  const auto code = launcher.WaitExit(45);
  ASSERT_TRUE(code.has_value()) << what << " did not stop within 45 s:\n" << launcher.output();
  EXPECT_EQ(*code, 0) << what << ":\n" << launcher.output();
}

inline double Distance(const pose_t& a, const pose_t& b) {
  return std::hypot(a.position[0] - b.position[0], a.position[1] - b.position[1], a.position[2] - b.position[2]);
}

// Site id -> position error against ground truth (m).
inline std::map<int, double> Errors(const traverse_t& t, const std::map<int, site_pose_t>& gt) {
  std::map<int, double> out;
  for (int i = 0; i < t.num_sites; ++i) {
    auto it = gt.find(t.site_ids[i]);
    if (it != gt.end()) out[t.site_ids[i]] = Distance(t.poses[i], it->second.pose);
  }
  return out;
}

// A split traverse against the one-host traverse of the same inputs, site
// by site: printed (tagged `tag`) and asserted. Thread timing in the front
// end and BA moves a site by up to ~2 mm between two runs on one host; the
// split run must stay within the accuracy target (0.1 % of the distance
// between sites) of the one-host run.
inline void ExpectSameTraverse(const std::string& tag, const traverse_t& split, const std::map<int, site_pose_t>& gt,
                               const traverse_t& reference, const std::map<int, site_pose_t>& reference_gt) {
  ASSERT_EQ(split.num_sites, reference.num_sites);
  auto split_errors = Errors(split, gt), reference_errors = Errors(reference, reference_gt);
  for (int i = 0; i < split.num_sites; ++i) {
    const int id = split.site_ids[i];
    ASSERT_EQ(id, reference.site_ids[i]);
    const double diff = Distance(split.poses[i], reference.poses[i]);
    std::cout << "[" << tag << "] site " << id << ": split vs one host " << diff * 1000 << " mm; error vs truth split "
              << split_errors[id] * 1000 << " mm, one host " << reference_errors[id] * 1000 << " mm\n";
    ASSERT_TRUE(gt.count(id)) << "no SITE_POSE_GT for site " << id;
    const int previous = i == 0 ? id : split.site_ids[i - 1];
    ASSERT_TRUE(gt.count(previous)) << "no SITE_POSE_GT for site " << previous;
    const double spacing = Distance(gt.at(id).pose, gt.at(previous).pose);
    EXPECT_LE(diff, 1e-3 * spacing) << "site " << id << ", " << spacing << " m from the previous site";
  }
}

// One recorded log, counted: messages per channel and the stereo pairs
// (site -> pair indices) it holds.
struct LogCounts {
  std::map<std::string, int> messages;
  std::map<int, std::set<int>> pairs;
};

inline LogCounts CountLog(const std::string& path) {
  LogCounts c;
  lcm::LogFile log(path, "r");
  if (!log.good()) return c;
  for (const lcm::LogEvent* e = log.readNextEvent(); e; e = log.readNextEvent()) {
    ++c.messages[e->channel];
    if (e->channel == "NAVCAM_STEREO") {
      stereo_image_t m;
      if (m.decode(e->data, 0, e->datalen) == e->datalen) c.pairs[m.site_id].insert(m.pair_index);
    }
  }
  return c;
}

// What crossed from the vehicle to the ground: one line per channel the
// vehicle published (sent, received, lost) and one per site whose images
// did not all arrive (which pairs). Returns the stereo pairs lost.
inline int ReportLink(const std::string& title, const LogCounts& sent, const LogCounts& received, std::string* text) {
  std::ostringstream out;
  out << title << "\n  channel            sent  received  lost\n";
  for (const char* ch : {"NAVCAM_STEREO", "ROVER_SITE", "IMU", "WHEEL_ODOM", "GT_POSE", "SITE_POSE_GT",
                         "SITE_POSE_DR", "DR_POSE"}) {
    const int s = sent.messages.count(ch) ? sent.messages.at(ch) : 0;
    const int r = received.messages.count(ch) ? received.messages.at(ch) : 0;
    char line[128];
    std::snprintf(line, sizeof(line), "  %-16s %6d  %8d  %4d (%.1f %%)\n", ch, s, r, s - r,
                  s > 0 ? 100.0 * (s - r) / s : 0.0);
    out << line;
  }
  int lost = 0;
  for (const auto& [site, pairs] : sent.pairs) {
    std::set<int> got = received.pairs.count(site) ? received.pairs.at(site) : std::set<int>{};
    std::string missing;
    int n = 0;
    for (int p : pairs)
      if (!got.count(p)) {
        missing += (missing.empty() ? "" : ",") + std::to_string(p);
        ++n;
      }
    lost += n;
    if (n > 0)
      out << "  site " << site << ": " << n << " of " << pairs.size() << " stereo pairs lost (pairs " << missing
          << ")\n";
  }
  *text = out.str();
  return lost;
}

// The fixture of a split run: two namespaces joined by a link, the test's
// thread in the ground's (what it opens listens there), the ground's bus,
// and a folder for the launchers' logs (removed unless the test failed).
class SplitLinkTest : public ::testing::Test {
 protected:
  // tag: the namespaces' prefix (a few letters; the pid is appended);
  // url: the bus the test hears in the ground namespace.
  void SetUpLink(const std::string& tag, const std::string& url) {
    if (geteuid() != 0) GTEST_SKIP() << "needs root (CAP_NET_ADMIN) to create network namespaces; run as root";
    std::string error;
    link_ = std::make_unique<NetnsLink>(tag + std::to_string(getpid() % 100000));
    if (!link_->Create(&error))
      GTEST_SKIP() << "cannot create network namespaces (needs root / CAP_NET_ADMIN and iproute2): " << error;
    in_ground_ = std::make_unique<InNetns>(link_->ground());
    ASSERT_TRUE(in_ground_->ok()) << "cannot enter namespace " << link_->ground();
    bus_ = std::make_unique<GroundBus>(url);
    dir_ = ::testing::TempDir() + "/" + tag + "_" + std::to_string(getpid());
    std::filesystem::remove_all(dir_);
  }
  void TearDown() override {
    bus_.reset();
    in_ground_.reset();
    link_.reset();
    // The runs' logs (tens of MB of images) are kept only to look into a failure.
    if (!HasFailure() && !dir_.empty()) std::filesystem::remove_all(dir_);
  }

  std::unique_ptr<NetnsLink> link_;
  std::unique_ptr<InNetns> in_ground_;
  std::unique_ptr<GroundBus> bus_;
  std::string dir_;
};

}  // namespace vloc::testing
