#pragma once
// Logs the first occurrence of a problem, then at most one line per period
// with the number of occurrences not logged in between: a flood of bad
// messages gives a few lines, never one per message, and never silence.
//   static RateLimitedLog log;
//   if (log.ShouldLog()) LOG(ERROR) << "bad thing" << log.Suppressed();

#include <chrono>
#include <cstdint>
#include <string>

namespace vloc {

class RateLimitedLog {
 public:
  explicit RateLimitedLog(double period_s = 5.0) : period_s_(period_s) {}

  // True for the first call and then once per period; counts the rest.
  bool ShouldLog() {
    const double now = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
    if (logged_ > 0 && now - last_s_ < period_s_) {
      ++pending_;
      return false;
    }
    ++logged_;
    last_s_ = now;
    suppressed_ = pending_;
    pending_ = 0;
    return true;
  }
  // " (N more not logged)" when the last ShouldLog() skipped some, else "".
  std::string Suppressed() const {
    return suppressed_ > 0 ? " (" + std::to_string(suppressed_) + " more not logged in the last " +
                                 std::to_string(static_cast<int>(period_s_)) + " s)"
                           : std::string();
  }

 private:
  double period_s_;
  double last_s_ = 0;
  int64_t logged_ = 0, pending_ = 0, suppressed_ = 0;
};

}  // namespace vloc
