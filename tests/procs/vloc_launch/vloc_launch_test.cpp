// vloc_launch as a real process over real LCM (ports 7822-7837), with
// /bin/sh and sleep as its children: starting a group, restarting after
// SIGKILL, giving up, SIGTERM leaving no process, orders over LCM, log
// files, bad group files, --exit-when-done, the grace cut short once the
// rest is idle. Every wait has a timeout.

#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "vloc/launch/proc_stats.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/procman_order_t.hpp"
#include "vloc/procman_peers_t.hpp"
#include "vloc/procman_status_t.hpp"
#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

namespace fs = std::filesystem;
using testing::BinPath;
using testing::ErrorLines;
using testing::Subprocess;
using testing::TestLcmUrl;

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A scratch folder with the group file and the launcher's logs.
struct Scratch {
  explicit Scratch(const std::string& name)
      : dir(::testing::TempDir() + "/vloc_launch_test_" + std::to_string(getpid()) + "_" + name) {
    fs::remove_all(dir);
    fs::create_directories(dir + "/logs");
  }
  std::string WriteGroup(const std::string& text) const {
    const std::string path = dir + "/group.yaml";
    std::ofstream(path) << text;
    return path;
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  Scratch(const Scratch&) = delete;
  Scratch& operator=(const Scratch&) = delete;
  std::string Log(const std::string& name) const { return ReadFile(dir + "/logs/" + name + ".log"); }
  std::string dir;
};

// Keeps the latest PROCMAN_STATUS.
class StatusWatcher {
 public:
  explicit StatusWatcher(const std::string& url) {
    std::string error;
    transport_ = MakeLcmTransport(url, &error);
    EXPECT_TRUE(transport_) << error;
    if (transport_)
      Subscribe<procman_status_t>(*transport_, "PROCMAN_STATUS", [this](const std::string&, const procman_status_t& m) {
        last_ = m;
        ++count_;
      });
  }
  // Waits until a status satisfies `done`.
  bool WaitFor(const std::function<bool(const procman_status_t&)>& done, double timeout_s = 15.0) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < deadline) {
      if (transport_) transport_->Handle(100);
      if (last_ && done(*last_)) return true;
    }
    return false;
  }
  const proc_status_t* Find(const std::string& name) const {
    if (!last_) return nullptr;
    for (const auto& p : last_->procs)
      if (p.name == name) return &p;
    return nullptr;
  }
  // True when `name` is in `state` in the latest status.
  bool Is(const std::string& name, int8_t state) const {
    const proc_status_t* p = Find(name);
    return p && p->state == state;
  }
  void Order(const std::string& target, int8_t kind, int8_t action, const std::string& host = "") {
    procman_order_t order;
    order.utime = 0;
    order.host = host;
    order.target = target;
    order.target_kind = kind;
    order.action = action;
    ASSERT_TRUE(Publish(*transport_, "PROCMAN_ORDERS", order));
  }
  const std::optional<procman_status_t>& last() const { return last_; }
  int count() const { return count_; }

 private:
  std::unique_ptr<Transport> transport_;
  std::optional<procman_status_t> last_;
  int count_ = 0;
};

constexpr int8_t kRunning = proc_status_t::STATE_RUNNING;

Subprocess Launch(const Scratch& scratch, const std::string& group_file, int port,
                  std::vector<std::string> extra = {}) {
  std::vector<std::string> argv = {BinPath("vloc_launch"), "--config", group_file, "--lcm-url", TestLcmUrl(port),
                                   "--log-dir", scratch.dir + "/logs"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  return Subprocess(argv);
}


const char* kTwoSleepers = R"(
group: pair
defaults: {backoff_initial: 0.1, backoff_max: 0.5, stop_timeout: 2}
processes:
  - {name: first, command: sleep, args: ["60"]}
  - {name: second, command: /bin/sh, args: [-c, "exec sleep 60"], depends_on: [first]}
)";

