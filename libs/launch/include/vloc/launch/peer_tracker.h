#pragma once
// What one launcher knows of the others on its LCM bus (libbot2's sheriff
// view of its deputies), with no LCM in it: fed every status report the
// launcher hears, it names launchers that join, fall silent for
// lost_after_s (LOST), come back, restart (new pid), and the processes of
// other hosts that change state or restart.
//
//   PeerTracker peers("ground", getpid(), {});
//   for (const PeerEvent& e : peers.OnReport(report, now)) LOG(INFO) << e.text;
//   for (const PeerEvent& e : peers.Check(now)) LOG(WARNING) << e.text;

#include <sys/types.h>

#include <chrono>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "vloc/launch/supervisor.h"

namespace vloc {

class OptionsReader;

struct PeerTrackerOptions {
  double lost_after_s = 3.0;  // s without a status report before a launcher is LOST (3 missed 1 Hz reports)

  void Visit(OptionsReader& r);
  // Returns false with one line in *error for a bad value.
  bool Check(std::string* error) const;
};

// One launcher's status report, as received.
struct PeerReport {
  std::string host;                     // the launcher's host (or role) name
  int launcher_pid = 0;
  std::vector<ProcessStatus> procs;     // name, state, pid, restarts, last_exit_code are used
};

enum class PeerEventKind {
  kJoined,            // first report from this host
  kLost,              // no report for lost_after_s
  kBack,              // reports again after being lost
  kLauncherRestarted, // same host, new launcher pid (the old one silent for lost_after_s)
  kDuplicateHost,     // two live launchers report the same host name
  kProcessChanged,    // one of its processes changed state, pid or restart count
};

struct PeerEvent {
  PeerEventKind kind;
  std::string host;
  std::string process;  // kProcessChanged only
  std::string text;     // one line for the log, naming host, process and what changed
};

// A launcher as currently seen.
struct PeerView {
  std::string host;
  int launcher_pid = 0;
  bool lost = false;
  double seconds_since_heard = 0.0;  // s
  int reports = 0;                   // reports received from it
  int times_lost = 0;                // times it went LOST
};

class PeerTracker {
 public:
  using Clock = std::chrono::steady_clock;

  // `own_host` / `own_pid`: this launcher, whose own reports are ignored.
  PeerTracker(std::string own_host, int own_pid, PeerTrackerOptions options);

  std::vector<PeerEvent> OnReport(const PeerReport& report, Clock::time_point now);
  // Launchers that have just become LOST.
  std::vector<PeerEvent> Check(Clock::time_point now);
  // True when `host`'s launcher is not LOST and last reported `name` RUNNING.
  bool IsRunning(const std::string& host, const std::string& name) const;
  // Every launcher heard from, by host name.
  std::vector<PeerView> Peers(Clock::time_point now) const;

 private:
  struct Peer {
    int launcher_pid = 0;
    Clock::time_point last_heard;
    Clock::time_point lost_since;
    bool lost = false;
    int reports = 0;
    int times_lost = 0;
    std::map<std::string, ProcessStatus> procs;
  };
  // OnReport's parts: a duplicate host said once per launcher pid; a known
  // host under another pid (a second live launcher, or a restart); each
  // process whose state, pid or restarts changed since the last report.
  void NoteDuplicateOnce(int launcher_pid, const std::string& host, const std::string& text,
                         std::vector<PeerEvent>* events);
  void OnOtherLauncher(const std::string& host, const Peer& peer, int launcher_pid, Clock::time_point now,
                       std::vector<PeerEvent>* events);
  static void ProcessChanges(const std::string& host, const Peer& peer, const PeerReport& report,
                             std::vector<PeerEvent>* events);
  std::string own_host_;
  int own_pid_;
  PeerTrackerOptions options_;
  std::map<std::string, Peer> peers_;
  std::set<int> duplicate_noted_;  // launcher pids already reported as a duplicate host
};

}  // namespace vloc
