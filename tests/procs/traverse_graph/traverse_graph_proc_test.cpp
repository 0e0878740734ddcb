// traverse_graph over real LCM (ports 7780-7781, 7785, 7789): dead-reckoning and
// visual site poses in, TRAVERSE out with the visual poses winning; a
// restarted process reloads its graph and continues; a revisit (a BA result
// between non-adjacent sites) closes the loop.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/localization_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/posegraph/graph_io.h"
#include "vloc/testing/subprocess.h"
#include "vloc/traverse_t.hpp"

namespace vloc {
namespace {

using testing::BinPath;
using testing::Subprocess;
using testing::TestLcmUrl;

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

bool WaitFor(Transport& transport, double timeout_s, const std::function<bool()>& done) {
  const double deadline = Now() + timeout_s;
  while (Now() < deadline) {
    transport.Handle(100);
    if (done()) return true;
  }
  return false;
}

Matrix6d Diag(double p, double r) {
  Vector6d d;
  d << p * p, p * p, p * p, r * r, r * r, r * r;
  return d.asDiagonal();
}

// Truth: sites 10 m apart along x. DR drifts 0.5 m to the left per site.
Pose3 Truth(int i) { return MakePose(10.0 * i, 0, 0, 0, 0, 0); }
Pose3 Dr(int i) { return MakePose(10.0 * i, 0.5 * i, 0, 0, 0, 0); }

site_pose_t DrMessage(int i) {
  PoseWithCovariance p;
  p.pose = Dr(i);
  p.utime = 1000000LL * (i + 1);
  p.covariance = Diag(0.5 * i + 0.01, 0.01 * i + 0.001);
  return SitePoseToMessage(i, site_pose_t::SOURCE_DEAD_RECKONING, p);
}

localization_t VisualMessage(int i) {
  localization_t m{};
  m.utime = 1000000LL * (i + 1);
  m.site_id = i;
  m.reference_site_id = i - 1;
  m.status = localization_t::STATUS_OK;
  m.message = "ok";
  PoseWithCovariance rel;
  rel.pose = Truth(i - 1).inverse() * Truth(i);
  rel.covariance = Diag(0.01, 0.0005);
  m.relative_pose = PoseToMessage(rel, "body", "body");
  PoseWithCovariance abs;
  abs.pose = Truth(i);
  m.pose = PoseToMessage(abs, "world", "body");
  return m;
}

// The shipped config with graph_path set to `graph_path_yaml` (a YAML value), written to `config`.
void WriteConfig(const std::string& config, const std::string& graph_path_yaml) {
  std::ifstream in("config/procs/traverse_graph.yaml");
  std::ofstream out(config);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("graph_path:", 0) == 0) line = "graph_path: " + graph_path_yaml;
    out << line << "\n";
  }
}

// Sites 0..n-1: each site's DR pose, then (from site 1 on) its visual pose,
// each waited for in a TRAVERSE.
void PublishSites(Transport& transport, int n, const std::vector<traverse_t>& received, const Subprocess& proc) {
  for (int i = 0; i < n; ++i) {
    Publish(transport, "SITE_POSE_DR", DrMessage(i));
    ASSERT_TRUE(WaitFor(transport, 10, [&] { return !received.empty() && received.back().num_sites == i + 1; }))
        << proc.output();
    if (i == 0) continue;
    const size_t before = received.size();
    Publish(transport, "SITE_POSE_VISUAL", VisualMessage(i));
    ASSERT_TRUE(WaitFor(transport, 10, [&] { return received.size() > before; })) << proc.output();
  }
}

