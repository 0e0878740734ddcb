// vloc_launch: starts a process group from a group file, restarts what
// crashes, logs each process's output, publishes PROCMAN_STATUS at 1 Hz and
// obeys PROCMAN_ORDERS. SIGINT/SIGTERM stops every child (its stop signal,
// then SIGKILL after its stop_timeout). See libs/launch/include/vloc/launch/group_file.h.
// With --host NAME it runs only the processes of host (role) NAME of a
// group split across machines, names itself NAME in PROCMAN_STATUS and
// reports the other hosts' launchers (PROCMAN_PEERS; LOST after --lost-after s).

#include <unistd.h>

#include <iostream>

#include "launch_adapter.h"
#include "launch_environment.h"
#include "launch_run.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/launch/group_file.h"
#include "vloc/launch/supervisor.h"
#include "vloc/lcm_io/process.h"

namespace {

// The group file (`whole`) and this host's part of it (`file`: all of it
// without --host), --lost-after into `peer_options`; false after one error line.
bool ReadGroupFile(const vloc::ProcessSetup& setup, const std::string& host, vloc::GroupFile* whole,
                   vloc::GroupFile* file, vloc::PeerTrackerOptions* peer_options) {
  peer_options->lost_after_s = setup.args.GetDouble("lost-after", peer_options->lost_after_s);
  try {
    *whole = *file = vloc::ParseGroupFile(setup.config_path);
    if (!host.empty()) *file = vloc::SelectHost(*whole, host);
    std::string error;
    if (!peer_options->Check(&error)) throw vloc::ConfigError("--lost-after: " + error);
  } catch (const vloc::ConfigError& e) {
    std::cerr << "vloc_launch: " << e.what() << "\n";
    return false;
  }
  return true;
}

// --exit-when-done's names are processes of `file`; false after one error line.
bool ProcessesOf(const vloc::GroupFile& file, const std::vector<std::string>& names) {
  for (const auto& n : names) {
    if (!file.Find(n)) {
      std::cerr << "vloc_launch: --exit-when-done names unknown process '" << n << "' (not in " << file.path << ")\n";
      return false;
    }
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  const std::vector<std::string> groups = vloc::CollectFlagValues(argc, argv, "group");
  std::vector<std::string> arg_strings = vloc::ArgsWithDefaultLcmUrl(argc, argv);
  std::vector<char*> args;
  for (auto& a : arg_strings) args.push_back(a.data());
  auto setup = vloc::SetupProcess(
      static_cast<int>(args.size()), args.data(),
      {"vloc_launch",
       {"group", "log-dir", "bin-dir", "exit-when-done", "exit-grace", "echo", "host", "lost-after"},
       true,
       "--config config/groups/rover_sim.yaml [--host NAME] [--group NAME[,NAME] ...] [--log-dir DIR] "
       "[--lcm-url URL] [--bin-dir DIR] [--exit-when-done[=NAME,...]] [--exit-grace S] [--lost-after S] [--echo]"});
  if (!setup) return 1;

  vloc::LaunchPaths paths;
  std::string error;
  if (!vloc::SetupLaunchEnvironment(setup->args, setup->lcm_url, &paths, &error)) {
    std::cerr << "vloc_launch: " << error << "\n";
    return 1;
  }
  const std::string host = setup->args.Get("host", "");
  vloc::PeerTrackerOptions peer_options;
  vloc::GroupFile whole, file;
  if (!ReadGroupFile(*setup, host, &whole, &file, &peer_options)) return 1;
  const bool exit_when_done = setup->args.Has("exit-when-done");
  std::vector<std::string> done_names = vloc::CollectFlagValues(argc, argv, "exit-when-done");
  if (!ProcessesOf(file, done_names)) return 1;
  LOG(INFO) << "group file " << file.path << ": " << file.processes.size() << " processes"
            << (host.empty() ? "" : " of host " + host + " (" + std::to_string(whole.processes.size()) + " in all)")
            << "; VLOC_BIN="
            << paths.bin_dir << " VLOC_ROOT=" << paths.root << " logs in " << paths.log_dir;

  vloc::Supervisor supervisor(file, {paths.log_dir, setup->args.Has("echo")});
  if (exit_when_done && done_names.empty()) done_names = supervisor.ExitWhenDoneNames();
  if (!supervisor.StartGroups(groups, &error)) {
    std::cerr << "vloc_launch: " << error << "\n";
    return 1;
  }
  char machine[256] = {};
  gethostname(machine, sizeof(machine) - 1);
  vloc::LaunchLcmAdapter adapter(supervisor, *setup->transport, host.empty() ? std::string(machine) : host, 1.0,
                                 peer_options, host.empty() ? nullptr : &whole);
  adapter.Subscribe();

  vloc::LaunchRunOptions run{exit_when_done, done_names, std::nullopt};
  if (setup->args.Has("exit-grace")) run.exit_grace_s = setup->args.GetDouble("exit-grace", 0.0);
  return vloc::RunLauncher(*setup->transport, supervisor, adapter, run);
}
