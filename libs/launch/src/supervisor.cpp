#include "vloc/launch/supervisor.h"

#include <fcntl.h>
#include <glog/logging.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "vloc/common/printable.h"
#include "vloc/launch/proc_stats.h"

extern char** environ;

namespace vloc {

const char* ProcStateName(ProcState state) {
  switch (state) {
    case ProcState::kStopped: return "STOPPED";
    case ProcState::kStarting: return "STARTING";
    case ProcState::kRunning: return "RUNNING";
    case ProcState::kStopping: return "STOPPING";
    case ProcState::kBackoff: return "BACKOFF";
    case ProcState::kExited: return "EXITED";
    case ProcState::kGaveUp: return "GAVE_UP";
  }
  return "?";
}

struct Supervisor::Proc {
  ProcessSpec spec;
  int index = 0;                  // in procs_: what VLOC_LAUNCH_OWNER names
  int instance = 0;               // starts so far: with index, which run a descendant came from
  ProcState state = ProcState::kStopped;
  pid_t pid = 0;                  // also the process-group id
  int out_fd = -1;                // read end of the child's stdout+stderr pipe
  std::string partial;            // output after the last newline
  int log_fd = -1;
  bool log_opened = false;
  int restarts = 0;               // automatic restarts, reported
  int restarts_in_row = 0;        // since the last order or a long run; vs max_restarts
  int backoff_step = 0;
  int last_exit_code = 0;
  bool has_exited = false;
  bool selected = false;          // asked to run at some point (DoneOutcome)
  bool signal_sent = false;       // stop signal sent (state kStopping)
  bool kill_sent = false;
  bool restart_after_stop = false;
  bool waiting_noted = false;
  Clock::time_point started_at, stop_deadline, next_start_at;
  std::optional<Clock::time_point> deps_ready_since;
  bool cpu_valid = false;
  uint64_t last_cpu_ticks = 0;
  Clock::time_point last_cpu_time;
};

namespace {

// The environment variable that marks every child (and what it forks) as
// this launcher's: "<launcher pid>:<process index>:<instance>".
constexpr const char* kOwnerVariable = "VLOC_LAUNCH_OWNER";

double Seconds(Supervisor::Clock::duration d) { return std::chrono::duration<double>(d).count(); }

std::string Fmt(double seconds) {
  std::ostringstream out;
  out.precision(3);
  out << seconds;
  return out.str();
}

std::string JoinCommand(const std::string& program, const std::vector<std::string>& args) {
  std::string out = program;
  for (const auto& a : args) out += " " + a;
  return out;
}

bool IsExecutableFile(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && access(path.c_str(), X_OK) == 0;
}

// The program to exec: a path (relative to working_dir when given) or a
// name searched on PATH. Empty with *error when it cannot be run.
std::string ResolveProgram(const ProcessSpec& spec, std::string* error) {
  const std::string& cmd = spec.command;
  if (cmd.find('/') != std::string::npos) {
    std::string path = cmd;
    if (cmd[0] != '/' && !spec.working_dir.empty()) path = spec.working_dir + "/" + cmd;
    if (!IsExecutableFile(path)) {
      *error = "cannot run '" + path + "': " +
               (access(path.c_str(), F_OK) == 0 ? "not an executable file" : "no such file") +
               "; build it or fix 'command'";
      return "";
    }
    return path;
  }
  std::string path_var;
  auto it = spec.env.find("PATH");
  if (it != spec.env.end()) path_var = it->second;
  else if (const char* p = std::getenv("PATH")) path_var = p;
  std::stringstream dirs(path_var);
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    if (dir.empty()) dir = ".";
    const std::string candidate = dir + "/" + cmd;
    if (IsExecutableFile(candidate)) return candidate;
  }
  *error = "cannot run '" + cmd + "': not found on PATH; install it or give its full path in 'command'";
  return "";
}

}  // namespace

Supervisor::Supervisor(GroupFile file, SupervisorOptions options)
    : file_(std::move(file)), options_(std::move(options)) {
  for (const auto& spec : file_.processes) {
    auto p = std::make_unique<Proc>();
    p->spec = spec;
    p->index = static_cast<int>(procs_.size());
    procs_.push_back(std::move(p));
  }
  if (!options_.log_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(options_.log_dir, ec);
    if (ec) LOG(ERROR) << "cannot create log directory " << options_.log_dir << ": " << ec.message();
  }
  // A child whose reader is gone must not kill the launcher on write.
  signal(SIGPIPE, SIG_IGN);
  // What a child leaves behind (a daemon, setsid'd out of its group) is
  // re-parented to the launcher, not init: it stays in the tree Sweep() walks.
  self_ = getpid();
  if (prctl(PR_SET_CHILD_SUBREAPER, 1) != 0)
    LOG(ERROR) << "cannot become the child subreaper (" << std::strerror(errno)
               << "): what children leave behind re-parents to init and is only found by its "
               << kOwnerVariable << " marker";
  last_status_time_ = next_sweep_ = Clock::now();
}