TEST(VlocLaunch, StartsAGroupAndPublishesItsStatus) {
  Scratch scratch("start");
  const int port = 7822;
  StatusWatcher watcher(TestLcmUrl(port));
  Subprocess launcher = Launch(scratch, scratch.WriteGroup(kTwoSleepers), port);
  ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t&) {
    return watcher.Is("first", kRunning) && watcher.Is("second", kRunning);
  })) << launcher.output();
  const procman_status_t& status = *watcher.last();
  EXPECT_EQ(status.launcher_pid, launcher.pid());
  EXPECT_EQ(status.num_procs, 2);
  EXPECT_FALSE(status.host.empty());
  for (const auto& p : status.procs) {
    EXPECT_EQ(p.group, "pair");
    EXPECT_GT(p.pid, 0);
    EXPECT_TRUE(ProcessAlive(p.pid)) << p.name;
    EXPECT_EQ(p.restarts, 0);
  }
  // Reports keep coming, with memory figures.
  const int seen = watcher.count();
  ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t& s) {
    return watcher.count() >= seen + 2 && watcher.Find("first")->rss_bytes > 0;
  }));
  launcher.Signal(SIGTERM);
  EXPECT_EQ(launcher.WaitExit(15), std::optional<int>(0)) << launcher.output();
}

TEST(VlocLaunch, RestartsAProcessKilledWithSigkill) {
  Scratch scratch("sigkill");
  const int port = 7823;
  StatusWatcher watcher(TestLcmUrl(port));
  Subprocess launcher = Launch(scratch, scratch.WriteGroup(kTwoSleepers), port);
  ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t&) { return watcher.Is("second", kRunning); }))
      << launcher.output();
  const int32_t old_pid = watcher.Find("second")->pid;
  ASSERT_EQ(kill(old_pid, SIGKILL), 0);
  ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t&) {
    const proc_status_t* p = watcher.Find("second");
    return p->state == kRunning && p->pid != old_pid && p->pid > 0;
  })) << launcher.output();
  const proc_status_t* p = watcher.Find("second");
  EXPECT_EQ(p->restarts, 1);
  EXPECT_EQ(p->last_exit_code, -SIGKILL);
  EXPECT_EQ(watcher.Find("first")->restarts, 0);
  EXPECT_NE(scratch.Log("second").find("killed by SIGKILL"), std::string::npos) << scratch.Log("second");
  launcher.Signal(SIGTERM);
  EXPECT_EQ(launcher.WaitExit(15), std::optional<int>(0)) << launcher.output();
}

TEST(VlocLaunch, GivesUpAfterItsLimit) {
  Scratch scratch("giveup");
  const int port = 7824;
  StatusWatcher watcher(TestLcmUrl(port));
  Subprocess launcher = Launch(scratch, scratch.WriteGroup(R"(
processes:
  - {name: crasher, command: /bin/sh, args: [-c, "echo failing; exit 7"], max_restarts: 2,
     backoff_initial: 0.05, backoff_max: 0.2}
  - {name: steady, command: sleep, args: ["60"]}
)"),
                               port);
  ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t&) {
    return watcher.Is("crasher", proc_status_t::STATE_GAVE_UP);
  })) << launcher.output();
  const proc_status_t* p = watcher.Find("crasher");
  EXPECT_EQ(p->restarts, 2);
  EXPECT_EQ(p->last_exit_code, 7);
  EXPECT_EQ(p->pid, 0);
  EXPECT_TRUE(watcher.Is("steady", kRunning));
  const std::string log = scratch.Log("crasher");
  size_t runs = 0;
  for (size_t pos = log.find("[crasher] failing"); pos != std::string::npos; pos = log.find("[crasher] failing", pos + 1))
    ++runs;
  EXPECT_EQ(runs, 3u) << log;  // the first run + 2 restarts
  EXPECT_NE(log.find("gave up after 2 restarts"), std::string::npos) << log;
  launcher.Signal(SIGTERM);
  EXPECT_EQ(launcher.WaitExit(15), std::optional<int>(0)) << launcher.output();
}

