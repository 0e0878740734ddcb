// Supervisor with small real children (/bin/sh, sleep): start order,
// restarts after SIGKILL, giving up, stop escalation to SIGKILL, stop order,
// no process left behind, per-process log files, CPU and memory. Every wait
// has a timeout; nothing relies on a fixed sleep.

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "vloc/launch/proc_stats.h"
#include "vloc/launch/supervisor.h"

namespace vloc {
namespace {

namespace fs = std::filesystem;

std::string TempDir(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "/launch_unit_" + std::to_string(getpid()) + "_" + name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Removes every TempDir() of this test binary when the tests end.
class RemoveTempDirs : public ::testing::Environment {
 public:
  void TearDown() override {
    const std::string prefix = "launch_unit_" + std::to_string(getpid()) + "_";
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(::testing::TempDir(), ec))
      if (entry.path().filename().string().rfind(prefix, 0) == 0) fs::remove_all(entry.path(), ec);
  }
};
const auto* const kRemoveTempDirs = ::testing::AddGlobalTestEnvironment(new RemoveTempDirs);

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

ProcessSpec Shell(const std::string& name, const std::string& script) {
  ProcessSpec p;
  p.name = name;
  p.command = "/bin/sh";
  p.args = {"-c", script};
  p.group = "test";
  p.backoff_initial = 0.05;
  p.backoff_max = 0.2;
  p.stop_timeout = 2.0;
  return p;
}

ProcessStatus StatusOf(Supervisor& s, const std::string& name) {
  for (const auto& st : s.Status())
    if (st.name == name) return st;
  ADD_FAILURE() << "no process " << name;
  return {};
}

// Steps the supervisor until `done` holds or timeout_s passes.
bool StepUntil(Supervisor& s, const std::function<bool()>& done, double timeout_s = 10.0) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    s.Step(20);
  }
  return true;
}

bool GroupGone(pid_t pgid) { return ReadProcessGroupUsage().count(pgid) == 0; }

// A sleep duration unique to the test (7777.<test pid><n>): finds its
// daemons among everything else on the machine.
std::string UniqueSleep(int n) { return "7777." + std::to_string(getpid()) + std::to_string(n); }
int CountSleepers(const std::string& duration) { return static_cast<int>(FindProcesses("sleep", {duration}).size()); }

// A process that daemonises (setsid: out of its process group, re-parented
// when its shell ends) leaves nothing behind (issue 30: one orphan per
// start, 4 after 3 restarts and the launcher's stop): its leftovers are
// killed when the instance that started them ends, when it is stopped, and
// by StopAll.
TEST(Supervisor, DaemonsOfItsProcessesDieWithThem) {
  const std::string dir = TempDir("daemons");
  const std::string restarted = UniqueSleep(1), kept = UniqueSleep(2);
  GroupFile file;
  // The restarter ends once its daemon is in a session of its own (out of the process group).
  const std::string flag = dir + "/daemon_started";
  file.processes = {Shell("restarter", "rm -f " + flag + "; setsid sh -c 'echo x > " + flag + "; exec sleep " +
                                           restarted + "' & while [ ! -s " + flag + " ]; do sleep 0.01; done; exit 1"),
                    Shell("keeper", "setsid sleep " + kept + " & echo ready; while :; do sleep 0.05; done")};
  file.processes[0].restart = RestartPolicy::kAlways;
  file.processes[0].max_restarts = 3;
  file.processes[0].backoff_max = 5.0;  // runs shorter than this count towards max_restarts
  Supervisor s(file, {dir});
  ASSERT_TRUE(s.Start("restarter", false, nullptr));
  // Four starts, each leaving a daemon, each daemon killed once its instance ends.
  ASSERT_TRUE(StepUntil(s, [&] { return StatusOf(s, "restarter").state == ProcState::kGaveUp; }, 30.0));
  ASSERT_TRUE(StepUntil(s, [&] { return CountSleepers(restarted) == 0 && s.AllStopped(); }, 10.0))
      << CountSleepers(restarted) << " daemons of 'restarter' left";
  const std::string log = ReadFile(dir + "/restarter.log");
  EXPECT_NE(log.find("left behind by its instance 4"), std::string::npos) << log;

  // Stopping a process ends its daemon too (it left the process group).
  ASSERT_TRUE(s.Start("keeper", false, nullptr));
  ASSERT_TRUE(StepUntil(s, [&] { return CountSleepers(kept) == 1; })) << ReadFile(dir + "/keeper.log");
  ASSERT_TRUE(s.Stop("keeper", false, nullptr));
  ASSERT_TRUE(StepUntil(s, [&] { return StatusOf(s, "keeper").state == ProcState::kStopped && CountSleepers(kept) == 0; }))
      << CountSleepers(kept) << " daemons of 'keeper' left";

  // And StopAll everything, AllStopped waiting for it.
  ASSERT_TRUE(s.Start("keeper", false, nullptr));
  ASSERT_TRUE(StepUntil(s, [&] { return CountSleepers(kept) == 1; }));
  EXPECT_TRUE(StepUntil(s, [&] { return s.NumOtherDescendants() >= 1; }));  // swept at least once a second
  s.StopAll();
  ASSERT_TRUE(StepUntil(s, [&] { return s.AllStopped(); }));
  EXPECT_EQ(CountSleepers(kept), 0);
  EXPECT_EQ(s.NumOtherDescendants(), 0);
  fs::remove_all(dir);
}

