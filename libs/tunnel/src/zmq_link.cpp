#include "vloc/tunnel/zmq_link.h"

#include <sys/eventfd.h>
#include <unistd.h>

#include <atomic>
#include <cstring>
#include <zmq.hpp>

namespace vloc::tunnel {

struct ZmqLink::Impl {
  LinkOptions options;
  std::string endpoint;
  zmq::context_t context{1};
  zmq::socket_t socket{context, zmq::socket_type::dealer};
  zmq::socket_t monitor{context, zmq::socket_type::pair};
  int wake_fd = -1;
};

ZmqLink::ZmqLink(const LinkOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  impl_->endpoint = options.bind.empty() ? options.connect : options.bind;
  impl_->wake_fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
}

ZmqLink::~ZmqLink() {
  impl_->socket.set(zmq::sockopt::linger, 0);
  impl_->monitor.set(zmq::sockopt::linger, 0);
  impl_->socket.close();
  impl_->monitor.close();
  if (impl_->wake_fd >= 0) close(impl_->wake_fd);
}

const std::string& ZmqLink::endpoint() const { return impl_->endpoint; }

bool ZmqLink::Start(std::string* error) {
  Impl& m = *impl_;
  try {
    m.socket.set(zmq::sockopt::linger, 0);
    m.socket.set(zmq::sockopt::heartbeat_ivl, static_cast<int>(m.options.heartbeat_s * 1000));
    m.socket.set(zmq::sockopt::heartbeat_timeout, static_cast<int>(m.options.heartbeat_timeout_s * 1000));
    m.socket.set(zmq::sockopt::heartbeat_ttl, static_cast<int>(m.options.heartbeat_timeout_s * 1000));
    m.socket.set(zmq::sockopt::reconnect_ivl, 200);
    m.socket.set(zmq::sockopt::reconnect_ivl_max, 2000);
    m.socket.set(zmq::sockopt::maxmsgsize, static_cast<int64_t>(m.options.max_frame_bytes));
    m.socket.set(zmq::sockopt::sndhwm, 256);  // frames; the tunnel's window bounds what is in flight
    m.socket.set(zmq::sockopt::immediate, true);  // no queueing to a connection not yet made
    const std::string monitor_endpoint = "inproc://vloc-tunnel-monitor";
    if (zmq_socket_monitor(m.socket.handle(), monitor_endpoint.c_str(),
                           ZMQ_EVENT_HANDSHAKE_SUCCEEDED | ZMQ_EVENT_DISCONNECTED) != 0)
      throw zmq::error_t();
    m.monitor.connect(monitor_endpoint);
    if (!m.options.bind.empty())
      m.socket.bind(m.options.bind);
    else
      m.socket.connect(m.options.connect);
  } catch (const zmq::error_t& e) {
    if (error) *error = "cannot " + std::string(m.options.bind.empty() ? "connect to '" : "bind '") + m.endpoint +
                        "': " + e.what() + " (an endpoint is like tcp://*:7720 or tcp://10.0.0.1:7720)";
    return false;
  }
  return true;
}

void ZmqLink::Poll(int timeout_ms, const std::function<void(const uint8_t*, size_t)>& on_frame,
                   const std::function<void()>& on_up, const std::function<void()>& on_down) {
  Impl& m = *impl_;
  zmq::pollitem_t items[] = {{m.socket.handle(), 0, ZMQ_POLLIN, 0},
                             {m.monitor.handle(), 0, ZMQ_POLLIN, 0},
                             {nullptr, m.wake_fd, ZMQ_POLLIN, 0}};
  try {
    zmq::poll(items, m.wake_fd >= 0 ? 3 : 2, std::chrono::milliseconds(timeout_ms));
  } catch (const zmq::error_t&) {
    return;  // EINTR
  }
  if (items[2].revents & ZMQ_POLLIN) {
    uint64_t n;
    [[maybe_unused]] ssize_t r = read(m.wake_fd, &n, sizeof(n));
  }
  // Connection events: frame 1 is the event (u16) and its value (u32), frame 2 the address.
  while (true) {
    zmq::message_t event, address;
    if (!m.monitor.recv(event, zmq::recv_flags::dontwait)) break;
    if (event.more()) (void)m.monitor.recv(address, zmq::recv_flags::dontwait);
    if (event.size() < 2) continue;
    uint16_t id;
    std::memcpy(&id, event.data(), sizeof(id));
    if (id == ZMQ_EVENT_HANDSHAKE_SUCCEEDED) on_up();
    if (id == ZMQ_EVENT_DISCONNECTED) on_down();
  }
  // At most a bounded batch per call, so that sending keeps its turn.
  for (int i = 0; i < 256; ++i) {
    zmq::message_t frame;
    try {
      if (!m.socket.recv(frame, zmq::recv_flags::dontwait)) break;
    } catch (const zmq::error_t&) {
      break;
    }
    // A multi-part message is not the tunnel's: its parts are read and each fails validation.
    on_frame(static_cast<const uint8_t*>(frame.data()), frame.size());
  }
}

bool ZmqLink::Send(const std::vector<uint8_t>& frame) {
  try {
    return impl_->socket.send(zmq::buffer(frame), zmq::send_flags::dontwait).has_value();
  } catch (const zmq::error_t&) {
    return false;
  }
}

void ZmqLink::Wake() {
  const uint64_t one = 1;
  if (impl_->wake_fd >= 0) {
    [[maybe_unused]] ssize_t r = write(impl_->wake_fd, &one, sizeof(one));
  }
}

}  // namespace vloc::tunnel
