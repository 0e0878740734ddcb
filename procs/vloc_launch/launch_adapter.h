#pragma once
// vloc_launch's LCM side: publishes the Supervisor's state as
// procman_status_t on PROCMAN_STATUS at 1 Hz (and right after each order)
// and obeys procman_order_t on PROCMAN_ORDERS addressed to this host (or
// to every host, when `host` is empty). With a group split across hosts
// (GroupFile host keys) an order for another host's process or group is
// left to that host's launcher. It also listens to the other launchers'
// PROCMAN_STATUS: joins, LOST launchers (silent for lost_after_s), returns
// and their processes' changes are logged, and the view is published as
// procman_peers_t on PROCMAN_PEERS with each status.

#include <chrono>
#include <memory>
#include <string>

#include "vloc/launch/peer_tracker.h"
#include "vloc/launch/supervisor.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/procman_order_t.hpp"
#include "vloc/procman_peers_t.hpp"
#include "vloc/procman_status_t.hpp"

namespace vloc {

inline constexpr char kProcmanStatusChannel[] = "PROCMAN_STATUS";
inline constexpr char kProcmanOrdersChannel[] = "PROCMAN_ORDERS";
inline constexpr char kProcmanPeersChannel[] = "PROCMAN_PEERS";

class LaunchLcmAdapter {
 public:
  // `whole_file`: the whole group file when the supervisor runs only this
  // host's part of it (orders for the other parts are not errors here).
  LaunchLcmAdapter(Supervisor& supervisor, Transport& transport, std::string host,
                   double status_period_s = 1.0, PeerTrackerOptions peer_options = {},
                   const GroupFile* whole_file = nullptr);

  void Subscribe();
  // Publishes when a period has passed (or an order asked for a report).
  void Tick();
  void PublishStatus();
  // Orders are ignored once the launcher is shutting down.
  void SetShuttingDown() { shutting_down_ = true; }

  // What the order subscription received, for the closing log line.
  std::string SubscriptionLine() const { return SubscriptionSummary({order_stats_, status_stats_}); }

  // Applies one order; public for tests.
  void HandleOrder(const procman_order_t& order);
  // Takes another launcher's status; public for tests.
  void HandleStatus(const procman_status_t& status);

 private:
  Supervisor& supervisor_;
  Transport& transport_;
  std::string host_;
  std::chrono::steady_clock::duration period_;
  std::chrono::steady_clock::time_point next_status_;
  bool shutting_down_ = false;
  static constexpr int kOrderQueue = 200;  // orders are small and an operator's burst must not be lost
  std::shared_ptr<SubscriptionStats> order_stats_;
  std::shared_ptr<SubscriptionStats> status_stats_;
  PeerTrackerOptions peer_options_;
  PeerTracker peers_;
  const GroupFile* whole_file_;
  static constexpr int kStatusQueue = 200;  // every launcher's 1 Hz report
  bool OwnedElsewhere(const std::string& target, bool is_group) const;
};

}  // namespace vloc
