// The backend processes' state is bounded whatever the bus sends (issue 30),
// over real LCM (ports 7621, 7622):
//  - crosssite_ba kept the DR pose and estimate of every site id it heard,
//    and rewrote its whole state file for every message (a flood of ids:
//    linear memory, quadratic disk): now the newest site_window ids, one
//    appended line per message, the file rewritten whole at twice the state;
//  - dead_reckoning searched every arrival it had seen for each new one and
//    kept every sample of its attitude history and wheel queue however close
//    in time: now a window of site ids and a cap on buffered samples.
// Floods are paced by what the process has handled (a reply or a refusal
// line after each batch), never by sleeps; conditions are waited on with
// generous deadlines (ctest -j2 on 2 cores).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>

#include "vloc/ba/synthetic.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/process.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/localization_t.hpp"
#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

using testing::BinPath;
using testing::ProcStatusMb;
using testing::Subprocess;
using testing::TestLcmUrl;

// A folder in /tmp removed when the test ends.
struct Scratch {
  explicit Scratch(const std::string& name)
      : dir(std::filesystem::temp_directory_path() /
            ("vloc_backend_bounds_" + name + "_" + std::to_string(getpid()))) {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
  }
  ~Scratch() { std::filesystem::remove_all(dir); }
  std::filesystem::path dir;
};

// The first integer of the output matching "<before>(\d+)"; -1 if none.
long Count(const std::string& output, const std::string& before) {
  std::smatch m;
  if (!std::regex_search(output, m, std::regex(before + "(\\d+)"))) return -1;
  return std::stol(m[1]);
}

size_t LineCount(const std::filesystem::path& path) {
  std::ifstream f(path);
  size_t n = 0;
  for (std::string line; std::getline(f, line);) ++n;
  return n;
}

// Handles the test's subscriptions (and drains the process's output, so
// its pipe never fills) until `done` or the timeout.
bool WaitFor(Transport& transport, Subprocess& proc, double timeout_s, const std::function<bool()>& done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < deadline) {
    transport.Handle(50);
    proc.Drain();
    if (done()) return true;
  }
  return false;
}

// crosssite_ba's good pair (sites 1 -> 2) and a corrupt message whose
// BAD_INPUT reply names a chosen site: the flood's pacing marker.
struct TiePairs {
  TiePairs() {
    const NavcamModel navcam = LoadOptionsFile<NavcamModel>("config/navcam.yaml");
    previous = MakePose(3.0, -1.0, 0.2, 0.02, -0.01, 0.3);
    current = previous * MakePose(10.0, 0.5, 0.1, 0.01, 0.02, 0.05);
    SyntheticTiePointOptions so;
    so.seed = 21;
    SyntheticTiePoints syn =
        MakeSyntheticTiePoints(navcam, previous, current, current * MakePose(0.6, -0.7, 0.1, 0.0, 0.01, 0.05), so);
    good = TiePointsToMessage(syn.set);
    corrupt = good;
    corrupt.points[0].observations[0].pair_index = 99;
  }
  tie_points_t Marker(int site) const {
    tie_points_t m = corrupt;
    m.previous_site_id = site - 1;
    m.current_site_id = site;
    return m;
  }
  Pose3 previous, current;
  tie_points_t good, corrupt;
};