// `nice` lowers a process's priority below the launcher's (the simulator
// below the vehicle's localisation in the demo groups).
TEST(Supervisor, NiceLowersTheProcessPriority) {
  const int own = getpriority(PRIO_PROCESS, 0);
  if (own + 7 > 19) GTEST_SKIP() << "the test runs at nice " << own << ": no room for 7 more";
  const std::string dir = TempDir("nice");
  GroupFile file;
  file.processes = {Shell("plain", "nice > " + dir + "/plain; exec sleep 30"),
                    Shell("low", "nice > " + dir + "/low; exec sleep 30")};
  file.processes[1].nice = 7;
  Supervisor s(file, {});
  ASSERT_TRUE(s.Start("plain", false, nullptr));
  ASSERT_TRUE(s.Start("low", false, nullptr));
  const auto read = [&](const std::string& name) {
    std::ifstream f(dir + "/" + name);
    int value = -100;
    f >> value;
    return value;
  };
  ASSERT_TRUE(StepUntil(s, [&] { return read("plain") != -100 && read("low") != -100; }));
  EXPECT_EQ(read("plain"), own);
  EXPECT_EQ(read("low"), own + 7);
  s.StopAll();
  ASSERT_TRUE(StepUntil(s, [&] { return s.AllStopped(); }));
  fs::remove_all(dir);
}

TEST(Supervisor, NamesWithControlCharactersAreEscapedOrRefused) {
  GroupFile file;
  file.processes = {Shell("a", "exit 0")};
  Supervisor s(file, {});
  std::string error;
  EXPECT_FALSE(s.Stop("evil\nI0101 forged line", false, &error));
  EXPECT_EQ(error.find('\n'), std::string::npos) << error;
  EXPECT_NE(error.find("unknown process 'evil\\nI0101 forged line'"), std::string::npos) << error;
}