TEST(TraverseGraphProcess, OptimisesPublishesSavesAndReloads) {
  const std::string url = TestLcmUrl(7780);
  const auto dir = std::filesystem::temp_directory_path() / "vloc_traverse_graph_proc_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string graph_path = (dir / "traverse.graph").string();
  const std::string config = (dir / "traverse_graph.yaml").string();
  WriteConfig(config, graph_path);
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  std::vector<traverse_t> received;
  Subscribe<traverse_t>(*transport, "TRAVERSE", [&](const std::string&, const traverse_t& m) { received.push_back(m); });
  {
    Subprocess proc({BinPath("traverse_graph"), "--config", config, "--lcm-url", url});
    ASSERT_TRUE(proc.WaitForOutput("waiting for", 30)) << proc.output();
    ASSERT_NO_FATAL_FAILURE(PublishSites(*transport, 4, received, proc));
    // A failed BA result adds nothing.
    localization_t failed = VisualMessage(3);
    failed.status = localization_t::STATUS_TOO_FEW_POINTS;
    Publish(*transport, "SITE_POSE_VISUAL", failed);
    const traverse_t& t = received.back();
    EXPECT_EQ(t.num_sites, 4);
    EXPECT_EQ(t.num_visual_edges, 3);
    EXPECT_EQ(t.num_edges, 6);
    EXPECT_EQ(t.num_loop_edges, 0);
    EXPECT_EQ(t.utime, 4000000);
    EXPECT_LE(t.final_chi2, t.initial_chi2 + 1e-9);
    for (int i = 0; i < 4; ++i) {
      EXPECT_EQ(t.site_ids[i], i);
      const PoseWithCovariance p = PoseFromMessage(t.poses[i]);
      // Visual edges (1 cm) dominate DR (>= 0.5 m): the optimum is within a few cm of the truth.
      EXPECT_LT((p.pose.translation() - Truth(i).translation()).norm(), 0.05) << i;
      if (i > 0) {
        EXPECT_GT(p.covariance(0, 0), 0.0);
        EXPECT_LT(std::sqrt(p.covariance(1, 1)), 0.1);
      }
    }
    proc.Signal(SIGTERM);
    EXPECT_EQ(proc.WaitExit(20), 0) << proc.output();
  }
  ASSERT_TRUE(std::filesystem::exists(graph_path));
  // Restart: the graph comes back and the next site continues it.
  received.clear();
  Subprocess proc({BinPath("traverse_graph"), "--config", config, "--lcm-url", url});
  ASSERT_TRUE(proc.WaitForOutput("waiting for", 30)) << proc.output();
  EXPECT_NE(proc.output().find("reloaded"), std::string::npos) << proc.output();
  Publish(*transport, "SITE_POSE_DR", DrMessage(4));
  ASSERT_TRUE(WaitFor(*transport, 10, [&] { return !received.empty() && received.back().num_sites == 5; }))
      << proc.output();
  EXPECT_EQ(received.back().num_visual_edges, 3);
  const PoseWithCovariance p3 = PoseFromMessage(received.back().poses[3]);
  EXPECT_LT((p3.pose.translation() - Truth(3).translation()).norm(), 0.05);
  // Site 4 = optimised site 3 + DR motion 3->4.
  const PoseWithCovariance p4 = PoseFromMessage(received.back().poses[4]);
  EXPECT_LT((p4.pose.translation() - (p3.pose * (Dr(3).inverse() * Dr(4))).translation()).norm(), 0.05);
  // Site 0 again: a new traverse starts, the old graph is set aside.
  Publish(*transport, "SITE_POSE_DR", DrMessage(0));
  ASSERT_TRUE(WaitFor(*transport, 10, [&] { return received.back().num_sites == 1; })) << proc.output();
  EXPECT_TRUE(std::filesystem::exists(graph_path + ".previous"));
  proc.Signal(SIGTERM);
  EXPECT_EQ(proc.WaitExit(20), 0) << proc.output();
  std::filesystem::remove_all(dir);
}

// graph_path ending in .g2o: the process saves its graph as a 3D g2o file
// (which vloc_posegraph and g2o read) and reloads it on restart.
TEST(TraverseGraphProcess, SavesAndReloadsItsGraphInG2o) {
  const std::string url = TestLcmUrl(7789);
  const auto dir = std::filesystem::temp_directory_path() / "vloc_traverse_graph_g2o_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string graph_path = (dir / "traverse.g2o").string();
  const std::string config = (dir / "traverse_graph.yaml").string();
  WriteConfig(config, graph_path);
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  std::vector<traverse_t> received;
  Subscribe<traverse_t>(*transport, "TRAVERSE", [&](const std::string&, const traverse_t& m) { received.push_back(m); });
  {
    Subprocess proc({BinPath("traverse_graph"), "--config", config, "--lcm-url", url});
    ASSERT_TRUE(proc.WaitForOutput("waiting for", 30)) << proc.output();
    ASSERT_NO_FATAL_FAILURE(PublishSites(*transport, 3, received, proc));
    proc.Signal(SIGTERM);
    EXPECT_EQ(proc.WaitExit(20), 0) << proc.output();
  }
  const traverse_t before_restart = received.back();
  posegraph::GraphFile file;
  ASSERT_TRUE(posegraph::ReadGraphFile(graph_path, &file, &error)) << error;
  EXPECT_EQ(file.format, posegraph::GraphFormat::kG2o);
  EXPECT_EQ(file.dimension, 3);
  EXPECT_EQ(file.num_nodes(), 3u);
  EXPECT_EQ(file.num_edges(), 4u);  // 2 DR + 2 visual
  received.clear();
  Subprocess proc({BinPath("traverse_graph"), "--config", config, "--lcm-url", url});
  ASSERT_TRUE(proc.WaitForOutput("waiting for", 30)) << proc.output();
  EXPECT_NE(proc.output().find("reloaded"), std::string::npos) << proc.output();
  ASSERT_TRUE(WaitFor(*transport, 10, [&] { return !received.empty(); })) << proc.output();
  ASSERT_EQ(received.back().num_sites, 3);
  EXPECT_EQ(received.back().num_visual_edges, 2);
  for (int i = 0; i < 3; ++i) {
    const Pose3 a = PoseFromMessage(received.back().poses[i]).pose, b = PoseFromMessage(before_restart.poses[i]).pose;
    EXPECT_LT((a.translation() - b.translation()).norm(), 1e-6) << i;
  }
  proc.Signal(SIGTERM);
  EXPECT_EQ(proc.WaitExit(20), 0) << proc.output();
  std::filesystem::remove_all(dir);
}