Supervisor::~Supervisor() {
  KillAll();
  for (auto& p : procs_) {
    if (p->pid > 0) {
      int status = 0;
      waitpid(p->pid, &status, 0);
      kill(-p->pid, SIGKILL);
      p->pid = 0;
    }
    if (p->out_fd >= 0) close(p->out_fd);
    if (p->log_fd >= 0) close(p->log_fd);
    p->out_fd = p->log_fd = -1;
  }
  // Every other descendant too, and the orphans among them reaped (2 s at most).
  const auto until = Clock::now() + std::chrono::seconds(2);
  do {
    Sweep(Clock::now(), true);
    if (num_other_descendants_ == 0) break;
    usleep(10000);
  } while (Clock::now() < until);
}

bool Supervisor::ForTargets(const std::string& target, bool is_group, std::string* error,
                            const std::function<void(Proc&)>& action) {
  bool any = false;
  for (auto& p : procs_) {
    if ((is_group && p->spec.group == target) || (!is_group && p->spec.name == target)) {
      action(*p);
      any = true;
    }
  }
  if (!any && error) {
    std::string known;
    if (is_group) {
      for (const auto& g : file_.Groups()) known += " " + g;
    } else {
      for (const auto& p : procs_) known += " " + p->spec.name;
    }
    *error = std::string(is_group ? "unknown group '" : "unknown process '") + Printable(target) + "'; known:" + known;
  }
  return any;
}

bool Supervisor::StartGroups(const std::vector<std::string>& groups, std::string* error) {
  const auto known = file_.Groups();
  for (const auto& g : groups) {
    if (std::find(known.begin(), known.end(), g) == known.end()) {
      std::string list;
      for (const auto& k : known) list += " " + k;
      if (error) *error = "unknown group '" + g + "' in " + file_.path + "; groups in the file:" + list;
      return false;
    }
  }
  for (auto& p : procs_) {
    const bool chosen = groups.empty() || std::find(groups.begin(), groups.end(), p->spec.group) != groups.end();
    if (chosen && p->spec.autostart) RequestStart(*p);
  }
  return true;
}

bool Supervisor::Start(const std::string& target, bool is_group, std::string* error) {
  return ForTargets(target, is_group, error, [this](Proc& p) { RequestStart(p); });
}

bool Supervisor::Stop(const std::string& target, bool is_group, std::string* error) {
  return ForTargets(target, is_group, error, [this](Proc& p) { RequestStop(p, false); });
}

bool Supervisor::Restart(const std::string& target, bool is_group, std::string* error) {
  return ForTargets(target, is_group, error, [this](Proc& p) { RequestStop(p, true); });
}

void Supervisor::StopAll() {
  stopping_all_ = true;
  sweep_due_ = true;
  for (auto& p : procs_) RequestStop(*p, false);
}

void Supervisor::KillAll() {
  stopping_all_ = true;
  sweep_due_ = true;
  for (auto& p : procs_) {
    if (p->pid > 0) SignalDescendants(*p, SIGKILL);
    if (p->pid <= 0) {
      if (p->state == ProcState::kStarting || p->state == ProcState::kBackoff) p->state = ProcState::kStopped;
      continue;
    }
    kill(-p->pid, SIGKILL);
    kill(p->pid, SIGKILL);
    p->state = ProcState::kStopping;
    p->signal_sent = p->kill_sent = true;
    p->restart_after_stop = false;
  }
}

bool Supervisor::AllStopped() const {
  if (!lingering_.empty() || num_other_descendants_ > 0) return false;
  for (const auto& p : procs_) {
    if (p->pid > 0 || p->state == ProcState::kStarting || p->state == ProcState::kBackoff) return false;
  }
  return true;
}

void Supervisor::RequestStart(Proc& p) {
  p.selected = true;
  stopping_all_ = false;
  if (p.pid > 0) {
    if (p.state == ProcState::kStopping) p.restart_after_stop = true;
    return;
  }
  if (p.state == ProcState::kStarting) return;
  p.state = ProcState::kStarting;
  p.restarts_in_row = 0;
  p.backoff_step = 0;
  p.deps_ready_since.reset();
  p.waiting_noted = false;
}

