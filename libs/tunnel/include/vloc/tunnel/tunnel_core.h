#pragma once
// One end of a reliable tunnel between two LCM buses, as a state machine
// with no LCM and no sockets in it (the process wires both in; the unit
// test drives two of these back to back):
//
//   local bus --OnLocalMessage--> per-channel queues (bounded, by priority)
//     --Pump--> chunks numbered in a window of unacknowledged frames --link-->
//   peer: OnFrame --> in-order check, reassembly --deliver--> its bus.
//
// Reliability: the peer acknowledges frames cumulatively; after a
// (re)connection or a gap each end asks the other to rewind and sends again
// every frame the other has not acknowledged, so a link that drops, or a
// peer that restarts, loses nothing that fit the window and the queues.
// Order is kept per channel. Urgent channels (poses, status, orders) go
// before normal ones and those before bulk ones (images), chunk by chunk,
// under an optional bandwidth cap. Every dropped message is counted under
// its channel and reason. A message this end republished and then hears on
// its own bus is not sent back (no loops).

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <regex>
#include <string>
#include <unordered_map>
#include <vector>

#include "vloc/common/options.h"
#include "vloc/tunnel/frame.h"

namespace vloc::tunnel {

enum Priority : int { kUrgent = 0, kNormal = 1, kBulk = 2 };

struct TunnelOptions {
  std::string name = "tunnel";       // this end's name in status and logs (e.g. vehicle / ground)
  std::string bind;                  // ZeroMQ endpoint to listen on, e.g. tcp://*:7720 (this or connect)
  std::string connect;               // ZeroMQ endpoint of the peer, e.g. tcp://10.0.0.1:7720
  std::vector<std::string> send_channels = {".*"};     // regexes: channels of this bus sent to the peer
  std::vector<std::string> receive_channels = {".*"};  // regexes: channels from the peer republished here
  std::vector<std::string> urgent_channels = {"PROCMAN_.*", "TUNNEL_STATUS", ".*_STATUS", ".*POSE.*", "TRAVERSE"};
  std::vector<std::string> bulk_channels = {"NAVCAM_STEREO", "UAV_CAMERA", "UAV_MOSAIC", ".*IMAGE.*"};
  int urgent_queue_messages = 256;   // per urgent channel, messages waiting before the oldest is dropped
  int normal_queue_messages = 4096;  // per normal channel
  int bulk_queue_messages = 64;      // per bulk channel (64 stereo pairs: a minute at 1/s)
  double queue_mb = 192;             // MB, per channel: bytes waiting before the oldest is dropped
  double max_message_mb = 32;        // MB, larger messages are dropped (counted)
  int max_channels = 256;            // channels tracked; messages of more are dropped (counted)
  int chunk_bytes = 16384;           // bytes per frame: the granularity at which urgent traffic overtakes bulk
  double window_mb = 4;              // MB sent and not yet acknowledged, at most
  double bandwidth_cap_mbps = 0;     // Mbit/s of frames sent (resends included); 0: no cap
  double reassembly_mb = 256;        // MB of partly received messages held, at most
  double echo_window_s = 10;         // s a republished message is remembered, to ignore its echo
  double heartbeat_s = 1;            // s between ZeroMQ heartbeats and keep-alive acknowledgements
  double heartbeat_timeout_s = 4;    // s without a frame from the peer before the link counts as down
  double status_period_s = 1;        // s between TUNNEL_STATUS reports
  std::string status_channel = "TUNNEL_STATUS";  // where the status goes

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct ChannelReport {
  std::string channel;
  int priority = kNormal;
  int queued_messages = 0;
  int64_t queued_bytes = 0;
  int64_t queued_bytes_high_water = 0;
  int64_t sent = 0;
  int64_t received = 0;
  int64_t dropped = 0;
  double latency_max_ms = 0;
};

struct TunnelReport {
  std::string peer_name;
  bool connected = false;
  int connects = 0;
  double seconds_since_peer = -1;
  double tx_bytes_per_s = 0, rx_bytes_per_s = 0;
  int64_t sent_messages = 0, received_messages = 0;
  int64_t in_flight_bytes = 0;
  int64_t queued_messages = 0, queued_bytes = 0, queued_bytes_high_water = 0;
  int64_t resent_frames = 0;
  int64_t dropped_queue_full = 0, dropped_too_large = 0, dropped_too_many_channels = 0;
  int64_t refused_from_peer = 0, rejected_frames = 0, echoes_skipped = 0;
  int latency_samples = 0;
  double latency_median_ms = 0, latency_max_ms = 0;
  std::vector<ChannelReport> channels;
};

// Republishes one message from the peer on this bus.
using DeliverFn = std::function<void(const std::string& channel, const uint8_t* data, size_t size)>;
// Hands one frame to the link; false when the link cannot take it now.
using SendFn = std::function<bool(const std::vector<uint8_t>& frame)>;

class TunnelCore {
 public:
  // `session` identifies this run (random, non-zero).
  TunnelCore(const TunnelOptions& options, uint64_t session);

