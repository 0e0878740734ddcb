#pragma once
// Typed publish/subscribe over a Transport. Subscribe() decodes each message,
// reports a message of the wrong type (or corrupt) in one log line and skips
// it, and catches every exception a handler throws: a bad message never
// takes a process down.

#include <glog/logging.h>

#include <exception>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "vloc/lcm_io/transport.h"

namespace vloc {

// Counts of what a typed subscription did, for status reports and tests.
struct SubscriptionStats {
  int64_t received = 0;        // messages that arrived
  int64_t decode_failures = 0; // wrong type or corrupt: skipped
  int64_t handler_failures = 0;// handler threw: logged, process continues
};

template <class Msg>
bool Publish(Transport& transport, const std::string& channel, const Msg& msg) {
  const int size = msg.getEncodedSize();
  std::vector<uint8_t> buffer(static_cast<size_t>(size));
  if (msg.encode(buffer.data(), 0, size) != size) {
    LOG(ERROR) << "channel " << channel << ": could not encode " << Msg::getTypeName() << "; not sent";
    return false;
  }
  if (!transport.Publish(channel, buffer.data(), buffer.size())) {
    LOG(ERROR) << "channel " << channel << ": publish of " << size << " bytes failed";
    return false;
  }
  return true;
}

// Decodes bytes into `msg`; false when they are not a Msg.
template <class Msg>
bool Decode(const uint8_t* data, size_t size, Msg* msg) {
  return msg->decode(data, 0, static_cast<int>(size)) == static_cast<int>(size);
}

template <class Msg>
using Handler = std::function<void(const std::string& channel, const Msg& msg)>;

// Subscribes `handler` to `channel`. The returned stats stay valid as long
// as the caller keeps the shared_ptr.
template <class Msg>
std::shared_ptr<SubscriptionStats> Subscribe(Transport& transport, const std::string& channel,
                                             Handler<Msg> handler, int queue_capacity = 30) {
  auto stats = std::make_shared<SubscriptionStats>();
  transport.Subscribe(
      channel,
      [stats, handler = std::move(handler)](const std::string& ch, const uint8_t* data, size_t size) {
        ++stats->received;
        Msg msg;
        bool decoded = false;
        try {
          decoded = Decode(data, size, &msg);
        } catch (const std::exception&) {
          decoded = false;
        }
        if (!decoded) {
          ++stats->decode_failures;
          LOG(ERROR) << "channel " << ch << ": a message of " << size << " bytes is not of type vloc::"
                     << Msg::getTypeName() << " (wrong type or corrupt); skipped";
          return;
        }
        try {
          handler(ch, msg);
        } catch (const std::exception& e) {
          ++stats->handler_failures;
          LOG(ERROR) << "channel " << ch << ": handling " << Msg::getTypeName() << " failed: " << e.what()
                     << "; message skipped, process continues";
        } catch (...) {
          ++stats->handler_failures;
          LOG(ERROR) << "channel " << ch << ": handling " << Msg::getTypeName()
                     << " failed with an unknown exception; message skipped, process continues";
        }
      },
      queue_capacity);
  return stats;
}

}  // namespace vloc