void Supervisor::RequestStop(Proc& p, bool restart_after) {
  if (p.pid > 0) {
    if (p.state != ProcState::kStopping) {
      p.state = ProcState::kStopping;
      p.signal_sent = false;
      p.kill_sent = false;
      p.restart_after_stop = restart_after;
    } else {
      p.restart_after_stop = p.restart_after_stop || restart_after;
    }
    return;
  }
  if (restart_after) {
    p.state = ProcState::kStopped;
    RequestStart(p);
  } else if (p.state == ProcState::kStarting || p.state == ProcState::kBackoff) {
    p.state = ProcState::kStopped;
  }
}

void Supervisor::SendStop(Proc& p, Clock::time_point now) {
  Note(p, "stopping pid " + std::to_string(p.pid) + " with " + SignalName(p.spec.stop_signal) + ", " +
              Fmt(p.spec.stop_timeout) + " s allowed");
  kill(-p.pid, p.spec.stop_signal);
  SignalDescendants(p, p.spec.stop_signal);  // those that left its process group too
  p.signal_sent = true;
  p.stop_deadline = now + std::chrono::duration_cast<Clock::duration>(
                              std::chrono::duration<double>(p.spec.stop_timeout));
}

bool Supervisor::DependenciesRunning(const Proc& p) const {
  for (const auto& d : p.spec.depends_on) {
    for (const auto& q : procs_)
      if (q->spec.name == d && q->state != ProcState::kRunning) return false;
  }
  if (remote_check_) {
    for (const auto& [host, name] : p.spec.remote_depends_on)
      if (!remote_check_(host, name)) return false;
  }
  return true;
}

bool Supervisor::HasStoppingDependents(const Proc& p) const {
  for (const auto& q : procs_) {
    if (q->pid <= 0 || q->state != ProcState::kStopping) continue;
    if (std::find(q->spec.depends_on.begin(), q->spec.depends_on.end(), p.spec.name) != q->spec.depends_on.end())
      return true;
  }
  return false;
}

void Supervisor::Step(int timeout_ms) {
  PumpOutput(timeout_ms);
  const auto now = Clock::now();
  ReapExited(now);
  if (sweep_due_ || now >= next_sweep_) {
    bool all_down = stopping_all_;
    for (const auto& p : procs_) all_down = all_down && p->pid <= 0;
    Sweep(now, all_down);
  }
  KillLingeringGroups(now);
  for (auto& p : procs_) {
    switch (p->state) {
      case ProcState::kStopping:
        AdvanceStop(*p, now);
        break;
      case ProcState::kBackoff:
        if (now >= p->next_start_at) {
          ++p->restarts;
          Spawn(*p, now);
        }
        break;
      case ProcState::kStarting:
        AdvanceStart(*p, now);
        break;
      default:
        break;
    }
  }
}

void Supervisor::ReapExited(Clock::time_point now) {
  for (auto& p : procs_) {
    if (p->pid <= 0) continue;
    int status = 0;
    const pid_t r = waitpid(p->pid, &status, WNOHANG);
    if (r == p->pid) OnExit(*p, status, now);
    else if (r < 0 && errno == ECHILD) OnExit(*p, 0, now);  // reaped elsewhere: treat as ended
  }
}

void Supervisor::KillLingeringGroups(Clock::time_point now) {
  if (lingering_.empty()) return;
  const auto usage = ReadProcessGroupUsage();
  for (auto it = lingering_.begin(); it != lingering_.end();) {
    if (!usage.count(it->first)) {
      it = lingering_.erase(it);
    } else if (Seconds(now - it->second) > 5.0) {
      LOG(ERROR) << "process group " << it->first << " still has processes 5 s after SIGKILL; giving up on them";
      it = lingering_.erase(it);
    } else {
      kill(-it->first, SIGKILL);
      ++it;
    }
  }
}

void Supervisor::AdvanceStop(Proc& p, Clock::time_point now) {
  if (p.pid <= 0) return;
  if (!p.signal_sent) {
    if (!HasStoppingDependents(p)) SendStop(p, now);
  } else if (!p.kill_sent && now >= p.stop_deadline) {
    Note(p, "did not stop within " + Fmt(p.spec.stop_timeout) + " s; sending SIGKILL");
    kill(-p.pid, SIGKILL);
    kill(p.pid, SIGKILL);
    SignalDescendants(p, SIGKILL);
    p.kill_sent = true;
  }
}

