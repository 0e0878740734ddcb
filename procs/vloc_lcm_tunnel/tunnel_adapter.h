#pragma once
// vloc_lcm_tunnel's wiring: the LCM bus on one side (a subscription to the
// channels it sends, a publisher of what the peer sends and of
// TUNNEL_STATUS), the ZeroMQ link on the other, TunnelCore in between.
// The bus is handled on the caller's thread (RunUntilSignal), the link on
// its own thread (RunLink); the core is shared under one mutex.

#include <atomic>
#include <map>
#include <mutex>
#include <string>

#include "vloc/lcm_io/transport.h"
#include "vloc/tunnel/tunnel_core.h"
#include "vloc/tunnel/zmq_link.h"

namespace vloc {

class TunnelAdapter {
 public:
  TunnelAdapter(Transport& transport, const tunnel::TunnelOptions& options);
  // Starts the link and subscribes to the channels sent. False with one line in *error.
  bool Start(std::string* error);
  // The link's loop, until `stop` is set: frames in and out, status reports.
  void RunLink(const std::atomic<bool>& stop);
  // One line of totals, for the end of the run.
  std::string Summary();
  // The peer's own status reports are heard on this bus, not only this end's
  // republished copies: both ends share one bus and would forward every
  // message round and round. The process stops with `LoopProblem()`.
  bool LoopDetected() const { return loop_detected_.load(); }
  std::string LoopProblem() const;

 private:
  void OnBusMessage(const std::string& channel, const uint8_t* data, size_t size);
  // A status report heard on this bus that this end did not republish: the peer's means a loop.
  void CheckForLoop(const uint8_t* data, size_t size);
  void PublishStatus(double now_s);

  Transport& transport_;
  tunnel::TunnelOptions options_;
  tunnel::ZmqLink link_;
  std::mutex mutex_;  // guards core_
  tunnel::TunnelCore core_;
  std::map<std::string, int64_t> dropped_logged_;  // per channel, drops already logged
  double next_status_s_ = 0;
  tunnel::TunnelReport last_report_;
  static constexpr int kLoopEvidence = 3;  // the peer's reports heard directly before it is called a loop
  int peer_reports_heard_directly_ = 0;     // guarded by mutex_
  std::string loop_peer_;                   // guarded by mutex_
  std::atomic<bool> loop_detected_{false};
};

}  // namespace vloc
