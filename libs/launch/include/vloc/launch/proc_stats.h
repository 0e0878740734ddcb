#pragma once
// CPU time and resident memory of processes from /proc (Linux).

#include <sys/types.h>

#include <cstdint>
#include <map>
#include <optional>

namespace vloc {

struct ProcUsage {
  uint64_t cpu_ticks = 0;  // user + system time, clock ticks (sysconf(_SC_CLK_TCK) per second)
  int64_t rss_bytes = 0;   // resident memory, bytes
  int num_processes = 0;   // processes summed
};

// Usage of one process from /proc/<pid>/stat; nullopt when it is gone.
std::optional<ProcUsage> ReadProcessUsage(pid_t pid);

// Usage summed over every live (not zombie) process of each process group,
// keyed by the group id, from one pass over /proc.
std::map<pid_t, ProcUsage> ReadProcessGroupUsage();

// Clock ticks per second for cpu_ticks.
double ClockTicksPerSecond();

// True while a process with this pid exists and is not a zombie.
bool ProcessAlive(pid_t pid);

}  // namespace vloc