TEST(VlocLaunch, SigtermStopsEverythingAndLeavesNoProcess) {
  Scratch scratch("sigterm");
  const int port = 7825;
  StatusWatcher watcher(TestLcmUrl(port));
  Subprocess launcher = Launch(scratch, scratch.WriteGroup(R"(
defaults: {stop_timeout: 1.0}
processes:
  - {name: plain, command: sleep, args: ["60"]}
  - {name: parent, command: /bin/sh, args: [-c, "sleep 60 & sleep 60 & echo ready; wait"]}
  - {name: stubborn, command: /bin/sh, args: [-c, "trap '' TERM INT; echo ready; while :; do sleep 0.05; done"],
     stop_signal: SIGINT}
)"),
                               port);
  ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t&) {
    return watcher.Is("plain", kRunning) && watcher.Is("parent", kRunning) && watcher.Is("stubborn", kRunning) &&
           scratch.Log("parent").find("] ready") != std::string::npos &&
           scratch.Log("stubborn").find("] ready") != std::string::npos;
  })) << launcher.output();
  std::set<pid_t> groups;
  for (const auto& p : watcher.last()->procs) groups.insert(p.pid);
  const auto before = ReadProcessGroupUsage();
  EXPECT_EQ(before.at(watcher.Find("parent")->pid).num_processes, 3);  // sh + 2 sleeps

  launcher.Signal(SIGTERM);
  EXPECT_EQ(launcher.WaitExit(20), std::optional<int>(0)) << launcher.output();
  const auto after = ReadProcessGroupUsage();  // live processes only
  for (pid_t g : groups) EXPECT_EQ(after.count(g), 0u) << "process group " << g << " still has processes";
  EXPECT_NE(scratch.Log("stubborn").find("sending SIGKILL"), std::string::npos) << scratch.Log("stubborn");
}

// The safety net: a launcher killed with SIGKILL cannot stop its children,
// but they get SIGTERM from the kernel (PR_SET_PDEATHSIG).
TEST(VlocLaunch, ChildrenEndWhenTheLauncherIsKilled) {
  Scratch scratch("pdeathsig");
  const int port = 7831;
  StatusWatcher watcher(TestLcmUrl(port));
  Subprocess launcher = Launch(scratch, scratch.WriteGroup(kTwoSleepers), port);
  ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t&) {
    return watcher.Is("first", kRunning) && watcher.Is("second", kRunning);
  })) << launcher.output();
  std::vector<pid_t> pids;
  for (const auto& p : watcher.last()->procs) pids.push_back(p.pid);
  launcher.Signal(SIGKILL);
  ASSERT_TRUE(launcher.WaitExit(10).has_value());
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  auto any_alive = [&] {
    for (pid_t pid : pids)
      if (ProcessAlive(pid)) return true;
    return false;
  };
  while (any_alive() && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_FALSE(any_alive());
}

TEST(VlocLaunch, ObeysOrdersSentOverLcm) {
  Scratch scratch("orders");
  const int port = 7826;
  StatusWatcher watcher(TestLcmUrl(port));
  Subprocess launcher = Launch(scratch, scratch.WriteGroup(R"(
defaults: {stop_timeout: 2}
processes:
  - {name: a, group: main, command: sleep, args: ["60"]}
  - {name: b, group: main, command: sleep, args: ["60"]}
  - {name: c, group: extra, command: sleep, args: ["60"]}
)"),
                               port, {"--group", "main"});
  ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t&) {
    return watcher.Is("a", kRunning) && watcher.Is("b", kRunning);
  })) << launcher.output();
  EXPECT_TRUE(watcher.Is("c", proc_status_t::STATE_STOPPED));

  watcher.Order("a", procman_order_t::TARGET_PROCESS, procman_order_t::ACTION_STOP);
  ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t&) { return watcher.Is("a", proc_status_t::STATE_STOPPED); }))
      << launcher.output();
  EXPECT_TRUE(watcher.Is("b", kRunning));

  // An order for another host is ignored; the next one (for every host) is obeyed.
  watcher.Order("a", procman_order_t::TARGET_PROCESS, procman_order_t::ACTION_START, "some-other-host");
  watcher.Order("extra", procman_order_t::TARGET_GROUP, procman_order_t::ACTION_START);
  ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t&) { return watcher.Is("c", kRunning); })) << launcher.output();
  EXPECT_TRUE(watcher.Is("a", proc_status_t::STATE_STOPPED));

  const int32_t b_pid = watcher.Find("b")->pid;
  watcher.Order("main", procman_order_t::TARGET_GROUP, procman_order_t::ACTION_RESTART);
  ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t&) {
    return watcher.Is("a", kRunning) && watcher.Is("b", kRunning) && watcher.Find("b")->pid != b_pid;
  })) << launcher.output();
  EXPECT_EQ(watcher.Find("b")->restarts, 0);  // ordered restarts are not counted as crashes
  launcher.Signal(SIGINT);
  EXPECT_EQ(launcher.WaitExit(15), std::optional<int>(0)) << launcher.output();
}