TEST(CrossSiteBaBounds, AFloodOfSitePoseDrIdsKeepsTheNewestSitesAndABoundedStateFile) {
  const Scratch scratch("crosssite");
  const std::string url = TestLcmUrl(7621);
  const std::filesystem::path state = scratch.dir / "crosssite_ba.state";
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  std::vector<localization_t> replies;
  Subscribe<localization_t>(*transport, "SITE_POSE_VISUAL",
                            [&](const std::string&, const localization_t& m) { replies.push_back(m); }, 100000);
  const TiePairs pairs;
  const auto reply_for = [&](int site) {
    return [&replies, site] { return !replies.empty() && replies.back().site_id == site; };
  };
  const std::vector<std::string> argv = {BinPath("crosssite_ba"), "--config", "config/procs/crosssite_ba.yaml",
                                         "--state-dir", scratch.dir.string(), "--lcm-url", url};
  double before_mb = 0;
  {
    Subprocess proc(argv);
    ASSERT_TRUE(proc.WaitForOutput("waiting for TIE_POINTS", 30)) << proc.output();
    Publish(*transport, "TIE_POINTS", pairs.good);
    ASSERT_TRUE(WaitFor(*transport, proc, 60, reply_for(2))) << proc.output();
    ASSERT_EQ(int(replies.back().status), int(localization_t::STATUS_OK)) << replies.back().message;
    before_mb = ProcStatusMb(proc.pid(), "VmRSS:");

    // 100,000 site ids (1000 ..) on SITE_POSE_DR, in batches of 500 (below
    // the queue, 1,000) each followed by a corrupt TIE_POINTS whose reply
    // names the batch.
    constexpr int kBatch = 500, kBatches = 200;
    PoseWithCovariance pose;
    pose.covariance = Matrix6d::Identity() * 0.01;
    for (int b = 0; b < kBatches; ++b) {
      for (int i = 0; i < kBatch; ++i) {
        pose.pose = MakePose(0.01 * i, 0, 0, 0, 0, 0.001 * b);
        ASSERT_TRUE(Publish(*transport, "SITE_POSE_DR",
                            SitePoseToMessage(1000 + b * kBatch + i, site_pose_t::SOURCE_DEAD_RECKONING, pose)));
      }
      Publish(*transport, "TIE_POINTS", pairs.Marker(1000 + (b + 1) * kBatch));
      ASSERT_TRUE(WaitFor(*transport, proc, 60, reply_for(1000 + (b + 1) * kBatch))) << proc.output().substr(0, 4000);
      EXPECT_EQ(int(replies.back().status), int(localization_t::STATUS_BAD_INPUT)) << replies.back().message;
      // Bounded at every step: at most 4 site_window + 16 lines (it was one
      // line per site, rewritten whole for every message).
      ASSERT_LE(LineCount(state), 4 * 1000u + 16);
    }
    // The good pair again after the flood: localised (its sites' DR poses
    // left the window: the message's motion serves).
    Publish(*transport, "TIE_POINTS", pairs.good);
    const size_t before = replies.size();
    ASSERT_TRUE(WaitFor(*transport, proc, 60, [&] { return replies.size() > before && replies.back().site_id == 2; }))
        << proc.output();
    EXPECT_EQ(int(replies.back().status), int(localization_t::STATUS_OK)) << replies.back().message;
    EXPECT_LT((PoseFromMessage(replies.back().pose).pose.translation() - pairs.current.translation()).norm(), 0.1);
    const double after_mb = ProcStatusMb(proc.pid(), "VmRSS:");
    std::printf("crosssite_ba resident memory: %.0f MB before 100,000 SITE_POSE_DR site ids, %.0f MB after; "
                "state file %zu lines, %.1f MB\n",
                before_mb, after_mb, LineCount(state), std::filesystem::file_size(state) / 1e6);
    EXPECT_LT(after_mb, before_mb + 15);  // 100,000 kept poses alone are ~45 MB

    proc.Signal(SIGTERM);
    ASSERT_EQ(proc.WaitExit(30), 0) << proc.output();
    const std::string& out = proc.output();
    EXPECT_NE(out.find("poses kept for 1000 DR / "), std::string::npos) << out.substr(out.size() - 2000);
    EXPECT_NE(out.find("kept the newest 1000 sites (site_window)"), std::string::npos);
    EXPECT_NE(out.find("dropped (queue full) 0"), std::string::npos) << out.substr(out.size() - 2000);
  }

  // A restart reloads the newest 1000 sites, also when the last appended
  // line was cut short by a crash.
  std::ofstream(state, std::ios::app) << "dr 123456 17 0.5";
  Subprocess proc(argv);
  ASSERT_TRUE(proc.WaitForOutput("waiting for TIE_POINTS", 30)) << proc.output();
  EXPECT_NE(proc.output().find("is cut short"), std::string::npos) << proc.output();
  EXPECT_EQ(Count(proc.output(), "dead reckoning of "), 1000) << proc.output();
  EXPECT_LE(LineCount(state), 2 * 1000u);  // rewritten whole on start
  proc.Signal(SIGTERM);
  ASSERT_EQ(proc.WaitExit(30), 0) << proc.output();
}

