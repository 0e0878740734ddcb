#pragma once
// Process-group files for vloc_launch (after libbot2's procman): a YAML file
// listing the processes of one or more groups, how to run them, when to
// start them and what to do when they end. Format (every key but name and
// command is optional; `defaults` sets any process key for all processes):
//
//   group: rover_sim                # group of processes that name none
//   env: {GLOG_v: "0"}              # environment added for every process
//   defaults: {restart: on-failure, max_restarts: 3, stop_timeout: 5}
//   processes:
//     - name: sim_rover             # unique; names the log file <log dir>/<name>.log
//       command: ${VLOC_BIN}/sim_rover    # path, or a program found on PATH
//       args: [--config, config/procs/sim_rover.yaml, --lcm-url, "${VLOC_LCM_URL}"]
//       env: {KEY: value}
//       group: rover_sim
//       depends_on: [logger]        # start once these are running
//       start_delay: 1.0            # s, after the dependencies run
//       restart: never              # never | on-failure | always
//       max_restarts: 3             # automatic restarts before GAVE_UP; -1 = no limit
//       backoff_initial: 0.5        # s, first restart delay, doubled each time
//       backoff_max: 10             # s, longest delay; a run this long resets it
//       stop_signal: SIGINT         # SIGINT | SIGTERM | SIGHUP | SIGQUIT | SIGUSR1 | SIGUSR2
//       stop_timeout: 5             # s, then SIGKILL
//       working_dir: ${VLOC_ROOT}
//       nice: 10                    # 0-19: higher yields the CPU to the others (a simulator below the localisation)
//       autostart: true             # start with its group
//       exit_when_done: true        # with --exit-when-done: its end ends the launcher
//       exit_grace: 10              # s, after that end, before the others are stopped
//       exit_idle: 3                # s, ... or sooner, once the others have been idle this long
//       host: vehicle               # host or role it runs on (see below)
//
// Groups across machines (one LCM bus, a launcher per machine, after
// libbot2's procman deputies): `host` names the machine or role a process
// runs on. Either no process names one (a single-machine file) or every
// process does (directly or through `defaults`). `vloc_launch --host
// vehicle` then starts only the processes of host `vehicle` (SelectHost);
// without --host a launcher runs the whole file on one machine. A
// depends_on on another host's process becomes a remote dependency of that
// launcher's part: vloc_launch waits until that host's launcher reports the
// process RUNNING on PROCMAN_STATUS.
// ${VAR} and ${VAR:-fallback} in command, args, env values and working_dir
// are expanded from the launcher's environment when the file is read; $$
// is a literal $. Errors are ConfigError with one line naming the file, the
// process, the key and the fix.

#include <yaml-cpp/yaml.h>

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace vloc {

enum class RestartPolicy { kNever, kOnFailure, kAlways };

// How to run and supervise one process.
struct ProcessSpec {
  std::string name;                          // unique in the file
  std::string command;                       // program: a path, or a name searched on PATH
  std::vector<std::string> args;             // arguments after the program name
  std::map<std::string, std::string> env;    // added to (overriding) the launcher's environment
  std::string group;                         // group name, for --group and group orders
  std::vector<std::string> depends_on;       // names that must be RUNNING before this starts
  double start_delay = 0.0;                  // s, wait after the dependencies run
  RestartPolicy restart = RestartPolicy::kOnFailure;  // when to restart after an exit
  int max_restarts = 5;                      // automatic restarts before giving up; -1 = no limit
  double backoff_initial = 0.5;              // s, delay before the first restart
  double backoff_max = 30.0;                 // s, longest restart delay (doubling); a run this long resets it
  int stop_signal = 15;                      // signal number sent to stop it (SIGTERM)
  double stop_timeout = 5.0;                 // s, time allowed to stop before SIGKILL
  std::string working_dir;                   // empty = the launcher's working directory
  int nice = 0;                              // scheduling niceness, 0-19: higher yields the CPU to the others
  bool autostart = true;                     // started when its group is started at launch
  bool exit_when_done = false;               // with --exit-when-done, the launcher ends when it ends
  double exit_grace = 0.0;                   // s, after an exit_when_done end, before stopping the rest
  double exit_idle = 0.0;                    // s, the grace ends once the rest has been idle this long; 0 = off
  std::string host;                          // host or role it runs on; empty = wherever the file is launched
  // Set by SelectHost: depends_on entries that run on another host, as
  // {host, process name}; the supervisor asks its RemoteCheck about them.
  std::vector<std::pair<std::string, std::string>> remote_depends_on;
};

// A parsed group file: processes in file order (the start order when no
// depends_on says otherwise).
struct GroupFile {
  std::string path;
  std::vector<ProcessSpec> processes;

  // Distinct group names in file order.
  std::vector<std::string> Groups() const;
  // Distinct host names in file order; empty for a single-machine file.
  std::vector<std::string> Hosts() const;
  const ProcessSpec* Find(const std::string& name) const;
};

// The part of `file` that runs on `host`: its processes, with depends_on
// entries naming another host's process moved to remote_depends_on.
// Throws ConfigError (one line naming the hosts the file has) when `host`
// has no process in the file or the file names no hosts.
GroupFile SelectHost(const GroupFile& file, const std::string& host);

// Returns the value of an environment-like variable, or nullopt when unset.
using VariableLookup = std::function<std::optional<std::string>(const std::string&)>;

// The launcher's own environment (getenv).
VariableLookup EnvironmentLookup();

// Expands ${VAR}, ${VAR:-fallback} and $$ in `text`. Returns false with one
// line in *error for an unset variable without fallback or a bad ${.
bool ExpandVariables(const std::string& text, const VariableLookup& lookup, std::string* out,
                     std::string* error);

// "SIGINT", "INT", "SIGTERM", ... or a number -> signal number; -1 when unknown.
int ParseSignalName(const std::string& name);
std::string SignalName(int signal_number);

// Reads and checks a group file. Throws ConfigError (one line) for a file
// that cannot be read, an unknown key, a missing name or command, a
// duplicate name, an unknown or circular dependency, a bad value, or an
// unset variable.
GroupFile ParseGroupFile(const std::string& path, const VariableLookup& lookup = EnvironmentLookup());
// The same from a YAML node; `context` names it in errors.
GroupFile ParseGroupYaml(const YAML::Node& root, const std::string& context,
                         const VariableLookup& lookup = EnvironmentLookup());

}  // namespace vloc
