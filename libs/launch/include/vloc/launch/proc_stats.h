#pragma once
// CPU time and resident memory of processes from /proc (Linux).

#include <sys/types.h>

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace vloc {

struct ProcUsage {
  uint64_t cpu_ticks = 0;  // user + system time, its reaped children's included, clock ticks
                           // (sysconf(_SC_CLK_TCK) per second)
  int64_t rss_bytes = 0;   // resident memory, bytes
  int num_processes = 0;   // processes summed
};

// Usage summed over every live (not zombie) process of each process group,
// keyed by the group id, from one pass over /proc.
std::map<pid_t, ProcUsage> ReadProcessGroupUsage();

// Clock ticks per second for cpu_ticks.
double ClockTicksPerSecond();

// True while a process with this pid exists and is not a zombie.
bool ProcessAlive(pid_t pid);

// One process as /proc/<pid>/stat tells it.
struct ProcEntry {
  pid_t pid = 0;
  pid_t ppid = 0;
  pid_t pgrp = 0;
  char state = '?';          // 'Z' zombie, 'R' running, 'S' sleeping, ...
  uint64_t start_ticks = 0;  // start time after boot, clock ticks (with pid: which process, across pid reuse)
  std::string comm;          // executable name (at most 15 characters)
  uint64_t cpu_ticks = 0;    // as ProcUsage::cpu_ticks
};

// Every process in /proc, one pass.
std::vector<ProcEntry> ReadProcessTable();

// A process's arguments (/proc/<pid>/cmdline); empty when it is gone or a zombie.
std::vector<std::string> ReadCommandLine(pid_t pid);

// Live processes (not zombies) running `program` (matched by file name)
// with exactly `args`: finds what a test started among everything else.
std::vector<pid_t> FindProcesses(const std::string& program, const std::vector<std::string>& args);

// The value of `name` in the environment a process was started with
// (/proc/<pid>/environ, its first 1 MB); nullopt when unset or unreadable.
std::optional<std::string> ReadStartEnvironment(pid_t pid, const std::string& name);

}  // namespace vloc