void Supervisor::AdvanceStart(Proc& p, Clock::time_point now) {
  if (!DependenciesRunning(p)) {
    p.deps_ready_since.reset();
    if (!p.waiting_noted) {
      std::string deps;
      for (const auto& d : p.spec.depends_on) deps += " " + d;
      if (remote_check_)
        for (const auto& [host, name] : p.spec.remote_depends_on) deps += " " + name + " (host " + host + ")";
      Note(p, "waiting for:" + deps);
      p.waiting_noted = true;
    }
    return;
  }
  if (!p.deps_ready_since) p.deps_ready_since = now;
  if (Seconds(now - *p.deps_ready_since) >= p.spec.start_delay) Spawn(p, now);
}

namespace {

// The strings' buffers as a null-terminated array for execve (valid while
// the strings live unchanged).
std::vector<char*> NullTerminated(std::vector<std::string>& strings) {
  std::vector<char*> out;
  for (auto& s : strings) out.push_back(s.data());
  out.push_back(nullptr);
  return out;
}

// The child's environment: the launcher's, overridden by the process's env,
// and the owner mark (launcher pid : process index : instance) by which the
// launcher knows its descendants.
std::vector<std::string> ChildEnvironment(const std::map<std::string, std::string>& env, const std::string& owner) {
  std::vector<std::string> env_strings;
  for (char** e = environ; e && *e; ++e) {
    const std::string entry = *e;
    const std::string key = entry.substr(0, entry.find('='));
    if (!env.count(key)) env_strings.push_back(entry);
  }
  for (const auto& [k, v] : env) env_strings.push_back(k + "=" + v);
  env_strings.push_back(std::string(kOwnerVariable) + "=" + owner);
  return env_strings;
}

// The process table's entries by parent pid.
std::multimap<pid_t, const ProcEntry*> ChildrenByParent(const std::vector<ProcEntry>& table) {
  std::multimap<pid_t, const ProcEntry*> children;
  for (const auto& e : table) children.emplace(e.ppid, &e);
  return children;
}

// Every live (not ended) process below `roots`, breadth first.
std::vector<const ProcEntry*> LiveDescendants(const std::multimap<pid_t, const ProcEntry*>& children,
                                              const std::vector<pid_t>& roots) {
  std::vector<const ProcEntry*> found;
  const auto add_children = [&](pid_t parent) {
    const auto range = children.equal_range(parent);
    for (auto it = range.first; it != range.second; ++it)
      if (it->second->state != 'Z' && it->second->state != 'X') found.push_back(it->second);
  };
  for (const pid_t root : roots) add_children(root);
  for (size_t i = 0; i < found.size(); ++i) add_children(found[i]->pid);
  return found;
}

// In the child after fork: its own process group, dies with the launcher
// (`parent`), default signals, stdin from /dev/null, stdout and stderr into
// out_fd, its niceness set to `niceness` (computed before fork;
// kLaunchersNiceness: left as it is), then the program; exit 126 / 127 with
// one line when it cannot.
constexpr int kLaunchersNiceness = 100;
[[noreturn]] void ExecChild(pid_t parent, int out_fd, const char* workdir, int niceness, char* const* argv,
                            char* const* envp) {
  setpgid(0, 0);
  prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (getppid() != parent) _exit(1);
  sigset_t none;
  sigemptyset(&none);
  sigprocmask(SIG_SETMASK, &none, nullptr);
  for (int s : {SIGPIPE, SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGCHLD}) signal(s, SIG_DFL);
  const int devnull = open("/dev/null", O_RDONLY);
  if (devnull >= 0) dup2(devnull, 0);
  dup2(out_fd, 1);
  dup2(out_fd, 2);
  if (workdir && chdir(workdir) != 0) {
    dprintf(2, "vloc_launch: cannot enter working_dir %s: %s\n", workdir, std::strerror(errno));
    _exit(126);
  }
  if (niceness != kLaunchersNiceness && setpriority(PRIO_PROCESS, 0, niceness) != 0) {
    static const char kMessage[] = "vloc_launch: cannot lower the priority ('nice'); running at the launcher's\n";
    (void)!write(2, kMessage, sizeof(kMessage) - 1);
  }
  execve(argv[0], argv, envp);
  dprintf(2, "vloc_launch: cannot run %s: %s\n", argv[0], std::strerror(errno));
  _exit(127);
}

}  // namespace

void Supervisor::OpenLog(Proc& p) {
  if (p.log_opened || options_.log_dir.empty()) return;
  const std::string path = options_.log_dir + "/" + p.spec.name + ".log";
  p.log_fd = open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  if (p.log_fd < 0) LOG(ERROR) << "cannot write log file " << path << ": " << std::strerror(errno);
  p.log_opened = true;
}

