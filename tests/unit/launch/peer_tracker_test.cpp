// PeerTracker on a fake clock: a launcher joins, falls silent past
// lost_after_s and is LOST once, comes back, restarts; another host's
// process that is killed and restarted is named with its new pid.

#include <gtest/gtest.h>

#include "vloc/launch/peer_tracker.h"

namespace vloc {
namespace {

using Clock = PeerTracker::Clock;

PeerReport Report(const std::string& host, int pid, pid_t proc_pid, int restarts,
                  ProcState state = ProcState::kRunning) {
  PeerReport r;
  r.host = host;
  r.launcher_pid = pid;
  ProcessStatus s;
  s.name = "dead_reckoning";
  s.pid = proc_pid;
  s.state = state;
  s.restarts = restarts;
  r.procs.push_back(s);
  return r;
}

std::vector<PeerEventKind> Kinds(const std::vector<PeerEvent>& events) {
  std::vector<PeerEventKind> kinds;
  for (const auto& e : events) kinds.push_back(e.kind);
  return kinds;
}

TEST(PeerTracker, LostAfterSilenceBackWhenHeardAgain) {
  PeerTrackerOptions options;
  options.lost_after_s = 3.0;
  ASSERT_TRUE(options.Check(nullptr));
  PeerTracker peers("ground", 100, options);
  const Clock::time_point t0{};
  auto at = [&](double s) { return t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s)); };

  // Its own reports are not a peer.
  EXPECT_TRUE(peers.OnReport(Report("ground", 100, 5, 0), at(0)).empty());
  auto events = peers.OnReport(Report("vehicle", 200, 7, 0), at(0));
  ASSERT_EQ(Kinds(events), std::vector<PeerEventKind>{PeerEventKind::kJoined});
  EXPECT_NE(events[0].text.find("launcher 'vehicle' (pid 200) joined with 1 processes"), std::string::npos);
  for (double t = 1; t <= 4; t += 1) EXPECT_TRUE(peers.OnReport(Report("vehicle", 200, 7, 0), at(t)).empty());
  EXPECT_TRUE(peers.Check(at(6.9)).empty());  // 2.9 s of silence

  events = peers.Check(at(7.0));
  ASSERT_EQ(Kinds(events), std::vector<PeerEventKind>{PeerEventKind::kLost});
  EXPECT_NE(events[0].text.find("launcher 'vehicle' (pid 200) LOST: no report for 3.00 s"), std::string::npos)
      << events[0].text;
  EXPECT_NE(events[0].text.find("last seen running: dead_reckoning"), std::string::npos) << events[0].text;
  EXPECT_TRUE(peers.Check(at(9.0)).empty());  // reported once
  auto views = peers.Peers(at(9.0));
  ASSERT_EQ(views.size(), 1u);
  EXPECT_TRUE(views[0].lost);
  EXPECT_DOUBLE_EQ(views[0].seconds_since_heard, 5.0);
  EXPECT_EQ(views[0].times_lost, 1);

  // Back, with its process killed and restarted by its own launcher meanwhile.
  events = peers.OnReport(Report("vehicle", 200, 8, 1), at(12.0));
  ASSERT_EQ(Kinds(events), (std::vector<PeerEventKind>{PeerEventKind::kBack, PeerEventKind::kProcessChanged}));
  EXPECT_NE(events[0].text.find("back after 8.00 s without a report (lost for 5.00 s)"), std::string::npos)
      << events[0].text;
  EXPECT_EQ(events[1].process, "dead_reckoning");
  EXPECT_NE(events[1].text.find("'dead_reckoning' RUNNING -> RUNNING, pid 7 -> 8, restarts 1"), std::string::npos)
      << events[1].text;
  EXPECT_FALSE(peers.Peers(at(12.0))[0].lost);

  // A state change, then the launcher itself restarted.
  events = peers.OnReport(Report("vehicle", 200, 0, 1, ProcState::kBackoff), at(13.0));
  ASSERT_EQ(Kinds(events), std::vector<PeerEventKind>{PeerEventKind::kProcessChanged});
  EXPECT_NE(events[0].text.find("RUNNING -> BACKOFF, pid 8 -> 0"), std::string::npos) << events[0].text;
  // A second live launcher under the same name: said once, not as a restart.
  events = peers.OnReport(Report("vehicle", 201, 9, 0), at(14.0));
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events[0].kind, PeerEventKind::kDuplicateHost);
  EXPECT_NE(events[0].text.find("two launchers call themselves 'vehicle' (pids 200 and 201)"), std::string::npos)
      << events[0].text;
  peers.OnReport(Report("vehicle", 200, 9, 0), at(14.5));
  for (const auto& e : peers.OnReport(Report("vehicle", 201, 9, 0), at(15.0)))
    EXPECT_NE(e.kind, PeerEventKind::kDuplicateHost);
  // The launcher restarted: the old pid silent for lost_after_s first.
  events = peers.OnReport(Report("vehicle", 202, 9, 0), at(19.0));
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().kind, PeerEventKind::kLauncherRestarted);
  EXPECT_NE(events.back().text.find("pid 201 -> 202"), std::string::npos) << events.back().text;
  // Another launcher with this launcher's own name.
  events = peers.OnReport(Report("ground", 300, 1, 0), at(20.0));
  ASSERT_EQ(Kinds(events), std::vector<PeerEventKind>{PeerEventKind::kDuplicateHost});
  EXPECT_NE(events[0].text.find("also calls itself 'ground'"), std::string::npos);
}

TEST(PeerTracker, OptionsCheckRejectsNonPositive) {
  PeerTrackerOptions options;
  std::string error;
  options.lost_after_s = 0.0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_EQ(error, "lost_after_s = 0: must be > 0 and finite");
}

}  // namespace
}  // namespace vloc