// Issue 30: a process that daemonises (setsid, out of its process group)
// left one orphan per start, 4 after 3 restarts and the launcher's
// SIGTERM; an order target holding a newline forged a line in the
// launcher's log. Now the launcher is the subreaper, kills what an ended
// instance left behind, and ends every descendant on SIGTERM; names with
// control characters are refused in one escaped line.
TEST(VlocLaunch, OwnsWhatItsProcessesDaemoniseAndEscapesNames) {
  Scratch scratch("daemons");
  const int port = 7833;
  StatusWatcher watcher(TestLcmUrl(port));
  const std::string restarted = "7777." + std::to_string(getpid()) + "1", kept = "7777." + std::to_string(getpid()) + "2";
  auto sleepers = [](const std::string& duration) { return FindProcesses("sleep", {duration}).size(); };
  const std::string flag = scratch.dir + "/daemon_started";
  Subprocess launcher = Launch(scratch, scratch.WriteGroup(R"(
defaults: {stop_timeout: 2, backoff_initial: 0.05, backoff_max: 5}
processes:
  - {name: restarter, command: /bin/sh, restart: always, max_restarts: 3, args: [-c,
     "rm -f )" + flag + R"(; setsid sh -c 'echo x > )" + flag + R"(; exec sleep )" + restarted + R"(' &
      while [ ! -s )" + flag + R"( ]; do sleep 0.01; done; exit 1"]}
  - {name: keeper, command: /bin/sh, args: [-c, "setsid sleep )" + kept + R"( & echo ready; while :; do sleep 0.05; done"]}
)"),
                               port);
  ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t&) {
    return watcher.Is("restarter", proc_status_t::STATE_GAVE_UP) && watcher.Is("keeper", kRunning) &&
           sleepers(kept) == 1;
  }, 30.0)) << launcher.output();
  EXPECT_EQ(watcher.Find("restarter")->restarts, 3);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (sleepers(restarted) > 0 && std::chrono::steady_clock::now() < deadline) watcher.WaitFor([](auto&) { return false; }, 0.1);
  EXPECT_EQ(sleepers(restarted), 0u) << "daemons of 4 starts of 'restarter' left";
  EXPECT_NE(scratch.Log("restarter").find("left behind by its instance 4"), std::string::npos) << scratch.Log("restarter");

  const std::string forged = "I1127 00:00:00.000000     1 forged.cpp:1] forged line";
  watcher.Order("keeper\n" + forged, procman_order_t::TARGET_PROCESS, procman_order_t::ACTION_STOP);
  EXPECT_TRUE(launcher.WaitForOutput("refused: the name holds control characters", 15)) << launcher.output();
  EXPECT_NE(launcher.output().find("order to stop 'keeper\\n" + forged + "' refused"), std::string::npos)
      << launcher.output();
  EXPECT_EQ(launcher.output().find("\n" + forged), std::string::npos) << launcher.output();
  EXPECT_TRUE(watcher.Is("keeper", kRunning));

  launcher.Signal(SIGTERM);
  EXPECT_EQ(launcher.WaitExit(20), std::optional<int>(0)) << launcher.output();
  EXPECT_EQ(sleepers(kept) + sleepers(restarted), 0u) << "daemons left after the launcher's SIGTERM";
}

TEST(VlocLaunch, WritesOneLogFilePerProcessWithTheNameOnEveryLine) {
  Scratch scratch("logs");
  const int port = 7827;
  Subprocess launcher = Launch(scratch, scratch.WriteGroup(R"(
processes:
  - {name: speaker, command: /bin/sh, args: [-c, "echo hello; echo oops >&2; echo bye"], restart: never}
  - {name: quiet, command: /bin/sh, args: [-c, "echo shh"], restart: never}
)"),
                               port, {"--exit-when-done"});
  ASSERT_EQ(launcher.WaitExit(15), std::optional<int>(0)) << launcher.output();
  const std::string log = scratch.Log("speaker");
  EXPECT_NE(log.find("[speaker] hello\n[speaker] oops\n[speaker] bye\n"), std::string::npos) << log;
  std::istringstream lines(log);
  std::string line;
  while (std::getline(lines, line)) EXPECT_EQ(line.rfind("[speaker] ", 0), 0u) << line;
  EXPECT_NE(scratch.Log("quiet").find("[quiet] shh\n"), std::string::npos);
  EXPECT_EQ(scratch.Log("quiet").find("speaker"), std::string::npos);
}

