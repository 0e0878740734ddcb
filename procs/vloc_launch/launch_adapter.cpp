#include "launch_adapter.h"

#include <glog/logging.h>
#include <unistd.h>

#include "vloc/common/printable.h"
#include "vloc/lcm_io/convert_launch.h"

namespace vloc {

LaunchLcmAdapter::LaunchLcmAdapter(Supervisor& supervisor, Transport& transport, std::string host,
                                   double status_period_s, PeerTrackerOptions peer_options,
                                   const GroupFile* whole_file)
    : supervisor_(supervisor),
      transport_(transport),
      host_(std::move(host)),
      period_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
          std::chrono::duration<double>(status_period_s))),
      next_status_(std::chrono::steady_clock::now()),
      peer_options_(peer_options),
      peers_(host_, static_cast<int>(getpid()), peer_options),
      whole_file_(whole_file) {
  supervisor_.SetRemoteCheck(
      [this](const std::string& host, const std::string& name) { return peers_.IsRunning(host, name); });
}

void LaunchLcmAdapter::Subscribe() {
  order_stats_ = vloc::Subscribe<procman_order_t>(
      transport_, kProcmanOrdersChannel,
      [this](const std::string&, const procman_order_t& order) { HandleOrder(order); },
      kOrderQueue);
  status_stats_ = vloc::Subscribe<procman_status_t>(
      transport_, kProcmanStatusChannel,
      [this](const std::string&, const procman_status_t& status) { HandleStatus(status); }, kStatusQueue);
}

void LaunchLcmAdapter::HandleStatus(const procman_status_t& status) {
  for (const PeerEvent& e : peers_.OnReport(PeerReportFromMessage(status), std::chrono::steady_clock::now())) {
    if (e.kind == PeerEventKind::kDuplicateHost) LOG(WARNING) << "peers: " << e.text;
    else LOG(INFO) << "peers: " << e.text;
  }
}

bool LaunchLcmAdapter::OwnedElsewhere(const std::string& target, bool is_group) const {
  if (!whole_file_) return false;
  for (const auto& p : whole_file_->processes)
    if (p.host != host_ && (is_group ? p.group == target : p.name == target)) return true;
  return false;
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
  // A name in a log line is escaped; one holding control characters (a
  // newline would forge a line of this log) names nothing and is refused.
  const std::string target = Printable(order.target);
  if (HasControlCharacters(order.target)) {
    LOG(ERROR) << kProcmanOrdersChannel << ": order to " << action << " '" << target
               << "' refused: the name holds control characters";
    return;
  }
  if (shutting_down_) {
    LOG(WARNING) << "order to " << action << " '" << target << "' ignored: shutting down";
    return;
  }
  std::string error;
  if (OwnedElsewhere(order.target, is_group)) {
    // Part (a group) or all (a process) of the target runs on another host:
    // apply the order to what is here, if anything, without an error.
    bool mine = false;
    for (const auto& p : supervisor_.file().processes)
      mine = mine || (is_group ? p.group == order.target : p.name == order.target);
    if (!mine) {
      LOG(INFO) << "order to " << action << " '" << target << "' is for another host's launcher; not mine";
      return;
    }
  }
  LOG(INFO) << "order: " << action << (is_group ? " group '" : " process '") << target << "'";
  bool ok = false;
  if (order.action == procman_order_t::ACTION_START) ok = supervisor_.Start(order.target, is_group, &error);
  else if (order.action == procman_order_t::ACTION_STOP) ok = supervisor_.Stop(order.target, is_group, &error);
  else ok = supervisor_.Restart(order.target, is_group, &error);
  if (!ok) LOG(ERROR) << "order to " << action << " ignored: " << error;
  next_status_ = std::chrono::steady_clock::now();  // report the change soon
}

void LaunchLcmAdapter::Tick() {
  const auto now = std::chrono::steady_clock::now();
  for (const PeerEvent& e : peers_.Check(now)) LOG(WARNING) << "peers: " << e.text;
  if (now < next_status_) return;
  PublishStatus();
  next_status_ = now + period_;
}

namespace {

int64_t WallMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

void LaunchLcmAdapter::PublishStatus() {
  const int64_t utime = WallMicros();
  Publish(transport_, kProcmanStatusChannel,
          ProcmanStatusToMessage(host_, static_cast<int32_t>(getpid()), utime, supervisor_.Status()));
  Publish(transport_, kProcmanPeersChannel,
          ProcmanPeersToMessage(host_, static_cast<int32_t>(getpid()), utime, peer_options_.lost_after_s,
                                peers_.Peers(std::chrono::steady_clock::now())));
}

}  // namespace vloc