// The revisit as crosssite_ba publishes it: site 6 is back at site 2's place
// (sim_rover --revisit 2); sites 1-2 are localized visually (1 cm), 3-6 by
// dead reckoning only, which drifts 0.5 m left per site. The BA result 2 -> 6
// (identity, 1 cm) becomes a loop edge and pulls site 6 to site 2.
TEST(TraverseGraphProcess, RevisitOfAnEarlierSiteClosesTheLoop) {
  const std::string url = TestLcmUrl(7785);
  const auto dir = std::filesystem::temp_directory_path() / "vloc_traverse_graph_revisit_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string config = (dir / "traverse_graph.yaml").string();
  WriteConfig(config, "\"\"");
  auto truth = [](int i) { return i == 6 ? Truth(2) : MakePose(i <= 4 ? 10.0 * i : 40.0 - 10.0 * (i - 4), i <= 4 ? 0 : 8, 0, 0, 0, 0); };
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  std::vector<traverse_t> received;
  Subscribe<traverse_t>(*transport, "TRAVERSE", [&](const std::string&, const traverse_t& m) { received.push_back(m); });
  Subprocess proc({BinPath("traverse_graph"), "--config", config, "--lcm-url", url});
  ASSERT_TRUE(proc.WaitForOutput("waiting for", 30)) << proc.output();
  for (int i = 0; i <= 6; ++i) {
    PoseWithCovariance dr;
    dr.pose = MakePose(0, 0.5 * i, 0, 0, 0, 0) * truth(i);
    dr.utime = 1000000LL * (i + 1);
    dr.covariance = Diag(0.5 * i + 0.01, 0.01 * i + 0.001);
    Publish(*transport, "SITE_POSE_DR", SitePoseToMessage(i, site_pose_t::SOURCE_DEAD_RECKONING, dr));
    ASSERT_TRUE(WaitFor(*transport, 10, [&] { return !received.empty() && received.back().num_sites == i + 1; }))
        << proc.output();
    if (i == 0 || i > 2) continue;
    localization_t m = VisualMessage(i);
    const size_t before = received.size();
    Publish(*transport, "SITE_POSE_VISUAL", m);
    ASSERT_TRUE(WaitFor(*transport, 10, [&] { return received.size() > before; })) << proc.output();
  }
  auto error_of = [&](int i) {
    return (PoseFromMessage(received.back().poses[i]).pose.translation() - truth(i).translation()).norm();
  };
  const double before = error_of(6);
  localization_t loop = VisualMessage(6);
  loop.reference_site_id = 2;
  PoseWithCovariance rel;
  rel.covariance = Diag(0.01, 0.0005);
  loop.relative_pose = PoseToMessage(rel, "site_2", "site_6");
  const size_t count = received.size();
  Publish(*transport, "SITE_POSE_VISUAL", loop);
  ASSERT_TRUE(WaitFor(*transport, 10, [&] { return received.size() > count; })) << proc.output();
  const traverse_t& t = received.back();
  EXPECT_EQ(t.num_loop_edges, 1);
  EXPECT_EQ(t.num_visual_edges, 3);
  const double after = error_of(6);
  EXPECT_GT(before, 1.0);
  EXPECT_LT(after, error_of(2) + 0.05) << "before " << before;
  EXPECT_LT(after, 0.1);
  proc.Signal(SIGTERM);
  EXPECT_EQ(proc.WaitExit(20), 0) << proc.output();
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vloc
