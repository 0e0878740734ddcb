#pragma once
// vloc_launch's LCM side: publishes the Supervisor's state as
// procman_status_t on PROCMAN_STATUS at 1 Hz (and right after each order)
// and obeys procman_order_t on PROCMAN_ORDERS addressed to this host (or
// to every host, when `host` is empty).

#include <chrono>
#include <memory>
#include <string>

#include "vloc/launch/supervisor.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/procman_order_t.hpp"
#include "vloc/procman_status_t.hpp"

namespace vloc {

inline constexpr char kProcmanStatusChannel[] = "PROCMAN_STATUS";
inline constexpr char kProcmanOrdersChannel[] = "PROCMAN_ORDERS";

class LaunchLcmAdapter {
 public:
  LaunchLcmAdapter(Supervisor& supervisor, Transport& transport, std::string host,
                   double status_period_s = 1.0);

  void Subscribe();
  // Publishes when a period has passed (or an order asked for a report).
  void Tick();
  void PublishStatus();
  // Orders are ignored once the launcher is shutting down.
  void SetShuttingDown() { shutting_down_ = true; }

  // What the order subscription received, for the closing log line.
  std::string SubscriptionLine() const { return SubscriptionSummary({order_stats_}); }

  // Applies one order; public for tests.
  void HandleOrder(const procman_order_t& order);

 private:
  Supervisor& supervisor_;
  Transport& transport_;
  std::string host_;
  std::chrono::steady_clock::duration period_;
  std::chrono::steady_clock::time_point next_status_;
  bool shutting_down_ = false;
  static constexpr int kOrderQueue = 200;  // orders are small and an operator's burst must not be lost
  std::shared_ptr<SubscriptionStats> order_stats_;
};

}  // namespace vloc