void Supervisor::RetryStartLater(Proc& p, Clock::time_point now, const std::string& why) {
  Note(p, why + "; will retry");
  p.state = ProcState::kBackoff;
  p.next_start_at = now + std::chrono::seconds(1);
}

void Supervisor::Spawn(Proc& p, Clock::time_point now) {
  const ProcessSpec& spec = p.spec;
  OpenLog(p);
  std::string error;
  const std::string program = ResolveProgram(spec, &error);
  if (program.empty() || (!spec.working_dir.empty() && !std::filesystem::is_directory(spec.working_dir))) {
    if (error.empty()) error = "working_dir '" + spec.working_dir + "' is not a directory; fix 'working_dir'";
    WriteLine(p, "vloc_launch: " + error);
    LOG(ERROR) << file_.path << ": process '" << spec.name << "': " << error;
    p.state = ProcState::kGaveUp;
    p.last_exit_code = 127;
    p.has_exited = true;
    return;
  }
  // Everything the child needs is built before fork.
  std::vector<std::string> arg_strings = {program};
  arg_strings.insert(arg_strings.end(), spec.args.begin(), spec.args.end());
  const std::vector<char*> argv = NullTerminated(arg_strings);
  ++p.instance;
  std::vector<std::string> env_strings = ChildEnvironment(
      spec.env, std::to_string(self_) + ":" + std::to_string(p.index) + ":" + std::to_string(p.instance));
  const std::vector<char*> envp = NullTerminated(env_strings);
  const char* workdir = spec.working_dir.empty() ? nullptr : spec.working_dir.c_str();
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) return RetryStartLater(p, now, std::string("pipe failed: ") + std::strerror(errno));
  const pid_t parent = getpid();
  const int niceness =
      spec.nice > 0 ? std::clamp(getpriority(PRIO_PROCESS, 0) + spec.nice, -20, 19) : kLaunchersNiceness;
  const pid_t pid = fork();
  if (pid < 0) {
    close(fds[0]);
    close(fds[1]);
    return RetryStartLater(p, now, std::string("fork failed: ") + std::strerror(errno));
  }
  if (pid == 0) ExecChild(parent, fds[1], workdir, niceness, argv.data(), envp.data());
  setpgid(pid, pid);  // also here, so signals to -pid work at once
  close(fds[1]);
  fcntl(fds[0], F_SETFL, fcntl(fds[0], F_GETFL) | O_NONBLOCK);
  if (p.out_fd >= 0) close(p.out_fd);
  p.out_fd = fds[0];
  p.partial.clear();
  p.pid = pid;
  p.state = ProcState::kRunning;
  p.started_at = now;
  p.signal_sent = p.kill_sent = false;
  p.cpu_valid = false;
  p.waiting_noted = false;
  Note(p, "started pid " + std::to_string(pid) + (spec.nice > 0 ? " at nice " + std::to_string(niceness) : "") + ": " +
              JoinCommand(program, spec.args));
}

namespace {

// A wait status as an exit code (-signal when killed) and its words.
int ExitCode(int wait_status, std::string* how) {
  if (WIFSIGNALED(wait_status)) {
    *how = "killed by " + SignalName(WTERMSIG(wait_status));
    return -WTERMSIG(wait_status);
  }
  *how = "exited with code " + std::to_string(WEXITSTATUS(wait_status));
  return WEXITSTATUS(wait_status);
}

}  // namespace

void Supervisor::OnExit(Proc& p, int wait_status, Clock::time_point now) {
  FlushOutput(p);
  const pid_t pid = p.pid;
  // Whatever the process left behind in its group goes too; Step() checks
  // that it is gone before AllStopped() says so.
  if (kill(-pid, SIGKILL) == 0) lingering_.push_back({pid, now});
  p.pid = 0;
  sweep_due_ = true;  // and what it left elsewhere (Sweep)
  p.has_exited = true;
  std::string how;
  const int code = ExitCode(wait_status, &how);
  p.last_exit_code = code;
  const double ran = Seconds(now - p.started_at);
  Note(p, "pid " + std::to_string(pid) + " " + how + " after " + Fmt(ran) + " s");
  if (p.state == ProcState::kStopping) {
    const bool again = p.restart_after_stop;
    p.restart_after_stop = false;
    p.state = ProcState::kStopped;
    if (again) RequestStart(p);
    return;
  }
  const bool restart = p.spec.restart == RestartPolicy::kAlways ||
                       (p.spec.restart == RestartPolicy::kOnFailure && code != 0);
  if (!restart) {
    p.state = ProcState::kExited;
    return;
  }
  ScheduleRestart(p, ran, now);
}

