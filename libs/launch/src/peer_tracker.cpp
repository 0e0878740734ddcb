#include "vloc/launch/peer_tracker.h"

#include <cmath>
#include <sstream>

#include "vloc/common/options.h"

namespace vloc {

namespace {

double Seconds(PeerTracker::Clock::duration d) { return std::chrono::duration<double>(d).count(); }

std::string Fmt(double seconds) {
  std::ostringstream out;
  out.precision(2);
  out << std::fixed << seconds;
  return out.str();
}

}  // namespace

void PeerTrackerOptions::Visit(OptionsReader& r) {
  r.Optional("lost_after_s", &lost_after_s, "s without a status report before a launcher is LOST (1 Hz reports)",
             Positive() && Finite());
}

bool PeerTrackerOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

PeerTracker::PeerTracker(std::string own_host, int own_pid, PeerTrackerOptions options)
    : own_host_(std::move(own_host)), own_pid_(own_pid), options_(options) {}

std::vector<PeerEvent> PeerTracker::OnReport(const PeerReport& report, Clock::time_point now) {
  std::vector<PeerEvent> events;
  if (report.host == own_host_ && report.launcher_pid == own_pid_) return events;
  const std::string& host = report.host;
  if (host == own_host_) {
    // Another launcher claims this launcher's host: both would run its part.
    NoteDuplicateOnce(report.launcher_pid, host,
                      "another launcher (pid " + std::to_string(report.launcher_pid) + ") also calls itself '" + host +
                          "': both run that host's processes; give each machine its own --host",
                      &events);
    return events;
  }
  auto found = peers_.find(host);
  const bool is_new = found == peers_.end();
  Peer& peer = peers_[host];
  if (is_new) {
    events.push_back({PeerEventKind::kJoined, host, "",
                      "launcher '" + host + "' (pid " + std::to_string(report.launcher_pid) + ") joined with " +
                          std::to_string(report.procs.size()) + " processes"});
  } else {
    if (peer.lost)
      events.push_back({PeerEventKind::kBack, host, "",
                        "launcher '" + host + "' is back after " + Fmt(Seconds(now - peer.last_heard)) +
                            " s without a report (lost for " + Fmt(Seconds(now - peer.lost_since)) + " s)"});
    if (peer.launcher_pid != report.launcher_pid) OnOtherLauncher(host, peer, report.launcher_pid, now, &events);
    ProcessChanges(host, peer, report, &events);
  }
  peer.procs.clear();
  for (const auto& p : report.procs) peer.procs[p.name] = p;
  peer.launcher_pid = report.launcher_pid;
  peer.last_heard = now;
  peer.lost = false;
  ++peer.reports;
  return events;
}

void PeerTracker::NoteDuplicateOnce(int launcher_pid, const std::string& host, const std::string& text,
                                    std::vector<PeerEvent>* events) {
  if (!duplicate_noted_.insert(launcher_pid).second) return;
  events->push_back({PeerEventKind::kDuplicateHost, host, "", text});
}

void PeerTracker::OnOtherLauncher(const std::string& host, const Peer& peer, int launcher_pid, Clock::time_point now,
                                  std::vector<PeerEvent>* events) {
  if (!peer.lost && Seconds(now - peer.last_heard) < options_.lost_after_s) {
    // Two live launchers under one name (reports alternate): say it once.
    NoteDuplicateOnce(launcher_pid, host,
                      "two launchers call themselves '" + host + "' (pids " + std::to_string(peer.launcher_pid) +
                          " and " + std::to_string(launcher_pid) +
                          "): both run that host's processes; give each machine its own --host",
                      events);
    return;
  }
  events->push_back({PeerEventKind::kLauncherRestarted, host, "",
                     "launcher '" + host + "' restarted: pid " + std::to_string(peer.launcher_pid) + " -> " +
                         std::to_string(launcher_pid)});
}

void PeerTracker::ProcessChanges(const std::string& host, const Peer& peer, const PeerReport& report,
                                 std::vector<PeerEvent>* events) {
  for (const auto& p : report.procs) {
    auto it = peer.procs.find(p.name);
    if (it == peer.procs.end()) continue;
    const ProcessStatus& was = it->second;
    if (was.state == p.state && was.pid == p.pid && was.restarts == p.restarts) continue;
    std::string text = "launcher '" + host + "': process '" + p.name + "' " + ProcStateName(was.state) + " -> " +
                       ProcStateName(p.state);
    if (was.pid != p.pid) text += ", pid " + std::to_string(was.pid) + " -> " + std::to_string(p.pid);
    if (was.restarts != p.restarts) text += ", restarts " + std::to_string(p.restarts);
    if (p.has_exited && p.state != ProcState::kRunning) text += ", last exit " + std::to_string(p.last_exit_code);
    events->push_back({PeerEventKind::kProcessChanged, host, p.name, text});
  }
}

std::vector<PeerEvent> PeerTracker::Check(Clock::time_point now) {
  std::vector<PeerEvent> events;
  for (auto& [host, peer] : peers_) {
    const double silent = Seconds(now - peer.last_heard);
    if (peer.lost || silent < options_.lost_after_s) continue;
    peer.lost = true;
    peer.lost_since = now;
    ++peer.times_lost;
    std::string procs;
    for (const auto& [name, p] : peer.procs)
      if (p.state == ProcState::kRunning) procs += (procs.empty() ? "" : ", ") + name;
    events.push_back({PeerEventKind::kLost, host, "",
                      "launcher '" + host + "' (pid " + std::to_string(peer.launcher_pid) + ") LOST: no report for " +
                          Fmt(silent) + " s; its processes (last seen running: " +
                          (procs.empty() ? "none" : procs) + ") are in an unknown state"});
  }
  return events;
}

bool PeerTracker::IsRunning(const std::string& host, const std::string& name) const {
  auto it = peers_.find(host);
  if (it == peers_.end() || it->second.lost) return false;
  auto p = it->second.procs.find(name);
  return p != it->second.procs.end() && p->second.state == ProcState::kRunning;
}

std::vector<PeerView> PeerTracker::Peers(Clock::time_point now) const {
  std::vector<PeerView> views;
  for (const auto& [host, peer] : peers_) {
    PeerView v;
    v.host = host;
    v.launcher_pid = peer.launcher_pid;
    v.lost = peer.lost;
    v.seconds_since_heard = Seconds(now - peer.last_heard);
    v.reports = peer.reports;
    v.times_lost = peer.times_lost;
    views.push_back(v);
  }
  return views;
}

}  // namespace vloc
