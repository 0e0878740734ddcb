#pragma once
// The tunnel's link: one ZeroMQ DEALER socket over TCP, bound on one end
// and connected on the other. ZeroMQ reconnects by itself (reconnect_ivl),
// detects a dead peer with ZMTP heartbeats (ZMQ_HEARTBEAT_*), refuses
// frames over max_frame_bytes (ZMQ_MAXMSGSIZE: the peer is disconnected),
// and reports connections through its socket monitor. What a reconnection
// loses is resent by TunnelCore (its acknowledgements), not by ZeroMQ.

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace vloc::tunnel {

struct LinkOptions {
  std::string bind;                  // e.g. tcp://*:7720 (this or connect)
  std::string connect;               // e.g. tcp://10.0.0.1:7720
  double heartbeat_s = 1;            // s between ZMTP heartbeats
  double heartbeat_timeout_s = 4;    // s without traffic before the connection is closed
  size_t max_frame_bytes = 1 << 20;  // larger frames from the peer close its connection
};

class ZmqLink {
 public:
  explicit ZmqLink(const LinkOptions& options);
  ~ZmqLink();
  ZmqLink(const ZmqLink&) = delete;
  ZmqLink& operator=(const ZmqLink&) = delete;

  // Binds or connects. False with one line in *error (e.g. address in use).
  bool Start(std::string* error);
  // Waits up to timeout_ms for frames, connection events or Wake(), then
  // calls on_frame for each frame received, on_up for each new connection
  // (handshake done) and on_down for each connection lost.
  void Poll(int timeout_ms, const std::function<void(const uint8_t*, size_t)>& on_frame,
            const std::function<void()>& on_up, const std::function<void()>& on_down);
  // Queues one frame without blocking; false when it cannot be sent now.
  bool Send(const std::vector<uint8_t>& frame);
  // Ends a Poll early; callable from any thread.
  void Wake();
  const std::string& endpoint() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vloc::tunnel
