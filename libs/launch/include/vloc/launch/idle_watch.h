#pragma once
// When a group of processes has gone idle (vloc_launch's exit_idle: the
// grace after the simulator's end stops as soon as the pipeline has
// finished its last piece of work instead of waiting out the full grace).

#include <sys/types.h>

#include <cstdint>
#include <map>

namespace vloc {

class IdleWatch {
 public:
  // Idle: the processes together used under `max_core_fraction` of one
  // core for `idle_s` seconds.
  IdleWatch(double idle_s, double ticks_per_second, double max_core_fraction = 0.05);
  // The CPU ticks of each running process by pid (Supervisor::CpuTicks) at
  // time `t` (s, monotonic), fed now and then: true once idle. A process
  // that appeared since the last call counts with all its time;
  // `start_pending` (one about to restart) is busy. What uses no CPU (a
  // timer, disk or network waits) looks idle: exit_idle is for pipelines
  // that compute to the end.
  bool Update(double t, const std::map<pid_t, uint64_t>& ticks, bool start_pending = false);

 private:
  double idle_s_, ticks_per_second_, max_core_fraction_;
  bool started_ = false;
  double last_t_ = 0, idle_since_ = 0;
  std::map<pid_t, uint64_t> last_;
};

}  // namespace vloc
