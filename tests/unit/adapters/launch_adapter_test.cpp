// vloc_launch's adapter in-process over MockTransport, over a Supervisor
// that is never stepped (an order changes what is asked of a process; no
// child is started): which PROCMAN_ORDERS it obeys (its host or every host,
// known actions, printable names, not while shutting down, not another
// host's part of a split group), and what it publishes on PROCMAN_STATUS and
// PROCMAN_PEERS (its processes; the other launchers it hears, not itself).
#include <gtest/gtest.h>

#include <string>

#include "launch_adapter.h"
#include "launch_run.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"

namespace vloc {
namespace {

ProcessSpec Spec(const std::string& name, const std::string& group, const std::string& host = "") {
  ProcessSpec p;
  p.name = name;
  p.command = "/bin/true";
  p.group = group;
  p.host = host;
  return p;
}

// Processes a, b (group g) on host "rover", c (group g) on host "ground".
GroupFile SplitFile() {
  GroupFile f;
  f.path = "split.yaml";
  f.processes = {Spec("a", "g", "rover"), Spec("b", "g", "rover"), Spec("c", "g", "ground")};
  return f;
}

GroupFile RoverPart() {
  GroupFile f = SplitFile();
  f.processes.pop_back();
  return f;
}

struct Launcher {
  MockTransport bus;
  GroupFile whole = SplitFile();
  Supervisor supervisor{RoverPart(), {}};
  LaunchLcmAdapter adapter{supervisor, bus, "rover", /*status_period_s=*/3600, {}, &whole};
  Launcher() { adapter.Subscribe(); }