void Supervisor::FlushOutput(Proc& p) {
  if (p.out_fd < 0) return;
  ReadOutput(p);
  if (p.out_fd < 0) return;
  if (!p.partial.empty()) WriteLine(p, p.partial);
  p.partial.clear();
  close(p.out_fd);
  p.out_fd = -1;
}

void Supervisor::ScheduleRestart(Proc& p, double ran, Clock::time_point now) {
  if (ran >= p.spec.backoff_max) {  // a long run: count its failures afresh
    p.backoff_step = 0;
    p.restarts_in_row = 0;
  }
  if (p.spec.max_restarts >= 0 && p.restarts_in_row >= p.spec.max_restarts) {
    p.state = ProcState::kGaveUp;
    Note(p, "gave up after " + std::to_string(p.restarts_in_row) + " restarts (max_restarts " +
                std::to_string(p.spec.max_restarts) + ")");
    LOG(ERROR) << "process '" << p.spec.name << "' gave up after " << p.restarts_in_row
               << " restarts; see its log file";
    return;
  }
  const double delay = std::min(p.spec.backoff_initial * std::pow(2.0, p.backoff_step), p.spec.backoff_max);
  ++p.backoff_step;
  ++p.restarts_in_row;
  p.state = ProcState::kBackoff;
  p.next_start_at = now + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(delay));
  Note(p, "restarting in " + Fmt(delay) + " s (restart " + std::to_string(p.restarts_in_row) + " of " +
              (p.spec.max_restarts < 0 ? std::string("unlimited") : std::to_string(p.spec.max_restarts)) + ")");
}

void Supervisor::PumpOutput(int timeout_ms) {
  std::vector<pollfd> fds;
  std::vector<Proc*> owners;
  for (auto& p : procs_) {
    if (p->out_fd < 0) continue;
    fds.push_back({p->out_fd, POLLIN, 0});
    owners.push_back(p.get());
  }
  const int n = poll(fds.empty() ? nullptr : fds.data(), fds.size(), std::max(0, timeout_ms));
  if (n <= 0) return;
  for (size_t i = 0; i < fds.size(); ++i)
    if (fds[i].revents & (POLLIN | POLLHUP | POLLERR)) ReadOutput(*owners[i]);
}

