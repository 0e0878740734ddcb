#include "launch_run.h"

#include <glog/logging.h>

#include <algorithm>
#include <chrono>

#include "vloc/lcm_io/process.h"

namespace vloc {

int RunLauncher(Transport& transport, Supervisor& supervisor, LaunchLcmAdapter& adapter,
                const LaunchRunOptions& options) {
  const auto step = [&](int wait_ms) {
    supervisor.Step(wait_ms);
    adapter.Tick();
  };
  std::optional<int> outcome;
  RunUntilSignal(
      transport, 20, [&] { step(30); },
      [&] {
        if (options.exit_when_done) outcome = supervisor.DoneOutcome(options.done_names);
        return outcome.has_value();
      });

  if (outcome && *outcome == 0) {
    // Give the others time to finish their last piece of work.
    double grace = 0.0;
    for (const auto& n : options.done_names)
      if (const auto* spec = supervisor.file().Find(n)) grace = std::max(grace, spec->exit_grace);
    grace = options.exit_grace_s.value_or(grace);
    LOG(INFO) << "done (--exit-when-done): stopping the rest in " << grace << " s";
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(grace);
    while (std::chrono::steady_clock::now() < until && !StopSignalPending()) {
      transport.Handle(20);
      step(30);
    }
  }
  if (outcome && *outcome != 0) LOG(ERROR) << "done (--exit-when-done) with a failure; stopping the rest";
  adapter.SetShuttingDown();
  supervisor.StopAll();
  while (!supervisor.AllStopped()) {
    if (StopSignalPending()) {
      LOG(WARNING) << "second stop signal: killing every process now";
      supervisor.KillAll();
    }
    step(50);
  }
  adapter.PublishStatus();
  LOG(INFO) << "every process stopped; orders: " << adapter.SubscriptionLine() << "; exiting";
  return outcome.value_or(0);
}

}  // namespace vloc