TEST(VlocLaunch, BadGroupFileGivesOneClearErrorLine) {
  Scratch scratch("bad");
  const int port = 7828;
  {
    const std::string file = scratch.WriteGroup("processes:\n  - {name: sim, comand: /bin/true}\n");
    Subprocess launcher = Launch(scratch, file, port);
    ASSERT_EQ(launcher.WaitExit(15), std::optional<int>(1)) << launcher.output();
    const auto errors = ErrorLines(launcher.output());
    ASSERT_EQ(errors.size(), 1u) << launcher.output();
    EXPECT_NE(errors[0].find(file), std::string::npos) << errors[0];
    EXPECT_NE(errors[0].find("'sim'"), std::string::npos) << errors[0];
    EXPECT_NE(errors[0].find("did you mean 'command'"), std::string::npos) << errors[0];
  }
  {
    Subprocess launcher = Launch(scratch, scratch.WriteGroup("processes:\n  - {name: sim, args: [x]}\n"), port);
    ASSERT_EQ(launcher.WaitExit(15), std::optional<int>(1)) << launcher.output();
    const auto errors = ErrorLines(launcher.output());
    ASSERT_EQ(errors.size(), 1u) << launcher.output();
    EXPECT_NE(errors[0].find("no 'command'"), std::string::npos) << errors[0];
  }
  {
    Subprocess launcher = Launch(scratch, scratch.WriteGroup(kTwoSleepers), port, {"--group", "nope"});
    ASSERT_EQ(launcher.WaitExit(15), std::optional<int>(1)) << launcher.output();
    const auto errors = ErrorLines(launcher.output());
    ASSERT_EQ(errors.size(), 1u) << launcher.output();
    EXPECT_NE(errors[0].find("unknown group 'nope'"), std::string::npos) << errors[0];
  }
}

// The demo's pattern: the simulator's clean end stops the rest and exits 0;
// a failed end exits 1.
TEST(VlocLaunch, ExitWhenDoneFollowsTheSimulatorsEnd) {
  const char* group = R"(
defaults: {stop_timeout: 2}
processes:
  - {name: worker, command: /bin/sh, args: [-c, "trap 'echo worker got INT; exit 0' INT; while :; do sleep 0.05; done"],
     stop_signal: SIGINT}
  - {name: sim, command: /bin/sh, args: [-c, "echo simulating; exit ${SIM_EXIT}"], depends_on: [worker],
     restart: never, exit_when_done: true, exit_grace: 0.2}
)";
  for (const int sim_exit : {0, 3}) {
    SCOPED_TRACE(sim_exit);
    Scratch scratch("done" + std::to_string(sim_exit));
    setenv("SIM_EXIT", std::to_string(sim_exit).c_str(), 1);
    const int port = 7829 + (sim_exit ? 1 : 0);
    StatusWatcher watcher(TestLcmUrl(port));
    Subprocess launcher = Launch(scratch, scratch.WriteGroup(group), port, {"--exit-when-done"});
    ASSERT_EQ(launcher.WaitExit(20), std::optional<int>(sim_exit == 0 ? 0 : 1)) << launcher.output();
    EXPECT_NE(scratch.Log("sim").find("[sim] simulating"), std::string::npos);
    EXPECT_NE(scratch.Log("worker").find("[worker] worker got INT"), std::string::npos) << scratch.Log("worker");
    // The last status shows both ended.
    ASSERT_TRUE(watcher.WaitFor([&](const procman_status_t&) {
      return watcher.Is("worker", proc_status_t::STATE_STOPPED) && watcher.Find("sim")->pid == 0;
    }, 5.0));
    EXPECT_EQ(watcher.Find("sim")->last_exit_code, sim_exit);
  }
  unsetenv("SIM_EXIT");
}

