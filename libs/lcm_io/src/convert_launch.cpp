#include "vloc/lcm_io/convert_launch.h"

namespace vloc {
namespace {

// A launcher's message with its header: time, host, pid.
template <class Msg>
Msg FromLauncher(const std::string& host, int32_t launcher_pid, int64_t utime) {
  Msg msg;
  msg.utime = utime;
  msg.host = host;
  msg.launcher_pid = launcher_pid;
  return msg;
}

// The fields a process's status and its message share by name.
template <class From, class To>
void CopyCommonFields(const From& from, To* to) {
  to->name = from.name;
  to->group = from.group;
  to->pid = from.pid;
  to->restarts = from.restarts;
  to->last_exit_code = from.last_exit_code;
}

}  // namespace

procman_status_t ProcmanStatusToMessage(const std::string& host, int32_t launcher_pid, int64_t utime,
                                        const std::vector<ProcessStatus>& procs) {
  auto msg = FromLauncher<procman_status_t>(host, launcher_pid, utime);
  for (const ProcessStatus& s : procs) {
    proc_status_t p;
    CopyCommonFields(s, &p);
    p.state = static_cast<int8_t>(s.state);
    p.cpu_percent = s.cpu_percent;
    p.rss_bytes = s.rss_bytes;
    p.uptime_seconds = s.uptime_seconds;
    msg.procs.push_back(p);
  }
  msg.num_procs = static_cast<int32_t>(msg.procs.size());
  return msg;
}

PeerReport PeerReportFromMessage(const procman_status_t& msg) {
  PeerReport report;
  report.host = msg.host;
  report.launcher_pid = msg.launcher_pid;
  for (const proc_status_t& p : msg.procs) {
    ProcessStatus s;
    CopyCommonFields(p, &s);
    s.state = static_cast<ProcState>(p.state);
    s.has_exited = p.last_exit_code != 0 || p.state == proc_status_t::STATE_EXITED;
    report.procs.push_back(s);
  }
  return report;
}

procman_peers_t ProcmanPeersToMessage(const std::string& host, int32_t launcher_pid, int64_t utime,
                                      double lost_after_s, const std::vector<PeerView>& peers) {
  auto msg = FromLauncher<procman_peers_t>(host, launcher_pid, utime);
  msg.lost_after_seconds = lost_after_s;
  for (const PeerView& v : peers) {
    procman_peer_t p;
    p.host = v.host;
    p.launcher_pid = v.launcher_pid;
    p.state = v.lost ? procman_peer_t::STATE_LOST : procman_peer_t::STATE_ALIVE;
    p.seconds_since_heard = v.seconds_since_heard;
    p.reports = v.reports;
    p.times_lost = v.times_lost;
    msg.peers.push_back(p);
  }
  msg.num_peers = static_cast<int32_t>(msg.peers.size());
  return msg;
}

}  // namespace vloc
