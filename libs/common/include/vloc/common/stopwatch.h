#pragma once
// Elapsed wall time, for the summaries' timings.

#include <chrono>

namespace vloc {

// Seconds of steady-clock time since `start`.
inline double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Started when made; Seconds() is the wall time since then (or the last Restart()).
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  void Restart() { start_ = std::chrono::steady_clock::now(); }
  double Seconds() const { return SecondsSince(start_); }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace vloc
