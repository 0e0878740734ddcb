#include "launch_adapter.h"

#include <glog/logging.h>
#include <unistd.h>

namespace vloc {

LaunchLcmAdapter::LaunchLcmAdapter(Supervisor& supervisor, Transport& transport, std::string host,
                                   double status_period_s)
    : supervisor_(supervisor),
      transport_(transport),
      host_(std::move(host)),
      period_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
          std::chrono::duration<double>(status_period_s))),
      next_status_(std::chrono::steady_clock::now()) {}

void LaunchLcmAdapter::Subscribe() {
  order_stats_ = vloc::Subscribe<procman_order_t>(
      transport_, kProcmanOrdersChannel,
      [this](const std::string&, const procman_order_t& order) { HandleOrder(order); },
      kOrderQueue);
}

void LaunchLcmAdapter::HandleOrder(const procman_order_t& order) {
  if (!order.host.empty() && order.host != host_) return;
  const char* action = order.action == procman_order_t::ACTION_START  ? "start"
                       : order.action == procman_order_t::ACTION_STOP ? "stop"
                       : order.action == procman_order_t::ACTION_RESTART ? "restart"
                                                                          : nullptr;
  const bool is_group = order.target_kind == procman_order_t::TARGET_GROUP;
  if (!action || (!is_group && order.target_kind != procman_order_t::TARGET_PROCESS)) {
    LOG(ERROR) << kProcmanOrdersChannel << ": order with action " << int(order.action) << " and target kind "
               << int(order.target_kind) << " is not understood; use the ACTION_* and TARGET_* constants";
    return;
  }
  if (shutting_down_) {
    LOG(WARNING) << "order to " << action << " '" << order.target << "' ignored: shutting down";
    return;
  }
  LOG(INFO) << "order: " << action << (is_group ? " group '" : " process '") << order.target << "'";
  std::string error;
  bool ok = false;
  if (order.action == procman_order_t::ACTION_START) ok = supervisor_.Start(order.target, is_group, &error);
  else if (order.action == procman_order_t::ACTION_STOP) ok = supervisor_.Stop(order.target, is_group, &error);
  else ok = supervisor_.Restart(order.target, is_group, &error);
  if (!ok) LOG(ERROR) << "order to " << action << " ignored: " << error;
  next_status_ = std::chrono::steady_clock::now();  // report the change soon
}

void LaunchLcmAdapter::Tick() {
  const auto now = std::chrono::steady_clock::now();
  if (now < next_status_) return;
  PublishStatus();
  next_status_ = now + period_;
}

void LaunchLcmAdapter::PublishStatus() {
  procman_status_t msg;
  msg.utime = std::chrono::duration_cast<std::chrono::microseconds>(
                  std::chrono::system_clock::now().time_since_epoch())
                  .count();
  msg.host = host_;
  msg.launcher_pid = static_cast<int32_t>(getpid());
  for (const auto& s : supervisor_.Status()) {
    proc_status_t p;
    p.name = s.name;
    p.group = s.group;
    p.pid = s.pid;
    p.state = static_cast<int8_t>(s.state);
    p.restarts = s.restarts;
    p.last_exit_code = s.last_exit_code;
    p.cpu_percent = s.cpu_percent;
    p.rss_bytes = s.rss_bytes;
    p.uptime_seconds = s.uptime_seconds;
    msg.procs.push_back(p);
  }
  msg.num_procs = static_cast<int32_t>(msg.procs.size());
  Publish(transport_, kProcmanStatusChannel, msg);
}

}  // namespace vloc