  // A message heard on this bus (channel already matched send_channels).
  // Queues it unless it is the echo of one this end republished. `wall_us`
  // is the wall-clock time (us).
  // False when the message is the echo of one this end republished (skipped), true when taken.
  bool OnLocalMessage(const std::string& channel, const uint8_t* data, size_t size, int64_t wall_us, double now_s);
  // A frame from the link. Messages completed by it go to `deliver` (after
  // being remembered as echoes). Malformed frames are counted, never trusted.
  void OnFrame(const uint8_t* bytes, size_t size, int64_t wall_us, double now_s, const DeliverFn& deliver);
  // The link came up / went down.
  void OnConnected(double now_s);
  void OnDisconnected();
  // A message of this bus lost before the tunnel could queue it (the LCM
  // subscription's own queue overflowed).
  void OnLocalDrop(const std::string& channel);
  // True when Pump has something to send now or soon (the caller polls faster).
  bool HasWork() const;
  // Sends what is due: acknowledgements, then data frames by priority while
  // the window, the bandwidth cap and the link allow.
  void Pump(double now_s, const SendFn& send);

  // The report for TUNNEL_STATUS; rates and latencies over the time since
  // the previous report (which this call starts anew).
  TunnelReport Report(double now_s);
  // The other end's name as it introduced itself ("" until heard).
  const std::string& peer_name() const { return peer_name_; }
  bool connected() const { return connected_; }
  uint64_t session() const { return session_; }

 private:
  struct Outgoing {
    uint64_t msg_id = 0;
    uint64_t order = 0;  // global arrival order, FIFO within a priority
    int64_t heard_utime = 0;
    std::vector<uint8_t> bytes;
    size_t sent_offset = 0;
  };
  struct Channel {
    int priority = kNormal;
    bool send = false;  // matched send_channels (queued here)
    int accept = -1;    // -1 unknown, 0 refused, 1 accepted from the peer
    std::deque<Outgoing> queue;
    int64_t queued_bytes = 0, high_water = 0;
    int64_t sent = 0, received = 0, dropped = 0;
    double latency_max_ms = 0;
  };
  struct InFlight {
    uint64_t seq;
    std::vector<uint8_t> frame;
  };
  struct Partial {
    uint64_t first_seq = 0;  // seq of its first chunk: acknowledged only once the message is complete
    std::string channel;
    std::vector<uint8_t> bytes;
    size_t filled = 0;
  };

  Channel* FindOrAdd(const std::string& channel);
  bool MatchesAny(const std::vector<std::regex>& patterns, const std::string& channel) const;
  uint64_t EchoKey(const std::string& channel, const uint8_t* data, size_t size) const;
  void RememberEcho(uint64_t key, double now_s);
  bool ConsumeEcho(uint64_t key, double now_s);
  void OnControl(const Frame& frame, double now_s);
  void OnData(const Frame& frame, int64_t wall_us, double now_s, const DeliverFn& deliver);
  // Whether a data frame is the next expected (a gap asks for a rewind).
  bool InSequence(const DataFrame& d, double now_s);
  // A message's first chunk: its reassembly buffer (oldest ones giving way
  // to the bounds), or partials_.end() when refused.
  std::map<uint64_t, Partial>::iterator StartMessage(const DataFrame& d);
  // An incomplete message dropped as a protocol error.
  void DropPartial(std::map<uint64_t, Partial>::iterator it);
  // A reassembled message counted and handed on (latency_us: now - sent).
  void DeliverMessage(Partial done, int64_t latency_us, double now_s, const DeliverFn& deliver);
  bool NextChunk(std::vector<uint8_t>* frame);
  bool TakeTokens(size_t bytes, double now_s);
  uint64_t AckedSeq() const;

  TunnelOptions options_;
  uint64_t session_;
  FrameLimits limits_;
  std::vector<std::regex> send_, receive_, urgent_, bulk_;
  std::map<std::string, Channel> channels_;

  // Sending.
  uint64_t next_seq_ = 1, next_msg_id_ = 1, next_order_ = 0, max_sent_seq_ = 0;
  std::deque<InFlight> window_;
  size_t cursor_ = 0;  // window_[cursor_] is the next frame to (re)send on this connection
  int64_t window_bytes_ = 0;
  int64_t queued_messages_ = 0, queued_bytes_ = 0, queued_high_water_ = 0;
  double tokens_ = 0, tokens_time_ = -1;
  bool connected_ = false, synced_ = false;
  double connected_time_ = 0;
  int connects_ = 0;

  // Receiving.
  uint64_t peer_session_ = 0;
  uint64_t expected_ = 0;  // next DATA seq of peer_session_ (0: take the first one seen)
  std::string peer_name_;
  std::map<uint64_t, Partial> partials_;  // by msg_id
  int64_t partial_bytes_ = 0;
  bool rewind_due_ = false;
  double last_rewind_request_ = -1e9, last_control_sent_ = -1e9, last_heard_ = -1;
  int frames_since_ack_ = 0;

  // Echoes: key -> times republished, and their expiry order.
  std::unordered_map<uint64_t, int> echoes_;
  std::deque<std::pair<double, uint64_t>> echo_order_;

  // Counters.
  int64_t sent_messages_ = 0, received_messages_ = 0, resent_frames_ = 0;
  int64_t dropped_queue_full_ = 0, dropped_too_large_ = 0, dropped_too_many_channels_ = 0;
  int64_t refused_from_peer_ = 0, rejected_frames_ = 0, echoes_skipped_ = 0;
  int64_t period_tx_bytes_ = 0, period_rx_bytes_ = 0;
  double period_start_ = -1;
  std::vector<double> period_latencies_ms_;
};

}  // namespace vloc::tunnel