// exit_idle: the grace (30 s here) ends once the rest has finished its last
// piece of work (a worker busy for 4 s after the simulator's end, longer
// than exit_idle, in a child process as a script's tools are) and has
// stayed idle for 2 s, and not before that work is done.
TEST(VlocLaunch, GraceEndsOnceTheRestIsIdle) {
  Scratch scratch("idle");
  const std::string flag = scratch.dir + "/sim_ended";
  const std::string group = R"(
defaults: {stop_timeout: 2}
processes:
  - {name: worker, command: /bin/sh, stop_signal: SIGINT, args: [-c, "trap 'echo worker got INT; exit 0' INT;
     while [ ! -f )" + flag + R"( ]; do sleep 0.05; done; timeout 4 sh -c 'while :; do :; done';
     echo finished; while :; do sleep 0.5; done"]}
  - {name: sim, command: /bin/sh, args: [-c, "sleep 0.5; touch )" + flag + R"("], depends_on: [worker],
     restart: never, exit_when_done: true, exit_grace: 30, exit_idle: 2}
)";
  const int port = 7837;
  Subprocess launcher = Launch(scratch, scratch.WriteGroup(group), port, {"--exit-when-done"});
  ASSERT_EQ(launcher.WaitExit(25), std::optional<int>(0)) << launcher.output();
  const std::string log = scratch.Log("worker");
  const size_t finished = log.find("[worker] finished\n"), stopped = log.find("[worker] worker got INT");
  ASSERT_NE(stopped, std::string::npos) << log;
  EXPECT_LT(finished, stopped) << log;
  const size_t idle = launcher.output().find("the rest idle for 2 s, ");
  ASSERT_NE(idle, std::string::npos) << launcher.output();
  // 4 s of work, then 2 s idle sampled every 0.5 s (the work may start a little before the grace does).
  EXPECT_GE(std::atof(launcher.output().c_str() + idle + 23), 5.0) << launcher.output();
}

// One group split over two launchers on one bus (--host vehicle / ground,
// as on two machines): each runs its part and names its host; an order is
// applied by the launcher that owns the target and left alone by the
// other; a launcher killed is reported LOST by the other.
TEST(VlocLaunch, SplitGroupOneLauncherPerHost) {
  Scratch vehicle_dir("split_vehicle"), ground_dir("split_ground");
  const int port = 7832;
  const std::string group = R"(
defaults: {stop_timeout: 2}
processes:
  - {name: va, command: sleep, args: ["60"], host: vehicle}
  - {name: gb, command: sleep, args: ["60"], host: ground}
)";
  const std::string file = vehicle_dir.WriteGroup(group);
  {
    Subprocess bad = Launch(vehicle_dir, file, port, {"--host", "laptop"});
    EXPECT_EQ(bad.WaitExit(10), std::optional<int>(1));
    EXPECT_NE(bad.output().find("no process runs on host 'laptop'; hosts in the file: vehicle ground"),
              std::string::npos) << bad.output();
  }
  std::string error;
  auto transport = MakeLcmTransport(TestLcmUrl(port), &error);
  ASSERT_TRUE(transport) << error;
  std::map<std::string, procman_status_t> status;
  Subscribe<procman_status_t>(*transport, "PROCMAN_STATUS",
                              [&](const std::string&, const procman_status_t& m) { status[m.host] = m; });
  std::map<std::string, procman_peers_t> peers;  // by reporting host
  Subscribe<procman_peers_t>(*transport, "PROCMAN_PEERS",
                             [&](const std::string&, const procman_peers_t& m) { peers[m.host] = m; });
  // The state of `peer` as `host`'s launcher last published it; -1 when absent.
  auto peer_state = [&](const std::string& host, const std::string& peer) -> int {
    if (!peers.count(host)) return -1;
    for (const auto& p : peers[host].peers)
      if (p.host == peer) return p.state;
    return -1;
  };
  Subprocess vehicle = Launch(vehicle_dir, file, port, {"--host", "vehicle", "--lost-after", "1.5"});
  Subprocess ground = Launch(ground_dir, file, port, {"--host", "ground", "--lost-after", "1.5"});
  auto proc = [&](const std::string& host, const std::string& name) -> const proc_status_t* {
    if (!status.count(host)) return nullptr;
    for (const auto& p : status[host].procs)
      if (p.name == name) return &p;
    return nullptr;
  };
  auto wait = [&](const std::function<bool()>& done, double timeout_s) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < deadline) {
      transport->Handle(100);
      vehicle.Drain();
      ground.Drain();
      if (done()) return true;
    }
    return false;
  };
  ASSERT_TRUE(wait([&] {
    return proc("vehicle", "va") && proc("vehicle", "va")->state == kRunning && proc("ground", "gb") &&
           proc("ground", "gb")->state == kRunning;
  }, 15)) << vehicle.output() << ground.output();
  EXPECT_EQ(status["vehicle"].num_procs, 1);
  EXPECT_EQ(status["ground"].num_procs, 1);
  EXPECT_EQ(status["vehicle"].launcher_pid, vehicle.pid());
  ASSERT_TRUE(wait([&] {
    return vehicle.output().find("peers: launcher 'ground' (pid") != std::string::npos &&
           ground.output().find("peers: launcher 'vehicle' (pid") != std::string::npos;
  }, 5)) << vehicle.output() << ground.output();
  ASSERT_TRUE(wait([&] {
    return peer_state("ground", "vehicle") == procman_peer_t::STATE_ALIVE &&
           peer_state("vehicle", "ground") == procman_peer_t::STATE_ALIVE;
  }, 5));
  EXPECT_DOUBLE_EQ(peers["ground"].lost_after_seconds, 1.5);

  // An order for gb with no host: the ground's launcher restarts it; the vehicle's leaves it, without an error.
  const int32_t old_gb = proc("ground", "gb")->pid;
  procman_order_t order;
  order.utime = 0;
  order.host = "";
  order.target = "gb";
  order.target_kind = procman_order_t::TARGET_PROCESS;
  order.action = procman_order_t::ACTION_RESTART;
  ASSERT_TRUE(Publish(*transport, "PROCMAN_ORDERS", order));
  ASSERT_TRUE(wait([&] { return proc("ground", "gb")->state == kRunning && proc("ground", "gb")->pid != old_gb; }, 10))
      << ground.output();
  ASSERT_TRUE(wait([&] { return vehicle.output().find("'gb' is for another host's launcher") != std::string::npos; },
                   5)) << vehicle.output();
  EXPECT_EQ(vehicle.output().find("unknown process"), std::string::npos) << vehicle.output();
  // Addressed to the vehicle by host.
  order.host = "vehicle";
  order.target = "va";
  order.action = procman_order_t::ACTION_STOP;
  ASSERT_TRUE(Publish(*transport, "PROCMAN_ORDERS", order));
  ASSERT_TRUE(wait([&] { return proc("vehicle", "va")->state == proc_status_t::STATE_STOPPED; }, 10))
      << vehicle.output();
  EXPECT_EQ(proc("ground", "gb")->state, kRunning);
  ASSERT_TRUE(wait([&] {
    const std::string& out = ground.output();
    const size_t at = out.find("launcher 'vehicle': process 'va' ");  // RUNNING -> STOPPING, then -> STOPPED
    return at != std::string::npos && out.find("-> STOPPED, pid", at) != std::string::npos;
  }, 5)) << ground.output();

  // The vehicle's launcher dies: the ground names it LOST.
  vehicle.Signal(SIGKILL);
  vehicle.WaitExit(5);
  const auto killed = std::chrono::steady_clock::now();
  ASSERT_TRUE(wait([&] { return ground.output().find("launcher 'vehicle' (pid " + std::to_string(vehicle.pid()) +
                                                     ") LOST: no report for") != std::string::npos; },
                   5)) << ground.output();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count(), 1.5 + 1.2);
  // ... and publishes it so on PROCMAN_PEERS.
  ASSERT_TRUE(wait([&] { return peer_state("ground", "vehicle") == procman_peer_t::STATE_LOST; }, 3));
  for (const auto& p : peers["ground"].peers) {
    if (p.host != "vehicle") continue;
    EXPECT_EQ(p.launcher_pid, vehicle.pid());
    EXPECT_EQ(p.times_lost, 1);
    EXPECT_GE(p.seconds_since_heard, 1.5);
  }
  ground.Signal(SIGTERM);
  EXPECT_EQ(ground.WaitExit(15), std::optional<int>(0)) << ground.output();
}

}  // namespace
}  // namespace vloc
