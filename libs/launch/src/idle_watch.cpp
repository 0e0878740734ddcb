#include "vloc/launch/idle_watch.h"

namespace vloc {

IdleWatch::IdleWatch(double idle_s, double ticks_per_second, double max_core_fraction)
    : idle_s_(idle_s), ticks_per_second_(ticks_per_second), max_core_fraction_(max_core_fraction) {}

bool IdleWatch::Update(double t, const std::map<pid_t, uint64_t>& ticks, bool start_pending) {
  if (!started_ || t <= last_t_) {
    if (!started_) idle_since_ = t;
    started_ = true;
    last_ = ticks, last_t_ = t;
    return false;
  }
  bool busy = start_pending || !(ticks_per_second_ > 0);
  uint64_t used = 0;
  for (const auto& [pid, now] : ticks) {
    const auto before = last_.find(pid);
    if (before == last_.end()) used += now;  // started since: all its time is new
    else if (now > before->second) used += now - before->second;
  }
  busy = busy || static_cast<double>(used) / ticks_per_second_ > max_core_fraction_ * (t - last_t_);
  if (busy) idle_since_ = t;
  last_ = ticks, last_t_ = t;
  return t - idle_since_ >= idle_s_;
}

}  // namespace vloc
