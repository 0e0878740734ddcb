#pragma once
// Test support for vloc_lcm_tunnel: one LCM bus as the test sees it, with
// every message on test channels recorded by channel (payload = an 8-byte
// index, then a pattern of the message's size) and the newest
// TUNNEL_STATUS of each tunnel. Header-only.

#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "vloc/lcm_io/transport.h"
#include "vloc/testing/subprocess.h"
#include "vloc/tunnel_status_t.hpp"

namespace vloc::testing {

inline std::vector<uint8_t> IndexedPayload(int64_t index, size_t size) {
  std::vector<uint8_t> p(std::max<size_t>(size, 8));
  std::memcpy(p.data(), &index, 8);
  for (size_t i = 8; i < p.size(); ++i) p[i] = static_cast<uint8_t>(index * 13 + i * 7);
  return p;
}

class TunnelBus {
 public:
  explicit TunnelBus(const std::string& url) {
    std::string error;
    transport_ = MakeLcmTransport(url, &error);
    EXPECT_TRUE(transport_) << error;
    if (!transport_) return;
    transport_->Subscribe(
        ".*",
        [this](const std::string& channel, const uint8_t* data, size_t size) {
          if (channel == "LCM_SELF_TEST") return;  // LCM's own start-up message
          if (channel == "TUNNEL_STATUS") {
            tunnel_status_t m;
            if (m.decode(data, 0, static_cast<int>(size)) > 0) status[m.name] = m;
            return;
          }
          int64_t index = -1;
          if (size >= 8) std::memcpy(&index, data, 8);
          const bool intact = size >= 8 && std::vector<uint8_t>(data, data + size) == IndexedPayload(index, size);
          if (!intact) ++corrupt, corrupt_channels.push_back(channel + ":" + std::to_string(size));
          received[channel].push_back(index);
          arrival_s[channel].push_back(NowS());
          arrival.push_back(channel);
        },
        100000);
  }
  bool ok() const { return transport_ != nullptr; }
  void Publish(const std::string& channel, int64_t index, size_t size) {
    const auto p = IndexedPayload(index, size);
    transport_->Publish(channel, p.data(), p.size());
  }
  void Handle(int timeout_ms) {
    if (transport_) transport_->Handle(timeout_ms);
  }
  size_t Count(const std::string& channel) const {
    auto it = received.find(channel);
    return it == received.end() ? 0 : it->second.size();
  }
  // The status of the tunnel `name`, or null.
  const tunnel_status_t* Status(const std::string& name) const {
    auto it = status.find(name);
    return it == status.end() ? nullptr : &it->second;
  }

  static double NowS() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  }
  std::map<std::string, std::vector<int64_t>> received;
  std::map<std::string, std::vector<double>> arrival_s;  // steady clock, s, beside `received`
  std::vector<std::string> arrival;  // channels in arrival order
  std::map<std::string, tunnel_status_t> status;
  int corrupt = 0;
  std::vector<std::string> corrupt_channels;

 private:
  std::unique_ptr<Transport> transport_;
};

// Handles both buses (and drains the processes' output) until `done` or the timeout.
inline bool WaitOn(const std::vector<TunnelBus*>& buses, const std::vector<Subprocess*>& procs,
                   const std::function<bool()>& done, double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  do {  // at least once: a zero timeout handles what is waiting
    for (TunnelBus* b : buses) b->Handle(buses.size() > 2 ? 2 : 20);
    for (Subprocess* p : procs) p->Drain();
    if (done()) return true;
  } while (std::chrono::steady_clock::now() < deadline);
  return false;
}

// 0, 1, ..., n-1 exactly: every message, in order, once.
inline bool InOrder(const std::vector<int64_t>& indices, int64_t n) {
  if (static_cast<int64_t>(indices.size()) != n) return false;
  for (int64_t i = 0; i < n; ++i)
    if (indices[static_cast<size_t>(i)] != i) return false;
  return true;
}

}  // namespace vloc::testing
