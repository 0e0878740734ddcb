#pragma once
// Process supervision for vloc_launch, with no LCM in it: starts the
// processes of a GroupFile with fork/exec, each in its own process group,
// pipes their stdout+stderr into per-process log files (every line
// prefixed with "[name] "), restarts what ends according to its policy with
// exponential back-off, gives up after max_restarts, stops with the
// configured signal and SIGKILLs what outlives its stop_timeout, and
// reports pid, state, restarts, exit code, CPU and memory per process.
//
// It owns every descendant it started: it is the child subreaper
// (PR_SET_CHILD_SUBREAPER), so what a child leaves behind (a daemon that
// escaped its process group with setsid) comes back to it rather than to
// init. Each child carries VLOC_LAUNCH_OWNER=<launcher pid>:<index>:<instance>
// in its environment, and the launcher's process tree is swept (/proc, at
// once after any exit or stop, else once a second): a descendant is
// signalled with its process's stop signal and SIGKILL, is SIGKILLed as a
// leftover once the instance that started it has ended (restarts do not
// pile up daemons), orphans that end are reaped, and StopAll/KillAll end
// every descendant, attributed or not. AllStopped() waits for all of them.
// (A SIGKILLed launcher cannot do this: its children get SIGTERM through
// PR_SET_PDEATHSIG, a daemon that left their group does not.)
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
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vloc/launch/group_file.h"
#include "vloc/launch/proc_stats.h"

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
  // True when no child (nor anything left in a child's process group, nor
  // any other descendant as of the last sweep) is alive and no start is
  // pending (after StopAll: everything has ended).
  bool AllStopped() const;

  // Waits up to timeout_ms for child output, then copies output to the
  // logs, reaps children, applies restart policies, starts what is due and
  // escalates overdue stops to SIGKILL.
  void Step(int timeout_ms);

  // Status of every process in file order. CPU% is measured since the
  // previous call.
  std::vector<ProcessStatus> Status();

  // CPU clock ticks used so far by each live process below the launcher
  // (its processes, whatever they forked, in their groups or not, and the
  // orphans it adopted; each with its reaped children's), by pid. No
  // effect on Status()'s CPU%.
  std::map<pid_t, uint64_t> CpuTicks() const;
  // True while a process waits to (re)start (starting or backing off).
  bool AnyStartPending() const;

  // For --exit-when-done: nullopt while any of `names` (every selected
  // process when empty) may still run; else 0 when each ended with exit
  // code 0 (or was stopped), 1 otherwise.
  std::optional<int> DoneOutcome(const std::vector<std::string>& names) const;

  // Names of processes marked exit_when_done in the file.
  std::vector<std::string> ExitWhenDoneNames() const;

  // The pids of all live children (process-group ids), for tests and checks.
  std::vector<pid_t> LivePids() const;

  // Live descendants (not zombies) other than the children LivePids()
  // gives: what the processes forked, daemons among them, as of the last
  // sweep of the process tree.
  int NumOtherDescendants() const { return num_other_descendants_; }

  const GroupFile& file() const { return file_; }

 private:
  struct Proc;
  bool ForTargets(const std::string& target, bool is_group, std::string* error,
                  const std::function<void(Proc&)>& action);
  void RequestStart(Proc& p);
  void RequestStop(Proc& p, bool restart_after);
  void SendStop(Proc& p, Clock::time_point now);
  void Spawn(Proc& p, Clock::time_point now);
  void OpenLog(Proc& p);  // once, when options_.log_dir is set
  void RetryStartLater(Proc& p, Clock::time_point now, const std::string& why);  // in 1 s
  void OnExit(Proc& p, int wait_status, Clock::time_point now);
  // OnExit's parts: the rest of the process's output written to its log;
  // its restart after the backoff (or giving up after max_restarts).
  void FlushOutput(Proc& p);
  void ScheduleRestart(Proc& p, double ran_s, Clock::time_point now);
  // Step's parts: the ended processes reaped, the process groups still
  // there after SIGKILL killed again (for 5 s), a stop moved on (SIGTERM once
  // no dependent is stopping, SIGKILL after stop_timeout), a start moved on
  // (once its dependencies run, after start_delay).
  void ReapExited(Clock::time_point now);
  void KillLingeringGroups(Clock::time_point now);
  void AdvanceStop(Proc& p, Clock::time_point now);
  void AdvanceStart(Proc& p, Clock::time_point now);
  void PumpOutput(int timeout_ms);
  void ReadOutput(Proc& p);
  void WriteLine(Proc& p, const std::string& line);
  void Note(Proc& p, const std::string& text);
  bool DependenciesRunning(const Proc& p) const;
  bool HasStoppingDependents(const Proc& p) const;
  // Which process instance started a descendant (index into procs_, -1 unknown).
  struct Owner {
    int index = -1;
    int instance = 0;
  };
  // Walks the launcher's process tree: reaps adopted orphans that ended,
  // SIGKILLs leftovers (their instance ended; every one when `everything`),
  // and counts what lives in num_other_descendants_.
  void Sweep(Clock::time_point now, bool everything);
  // Sweep's steps. A live process of the tree with the owner of its subtree's top.
  using OwnedEntry = std::pair<const ProcEntry*, Owner>;
  // The launcher's children, each with its owner: a process itself, known
  // from an earlier sweep, or named by the mark in its start environment.
  std::vector<OwnedEntry> TopOfTree(const std::multimap<pid_t, const ProcEntry*>& children,
                                    const std::map<pid_t, const Proc*>& leaders) const;
  // Walks `tree` (its tops in, every descendant appended), reaps ended
  // orphans, SIGKILLs the leftovers, remembers owners; returns how many live.
  int KillLeftovers(const std::multimap<pid_t, const ProcEntry*>& children,
                    const std::map<pid_t, const Proc*>& leaders, Clock::time_point now, bool everything,
                    std::vector<OwnedEntry>* tree);
  // killed_ without those gone; those alive 5 s after SIGKILL given up on.
  void ForgetEndedKills(const std::vector<OwnedEntry>& tree, Clock::time_point now);
  // Sends `sig` to every live descendant of p's current instance.
  void SignalDescendants(Proc& p, int sig);

  GroupFile file_;
  SupervisorOptions options_;
  std::vector<std::unique_ptr<Proc>> procs_;
  // Process groups whose leader ended but whose other members (SIGKILLed)
  // have not all gone yet, with the time the leader ended.
  std::vector<std::pair<pid_t, Clock::time_point>> lingering_;
  Clock::time_point last_status_time_;
  RemoteCheck remote_check_;
  pid_t self_ = 0;                       // the launcher's pid, root of its process tree
  bool stopping_all_ = false;            // StopAll / KillAll: every descendant goes
  bool sweep_due_ = true;                // a child ended or was signalled: sweep at the next Step
  Clock::time_point next_sweep_;         // else once a second
  int num_other_descendants_ = 0;        // from the last sweep
  // Owners seen while a descendant's ancestry still led to its process,
  // kept for when it is re-parented to the launcher: pid -> (start time, owner).
  std::map<pid_t, std::pair<uint64_t, Owner>> known_owners_;
  // Leftovers SIGKILLed and still alive: pid -> (when first killed, given up on: 5 s later, no longer waited for).
  std::map<pid_t, std::pair<Clock::time_point, bool>> killed_;
};

}  // namespace vloc
