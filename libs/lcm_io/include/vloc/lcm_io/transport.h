#pragma once
// The message transport behind an interface: real LCM (LcmTransport) or an
// in-process mock (MockTransport) for unit tests. Messages are raw bytes
// here; typed.h adds encoding, decoding and exception safety.

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <memory>
#include <string>
#include <vector>

namespace vloc {

// Called with the channel, the encoded bytes and the receive time (us).
using RawHandler = std::function<void(const std::string& channel, const uint8_t* data, size_t size)>;
// Called with the channel each time a message is dropped because the
// subscription's queue is full.
using DropHandler = std::function<void(const std::string& channel)>;

class Transport {
 public:
  virtual ~Transport() = default;
  // Returns false when the message could not be sent.
  virtual bool Publish(const std::string& channel, const void* data, size_t size) = 0;
  // `channel` is a regular expression as in LCM. `queue_capacity` is how
  // many messages may wait before the oldest are dropped; each drop calls
  // `on_drop` (LCM's own queue drops silently, so LcmTransport keeps its
  // own bounded queue per subscription). Returns an id.
  virtual int Subscribe(const std::string& channel, RawHandler handler, int queue_capacity = 30,
                        DropHandler on_drop = {}) = 0;
  virtual void Unsubscribe(int id) = 0;
  // Waits up to timeout_ms for messages and dispatches them. Returns >0 when
  // something was handled, 0 on timeout, kEndOfLog when a log being read
  // (file:// provider) is exhausted, other <0 on a transport error.
  virtual int Handle(int timeout_ms) = 0;
  static constexpr int kEndOfLog = -100;
};

// The LCM URL to use: `configured` when not empty, else $LCM_DEFAULT_URL,
// else kDefaultLcmUrl.
std::string ResolveLcmUrl(const std::string& configured);

// LCM's default multicast group with a receive buffer that carries 1 MB
// images without loss (the kernel caps it at net.core.rmem_max).
extern const char* const kDefaultLcmUrl;

// Starts LCM on `url`. Returns null and one error line (naming the URL and
// the fix) when LCM cannot start, e.g. without a multicast route.
std::unique_ptr<Transport> MakeLcmTransport(const std::string& url, std::string* error);

// In-process transport: Publish queues, Handle delivers to every matching
// subscriber, and the last message on each channel is kept for inspection.
// As with LCM, any thread may publish while one thread handles: the queue and
// the subscriptions are locked; handlers run outside the lock (they may
// publish or subscribe).
class MockTransport : public Transport {
 public:
  bool Publish(const std::string& channel, const void* data, size_t size) override;
  int Subscribe(const std::string& channel, RawHandler handler, int queue_capacity = 30,
                DropHandler on_drop = {}) override;
  void Unsubscribe(int id) override;
  int Handle(int timeout_ms) override;
  // Delivers until the queue is empty; returns how many were delivered.
  int HandleAll();

  int Count(const std::string& channel) const;
  // Valid until the next message on `channel` is published.
  const std::vector<uint8_t>* Last(const std::string& channel) const;

 private:
  struct Subscription {
    std::string pattern;
    RawHandler handler;
  };
  mutable std::mutex mutex_;
  std::map<int, Subscription> subscriptions_;
  int next_id_ = 1;
  std::deque<std::pair<std::string, std::vector<uint8_t>>> queue_;
  std::map<std::string, std::vector<uint8_t>> last_;
  std::map<std::string, int> counts_;
};

}  // namespace vloc
