#include "vloc/lcm_io/convert_tunnel.h"

namespace vloc {

tunnel_status_t TunnelStatusToMessage(const tunnel::TunnelReport& r, const tunnel::TunnelOptions& options,
                                      const std::string& endpoint, int64_t utime) {
  tunnel_status_t m;
  m.utime = utime;
  m.name = options.name;
  m.peer_name = r.peer_name;
  m.endpoint = endpoint;
  m.connected = r.connected;
  m.connects = r.connects;
  m.seconds_since_peer = r.seconds_since_peer;
  m.tx_bytes_per_s = r.tx_bytes_per_s;
  m.rx_bytes_per_s = r.rx_bytes_per_s;
  m.bandwidth_cap_bytes_per_s = options.bandwidth_cap_mbps * 1e6 / 8.0;
  m.sent_messages = r.sent_messages;
  m.received_messages = r.received_messages;
  m.in_flight_bytes = r.in_flight_bytes;
  m.queued_messages = r.queued_messages;
  m.queued_bytes = r.queued_bytes;
  m.queued_bytes_high_water = r.queued_bytes_high_water;
  m.resent_frames = r.resent_frames;
  m.dropped_queue_full = r.dropped_queue_full;
  m.dropped_too_large = r.dropped_too_large;
  m.dropped_too_many_channels = r.dropped_too_many_channels;
  m.refused_from_peer = r.refused_from_peer;
  m.rejected_frames = r.rejected_frames;
  m.echoes_skipped = r.echoes_skipped;
  m.latency_samples = r.latency_samples;
  m.latency_median_ms = r.latency_median_ms;
  m.latency_max_ms = r.latency_max_ms;
  for (const auto& c : r.channels) {
    tunnel_channel_status_t cm;
    cm.channel = c.channel;
    cm.priority = static_cast<int8_t>(c.priority);
    cm.queued_messages = c.queued_messages;
    cm.queued_bytes = c.queued_bytes;
    cm.queued_bytes_high_water = c.queued_bytes_high_water;
    cm.sent = c.sent;
    cm.received = c.received;
    cm.dropped = c.dropped;
    cm.latency_max_ms = c.latency_max_ms;
    m.channels.push_back(cm);
  }
  m.num_channels = static_cast<int32_t>(m.channels.size());
  return m;
}

}  // namespace vloc
