#include "launch_run.h"

#include <glog/logging.h>

#include <algorithm>
#include <chrono>

#include "vloc/launch/idle_watch.h"
#include "vloc/launch/proc_stats.h"
#include "vloc/lcm_io/process.h"

namespace vloc {

namespace {

// After a clean end: time for the others to finish their last piece of
// work, the largest exit_grace of the done processes (or --exit-grace),
// cut short once they have been idle for the largest exit_idle.
template <class Step>
void GiveGrace(Transport& transport, Supervisor& supervisor, const LaunchRunOptions& options, const Step& step) {
  double grace = 0.0, idle_s = 0.0;
  for (const auto& n : options.done_names) {
    if (const auto* spec = supervisor.file().Find(n)) {
      grace = std::max(grace, spec->exit_grace);
      idle_s = std::max(idle_s, spec->exit_idle);
    }
  }
  grace = options.exit_grace_s.value_or(grace);
  if (idle_s > 0) {
    LOG(INFO) << "done (--exit-when-done): stopping the rest in " << grace << " s, or once it has been idle for "
              << idle_s << " s";
  } else {
    LOG(INFO) << "done (--exit-when-done): stopping the rest in " << grace << " s";
  }
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const auto until = start + std::chrono::duration<double>(grace);
  IdleWatch idle(idle_s, ClockTicksPerSecond());
  auto next_sample = start;
  while (Clock::now() < until && !StopSignalPending()) {
    transport.Handle(20);
    step(30);
    const auto now = Clock::now();
    if (idle_s <= 0 || now < next_sample) continue;
    next_sample = now + std::chrono::milliseconds(500);
    const double t = std::chrono::duration<double>(now - start).count();
    if (idle.Update(t, supervisor.CpuTicks(), supervisor.AnyStartPending())) {
      LOG(INFO) << "the rest idle for " << idle_s << " s, " << t << " s into the grace: stopping the rest";
      return;
    }
  }
}

}  // namespace

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

  if (outcome && *outcome == 0) GiveGrace(transport, supervisor, options, step);
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