  void Order(const std::string& host, const std::string& target, int8_t action,
             int8_t kind = procman_order_t::TARGET_PROCESS) {
    procman_order_t o{};
    o.host = host;
    o.target = target;
    o.action = action;
    o.target_kind = kind;
    ASSERT_TRUE(Publish(bus, kProcmanOrdersChannel, o));
    bus.HandleAll();
  }
  ProcState State(const std::string& name) {
    for (const ProcessStatus& s : supervisor.Status())
      if (s.name == name) return s.state;
    ADD_FAILURE() << "no process " << name;
    return ProcState::kGaveUp;
  }
  template <class Msg>
  Msg Last(const std::string& channel) {
    Msg msg;
    const std::vector<uint8_t>* bytes = bus.Last(channel);
    EXPECT_TRUE(bytes && Decode(bytes->data(), bytes->size(), &msg)) << channel;
    return msg;
  }
};

TEST(LaunchAdapter, ObeysOrdersForItsHostOrEveryHost) {
  Launcher l;
  l.Order("ground", "a", procman_order_t::ACTION_START);
  EXPECT_EQ(l.State("a"), ProcState::kStopped) << "another host's order";
  l.Order("rover", "a", procman_order_t::ACTION_START);
  EXPECT_EQ(l.State("a"), ProcState::kStarting);
  EXPECT_EQ(l.State("b"), ProcState::kStopped);
  l.Order("", "g", procman_order_t::ACTION_START, procman_order_t::TARGET_GROUP);
  EXPECT_EQ(l.State("b"), ProcState::kStarting) << "an order for every host";
  l.Order("rover", "a", procman_order_t::ACTION_STOP);
  EXPECT_EQ(l.State("a"), ProcState::kStopped) << "a process never spawned stops at once";
}

TEST(LaunchAdapter, RefusesOrdersItCannotReadAndAllOnceShuttingDown) {
  Launcher l;
  l.Order("rover", "a", /*action=*/7);
  l.Order("rover", "a", procman_order_t::ACTION_START, /*kind=*/9);
  l.Order("rover", "a\nb", procman_order_t::ACTION_START);
  l.Order("rover", "nobody", procman_order_t::ACTION_START);
  EXPECT_EQ(l.State("a"), ProcState::kStopped);
  EXPECT_EQ(l.State("b"), ProcState::kStopped);
  l.adapter.SetShuttingDown();
  l.Order("rover", "a", procman_order_t::ACTION_START);
  EXPECT_EQ(l.State("a"), ProcState::kStopped) << "orders are ignored while shutting down";
}

TEST(LaunchAdapter, LeavesAnotherHostsPartOfASplitGroupToItsLauncher) {
  Launcher l;
  l.Order("", "c", procman_order_t::ACTION_START);  // ground's process: not an error here, nothing done
  EXPECT_EQ(l.State("a"), ProcState::kStopped);
  EXPECT_EQ(l.State("b"), ProcState::kStopped);
  l.Order("", "g", procman_order_t::ACTION_START, procman_order_t::TARGET_GROUP);
  EXPECT_EQ(l.State("a"), ProcState::kStarting) << "this host's part of the group";
  EXPECT_EQ(l.State("b"), ProcState::kStarting);
}

TEST(LaunchAdapter, PublishesItsProcessesAndThePeersItHearsOnTick) {
  Launcher l;
  l.Order("rover", "a", procman_order_t::ACTION_START);
  l.adapter.Tick();  // the first tick reports at once
  ASSERT_EQ(l.bus.Count(kProcmanStatusChannel), 1);
  const auto status = l.Last<procman_status_t>(kProcmanStatusChannel);
  EXPECT_EQ(status.host, "rover");
  ASSERT_EQ(status.num_procs, 2);
  EXPECT_EQ(status.procs[0].name, "a");
  EXPECT_EQ(status.procs[0].state, +proc_status_t::STATE_STARTING);
  EXPECT_EQ(status.procs[1].state, +proc_status_t::STATE_STOPPED);
  l.bus.HandleAll();  // it hears its own status: not a peer
  EXPECT_EQ(l.Last<procman_peers_t>(kProcmanPeersChannel).num_peers, 0);
  l.adapter.Tick();
  EXPECT_EQ(l.bus.Count(kProcmanStatusChannel), 1) << "not again before the period";

  procman_status_t ground{};
  ground.host = "ground";
  ground.launcher_pid = 4242;
  proc_status_t c{};
  c.name = "c";
  c.group = "g";
  c.state = proc_status_t::STATE_RUNNING;
  ground.procs.push_back(c);
  ground.num_procs = 1;
  ASSERT_TRUE(Publish(l.bus, kProcmanStatusChannel, ground));
  l.bus.HandleAll();
  l.Order("rover", "b", procman_order_t::ACTION_START);  // an order asks for a report on the next tick
  l.adapter.Tick();
  EXPECT_EQ(l.bus.Count(kProcmanStatusChannel), 3);
  const auto peers = l.Last<procman_peers_t>(kProcmanPeersChannel);
  ASSERT_EQ(peers.num_peers, 1);
  EXPECT_EQ(peers.peers[0].host, "ground");
  EXPECT_EQ(peers.peers[0].launcher_pid, 4242);
  EXPECT_EQ(peers.peers[0].state, +procman_peer_t::STATE_ALIVE);
}

ProcessSpec Shell(const std::string& name, const std::string& script, bool done) {
  ProcessSpec p = Spec(name, "g");
  p.command = "/bin/sh";
  p.args = {"-c", script};
  p.max_restarts = 0;
  p.stop_timeout = 2.0;
  p.exit_when_done = done;
  return p;
}

// RunLauncher with --exit-when-done over `done` (ends by itself) and a
// sleeper; returns its exit code and the final status it published.
int RunUntilDone(const std::string& done_script, procman_status_t* final_status) {
  MockTransport bus;
  GroupFile file;
  file.path = "done.yaml";
  file.processes = {Shell("done", done_script, true), Shell("sleeper", "exec sleep 30", false)};
  Supervisor supervisor(file, {});
  std::string error;
  EXPECT_TRUE(supervisor.StartGroups({}, &error)) << error;
  LaunchLcmAdapter adapter(supervisor, bus, "rover", 3600);
  adapter.Subscribe();
  LaunchRunOptions run{true, supervisor.ExitWhenDoneNames(), 0.0};
  const int rc = RunLauncher(bus, supervisor, adapter, run);
  EXPECT_TRUE(supervisor.AllStopped());
  EXPECT_TRUE(supervisor.LivePids().empty());
  const std::vector<uint8_t>* bytes = bus.Last(kProcmanStatusChannel);
  EXPECT_TRUE(bytes && Decode(bytes->data(), bytes->size(), final_status));
  return rc;
}

TEST(LaunchAdapter, ExitWhenDoneStopsTheRestAndReportsTheOutcome) {
  procman_status_t last{};
  EXPECT_EQ(RunUntilDone("exit 0", &last), 0);
  ASSERT_EQ(last.num_procs, 2);
  for (const proc_status_t& p : last.procs) EXPECT_EQ(p.pid, 0) << p.name << ": the last status shows it ended";
  EXPECT_EQ(RunUntilDone("exit 3", &last), 1) << "a done process that failed";
}

}  // namespace
}  // namespace vloc
