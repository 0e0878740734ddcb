#pragma once
// Typed publish/subscribe over a Transport.
// - Subscribe() checks each message's bytes against the type's schema
//   before decoding (lcm_schema.h: lcm-gen's decoders trust the bytes),
//   skips what is not a well-formed Msg, counts drops when the queue is
//   full, and catches every exception a handler throws: a bad message never
//   takes a process down. Errors are logged rate-limited, with counts.
// - Publish() refuses a message with a non-finite number where its schema
//   allows none: no process publishes NaN or infinity.

#include <glog/logging.h>

#include <exception>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "vloc/lcm_io/lcm_schema.h"
#include "vloc/lcm_io/rate_limited_log.h"
#include "vloc/lcm_io/transport.h"

namespace vloc {

// Counts of what a typed subscription did, for status reports and tests.
struct SubscriptionStats {
  int64_t received = 0;         // messages that arrived
  int64_t decode_failures = 0;  // wrong type or corrupt: skipped
  int64_t handler_failures = 0; // handler threw or rejected the content: logged, process continues
  int64_t dropped = 0;          // lost because the queue was full
  RateLimitedLog decode_log, handler_log, drop_log;
};

// Encodes `msg` into bytes; false (and *error) when it cannot, or when a
// float field holds a value its schema does not allow (NaN, infinity).
template <class Msg>
bool Encode(const Msg& msg, std::vector<uint8_t>* bytes, std::string* error) {
  const int size = msg.getEncodedSize();
  bytes->assign(static_cast<size_t>(size), 0);
  if (msg.encode(bytes->data(), 0, size) != size) {
    *error = std::string("could not encode ") + Msg::getTypeName();
    return false;
  }
  std::string first;
  const int bad = LcmSchema::Vloc().CountNonFinite(Msg::getTypeName(), bytes->data(), bytes->size(), &first);
  if (bad > 0) {
    *error = std::to_string(bad) + " non-finite value(s) in " + Msg::getTypeName() + ", first " + first;
    return false;
  }
  return true;
}

// Encode for a publisher whose messages come from its own code (the
// simulators): the bytes, or std::runtime_error with Encode's error (a NaN
// there is a bug, not a message to skip).
template <class Msg>
std::vector<uint8_t> EncodeOrThrow(const Msg& msg) {
  std::vector<uint8_t> bytes;
  std::string error;
  if (!Encode(msg, &bytes, &error)) throw std::runtime_error(error);
  return bytes;
}

template <class Msg>
bool Publish(Transport& transport, const std::string& channel, const Msg& msg) {
  static RateLimitedLog log;
  std::vector<uint8_t> buffer;
  std::string error;
  if (!Encode(msg, &buffer, &error)) {
    if (log.ShouldLog()) LOG(ERROR) << "channel " << channel << ": " << error << "; not sent" << log.Suppressed();
    return false;
  }
  if (!transport.Publish(channel, buffer.data(), buffer.size())) {
    if (log.ShouldLog())
      LOG(ERROR) << "channel " << channel << ": publish of " << buffer.size() << " bytes failed" << log.Suppressed();
    return false;
  }
  return true;
}

// Decodes bytes into `msg` after checking them against Msg's schema; false
// (and *why, when not null) when they are not one well-formed Msg.
template <class Msg>
bool Decode(const uint8_t* data, size_t size, Msg* msg, std::string* why = nullptr) {
  if (!LcmSchema::Vloc().Check(Msg::getTypeName(), data, size, why)) return false;
  try {
    if (msg->decode(data, 0, static_cast<int>(size)) == static_cast<int>(size)) return true;
  } catch (const std::exception& e) {
    if (why) *why = e.what();
    return false;
  }
  if (why) *why = "the decoder rejected it";
  return false;
}

template <class Msg>
using Handler = std::function<void(const std::string& channel, const Msg& msg)>;

// Subscribes `handler` to `channel`. The returned stats stay valid as long
// as the caller keeps the shared_ptr.
template <class Msg>
std::shared_ptr<SubscriptionStats> Subscribe(Transport& transport, const std::string& channel,
                                             Handler<Msg> handler, int queue_capacity = 30) {
  auto stats = std::make_shared<SubscriptionStats>();
  auto on_drop = [stats, queue_capacity](const std::string& ch) {
    ++stats->dropped;
    if (stats->drop_log.ShouldLog())
      LOG(WARNING) << "channel " << ch << ": queue of " << queue_capacity << " full, a message was dropped ("
                   << stats->dropped << " so far)" << stats->drop_log.Suppressed();
  };
  transport.Subscribe(
      channel,
      [stats, handler = std::move(handler)](const std::string& ch, const uint8_t* data, size_t size) {
        ++stats->received;
        Msg msg;
        std::string why;
        if (!Decode(data, size, &msg, &why)) {
          ++stats->decode_failures;
          if (stats->decode_log.ShouldLog())
            LOG(ERROR) << "channel " << ch << ": a message of " << size << " bytes is not a vloc::"
                       << Msg::getTypeName() << " (" << why << "); skipped (" << stats->decode_failures
                       << " so far)" << stats->decode_log.Suppressed();
          return;
        }
        try {
          handler(ch, msg);
          return;
        } catch (const std::exception& e) {
          why = e.what();
        } catch (...) {
          why = "an unknown exception";
        }
        ++stats->handler_failures;
        if (stats->handler_log.ShouldLog())
          LOG(ERROR) << "channel " << ch << ": " << Msg::getTypeName() << " rejected: " << why
                     << "; message skipped, process continues" << stats->handler_log.Suppressed();
      },
      queue_capacity, on_drop);
  return stats;
}

// "received R, undecodable U, rejected H, dropped D" summed over `stats`.
std::string SubscriptionSummary(const std::vector<std::shared_ptr<SubscriptionStats>>& stats);

}  // namespace vloc