TEST(Supervisor, StartsAGroupAfterItsDependencies) {
  GroupFile file;
  file.path = "test";
  file.processes = {Shell("base", "exec sleep 30"), Shell("top", "exec sleep 30")};
  file.processes[1].depends_on = {"base"};
  file.processes[1].start_delay = 0.3;
  Supervisor s(file, {});
  std::string error;
  ASSERT_TRUE(s.StartGroups({}, &error)) << error;
  s.Step(0);
  EXPECT_EQ(StatusOf(s, "base").state, ProcState::kRunning);
  EXPECT_EQ(StatusOf(s, "top").state, ProcState::kStarting);  // start_delay after base runs
  EXPECT_EQ(StatusOf(s, "top").pid, 0);
  ASSERT_TRUE(StepUntil(s, [&] { return StatusOf(s, "top").state == ProcState::kRunning; }));
  EXPECT_GT(StatusOf(s, "top").pid, 0);
  EXPECT_EQ(s.LivePids().size(), 2u);
  EXPECT_FALSE(s.StartGroups({"nope"}, &error));
  EXPECT_NE(error.find("unknown group 'nope'"), std::string::npos) << error;
}

TEST(Supervisor, DependentOfAProcessThatCannotRunWaitsAndIsReportedAsFailed) {
  GroupFile file;
  file.processes = {Shell("base", ""), Shell("top", "exec sleep 30")};
  file.processes[0].command = "/no/such/program";
  file.processes[1].depends_on = {"base"};
  Supervisor s(file, {});
  ASSERT_TRUE(s.StartGroups({}, nullptr));
  s.Step(0);
  EXPECT_EQ(StatusOf(s, "base").state, ProcState::kGaveUp);
  EXPECT_EQ(StatusOf(s, "base").last_exit_code, 127);
  EXPECT_EQ(StatusOf(s, "top").state, ProcState::kStarting);
  EXPECT_EQ(s.DoneOutcome({"top"}), std::optional<int>(1));
}

TEST(Supervisor, RestartsAProcessKilledWithSigkill) {
  GroupFile file;
  file.processes = {Shell("victim", "exec sleep 30")};
  Supervisor s(file, {});
  ASSERT_TRUE(s.StartGroups({}, nullptr));
  s.Step(0);
  const pid_t first = StatusOf(s, "victim").pid;
  ASSERT_GT(first, 0);
  ASSERT_EQ(kill(first, SIGKILL), 0);
  ASSERT_TRUE(StepUntil(s, [&] {
    const auto st = StatusOf(s, "victim");
    return st.state == ProcState::kRunning && st.pid != first;
  }));
  const auto st = StatusOf(s, "victim");
  EXPECT_EQ(st.restarts, 1);
  EXPECT_EQ(st.last_exit_code, -SIGKILL);
  EXPECT_TRUE(GroupGone(first));
}

TEST(Supervisor, GivesUpAfterMaxRestarts) {
  GroupFile file;
  file.processes = {Shell("crasher", "echo crashing; exit 3")};
  file.processes[0].max_restarts = 2;
  Supervisor s(file, {});
  ASSERT_TRUE(s.StartGroups({}, nullptr));
  ASSERT_TRUE(StepUntil(s, [&] { return StatusOf(s, "crasher").state == ProcState::kGaveUp; }));
  const auto st = StatusOf(s, "crasher");
  EXPECT_EQ(st.restarts, 2);
  EXPECT_EQ(st.last_exit_code, 3);
  EXPECT_EQ(st.pid, 0);
  EXPECT_EQ(s.DoneOutcome({}), std::optional<int>(1));
  // A start order clears the count and runs it again.
  ASSERT_TRUE(s.Start("crasher", false, nullptr));
  ASSERT_TRUE(StepUntil(s, [&] { return StatusOf(s, "crasher").restarts == 3; }));
}

TEST(Supervisor, PolicyNeverLeavesACleanExitAlone) {
  GroupFile file;
  file.processes = {Shell("once", "exit 0"), Shell("failing_once", "exit 4")};
  file.processes[0].restart = RestartPolicy::kOnFailure;
  file.processes[1].restart = RestartPolicy::kNever;
  Supervisor s(file, {});
  ASSERT_TRUE(s.StartGroups({}, nullptr));
  ASSERT_TRUE(StepUntil(s, [&] { return s.DoneOutcome({}).has_value(); }));
  EXPECT_EQ(StatusOf(s, "once").state, ProcState::kExited);
  EXPECT_EQ(StatusOf(s, "once").restarts, 0);
  EXPECT_EQ(StatusOf(s, "failing_once").state, ProcState::kExited);
  EXPECT_EQ(StatusOf(s, "failing_once").last_exit_code, 4);
  EXPECT_EQ(s.DoneOutcome({"once"}), std::optional<int>(0));
  EXPECT_EQ(s.DoneOutcome({}), std::optional<int>(1));
}

