// traverse_graph's waiting measurements are bounded whatever the bus sends
// (issue 30), over real LCM (port 7623): visual edges from sites not in the
// graph and absolute fixes of such sites waited in a list without bound
// (and each visual one was searched for its repeat); now a repeat replaces
// its copy and at most graph.max_pending (1000) wait, the oldest dropped in
// one line. After the flood the traverse still grows and is published.
// The flood is paced by the process's own line for its last message.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <regex>

#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/localization_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/testing/subprocess.h"
#include "vloc/traverse_t.hpp"

namespace vloc {
namespace {

using testing::BinPath;
using testing::ProcStatusMb;
using testing::Subprocess;
using testing::TestLcmUrl;

localization_t Visual(int reference, int site) {
  localization_t m{};
  m.utime = 1000000LL * (site + 1);
  m.site_id = site;
  m.reference_site_id = reference;
  m.status = localization_t::STATUS_OK;
  m.message = "ok";
  PoseWithCovariance rel;
  rel.pose = MakePose(10.0 * (site - reference), 0, 0, 0, 0, 0);
  rel.covariance = Matrix6d::Identity() * 1e-4;
  m.relative_pose = PoseToMessage(rel, "body", "body");
  m.pose = PoseToMessage(rel, "world", "body");
  return m;
}

site_pose_t Pose(int site) {
  PoseWithCovariance p;
  p.pose = MakePose(10.0 * site, 0, 0, 0, 0, 0);
  p.utime = 1000000LL * (site + 1);
  p.covariance = Matrix6d::Identity() * (0.01 + 0.01 * site);
  return SitePoseToMessage(site, site_pose_t::SOURCE_DEAD_RECKONING, p);
}

TEST(TraverseGraphBounds, AFloodOfWaitingMeasurementsKeepsMaxPending) {
  const std::string url = TestLcmUrl(7623);
  struct Scratch {  // removed when the test ends, failed or not
    Scratch() { std::filesystem::create_directories(dir); }
    ~Scratch() { std::filesystem::remove_all(dir); }
    std::filesystem::path dir =
        std::filesystem::temp_directory_path() / ("vloc_traverse_graph_bounds_" + std::to_string(getpid()));
  } scratch;
  const std::filesystem::path& dir = scratch.dir;
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  std::vector<traverse_t> received;
  Subscribe<traverse_t>(*transport, "TRAVERSE", [&](const std::string&, const traverse_t& m) { received.push_back(m); });
  Subprocess proc({BinPath("traverse_graph"), "--config", "config/procs/traverse_graph.yaml", "--state-dir",
                   dir.string(), "--lcm-url", url});
  ASSERT_TRUE(proc.WaitForOutput("waiting for", 30)) << proc.output();
  const double before_mb = ProcStatusMb(proc.pid(), "VmRSS:");

  // 100,000 visual edges from sites not in the graph (1 -> 2, 3 -> 4, ...),
  // each batch of 200 sent twice (the repeats replace their copies), and
  // 1,000 absolute fixes of such sites; a batch is below the queue (1,000).
  size_t handled_at = 0;  // where the last line waited for starts
  constexpr int kBatch = 200, kBatches = 500;
  for (int b = 0; b < kBatches; ++b) {
    for (int copy = 0; copy < 2; ++copy)
      for (int i = 0; i < kBatch; ++i) {
        const int from = 2 * (b * kBatch + i) + 1;
        Publish(*transport, "SITE_POSE_VISUAL", Visual(from, from + 1));
      }
    // The second copy of the batch's last edge: the process's line for it.
    const int last = 2 * ((b + 1) * kBatch - 1) + 1;
    const std::string line = "->" + std::to_string(last + 1) + ": reference site " + std::to_string(last) + " not in";
    for (int copy = 0; copy < 2; ++copy) {
      handled_at = proc.WaitForOutputAfter(line, handled_at + (copy > 0 ? 1 : 0), 60);
      ASSERT_NE(handled_at, std::string::npos) << proc.output().substr(proc.output().size() - 3000);
    }
  }
  for (int site = 500'001; site <= 501'000; ++site) {
    Publish(*transport, "SITE_POSE_FIX", Pose(site));
    if (site % kBatch != 0) continue;
    handled_at = proc.WaitForOutputAfter("absolute fix of site " + std::to_string(site) + ": ", handled_at, 60);
    ASSERT_NE(handled_at, std::string::npos) << proc.output().substr(proc.output().size() - 3000);
  }
  const double after_mb = ProcStatusMb(proc.pid(), "VmRSS:");

  // The traverse after the flood: sites 0 and 1 (the waiting edges name other sites).
  const auto wait_sites = [&](int n) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (std::chrono::steady_clock::now() < deadline && (received.empty() || received.back().num_sites < n)) {
      transport->Handle(50);
      proc.Drain();
    }
    return !received.empty() && received.back().num_sites == n;
  };
  Publish(*transport, "SITE_POSE_DR", Pose(0));
  ASSERT_TRUE(wait_sites(1)) << proc.output().substr(proc.output().size() - 3000);
  Publish(*transport, "SITE_POSE_DR", Pose(1));
  ASSERT_TRUE(wait_sites(2)) << proc.output().substr(proc.output().size() - 3000);
  std::printf("traverse_graph resident memory: %.0f MB before 100,000 waiting visual edges (each twice) and 1,000 fixes, "
              "%.0f MB after\n", before_mb, after_mb);
  EXPECT_LT(after_mb, before_mb + 10);  // 101,000 waiting measurements are ~45 MB

  proc.Signal(SIGTERM);
  ASSERT_EQ(proc.WaitExit(30), 0) << proc.output().substr(proc.output().size() - 3000);
  const std::string& out = proc.output();
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m, std::regex("last: [^\n]*?, (\\d+) pending"))) << out.substr(out.size() - 3000);
  EXPECT_EQ(std::stoi(m[1]), 1000);
  EXPECT_NE(out.find("more than max_pending 1000 measurements wait"), std::string::npos);
  EXPECT_NE(out.find("dropped (queue full) 0"), std::string::npos) << out.substr(out.size() - 3000);  // no queue overflow
}

}  // namespace
}  // namespace vloc
