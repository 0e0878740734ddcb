#include "vloc/launch/proc_stats.h"

#include <dirent.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace vloc {
namespace {

struct StatLine {
  pid_t pid = 0;
  char state = '?';
  pid_t pgrp = 0;
  ProcUsage usage;
};

std::optional<StatLine> ReadStat(const std::string& path) {
  std::ifstream in(path);
  if (!in) return std::nullopt;
  std::string text;
  std::getline(in, text);
  // "pid (comm) state ppid pgrp ..." -- comm may hold spaces and ')'.
  const size_t close = text.rfind(')');
  if (close == std::string::npos) return std::nullopt;
  StatLine s;
  s.pid = static_cast<pid_t>(std::atol(text.c_str()));
  std::istringstream rest(text.substr(close + 2));
  std::vector<std::string> f;  // f[0] is field 3 (state)
  std::string word;
  while (rest >> word) f.push_back(word);
  if (f.size() < 22) return std::nullopt;
  s.state = f[0].empty() ? '?' : f[0][0];
  s.pgrp = static_cast<pid_t>(std::atol(f[2].c_str()));
  s.usage.cpu_ticks = std::strtoull(f[11].c_str(), nullptr, 10) + std::strtoull(f[12].c_str(), nullptr, 10);
  s.usage.rss_bytes = std::atoll(f[21].c_str()) * static_cast<int64_t>(sysconf(_SC_PAGESIZE));
  s.usage.num_processes = 1;
  return s;
}

}  // namespace

std::optional<ProcUsage> ReadProcessUsage(pid_t pid) {
  auto s = ReadStat("/proc/" + std::to_string(pid) + "/stat");
  if (!s) return std::nullopt;
  return s->usage;
}

std::map<pid_t, ProcUsage> ReadProcessGroupUsage() {
  std::map<pid_t, ProcUsage> groups;
  DIR* dir = opendir("/proc");
  if (!dir) return groups;
  while (dirent* e = readdir(dir)) {
    if (e->d_name[0] < '0' || e->d_name[0] > '9') continue;
    auto s = ReadStat(std::string("/proc/") + e->d_name + "/stat");
    if (!s || s->state == 'Z' || s->state == 'X') continue;  // zombies hold no resources
    ProcUsage& g = groups[s->pgrp];
    g.cpu_ticks += s->usage.cpu_ticks;
    g.rss_bytes += s->usage.rss_bytes;
    g.num_processes += 1;
  }
  closedir(dir);
  return groups;
}

double ClockTicksPerSecond() { return static_cast<double>(sysconf(_SC_CLK_TCK)); }

bool ProcessAlive(pid_t pid) {
  auto s = ReadStat("/proc/" + std::to_string(pid) + "/stat");
  return s && s->state != 'Z' && s->state != 'X';
}

}  // namespace vloc