TEST(Supervisor, StopEscalatesToSigkillAfterTheTimeAllowed) {
  const std::string dir = TempDir("escalate");
  GroupFile file;
  file.processes = {Shell("stubborn", "trap '' TERM; echo ready; while :; do sleep 0.05; done")};
  file.processes[0].stop_timeout = 0.5;
  Supervisor s(file, {dir});
  ASSERT_TRUE(s.StartGroups({}, nullptr));
  ASSERT_TRUE(StepUntil(s, [&] { return ReadFile(dir + "/stubborn.log").find("] ready") != std::string::npos; }));
  const pid_t pid = StatusOf(s, "stubborn").pid;
  s.StopAll();
  s.Step(0);
  EXPECT_EQ(StatusOf(s, "stubborn").state, ProcState::kStopping);
  ASSERT_TRUE(StepUntil(s, [&] { return s.AllStopped(); }));
  EXPECT_EQ(StatusOf(s, "stubborn").state, ProcState::kStopped);
  EXPECT_EQ(StatusOf(s, "stubborn").last_exit_code, -SIGKILL);
  EXPECT_TRUE(GroupGone(pid));
  EXPECT_NE(ReadFile(dir + "/stubborn.log").find("sending SIGKILL"), std::string::npos);
}

TEST(Supervisor, StopAllStopsDependentsFirstAndLeavesNoProcess) {
  const std::string dir = TempDir("order");
  const std::string order = dir + "/order.txt";
  auto child = [&](const std::string& name) {
    // Appends its name when stopped; a grandchild sleeps in its group.
    return Shell(name, "trap 'echo " + name + " >> " + order + "; exit 0' TERM; sleep 30 & echo ready; "
                       "while :; do sleep 0.05; done");
  };
  GroupFile file;
  file.processes = {child("logger"), child("worker"), child("sim")};
  file.processes[1].depends_on = {"logger"};
  file.processes[2].depends_on = {"logger", "worker"};
  Supervisor s(file, {dir});
  ASSERT_TRUE(s.StartGroups({}, nullptr));
  ASSERT_TRUE(StepUntil(s, [&] {
    for (const char* n : {"logger", "worker", "sim"})
      if (ReadFile(dir + "/" + n + ".log").find("] ready") == std::string::npos) return false;
    return true;
  }));
  const std::vector<pid_t> groups = s.LivePids();
  ASSERT_EQ(groups.size(), 3u);
  s.StopAll();
  ASSERT_TRUE(StepUntil(s, [&] { return s.AllStopped(); }));
  EXPECT_EQ(ReadFile(order), "sim\nworker\nlogger\n");
  for (pid_t g : groups) EXPECT_TRUE(GroupGone(g)) << "process group " << g << " still has processes";
}

TEST(Supervisor, LogFilesPrefixEveryLineWithTheName) {
  const std::string dir = TempDir("logs");
  GroupFile file;
  file.processes = {Shell("talker", "echo one; echo two >&2; printf 'three'; exit 0")};
  file.processes[0].restart = RestartPolicy::kNever;
  Supervisor s(file, {dir});
  ASSERT_TRUE(s.StartGroups({}, nullptr));
  ASSERT_TRUE(StepUntil(s, [&] { return StatusOf(s, "talker").state == ProcState::kExited; }));
  const std::string log = ReadFile(dir + "/talker.log");
  EXPECT_NE(log.find("[talker] one\n"), std::string::npos) << log;
  EXPECT_NE(log.find("[talker] two\n"), std::string::npos) << log;
  EXPECT_NE(log.find("[talker] three\n"), std::string::npos) << log;
  std::istringstream lines(log);
  std::string line;
  int count = 0;
  while (std::getline(lines, line)) {
    EXPECT_EQ(line.rfind("[talker] ", 0), 0u) << line;
    ++count;
  }
  EXPECT_GE(count, 5);  // three lines + started + exited
}

