#pragma once
// Process supervision for vloc_launch, with no LCM in it: starts the
// processes of a GroupFile with fork/exec, each in its own process group,
// pipes their stdout+stderr into per-process log files (every line
// prefixed with "[name] "), restarts what ends according to its policy with
// exponential back-off, gives up after max_restarts, stops with the
// configured signal and SIGKILLs what outlives its stop_timeout, and
// reports pid, state, restarts, exit code, CPU and memory per process.
//
// Single-threaded: the owner calls Step() in its loop (it waits up to the
// given time for child output). Orders (Start/Stop/Restart) only change
// what Step() will do next.
//
//   Supervisor sup(ParseGroupFile("config/groups/rover_sim.yaml"), {"logs"});
//   sup.StartGroups({});            // every group
//   while (!done) sup.Step(50);
//   sup.StopAll(); while (!sup.AllStopped()) sup.Step(50);

#include <sys/types.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vloc/launch/group_file.h"

namespace vloc {

// Same numbers as proc_status_t's STATE_* constants.
enum class ProcState : int8_t {
  kStopped = 0,   // not running and not asked to run
  kStarting = 1,  // asked to run; waiting for its dependencies / start_delay
  kRunning = 2,   // alive
  kStopping = 3,  // stop signal sent; SIGKILL at the deadline
  kBackoff = 4,   // ended; restarts when its back-off delay is over
  kExited = 5,    // ended and not restarted (policy)
  kGaveUp = 6,    // ended max_restarts + 1 times in a row, or could not be run
};

const char* ProcStateName(ProcState state);

struct SupervisorOptions {
  std::string log_dir;         // per-process logs <log_dir>/<name>.log; empty = no files
  bool echo_output = false;    // also write the prefixed lines to the launcher's stdout
};

// One process's state for a status report.
struct ProcessStatus {
  std::string name;
  std::string group;
  pid_t pid = 0;               // 0 when not running
  ProcState state = ProcState::kStopped;
  int restarts = 0;            // automatic restarts since the launcher started
  int last_exit_code = 0;      // exit code, or -signal when killed by a signal
  bool has_exited = false;     // last_exit_code is meaningful
  double cpu_percent = 0.0;    // % of one core over the time since the previous Status()
  int64_t rss_bytes = 0;       // resident memory of its process group, bytes
  double uptime_seconds = 0.0; // s, since the current instance started
};

class Supervisor {
 public:
  using Clock = std::chrono::steady_clock;

  Supervisor(GroupFile file, SupervisorOptions options);
  // Kills (SIGKILL) whatever is still running: call StopAll()+Step() first
  // for a graceful stop.
  ~Supervisor();
  Supervisor(const Supervisor&) = delete;
  Supervisor& operator=(const Supervisor&) = delete;

  // Asks the autostart processes of `groups` (every group when empty) to
  // run. Returns false with one line in *error for an unknown group name.
  bool StartGroups(const std::vector<std::string>& groups, std::string* error);

  // Orders on a process (is_group false) or every process of a group.
  // Return false with one line in *error for an unknown name.
  bool Start(const std::string& target, bool is_group, std::string* error);
  bool Stop(const std::string& target, bool is_group, std::string* error);
  bool Restart(const std::string& target, bool is_group, std::string* error);

  // Answers whether another host's process is RUNNING (for
  // remote_depends_on). Without one, remote dependencies are not waited for.
  using RemoteCheck = std::function<bool(const std::string& host, const std::string& name)>;
  void SetRemoteCheck(RemoteCheck check) { remote_check_ = std::move(check); }

  // Stops every process gracefully: a process is signalled once the
  // processes that depend on it have stopped (reverse start order).
  void StopAll();
  // SIGKILLs every process group still alive, now.
  void KillAll();
  // True when no child (nor anything left in a child's process group) is
  // alive and no start is pending (after StopAll: everything has ended).
  bool AllStopped() const;

  // Waits up to timeout_ms for child output, then copies output to the
  // logs, reaps children, applies restart policies, starts what is due and
  // escalates overdue stops to SIGKILL.
  void Step(int timeout_ms);

  // Status of every process in file order. CPU% is measured since the
  // previous call.
  std::vector<ProcessStatus> Status();

  // For --exit-when-done: nullopt while any of `names` (every selected
  // process when empty) may still run; else 0 when each ended with exit
  // code 0 (or was stopped), 1 otherwise.
  std::optional<int> DoneOutcome(const std::vector<std::string>& names) const;

  // Names of processes marked exit_when_done in the file.
  std::vector<std::string> ExitWhenDoneNames() const;

  // The pids of all live children (process-group ids), for tests and checks.
  std::vector<pid_t> LivePids() const;

  const GroupFile& file() const { return file_; }

 private:
  struct Proc;
  Proc* FindProc(const std::string& name);
  bool ForTargets(const std::string& target, bool is_group, std::string* error,
                  const std::function<void(Proc&)>& action);
  void RequestStart(Proc& p);
  void RequestStop(Proc& p, bool restart_after);
  void SendStop(Proc& p, Clock::time_point now);
  void Spawn(Proc& p, Clock::time_point now);
  void OnExit(Proc& p, int wait_status, Clock::time_point now);
  void PumpOutput(int timeout_ms);
  void ReadOutput(Proc& p);
  void WriteLine(Proc& p, const std::string& line);
  void Note(Proc& p, const std::string& text);
  bool DependenciesRunning(const Proc& p) const;
  bool HasStoppingDependents(const Proc& p) const;

  GroupFile file_;
  SupervisorOptions options_;
  std::vector<std::unique_ptr<Proc>> procs_;
  // Process groups whose leader ended but whose other members (SIGKILLed)
  // have not all gone yet, with the time the leader ended.
  std::vector<std::pair<pid_t, Clock::time_point>> lingering_;
  Clock::time_point last_status_time_;
  RemoteCheck remote_check_;
};

}  // namespace vloc
