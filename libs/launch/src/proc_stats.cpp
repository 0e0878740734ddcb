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
  pid_t ppid = 0;
  pid_t pgrp = 0;
  uint64_t start_ticks = 0;
  std::string comm;
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
  const size_t open = text.find('(');
  if (open != std::string::npos && open < close) s.comm = text.substr(open + 1, close - open - 1);
  std::istringstream rest(text.substr(close + 2));
  std::vector<std::string> f;  // f[0] is field 3 (state)
  std::string word;
  while (rest >> word) f.push_back(word);
  if (f.size() < 22) return std::nullopt;
  s.state = f[0].empty() ? '?' : f[0][0];
  s.ppid = static_cast<pid_t>(std::atol(f[1].c_str()));
  s.pgrp = static_cast<pid_t>(std::atol(f[2].c_str()));
  s.start_ticks = std::strtoull(f[19].c_str(), nullptr, 10);
  // utime + stime, and cutime + cstime: a child's time moves into its parent's when it is reaped
  // (a shell whose work runs in short-lived tools keeps counting).
  for (int k = 11; k <= 14; ++k) s.usage.cpu_ticks += std::strtoull(f[k].c_str(), nullptr, 10);
  s.usage.rss_bytes = std::atoll(f[21].c_str()) * static_cast<int64_t>(sysconf(_SC_PAGESIZE));
  s.usage.num_processes = 1;
  return s;
}

}  // namespace

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

std::vector<ProcEntry> ReadProcessTable() {
  std::vector<ProcEntry> table;
  DIR* dir = opendir("/proc");
  if (!dir) return table;
  while (dirent* e = readdir(dir)) {
    if (e->d_name[0] < '0' || e->d_name[0] > '9') continue;
    auto s = ReadStat(std::string("/proc/") + e->d_name + "/stat");
    if (!s) continue;
    table.push_back({s->pid, s->ppid, s->pgrp, s->state, s->start_ticks, s->comm, s->usage.cpu_ticks});
  }
  closedir(dir);
  return table;
}

std::vector<std::string> ReadCommandLine(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/cmdline", std::ios::binary);
  std::vector<std::string> args;
  std::string arg;
  while (args.size() < 4096 && std::getline(in, arg, '\0')) args.push_back(arg);
  return args;
}

std::vector<pid_t> FindProcesses(const std::string& program, const std::vector<std::string>& args) {
  std::vector<pid_t> found;
  for (const auto& e : ReadProcessTable()) {
    if (e.state == 'Z' || e.state == 'X') continue;
    const auto argv = ReadCommandLine(e.pid);
    if (argv.empty() || std::vector<std::string>(argv.begin() + 1, argv.end()) != args) continue;
    const size_t slash = argv[0].rfind('/');
    if (argv[0].substr(slash == std::string::npos ? 0 : slash + 1) == program) found.push_back(e.pid);
  }
  return found;
}

std::optional<std::string> ReadStartEnvironment(pid_t pid, const std::string& name) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/environ", std::ios::binary);
  if (!in) return std::nullopt;
  const std::string prefix = name + "=";
  std::string entry;
  size_t read = 0;
  while (read < (1u << 20) && std::getline(in, entry, '\0')) {
    read += entry.size() + 1;
    if (entry.compare(0, prefix.size(), prefix) == 0) return entry.substr(prefix.size());
  }
  return std::nullopt;
}

}  // namespace vloc
