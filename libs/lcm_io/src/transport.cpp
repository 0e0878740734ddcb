#include "vloc/lcm_io/transport.h"

#include <lcm/lcm-cpp.hpp>

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <deque>
#include <cstdlib>
#include <regex>

namespace vloc {

const char* const kDefaultLcmUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=33554432";

std::string ResolveLcmUrl(const std::string& configured) {
  if (!configured.empty()) return configured;
  if (const char* env = std::getenv("LCM_DEFAULT_URL"); env && *env) return env;
  return kDefaultLcmUrl;
}

namespace {

class LcmTransport : public Transport {
 public:
  explicit LcmTransport(const std::string& url) : lcm_(url), reads_log_(url.rfind("file://", 0) == 0) {}
  bool good() { return lcm_.good(); }

  bool Publish(const std::string& channel, const void* data, size_t size) override {
    return lcm_.publish(channel, data, static_cast<unsigned int>(size)) == 0;
  }

  int Subscribe(const std::string& channel, RawHandler handler, int queue_capacity, DropHandler on_drop) override {
    auto holder = std::make_unique<Holder>();
    holder->handler = std::move(handler);
    holder->on_drop = std::move(on_drop);
    holder->capacity = static_cast<size_t>(std::max(queue_capacity, 1));
    holder->owner = this;
    holder->subscription = lcm_.subscribeFunction(channel, &LcmTransport::Enqueue, holder.get());
    holder->subscription->setQueueCapacity(0);  // unbounded in LCM; bounded (and counted) in Holder::queue
    const int id = next_id_++;
    holders_[id] = std::move(holder);
    return id;
  }

  void Unsubscribe(int id) override {
    auto it = holders_.find(id);
    if (it == holders_.end()) return;
    lcm_.unsubscribe(it->second->subscription);
    holders_.erase(it);
  }

  // Waits for a message, drains everything LCM has received into the
  // bounded queues (counting drops), then delivers in arrival order.
  int Handle(int timeout_ms) override {
    const int rc = lcm_.handleTimeout(timeout_ms);
    if (rc < 0 && reads_log_) return kEndOfLog;  // the file provider reports the log's end as an error
    if (rc <= 0) return rc;
    while (lcm_.handleTimeout(0) > 0) {
    }
    int delivered = 0;
    while (true) {
      Holder* next = nullptr;
      for (auto& [id, h] : holders_)
        if (!h->queue.empty() && (!next || h->queue.front().sequence < next->queue.front().sequence))
          next = h.get();
      if (!next) break;
      Queued q = std::move(next->queue.front());
      next->queue.pop_front();
      const RawHandler handler = next->handler;  // the call may unsubscribe (destroy) `next`
      handler(q.channel, q.bytes.data(), q.bytes.size());
      ++delivered;
    }
    return std::max(delivered, 1);
  }

 private:
  struct Queued {
    uint64_t sequence;
    std::string channel;
    std::vector<uint8_t> bytes;
  };
  struct Holder {
    RawHandler handler;
    DropHandler on_drop;
    size_t capacity = 30;
    std::deque<Queued> queue;
    LcmTransport* owner = nullptr;
    lcm::Subscription* subscription = nullptr;
  };
  static void Enqueue(const lcm::ReceiveBuffer* rbuf, const std::string& channel, Holder* holder) {
    const auto* bytes = static_cast<const uint8_t*>(rbuf->data);
    holder->queue.push_back({holder->owner->sequence_++, channel, std::vector<uint8_t>(bytes, bytes + rbuf->data_size)});
    while (holder->queue.size() > holder->capacity) {
      holder->queue.pop_front();
      if (holder->on_drop) holder->on_drop(channel);
    }
  }

  lcm::LCM lcm_;
  const bool reads_log_;  // file:// provider: reading a log
  std::map<int, std::unique_ptr<Holder>> holders_;
  int next_id_ = 1;
  uint64_t sequence_ = 0;
};

}  // namespace

std::unique_ptr<Transport> MakeLcmTransport(const std::string& url, std::string* error) {
  // LCM prints a multi-line explanation to stderr when it cannot start; hold
  // stderr while it starts so a failure is reported in our one line, and
  // pass LCM's text through when it starts fine.
  std::fflush(stderr);
  const int saved_stderr = dup(2);
  FILE* held = std::tmpfile();
  if (held && saved_stderr >= 0) dup2(fileno(held), 2);
  auto transport = std::make_unique<LcmTransport>(url);
  const bool good = transport->good();
  if (held && saved_stderr >= 0) {
    std::fflush(stderr);
    dup2(saved_stderr, 2);
    if (good) {
      std::rewind(held);
      char buf[512];
      size_t n;
      while ((n = std::fread(buf, 1, sizeof(buf), held)) > 0) std::fwrite(buf, 1, n, stderr);
    }
  }
  if (held) std::fclose(held);
  if (saved_stderr >= 0) close(saved_stderr);
  if (!good) {
    if (error) {
      *error = "LCM could not start on '" + url +
               "': no multicast route? Fix: sudo ip route add 224.0.0.0/4 dev lo "
               "(or set LCM_DEFAULT_URL / lcm_url to a reachable URL)";
    }
    return nullptr;
  }
  return transport;
}

bool MockTransport::Publish(const std::string& channel, const void* data, size_t size) {
  const auto* bytes = static_cast<const uint8_t*>(data);
  std::lock_guard<std::mutex> lock(mutex_);
  queue_.emplace_back(channel, std::vector<uint8_t>(bytes, bytes + size));
  last_[channel] = queue_.back().second;
  ++counts_[channel];
  return true;
}

int MockTransport::Subscribe(const std::string& channel, RawHandler handler, int /*queue_capacity*/,
                             DropHandler /*on_drop*/) {
  std::lock_guard<std::mutex> lock(mutex_);
  const int id = next_id_++;
  subscriptions_[id] = {channel, std::move(handler)};
  return id;
}

void MockTransport::Unsubscribe(int id) {
  std::lock_guard<std::mutex> lock(mutex_);
  subscriptions_.erase(id);
}

int MockTransport::Handle(int /*timeout_ms*/) {
  std::pair<std::string, std::vector<uint8_t>> message;
  std::map<int, Subscription> subscriptions;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (queue_.empty()) return 0;
    message = std::move(queue_.front());
    queue_.pop_front();
    // A copy: a handler may subscribe or unsubscribe while we deliver.
    subscriptions = subscriptions_;
  }
  const auto& [channel, bytes] = message;
  for (auto& [id, sub] : subscriptions) {
    if (std::regex_match(channel, std::regex(sub.pattern))) sub.handler(channel, bytes.data(), bytes.size());
  }
  return 1;
}

int MockTransport::HandleAll() {
  int n = 0;
  while (Handle(0) > 0) ++n;
  return n;
}

int MockTransport::Count(const std::string& channel) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = counts_.find(channel);
  return it == counts_.end() ? 0 : it->second;
}

const std::vector<uint8_t>* MockTransport::Last(const std::string& channel) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = last_.find(channel);
  return it == last_.end() ? nullptr : &it->second;
}

}  // namespace vloc
