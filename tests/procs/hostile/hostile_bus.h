#pragma once
// Shared by the hostile-input process tests: a test-side LCM endpoint that
// publishes raw bytes and collects every output message, a reader of
// recorded logs, and the start / stop of a process under test.

#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "vloc/lcm_io/lcm_schema.h"
#include "vloc/lcm_io/log_reader.h"
#include "vloc/lcm_io/process.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/testing/hostile.h"
#include "vloc/testing/subprocess.h"

namespace vloc::testing {

struct Event {
  std::string channel;
  std::vector<uint8_t> bytes;
};

// The events of a recorded log on channels matching `channels`.
inline std::vector<Event> ReadEvents(const std::string& path, const std::string& channels) {
  std::vector<Event> out;
  LogReader log(path);
  EXPECT_TRUE(log.good()) << log.error();
  const std::regex re(channels);
  while (const lcm::LogEvent* ev = log.Next()) {
    if (!std::regex_match(ev->channel, re)) continue;
    const auto* b = static_cast<const uint8_t*>(ev->data);
    out.push_back({ev->channel, std::vector<uint8_t>(b, b + ev->datalen)});
  }
  return out;
}

// Decodes the events of `channel` as Msg.
template <class Msg>
std::vector<Msg> DecodeAll(const std::vector<Event>& events, const std::string& channel) {
  std::vector<Msg> out;
  for (const Event& e : events) {
    Msg m;
    if (e.channel == channel && Decode(e.bytes.data(), e.bytes.size(), &m)) out.push_back(m);
  }
  return out;
}

// The test's end of the bus: publishes raw bytes (paced, so the kernel's
// socket buffers do not overflow), keeps every message on `outputs`.
class Bus {
 public:
  // Two LCM instances: one only publishes, one only receives.
  Bus(const std::string& url, const std::string& outputs) {
    std::string error;
    sender_ = MakeLcmTransport(url, &error);
    EXPECT_TRUE(sender_) << error;
    transport_ = MakeLcmTransport(url, &error);
    EXPECT_TRUE(transport_) << error;
    if (transport_)
      transport_->Subscribe(
          outputs,
          [this](const std::string& ch, const uint8_t* d, size_t n) {
            got_.push_back({ch, std::vector<uint8_t>(d, d + n)});
          },
          1000000);
  }
  // Publishes at most about 4 MB/s and 4000 messages/s: the receiver's
  // thread must read its socket before the kernel's buffer fills, also on a
  // loaded machine (a lost fragment loses a whole large message).
  void Send(const std::string& channel, const std::vector<uint8_t>& bytes) {
    sender_->Publish(channel, bytes.data(), bytes.size());
    budget_s_ += static_cast<double>(bytes.size() + 256) / 4e6 + 1.0 / 4000;
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (budget_s_ > elapsed + 0.005) Pump(static_cast<int>(1000 * (budget_s_ - elapsed)));
  }
  // Handles incoming messages for `ms` milliseconds.
  void Pump(int ms) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
    do {
      transport_->Handle(5);
      Drain();
    } while (std::chrono::steady_clock::now() < end);
  }
  // The process whose output pipe is read while the bus pumps (one at a
  // time; null = none). It must outlive the pumping.
  void Watch(Subprocess* p) { watched_ = p; }
  bool PumpUntil(const std::function<bool()>& done, double timeout_s) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (!done()) {
      if (std::chrono::steady_clock::now() > end) return false;
      transport_->Handle(20);
      Drain();
    }
    return true;
  }
  // Handles messages until none has arrived for `quiet_s` (or the timeout).
  bool PumpUntilQuiet(double quiet_s, double timeout_s) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    size_t seen = got_.size();
    auto last_change = std::chrono::steady_clock::now();
    while (std::chrono::steady_clock::now() < end) {
      transport_->Handle(20);
      Drain();
      if (got_.size() != seen) {
        seen = got_.size();
        last_change = std::chrono::steady_clock::now();
      } else if (std::chrono::steady_clock::now() - last_change > std::chrono::duration<double>(quiet_s)) {
        return true;
      }
    }
    return false;
  }
  const std::vector<Event>& got() const { return got_; }
  int Count(const std::string& channel) const {
    int n = 0;
    for (const Event& e : got_) n += e.channel == channel;
    return n;
  }
  // Output messages holding a non-finite number where their schema allows
  // none (type found from the fingerprint); *first names the first.
  int NonFinite(std::string* first) const {
    int bad = 0;
    for (const Event& e : got_) {
      if (e.bytes.size() < 8) continue;
      int64_t hash = 0;
      for (int k = 0; k < 8; ++k) hash = (hash << 8) | e.bytes[static_cast<size_t>(k)];
      const std::string type = LcmSchema::Vloc().TypeOfFingerprint(hash);
      if (type.empty()) continue;
      std::string what;
      if (LcmSchema::Vloc().CountNonFinite(type, e.bytes.data(), e.bytes.size(), &what) > 0 && bad++ == 0)
        *first = e.channel + ": " + what;
    }
    return bad;
  }

 private:
  void Drain() {
    if (watched_) watched_->Drain();
  }

  Subprocess* watched_ = nullptr;
  std::unique_ptr<Transport> sender_, transport_;
  std::vector<Event> got_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  double budget_s_ = 0;  // s of sending the messages so far take at the rate above
};

// A process under test, started and waited for until it has subscribed.
inline std::unique_ptr<Subprocess> StartProc(const std::vector<std::string>& argv) {
  auto p = std::make_unique<Subprocess>(argv);
  EXPECT_TRUE(p->WaitForOutput(kReadyLine, 60)) << p->output();
  return p;
}

// What happened to a process: the closing figures of a hostile run.
struct Outcome {
  std::string process;
  int hostile_sent = 0;
  bool alive_after_hostile = false;
  std::optional<int> exit_code;  // after SIGTERM; nullopt = hung
  int nonfinite_outputs = 0;
  std::string first_nonfinite;
  std::string status;  // the process's own counts, from its closing log line
  std::vector<std::string> sent;  // names of the hostile cases, in order (their bytes follow from them)
};

// Sends SIGTERM and records how the process ended.
inline void Stop(Subprocess* p, Outcome* o) {
  p->Signal(SIGTERM);
  o->exit_code = p->WaitExit(20);
  const std::string& out = p->output();
  const size_t at = out.rfind("messages received");
  if (at != std::string::npos) o->status = out.substr(at, out.find('\n', at) - at);
}

inline void Report(const Outcome& o) {
  std::printf("[hostile] %-16s %5d hostile messages; alive after them: %s; exit after SIGTERM: %s; "
              "non-finite outputs: %d; %s\n",
              o.process.c_str(), o.hostile_sent, o.alive_after_hostile ? "yes" : "NO",
              o.exit_code ? std::to_string(*o.exit_code).c_str() : "HUNG", o.nonfinite_outputs, o.status.c_str());
}

inline void ExpectSurvived(const Outcome& o, const Subprocess& p) {
  std::string last;
  for (size_t k = o.sent.size() > 10 ? o.sent.size() - 10 : 0; k < o.sent.size(); ++k) last += "\n  " + o.sent[k];
  EXPECT_TRUE(o.alive_after_hostile) << o.process << " died; the last hostile cases sent:" << last << "\n"
                                     << p.output().substr(p.output().size() > 4000 ? p.output().size() - 4000 : 0);
  EXPECT_EQ(o.exit_code, std::optional<int>(0)) << o.process << " did not stop cleanly";
  EXPECT_EQ(o.nonfinite_outputs, 0) << o.process << " published " << o.first_nonfinite;
}

}  // namespace vloc::testing
