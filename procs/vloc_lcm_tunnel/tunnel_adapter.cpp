#include "tunnel_adapter.h"

#include <glog/logging.h>

#include <chrono>
#include <random>
#include <sstream>

#include "vloc/lcm_io/convert_tunnel.h"
#include "vloc/lcm_io/typed.h"

namespace vloc {
namespace {

double NowS() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

int64_t WallUs() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

uint64_t NewSession() {
  std::random_device device;
  std::mt19937_64 rng((static_cast<uint64_t>(device()) << 32) ^ device() ^ static_cast<uint64_t>(WallUs()));
  uint64_t s = 0;
  while (s == 0) s = rng();
  return s;
}

tunnel::LinkOptions LinkOptionsFor(const tunnel::TunnelOptions& o) {
  tunnel::LinkOptions link;
  link.bind = o.bind;
  link.connect = o.connect;
  link.heartbeat_s = o.heartbeat_s;
  link.heartbeat_timeout_s = o.heartbeat_timeout_s;
  link.max_frame_bytes = tunnel::kDataOverheadBytes + static_cast<size_t>(o.chunk_bytes);
  return link;
}

// The bus subscription's queue, in messages: it also hears every message
// this end republishes (its echoes), so it holds a burst of the peer's
// traffic arriving faster than the bus thread runs (a loaded CPU) — 10,000
// dropped 1,315 echoes once, counted as losses. LCM holds the backlog
// anyway (its own queue is unbounded here); this only bounds it.
constexpr int kBusQueueMessages = 200000;

// One LCM subscription for every channel sent: (a)|(b)|...
std::string SubscriptionPattern(const std::vector<std::string>& patterns) {
  std::string out;
  for (const auto& p : patterns) out += (out.empty() ? "(" : "|(") + p + ")";
  return out;
}

}  // namespace

TunnelAdapter::TunnelAdapter(Transport& transport, const tunnel::TunnelOptions& options)
    : transport_(transport), options_(options), link_(LinkOptionsFor(options)), core_(options, NewSession()) {}

bool TunnelAdapter::Start(std::string* error) {
  if (!link_.Start(error)) return false;
  transport_.Subscribe(
      SubscriptionPattern(options_.send_channels),
      [this](const std::string& channel, const uint8_t* data, size_t size) { OnBusMessage(channel, data, size); },
      kBusQueueMessages, [this](const std::string& channel) {
        std::lock_guard<std::mutex> lock(mutex_);
        core_.OnLocalDrop(channel);
      });
  LOG(INFO) << options_.name << ": " << (options_.bind.empty() ? "connecting to " : "listening on ") << link_.endpoint()
            << ", sending " << SubscriptionPattern(options_.send_channels) << ", receiving "
            << SubscriptionPattern(options_.receive_channels);
  return true;
}

void TunnelAdapter::OnBusMessage(const std::string& channel, const uint8_t* data, size_t size) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const bool taken = core_.OnLocalMessage(channel, data, size, WallUs(), NowS());
    if (taken && channel == options_.status_channel) CheckForLoop(data, size);
  }
  link_.Wake();
}

void TunnelAdapter::CheckForLoop(const uint8_t* data, size_t size) {
  tunnel_status_t status;
  if (!Decode(data, size, &status) || status.name == options_.name) return;
  const std::string& peer = core_.peer_name();
  if (peer.empty() || status.name != peer) return;  // another tunnel on this bus (a ground with two rovers) is fine
  if (++peer_reports_heard_directly_ < kLoopEvidence || loop_detected_.load()) return;
  loop_peer_ = peer;
  loop_detected_ = true;
}

std::string TunnelAdapter::LoopProblem() const {
  return options_.name + ": the peer '" + loop_peer_ + "' publishes on this tunnel's own bus (" +
         std::to_string(kLoopEvidence) +
         " of its status reports heard here directly): the two ends would forward every message round and round; "
         "run one end per bus (one host each: rover_split_tunnel.yaml with --host), or join them without a tunnel";
}

void TunnelAdapter::RunLink(const std::atomic<bool>& stop) {
  const auto deliver = [this](const std::string& channel, const uint8_t* data, size_t size) {
    if (!transport_.Publish(channel, data, size)) LOG(WARNING) << "republishing on " << channel << " failed";
  };
  const auto send = [this](const std::vector<uint8_t>& frame) { return link_.Send(frame); };
  next_status_s_ = NowS();
  while (!stop.load()) {
    bool busy;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      busy = core_.HasWork();
    }
    link_.Poll(
        busy ? 2 : 50,
        [&](const uint8_t* bytes, size_t size) {
          // Republished after the lock is released: the bus thread, which hears every republished message
          // again (an echo, dropped by content), is not held up behind the link's work.
          std::vector<std::pair<std::string, std::vector<uint8_t>>> arrived;
          {
            std::lock_guard<std::mutex> lock(mutex_);
            const auto keep = [&](const std::string& channel, const uint8_t* data, size_t n) {
              arrived.emplace_back(channel, std::vector<uint8_t>(data, data + n));
            };
            core_.OnFrame(bytes, size, WallUs(), NowS(), keep);
          }
          for (const auto& [channel, message] : arrived) deliver(channel, message.data(), message.size());
        },
        [&] {
          std::lock_guard<std::mutex> lock(mutex_);
          core_.OnConnected(NowS());
          LOG(INFO) << options_.name << ": link up (" << link_.endpoint() << ")";
        },
        [&] {
          std::lock_guard<std::mutex> lock(mutex_);
          core_.OnDisconnected();
          LOG(WARNING) << options_.name << ": link down (" << link_.endpoint()
                       << "); queueing, everything not acknowledged goes again when it returns";
        });
    const double now = NowS();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      core_.Pump(now, send);
    }
    if (now >= next_status_s_) {
      PublishStatus(now);
      next_status_s_ = now + options_.status_period_s;
    }
  }
}

void TunnelAdapter::PublishStatus(double now_s) {
  tunnel::TunnelReport report;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    report = core_.Report(now_s);
  }
  // Every drop named: once per report period, per channel, with the new count.
  for (const auto& c : report.channels) {
    int64_t& logged = dropped_logged_[c.channel];
    if (c.dropped > logged) {
      LOG(WARNING) << options_.name << ": dropped " << (c.dropped - logged) << " message(s) on " << c.channel
                   << " (total " << c.dropped << "; queue full, too large or refused; see " << options_.status_channel
                   << ")";
      logged = c.dropped;
    }
  }
  if (report.rejected_frames > last_report_.rejected_frames)
    LOG(WARNING) << options_.name << ": " << report.rejected_frames - last_report_.rejected_frames
                 << " malformed frame(s) from the peer rejected";
  Publish(transport_, options_.status_channel, TunnelStatusToMessage(report, options_, link_.endpoint(), WallUs()));
  last_report_ = report;
}

std::string TunnelAdapter::Summary() {
  const tunnel::TunnelReport& r = last_report_;
  std::ostringstream s;
  s << options_.name << ": sent " << r.sent_messages << ", received " << r.received_messages << ", resent frames "
    << r.resent_frames << ", dropped " << r.dropped_queue_full << " (queue full) " << r.dropped_too_large
    << " (too large) " << r.dropped_too_many_channels << " (channels), refused " << r.refused_from_peer
    << ", rejected frames " << r.rejected_frames << ", echoes skipped " << r.echoes_skipped << ", connects "
    << r.connects << ", queue high water " << r.queued_bytes_high_water << " bytes";
  return s.str();
}

}  // namespace vloc
