#include "vloc/tunnel/tunnel_core.h"

#include <algorithm>
#include <cmath>

#include "vloc/common/stats.h"

namespace vloc::tunnel {
namespace {

constexpr double kMb = 1024.0 * 1024.0;
constexpr size_t kMaxEchoes = 100000;
constexpr size_t kMaxLatencySamples = 100000;
constexpr size_t kMaxPartials = 64;
constexpr double kSyncTimeoutS = 2.0;       // s after a connection without the peer's rewind: resend anyway
constexpr double kRewindRequestGapS = 1.0;  // s between two rewind requests for a gap
constexpr double kAckDelayS = 0.02;         // s an acknowledgement may wait to cover more frames
constexpr int kAckEveryFrames = 16;

std::vector<std::regex> Compile(const std::vector<std::string>& patterns) {
  std::vector<std::regex> out;
  for (const auto& p : patterns) out.emplace_back(p, std::regex::ECMAScript | std::regex::optimize);
  return out;
}

using Patterns = std::vector<std::string>;

bool AllRegexes(const Patterns& patterns) {
  for (const auto& p : patterns) {
    try {
      std::regex re(p);
    } catch (const std::regex_error&) {
      return false;
    }
  }
  return true;
}

bool ValidName(const std::string& name) { return !name.empty() && name.size() <= kMaxNameBytes; }

}  // namespace

void TunnelOptions::Visit(OptionsReader& r) {
  const Bound<Patterns> regexes = Rule<Patterns>(AllRegexes, "regular expressions");
  r.Optional("name", &name, "this end's name in status and logs", Rule<std::string>(ValidName, "1-64 characters long"));
  r.Optional("bind", &bind, "ZeroMQ endpoint to listen on, e.g. tcp://*:7720 (this or connect)");
  r.Optional("connect", &connect, "ZeroMQ endpoint of the peer, e.g. tcp://10.0.0.1:7720");
  r.Optional("send_channels", &send_channels, "regexes: channels of this bus sent to the peer", regexes);
  r.Optional("receive_channels", &receive_channels, "regexes: channels from the peer republished here", regexes);
  r.Optional("urgent_channels", &urgent_channels, "regexes: sent first (poses, status, orders)", regexes);
  r.Optional("bulk_channels", &bulk_channels, "regexes: sent last (images)", regexes);
  r.Optional("urgent_queue_messages", &urgent_queue_messages, "per urgent channel, messages waiting", AtLeast(1));
  r.Optional("normal_queue_messages", &normal_queue_messages, "per normal channel, messages waiting", AtLeast(1));
  r.Optional("bulk_queue_messages", &bulk_queue_messages, "per bulk channel, messages waiting", AtLeast(1));
  r.Optional("queue_mb", &queue_mb, "MB per channel waiting, then the oldest is dropped", Positive());
  r.Optional("max_message_mb", &max_message_mb, "MB, larger messages are dropped", InLeftOpen(0, 1024));
  r.Optional("max_channels", &max_channels, "channels tracked; messages of more are dropped", InRange(1, 100000));
  r.Optional("chunk_bytes", &chunk_bytes, "bytes per frame", InRange(512, 1 << 20));
  r.Optional("window_mb", &window_mb, "MB sent and not yet acknowledged", Positive());
  r.Optional("bandwidth_cap_mbps", &bandwidth_cap_mbps, "Mbit/s sent at most, 0: no cap", NonNegative() && Finite());
  r.Optional("reassembly_mb", &reassembly_mb, "MB of partly received messages held", Positive());
  r.Optional("echo_window_s", &echo_window_s, "s a republished message is remembered", Positive());
  r.Optional("heartbeat_s", &heartbeat_s, "s between heartbeats", Positive());
  r.Optional("heartbeat_timeout_s", &heartbeat_timeout_s, "s of silence before the link is down");
  r.Optional("status_period_s", &status_period_s, "s between status reports", Positive());
  r.Optional("status_channel", &status_channel, "channel of the status reports",
             Rule<std::string>(ValidChannelName, "a valid LCM channel name"));
  r.Relation("connect", bind.empty() || connect.empty(),
             "must be empty when bind is given (one end listens, the other connects)");
  r.Relation("reassembly_mb", reassembly_mb >= max_message_mb, "must be >= max_message_mb");
  r.Relation("window_mb", window_mb * kMb >= chunk_bytes, "must hold at least one chunk (chunk_bytes)");
  r.Relation("heartbeat_timeout_s", heartbeat_timeout_s > heartbeat_s, "must exceed heartbeat_s");
}

bool TunnelOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

TunnelCore::TunnelCore(const TunnelOptions& options, uint64_t session)
    : options_(options),
      session_(session ? session : 1),
      send_(Compile(options.send_channels)),
      receive_(Compile(options.receive_channels)),
      urgent_(Compile(options.urgent_channels)),
      bulk_(Compile(options.bulk_channels)) {
  limits_.max_message_bytes = static_cast<size_t>(options.max_message_mb * kMb);
  limits_.max_chunk_bytes = static_cast<size_t>(options.chunk_bytes);
}

bool TunnelCore::MatchesAny(const std::vector<std::regex>& patterns, const std::string& channel) const {
  for (const auto& re : patterns)
    if (std::regex_match(channel, re)) return true;
  return false;
}

TunnelCore::Channel* TunnelCore::FindOrAdd(const std::string& channel) {
  auto it = channels_.find(channel);
  if (it != channels_.end()) return &it->second;
  if (static_cast<int>(channels_.size()) >= options_.max_channels) return nullptr;
  Channel c;
  c.priority = MatchesAny(urgent_, channel) ? kUrgent : MatchesAny(bulk_, channel) ? kBulk : kNormal;
  c.send = channel != "LCM_SELF_TEST" && MatchesAny(send_, channel);  // LCM's start-up check stays on its bus
  return &channels_.emplace(channel, std::move(c)).first->second;
}

// FNV-1a over the channel, a separator and the bytes.
uint64_t TunnelCore::EchoKey(const std::string& channel, const uint8_t* data, size_t size) const {
  uint64_t h = 1469598103934665603ull;
  auto mix = [&h](uint8_t b) { h = (h ^ b) * 1099511628211ull; };
  for (char c : channel) mix(static_cast<uint8_t>(c));
  mix(0);
  for (size_t i = 0; i < size; ++i) mix(data[i]);
  return h;
}

void TunnelCore::RememberEcho(uint64_t key, double now_s) {
  ++echoes_[key];
  echo_order_.emplace_back(now_s, key);
  while (!echo_order_.empty() &&
         (echo_order_.size() > kMaxEchoes || echo_order_.front().first < now_s - options_.echo_window_s)) {
    auto it = echoes_.find(echo_order_.front().second);
    if (it != echoes_.end() && --it->second <= 0) echoes_.erase(it);
    echo_order_.pop_front();
  }
}

bool TunnelCore::ConsumeEcho(uint64_t key, double now_s) {
  auto it = echoes_.find(key);
  if (it == echoes_.end()) return false;
  if (--it->second <= 0) echoes_.erase(it);  // its expiry entry then finds nothing to remove
  return true;
}

bool TunnelCore::OnLocalMessage(const std::string& channel, const uint8_t* data, size_t size, int64_t wall_us,
                                double now_s) {
  if (ConsumeEcho(EchoKey(channel, data, size), now_s)) {
    ++echoes_skipped_;
    return false;
  }
  Channel* c = FindOrAdd(channel);
  if (!c) {
    ++dropped_too_many_channels_;
    return true;
  }
  if (!c->send) return true;  // heard, but not ours to send (e.g. a wider subscription)
  if (size > limits_.max_message_bytes || !ValidChannelName(channel)) {
    ++dropped_too_large_;
    ++c->dropped;
    return true;
  }
  Outgoing out;
  out.msg_id = next_msg_id_++;
  out.order = next_order_++;
  out.heard_utime = wall_us;
  out.bytes.assign(data, data + size);
  c->queue.push_back(std::move(out));
  c->queued_bytes += static_cast<int64_t>(size);
  queued_bytes_ += static_cast<int64_t>(size);
  ++queued_messages_;
  // Over its bounds: drop the oldest messages not yet started (a started one
  // is finished: its first chunks are already on their way).
  const size_t max_messages = static_cast<size_t>(c->priority == kUrgent   ? options_.urgent_queue_messages
                                                  : c->priority == kNormal ? options_.normal_queue_messages
                                                                           : options_.bulk_queue_messages);
  const int64_t max_bytes = static_cast<int64_t>(options_.queue_mb * kMb);
  while (c->queue.size() > max_messages || c->queued_bytes > max_bytes) {
    auto victim = std::find_if(c->queue.begin(), c->queue.end(), [](const Outgoing& o) { return o.sent_offset == 0; });
    if (victim == c->queue.end() || std::next(victim) == c->queue.end()) break;  // keep the newest
    c->queued_bytes -= static_cast<int64_t>(victim->bytes.size());
    queued_bytes_ -= static_cast<int64_t>(victim->bytes.size());
    --queued_messages_;
    c->queue.erase(victim);
    ++c->dropped;
    ++dropped_queue_full_;
  }
  c->high_water = std::max(c->high_water, c->queued_bytes);
  queued_high_water_ = std::max(queued_high_water_, queued_bytes_);
  return true;
}

void TunnelCore::OnFrame(const uint8_t* bytes, size_t size, int64_t wall_us, double now_s, const DeliverFn& deliver) {
  period_rx_bytes_ += static_cast<int64_t>(size);
  Frame frame;
  if (!DecodeFrame(bytes, size, limits_, &frame, nullptr)) {
    ++rejected_frames_;
    return;
  }
  last_heard_ = now_s;
  if (frame.session != peer_session_) {
    // A new run of the peer: what was partly received from the old one is gone.
    peer_session_ = frame.session;
    expected_ = 0;
    partials_.clear();
    partial_bytes_ = 0;
  }
  if (frame.kind == FrameKind::kControl)
    OnControl(frame, now_s);
  else
    OnData(frame, wall_us, now_s, deliver);
}

void TunnelCore::OnControl(const Frame& frame, double now_s) {
  const ControlFrame& c = frame.control;
  peer_name_ = c.name;
  if (c.acked_session == session_) {
    while (!window_.empty() && window_.front().seq <= c.acked_seq) {
      window_bytes_ -= static_cast<int64_t>(window_.front().frame.size());
      window_.pop_front();
      if (cursor_ > 0) --cursor_;
    }
  }
  if (frame.flags & kFlagRewind) {
    cursor_ = 0;  // everything not acknowledged goes again
    synced_ = true;
  }
}

bool TunnelCore::InSequence(const DataFrame& d, double now_s) {
  if (expected_ != 0 && d.seq < expected_) return false;  // a resent frame that already arrived
  if (expected_ != 0 && d.seq > expected_) {
    // A gap (frames lost with a connection): ignore until the peer rewinds.
    if (now_s - last_rewind_request_ > kRewindRequestGapS) {
      rewind_due_ = true;
      last_rewind_request_ = now_s;
    }
    return false;
  }
  expected_ = d.seq + 1;
  ++frames_since_ack_;
  return true;
}

void TunnelCore::DropPartial(std::map<uint64_t, Partial>::iterator it) {
  partial_bytes_ -= static_cast<int64_t>(it->second.bytes.size());
  partials_.erase(it);
  ++rejected_frames_;
}

std::map<uint64_t, TunnelCore::Partial>::iterator TunnelCore::StartMessage(const DataFrame& d) {
  if (auto it = partials_.find(d.msg_id); it != partials_.end()) {  // a message id reused by the peer: protocol error
    DropPartial(it);
    return partials_.end();
  }
  Channel* c = FindOrAdd(d.channel);
  if (c && c->accept < 0) c->accept = MatchesAny(receive_, d.channel) ? 1 : 0;
  if (!c || c->accept == 0) {
    ++refused_from_peer_;
    if (c) ++c->dropped;
    return partials_.end();
  }
  // Bounded reassembly: the oldest partial messages give way.
  while (!partials_.empty() && (partials_.size() >= kMaxPartials ||
                                partial_bytes_ + d.total_size > static_cast<int64_t>(options_.reassembly_mb * kMb)))
    DropPartial(partials_.begin());
  Partial p;
  p.first_seq = d.seq;
  p.channel = d.channel;
  p.bytes.resize(d.total_size);
  partial_bytes_ += d.total_size;
  return partials_.emplace(d.msg_id, std::move(p)).first;
}

void TunnelCore::DeliverMessage(Partial done, int64_t latency_us, double now_s, const DeliverFn& deliver) {
  Channel* c = FindOrAdd(done.channel);
  const double latency_ms = std::max(0.0, static_cast<double>(latency_us) / 1000.0);
  if (period_latencies_ms_.size() < kMaxLatencySamples) period_latencies_ms_.push_back(latency_ms);
  if (c) {
    ++c->received;
    c->latency_max_ms = std::max(c->latency_max_ms, latency_ms);
    // Only a channel this end also sends can echo back to it.
    if (c->send) RememberEcho(EchoKey(done.channel, done.bytes.data(), done.bytes.size()), now_s);
  }
  ++received_messages_;
  deliver(done.channel, done.bytes.data(), done.bytes.size());
}

void TunnelCore::OnData(const Frame& frame, int64_t wall_us, double now_s, const DeliverFn& deliver) {
  const DataFrame& d = frame.data;
  if (!InSequence(d, now_s)) return;
  auto it = partials_.find(d.msg_id);
  if (d.offset == 0) {
    it = StartMessage(d);
    if (it == partials_.end()) return;
  } else if (it == partials_.end()) {
    return;  // the rest of a refused message, or of one begun before this end restarted
  }
  Partial& p = it->second;
  if (p.channel != d.channel || p.bytes.size() != d.total_size || p.filled != d.offset) return DropPartial(it);
  if (d.chunk_size) std::copy(d.chunk, d.chunk + d.chunk_size, p.bytes.begin() + static_cast<long>(p.filled));
  p.filled += d.chunk_size;
  if (p.filled < p.bytes.size()) return;
  Partial done = std::move(p);
  partial_bytes_ -= static_cast<int64_t>(done.bytes.size());
  partials_.erase(it);
  DeliverMessage(std::move(done), wall_us - d.send_utime, now_s, deliver);
}

// Acknowledged: every frame before the first chunk of any message still
// incomplete, so that a restarted end is sent those messages whole again.
uint64_t TunnelCore::AckedSeq() const {
  uint64_t acked = expected_ ? expected_ - 1 : 0;
  for (const auto& [id, p] : partials_) acked = std::min(acked, p.first_seq - 1);
  return acked;
}

void TunnelCore::OnConnected(double now_s) {
  connected_ = true;
  synced_ = false;
  connected_time_ = now_s;
  rewind_due_ = true;  // ask the peer for everything this end has not acknowledged
  ++connects_;
}

void TunnelCore::OnDisconnected() {
  connected_ = false;
  synced_ = false;
}

void TunnelCore::OnLocalDrop(const std::string& channel) {
  ++dropped_queue_full_;
  if (Channel* c = FindOrAdd(channel)) ++c->dropped;
}

bool TunnelCore::HasWork() const {
  if (!connected_) return false;
  return rewind_due_ || frames_since_ack_ > 0 || !synced_ || cursor_ < window_.size() ||
         (queued_messages_ > 0 && window_bytes_ < static_cast<int64_t>(options_.window_mb * kMb));
}

bool TunnelCore::TakeTokens(size_t bytes, double now_s) {
  if (options_.bandwidth_cap_mbps <= 0) return true;
  const double rate = options_.bandwidth_cap_mbps * 1e6 / 8.0;  // bytes/s
  const double burst = std::max(2.0 * options_.chunk_bytes, 0.05 * rate);
  if (tokens_time_ < 0) tokens_ = burst;
  else tokens_ = std::min(burst, tokens_ + (now_s - tokens_time_) * rate);
  tokens_time_ = now_s;
  if (tokens_ <= 0) return false;
  tokens_ -= static_cast<double>(bytes);  // may go into debt by one frame
  return true;
}

// The next chunk by priority (then arrival), as a numbered frame.
bool TunnelCore::NextChunk(std::vector<uint8_t>* frame) {
  Channel* best = nullptr;
  const std::string* best_name = nullptr;
  for (auto& [name, c] : channels_) {
    if (c.queue.empty()) continue;
    if (!best || c.priority < best->priority ||
        (c.priority == best->priority && c.queue.front().order < best->queue.front().order)) {
      best = &c;
      best_name = &name;
    }
  }
  if (!best) return false;
  Outgoing& out = best->queue.front();
  DataFrame d;
  d.seq = next_seq_++;
  d.msg_id = out.msg_id;
  d.send_utime = out.heard_utime;
  d.total_size = static_cast<uint32_t>(out.bytes.size());
  d.offset = static_cast<uint32_t>(out.sent_offset);
  d.channel = *best_name;
  d.chunk = out.bytes.data() + out.sent_offset;
  d.chunk_size = std::min(out.bytes.size() - out.sent_offset, static_cast<size_t>(options_.chunk_bytes));
  *frame = EncodeData(session_, d);
  out.sent_offset += d.chunk_size;
  if (out.sent_offset >= out.bytes.size()) {
    best->queued_bytes -= static_cast<int64_t>(out.bytes.size());
    queued_bytes_ -= static_cast<int64_t>(out.bytes.size());
    --queued_messages_;
    ++best->sent;
    ++sent_messages_;
    best->queue.pop_front();
  }
  return true;
}

void TunnelCore::Pump(double now_s, const SendFn& send) {
  // Acknowledgements (and rewind requests) first: small, never capped.
  const bool ack_due = frames_since_ack_ >= kAckEveryFrames ||
                       (frames_since_ack_ > 0 && now_s - last_control_sent_ >= kAckDelayS);
  if (connected_ && (rewind_due_ || ack_due || now_s - last_control_sent_ >= options_.heartbeat_s)) {
    ControlFrame c;
    c.acked_session = peer_session_;
    c.acked_seq = AckedSeq();
    c.name = options_.name;
    const auto frame = EncodeControl(session_, rewind_due_ ? kFlagRewind : 0, c);
    if (send(frame)) {
      period_tx_bytes_ += static_cast<int64_t>(frame.size());
      rewind_due_ = false;
      frames_since_ack_ = 0;
      last_control_sent_ = now_s;
    }
  }
  if (!connected_) return;
  if (!synced_) {
    if (now_s - connected_time_ < kSyncTimeoutS) return;  // wait for the peer's rewind
    cursor_ = 0;
    synced_ = true;
  }
  const int64_t window_limit = static_cast<int64_t>(options_.window_mb * kMb);
  while (true) {
    if (cursor_ >= window_.size()) {
      if (window_bytes_ >= window_limit) return;
      std::vector<uint8_t> frame;
      if (!NextChunk(&frame)) return;
      window_bytes_ += static_cast<int64_t>(frame.size());
      window_.push_back({next_seq_ - 1, std::move(frame)});
    }
    const InFlight& f = window_[cursor_];
    if (!TakeTokens(f.frame.size(), now_s)) return;
    if (!send(f.frame)) {
      tokens_ += static_cast<double>(f.frame.size());
      return;
    }
    period_tx_bytes_ += static_cast<int64_t>(f.frame.size());
    if (f.seq <= max_sent_seq_) ++resent_frames_;
    max_sent_seq_ = std::max(max_sent_seq_, f.seq);
    ++cursor_;
  }
}

TunnelReport TunnelCore::Report(double now_s) {
  TunnelReport r;
  r.peer_name = peer_name_;
  r.connected = connected_ && last_heard_ >= 0 && now_s - last_heard_ < options_.heartbeat_timeout_s;
  r.connects = connects_;
  r.seconds_since_peer = last_heard_ < 0 ? -1 : now_s - last_heard_;
  const double period = period_start_ < 0 ? 0 : now_s - period_start_;
  if (period > 0) {
    r.tx_bytes_per_s = static_cast<double>(period_tx_bytes_) / period;
    r.rx_bytes_per_s = static_cast<double>(period_rx_bytes_) / period;
  }
  r.sent_messages = sent_messages_;
  r.received_messages = received_messages_;
  r.in_flight_bytes = window_bytes_;
  r.queued_messages = queued_messages_;
  r.queued_bytes = queued_bytes_;
  r.queued_bytes_high_water = queued_high_water_;
  r.resent_frames = resent_frames_;
  r.dropped_queue_full = dropped_queue_full_;
  r.dropped_too_large = dropped_too_large_;
  r.dropped_too_many_channels = dropped_too_many_channels_;
  r.refused_from_peer = refused_from_peer_;
  r.rejected_frames = rejected_frames_;
  r.echoes_skipped = echoes_skipped_;
  r.latency_samples = static_cast<int>(period_latencies_ms_.size());
  if (!period_latencies_ms_.empty()) {
    r.latency_median_ms = Median(period_latencies_ms_);
    r.latency_max_ms = *std::max_element(period_latencies_ms_.begin(), period_latencies_ms_.end());
  }
  for (auto& [name, c] : channels_) {
    ChannelReport cr;
    cr.channel = name;
    cr.priority = c.priority;
    cr.queued_messages = static_cast<int>(c.queue.size());
    cr.queued_bytes = c.queued_bytes;
    cr.queued_bytes_high_water = c.high_water;
    cr.sent = c.sent;
    cr.received = c.received;
    cr.dropped = c.dropped;
    cr.latency_max_ms = c.latency_max_ms;
    c.latency_max_ms = 0;
    r.channels.push_back(cr);
  }
  period_latencies_ms_.clear();
  period_tx_bytes_ = period_rx_bytes_ = 0;
  period_start_ = now_s;
  return r;
}

}  // namespace vloc::tunnel