void Supervisor::ReadOutput(Proc& p) {
  char buffer[8192];
  while (p.out_fd >= 0) {
    const ssize_t n = read(p.out_fd, buffer, sizeof(buffer));
    if (n > 0) {
      p.partial.append(buffer, static_cast<size_t>(n));
      size_t start = 0, nl;
      while ((nl = p.partial.find('\n', start)) != std::string::npos) {
        WriteLine(p, p.partial.substr(start, nl - start));
        start = nl + 1;
      }
      p.partial.erase(0, start);
      if (p.partial.size() > 65536) {  // a very long line: write it in pieces
        WriteLine(p, p.partial);
        p.partial.clear();
      }
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return;
    // End of output (or an error): the child closed its side.
    if (!p.partial.empty()) WriteLine(p, p.partial);
    p.partial.clear();
    close(p.out_fd);
    p.out_fd = -1;
  }
}

void Supervisor::WriteLine(Proc& p, const std::string& line) {
  std::string text = "[" + p.spec.name + "] " + line;
  if (!text.empty() && text.back() == '\r') text.pop_back();
  text += '\n';
  if (p.log_fd >= 0) {
    const ssize_t w = write(p.log_fd, text.data(), text.size());
    (void)w;
  }
  if (options_.echo_output) {
    std::fwrite(text.data(), 1, text.size(), stdout);
    std::fflush(stdout);
  }
}

void Supervisor::Note(Proc& p, const std::string& text) {
  WriteLine(p, "vloc_launch: " + text);
  LOG(INFO) << p.spec.name << ": " << text;
}

std::vector<ProcessStatus> Supervisor::Status() {
  const auto now = Clock::now();
  const auto usage = ReadProcessGroupUsage();
  const double ticks_per_second = ClockTicksPerSecond();
  std::vector<ProcessStatus> out;
  for (auto& p : procs_) {
    ProcessStatus s;
    s.name = p->spec.name;
    s.group = p->spec.group;
    s.pid = p->pid;
    s.state = p->state;
    s.restarts = p->restarts;
    s.last_exit_code = p->last_exit_code;
    s.has_exited = p->has_exited;
    if (p->pid > 0) {
      s.uptime_seconds = Seconds(now - p->started_at);
      auto it = usage.find(p->pid);
      if (it != usage.end()) {
        s.rss_bytes = it->second.rss_bytes;
        if (p->cpu_valid) {
          const double dt = Seconds(now - p->last_cpu_time);
          const double dticks = it->second.cpu_ticks >= p->last_cpu_ticks
                                    ? static_cast<double>(it->second.cpu_ticks - p->last_cpu_ticks)
                                    : 0.0;
          if (dt > 0) s.cpu_percent = 100.0 * dticks / ticks_per_second / dt;
        }
        p->cpu_valid = true;
        p->last_cpu_ticks = it->second.cpu_ticks;
        p->last_cpu_time = now;
      }
    }
    out.push_back(s);
  }
  last_status_time_ = now;
  return out;
}

std::map<pid_t, uint64_t> Supervisor::CpuTicks() const {
  const auto table = ReadProcessTable();
  std::map<pid_t, uint64_t> ticks;
  for (const ProcEntry* e : LiveDescendants(ChildrenByParent(table), {self_})) ticks[e->pid] = e->cpu_ticks;
  return ticks;
}

bool Supervisor::AnyStartPending() const {
  return std::any_of(procs_.begin(), procs_.end(), [](const auto& p) {
    return p->state == ProcState::kStarting || p->state == ProcState::kBackoff;
  });
}

std::vector<std::string> Supervisor::ExitWhenDoneNames() const {
  std::vector<std::string> names;
  for (const auto& p : procs_)
    if (p->spec.exit_when_done) names.push_back(p->spec.name);
  return names;
}

std::optional<int> Supervisor::DoneOutcome(const std::vector<std::string>& names) const {
  std::vector<const Proc*> targets;
  for (const auto& p : procs_) {
    const bool named = std::find(names.begin(), names.end(), p->spec.name) != names.end();
    if (names.empty() ? p->selected : named) targets.push_back(p.get());
  }
  // A process waiting to start is blocked for good when a dependency (or
  // one of its dependencies) has ended and will not run again.
  std::function<bool(const Proc&, int)> blocked = [&](const Proc& p, int depth) {
    if (depth > 64) return false;
    for (const auto& d : p.spec.depends_on) {
      for (const auto& q : procs_) {
        if (q->spec.name != d) continue;
        if (q->state == ProcState::kExited || q->state == ProcState::kGaveUp || q->state == ProcState::kStopped)
          return true;
        if (q->state == ProcState::kStarting && blocked(*q, depth + 1)) return true;
      }
    }
    return false;
  };
  bool ok = true;
  for (const Proc* p : targets) {
    if (p->pid > 0 || p->state == ProcState::kBackoff) return std::nullopt;
    if (p->state == ProcState::kStarting) {
      if (!blocked(*p, 0)) return std::nullopt;
      ok = false;
      continue;
    }
    if (p->state == ProcState::kGaveUp) ok = false;
    if (p->state == ProcState::kExited && p->last_exit_code != 0) ok = false;
  }
  return ok ? 0 : 1;
}

void Supervisor::SignalDescendants(Proc& p, int sig) {
  if (p.pid <= 0) return;
  const auto table = ReadProcessTable();
  const auto children = ChildrenByParent(table);
  const std::string marker = std::to_string(self_) + ":" + std::to_string(p.index) + ":" + std::to_string(p.instance);
  std::vector<pid_t> roots{p.pid};
  // Below its pid, and the launcher's adopted orphans marked (or seen before) as this instance's.
  const auto adopted = children.equal_range(self_);
  for (auto it = adopted.first; it != adopted.second; ++it) {
    const ProcEntry& e = *it->second;
    if (e.pid == p.pid || e.state == 'Z') continue;
    const auto known = known_owners_.find(e.pid);
    const bool seen = known != known_owners_.end() && known->second.first == e.start_ticks &&
                      known->second.second.index == p.index && known->second.second.instance == p.instance;
    if (seen || ReadStartEnvironment(e.pid, kOwnerVariable) == marker) roots.push_back(e.pid);
  }
  for (size_t i = 1; i < roots.size(); ++i) kill(roots[i], sig);  // the adopted ones
  for (const ProcEntry* e : LiveDescendants(children, roots)) kill(e->pid, sig);
  sweep_due_ = true;
}

void Supervisor::Sweep(Clock::time_point now, bool everything) {
  sweep_due_ = false;
  next_sweep_ = now + std::chrono::seconds(1);
  const auto table = ReadProcessTable();
  const auto children = ChildrenByParent(table);
  std::map<pid_t, const Proc*> leaders;
  for (const auto& p : procs_)
    if (p->pid > 0) leaders[p->pid] = p.get();
  std::vector<OwnedEntry> tree = TopOfTree(children, leaders);
  const int live = KillLeftovers(children, leaders, now, everything, &tree);
  ForgetEndedKills(tree, now);
  num_other_descendants_ = live;
  if (live > 0 && everything) sweep_due_ = true;
}

std::vector<Supervisor::OwnedEntry> Supervisor::TopOfTree(const std::multimap<pid_t, const ProcEntry*>& children,
                                                          const std::map<pid_t, const Proc*>& leaders) const {
  std::vector<OwnedEntry> top;
  const auto range = children.equal_range(self_);
  for (auto it = range.first; it != range.second; ++it) {
    const ProcEntry& e = *it->second;
    Owner owner;
    if (const auto l = leaders.find(e.pid); l != leaders.end()) {
      owner = {l->second->index, l->second->instance};
    } else if (const auto k = known_owners_.find(e.pid); k != known_owners_.end() && k->second.first == e.start_ticks) {
      owner = k->second.second;
    } else if (const auto mark = ReadStartEnvironment(e.pid, kOwnerVariable)) {
      int launcher = 0, index = -1, instance = 0;
      if (std::sscanf(mark->c_str(), "%d:%d:%d", &launcher, &index, &instance) == 3 && launcher == self_ &&
          index >= 0 && index < static_cast<int>(procs_.size()))
        owner = {index, instance};
    }
    top.push_back({&e, owner});
  }
  return top;
}

int Supervisor::KillLeftovers(const std::multimap<pid_t, const ProcEntry*>& children,
                              const std::map<pid_t, const Proc*>& leaders, Clock::time_point now, bool everything,
                              std::vector<OwnedEntry>* tree) {
  std::map<pid_t, std::pair<uint64_t, Owner>> owners;
  int live = 0;
  for (size_t i = 0; i < tree->size(); ++i) {
    const ProcEntry& e = *(*tree)[i].first;
    const Owner owner = (*tree)[i].second;
    const auto range = children.equal_range(e.pid);
    for (auto it = range.first; it != range.second; ++it) tree->push_back({it->second, owner});
    if (owner.index >= 0) owners[e.pid] = {e.start_ticks, owner};
    if (leaders.count(e.pid)) continue;  // the processes themselves: Step() reaps and stops them
    if (e.state == 'Z' || e.state == 'X') {
      if (e.ppid == self_) waitpid(e.pid, nullptr, WNOHANG);  // an adopted orphan that ended
      continue;
    }
    const Proc* p = owner.index >= 0 ? procs_[owner.index].get() : nullptr;
    const bool leftover = everything || (p && (p->pid <= 0 || p->instance != owner.instance));
    if (leftover) {
      const auto k = killed_.find(e.pid);
      if (k == killed_.end()) {
        const std::string what = "pid " + std::to_string(e.pid) + " (" + Printable(e.comm) + ")";
        if (p) Note(*procs_[owner.index], "killing " + what + ", left behind by its instance " +
                                              std::to_string(owner.instance));
        else LOG(WARNING) << "killing " << what << ", a descendant of unknown origin";
        killed_[e.pid] = {now, false};
      } else if (k->second.second) {
        continue;  // given up on: no longer waited for
      }
      kill(e.pid, SIGKILL);
    }
    ++live;
  }
  known_owners_ = std::move(owners);
  return live;
}

void Supervisor::ForgetEndedKills(const std::vector<OwnedEntry>& tree, Clock::time_point now) {
  for (auto it = killed_.begin(); it != killed_.end();) {
    const bool alive = std::any_of(tree.begin(), tree.end(), [&](const auto& t) {
      return t.first->pid == it->first && t.first->state != 'Z' && t.first->state != 'X';
    });
    if (!alive) {
      it = killed_.erase(it);
      continue;
    }
    if (!it->second.second && Seconds(now - it->second.first) > 5.0) {
      LOG(ERROR) << "pid " << it->first << " still alive 5 s after SIGKILL; giving up on it";
      it->second.second = true;
    }
    ++it;
  }
}

std::vector<pid_t> Supervisor::LivePids() const {
  std::vector<pid_t> pids;
  for (const auto& p : procs_)
    if (p->pid > 0) pids.push_back(p->pid);
  return pids;
}

}  // namespace vloc