TEST(Supervisor, OrdersStopStartAndRestart) {
  GroupFile file;
  file.processes = {Shell("a", "exec sleep 30"), Shell("b", "exec sleep 30")};
  file.processes[1].group = "other";
  file.processes[1].autostart = true;
  Supervisor s(file, {});
  ASSERT_TRUE(s.StartGroups({"test"}, nullptr));
  s.Step(0);
  EXPECT_EQ(StatusOf(s, "a").state, ProcState::kRunning);
  EXPECT_EQ(StatusOf(s, "b").state, ProcState::kStopped);  // its group was not started
  const pid_t a1 = StatusOf(s, "a").pid;
  ASSERT_TRUE(s.Restart("a", false, nullptr));
  ASSERT_TRUE(StepUntil(s, [&] { return StatusOf(s, "a").state == ProcState::kRunning && StatusOf(s, "a").pid != a1; }));
  EXPECT_EQ(StatusOf(s, "a").restarts, 0);  // ordered, not automatic
  ASSERT_TRUE(s.Start("other", true, nullptr));
  ASSERT_TRUE(StepUntil(s, [&] { return StatusOf(s, "b").state == ProcState::kRunning; }));
  ASSERT_TRUE(s.Stop("a", false, nullptr));
  ASSERT_TRUE(StepUntil(s, [&] { return StatusOf(s, "a").state == ProcState::kStopped; }));
  EXPECT_EQ(StatusOf(s, "b").state, ProcState::kRunning);
  std::string error;
  EXPECT_FALSE(s.Stop("nobody", false, &error));
  EXPECT_NE(error.find("unknown process 'nobody'"), std::string::npos) << error;
}

TEST(Supervisor, ReportsCpuAndMemory) {
  GroupFile file;
  file.processes = {Shell("busy", "while :; do :; done")};
  Supervisor s(file, {});
  ASSERT_TRUE(s.StartGroups({}, nullptr));
  s.Step(0);
  s.Status();  // baseline
  ProcessStatus st;
  ASSERT_TRUE(StepUntil(s, [&] {
    st = StatusOf(s, "busy");
    return st.cpu_percent > 0.0;
  }));
  EXPECT_GT(st.rss_bytes, 0);
  EXPECT_LE(st.cpu_percent, 100.0 * 1.05 * sysconf(_SC_NPROCESSORS_ONLN));
  EXPECT_GT(st.uptime_seconds, 0.0);
}

// A process that depends on another host's process starts only once the
// remote check reports that process RUNNING.
TEST(Supervisor, WaitsForARemoteDependency) {
  GroupFile file;
  ProcessSpec sim = Shell("sim", "exec sleep 30");
  sim.remote_depends_on = {{"ground", "frontend"}};
  file.processes = {sim};
  Supervisor sup(file, {TempDir("remote"), false});
  bool frontend_running = false;
  sup.SetRemoteCheck([&](const std::string& host, const std::string& name) {
    return host == "ground" && name == "frontend" && frontend_running;
  });
  std::string error;
  ASSERT_TRUE(sup.StartGroups({}, &error)) << error;
  for (int i = 0; i < 10; ++i) sup.Step(20);
  EXPECT_EQ(StatusOf(sup, "sim").state, ProcState::kStarting);
  frontend_running = true;
  EXPECT_TRUE(StepUntil(sup, [&] { return StatusOf(sup, "sim").state == ProcState::kRunning; }));
  sup.StopAll();
  EXPECT_TRUE(StepUntil(sup, [&] { return sup.AllStopped(); }));
}

}  // namespace
}  // namespace vloc