// dead_reckoning aligned on still IMU samples and its site 0 reported.
struct AlignedDeadReckoning {
  explicit AlignedDeadReckoning(int port)
      : url(TestLcmUrl(port)),
        proc({BinPath("dead_reckoning"), "--config", "config/procs/dead_reckoning.yaml", "--lcm-url", url}) {}
  void Start() {
    ASSERT_TRUE(proc.WaitForOutput(kReadyLine, 30)) << proc.output();
    std::string error;
    transport = MakeLcmTransport(url, &error);
    ASSERT_TRUE(transport) << error;
    for (int k = 0; k < 200; ++k) Imu(10'000);  // 2 s still: aligned
    Publish(*transport, "ROVER_SITE", SiteEventToMessage({t, 0, SiteEventType::kArrived, 7}));
    ASSERT_TRUE(Handled("site 0: dead-reckoning pose")) << proc.output();
  }
  void Imu(int64_t step_us) {
    t += step_us;
    ImuSample s;
    s.utime = t;
    s.linear_acceleration = Eigen::Vector3d(0, 0, 1.62);
    Publish(*transport, "IMU", ImuToMessage(s));
  }
  // Waits (draining the output) for `text` after what was already handled.
  bool Handled(const std::string& text) {
    const size_t at = proc.WaitForOutputAfter(text, handled_at, 60);
    if (at == std::string::npos) return false;
    handled_at = at;
    return true;
  }
  // A refusal line naming `k` (an arrival far beyond the newest site: a
  // corrupt id): what was sent before it has been handled.
  bool Mark(int k) {
    const int corrupt = 100'000'000 + k;
    Publish(*transport, "ROVER_SITE", SiteEventToMessage({t, corrupt, SiteEventType::kArrived, 7}));
    return Handled("arrival at site " + std::to_string(corrupt) + " is more than");
  }
  std::string url;
  Subprocess proc;
  std::unique_ptr<Transport> transport;
  int64_t t = 1'000'000;
  size_t handled_at = 0;
};

TEST(DeadReckoningBounds, FloodsOfSiteIdsImuAndWheelSamplesStayBounded) {
  AlignedDeadReckoning dr(7622);
  ASSERT_NO_FATAL_FAILURE(dr.Start());
  const double before_mb = ProcStatusMb(dr.proc.pid(), "VmRSS:");

  // ROVER_SITE: 50,000 new site ids in batches of 1,000 (each reported),
  // then 1,000 repeats inside the window and 1,000 ids older than it.
  constexpr int kSites = 50'000;
  for (int site = 1; site <= kSites; ++site) {
    Publish(*dr.transport, "ROVER_SITE", SiteEventToMessage({dr.t, site, SiteEventType::kArrived, 7}));
    if (site % 1000 == 0) {
      ASSERT_TRUE(dr.Handled("site " + std::to_string(site) + ": dead-reckoning pose"));
    }
  }
  for (int site = kSites - 999; site <= kSites; ++site)
    Publish(*dr.transport, "ROVER_SITE", SiteEventToMessage({dr.t, site, SiteEventType::kArrived, 7}));
  for (int site = 1; site <= 1000; ++site)
    Publish(*dr.transport, "ROVER_SITE", SiteEventToMessage({dr.t, site, SiteEventType::kArrived, 7}));
  ASSERT_TRUE(dr.Mark(0)) << dr.proc.output().substr(dr.handled_at);
  const double sites_mb = ProcStatusMb(dr.proc.pid(), "VmRSS:");

  // IMU: 300,000 still samples 1 us apart (0.3 s of message time), in
  // batches of 10,000.
  for (int k = 1; k <= 300'000; ++k) {
    dr.Imu(1);
    if (k % 10'000 == 0) {
      ASSERT_TRUE(dr.Mark(k)) << dr.proc.output().substr(dr.handled_at);
    }
  }
  const double imu_mb = ProcStatusMb(dr.proc.pid(), "VmRSS:");

  // WHEEL_ODOM: 300,000 samples 1 us apart ahead of the IMU (they wait for it).
  const int64_t wheel_start = dr.t;
  for (int k = 1; k <= 300'000; ++k) {
    Publish(*dr.transport, "WHEEL_ODOM", WheelOdometryToMessage({wheel_start + k, 0.0, 0.0}));
    if (k % 10'000 == 0) {
      ASSERT_TRUE(dr.Mark(300'000 + k)) << dr.proc.output().substr(dr.handled_at);
    }
  }
  const double wheel_mb = ProcStatusMb(dr.proc.pid(), "VmRSS:");
  // The IMU catches up: the waiting wheel samples are integrated, and the
  // next arrival is reported.
  for (int k = 0; k < 100; ++k) dr.Imu(10'000);
  Publish(*dr.transport, "ROVER_SITE", SiteEventToMessage({dr.t, kSites + 1, SiteEventType::kArrived, 7}));
  ASSERT_TRUE(dr.Handled("site " + std::to_string(kSites + 1) + ": dead-reckoning pose"))
      << dr.proc.output().substr(dr.handled_at);
  std::printf("dead_reckoning resident memory: %.0f MB aligned; %.0f MB after 52,000 ROVER_SITE arrivals, "
              "%.0f MB after 300,000 IMU samples 1 us apart, %.0f MB after 300,000 WHEEL_ODOM samples\n",
              before_mb, sites_mb, imu_mb, wheel_mb);
  EXPECT_LT(sites_mb, before_mb + 5);
  EXPECT_LT(imu_mb, before_mb + 15);
  EXPECT_LT(wheel_mb, before_mb + 15);

  dr.proc.Signal(SIGTERM);
  ASSERT_EQ(dr.proc.WaitExit(30), 0) << dr.proc.output();
  const std::string& out = dr.proc.output();
  EXPECT_EQ(Count(out, "duplicate arrivals "), 2000) << out.substr(out.size() - 2000);
  EXPECT_EQ(Count(out, "poses, "), kSites + 2) << out.substr(out.size() - 2000);  // "... N site poses"
  EXPECT_NE(out.find("dropped (queue full) 0"), std::string::npos) << out.substr(out.size() - 2000);
}

}  // namespace
}  // namespace vloc
