#pragma once
// vloc_launch's run, apart from main(): supervise and report until a stop
// signal or (--exit-when-done) the end of the named processes, then stop
// every process and publish the last status.

#include <optional>
#include <string>
#include <vector>

#include "launch_adapter.h"
#include "vloc/launch/group_file.h"
#include "vloc/launch/supervisor.h"
#include "vloc/lcm_io/transport.h"

namespace vloc {

struct LaunchRunOptions {
  bool exit_when_done = false;         // end when the processes of done_names have ended (--exit-when-done)
  std::vector<std::string> done_names; // those processes (with exit_when_done; checked against the file)
  std::optional<double> exit_grace_s;  // s, after a clean end, before stopping the rest (--exit-grace); default:
                                       // the largest exit_grace of done_names in the file
};

// Runs `supervisor` and `adapter` on `transport` (20 ms waits) until
// SIGINT/SIGTERM or, with exit_when_done, the end of done_names; after a
// clean end gives the others the grace period, then stops every process (a
// second signal kills them), publishes the final status and returns the exit
// code: 0, or 1 when a done process failed.
int RunLauncher(Transport& transport, Supervisor& supervisor, LaunchLcmAdapter& adapter,
                const LaunchRunOptions& options);

}  // namespace vloc
