// vloc_logger: records every LCM message on a URL to an LCM log, like
// lcm-logger, but with a deep receive queue. lcm-logger 1.3.1 keeps LCM's
// default 30-message subscription queue, so when the machine is busy (a
// burst of 100 Hz IMU after a Navcam render, on 2 cores) it silently drops
// small messages; vloc's evaluation needs every ground-truth message.
//   vloc_logger --out FILE [--channels REGEX] [--queue N] [--lcm-url URL]
// Events carry the receive time, as lcm-logger's do. Prints a summary
// (messages and bytes per channel) when stopped with SIGINT/SIGTERM.

#include <glog/logging.h>

#include <iostream>
#include <lcm/lcm-cpp.hpp>
#include <map>

#include "vloc/common/logging.h"
#include "vloc/lcm_io/process.h"

namespace {

class Recorder {
 public:
  explicit Recorder(const std::string& path) : log_(path, "w") {}
  bool good() { return log_.good(); }

  void Handle(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    lcm::LogEvent event;
    event.eventnum = 0;
    event.timestamp = rbuf->recv_utime;
    event.channel = channel;
    event.datalen = static_cast<int32_t>(rbuf->data_size);
    event.data = rbuf->data;
    if (log_.writeEvent(&event) != 0) {
      ++write_failures_;
      if (write_failures_ == 1) LOG(ERROR) << "writing the log failed (disk full?); later messages are lost";
      return;
    }
    ++counts_[channel];
    bytes_[channel] += rbuf->data_size;
  }

  void Report() const {
    int64_t total = 0;
    for (const auto& [channel, n] : counts_) {
      LOG(INFO) << "  " << channel << ": " << n << " messages, " << bytes_.at(channel) / 1024 << " kB";
      total += n;
    }
    LOG(INFO) << "recorded " << total << " messages on " << counts_.size() << " channels; write failures "
              << write_failures_;
  }

 private:
  lcm::LogFile log_;
  std::map<std::string, int64_t> counts_, bytes_;
  int64_t write_failures_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  vloc::BlockStopSignals();
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv, {"out", "channels", "queue", "lcm-url", "help"}, &error) || !args.Has("out") ||
      args.Has("help")) {
    std::cerr << "vloc_logger: " << (error.empty() ? "--out FILE is required" : error)
              << "\nusage: vloc_logger --out FILE [--channels REGEX] [--queue N] [--lcm-url URL]\n";
    return 1;
  }
  const std::string url = vloc::ResolveLcmUrl(args.Get("lcm-url"));
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::cerr << "vloc_logger: LCM could not start on '" << url
              << "': no multicast route? Fix: sudo ip route add 224.0.0.0/4 dev lo\n";
    return 1;
  }
  Recorder recorder(args.Get("out"));
  if (!recorder.good()) {
    std::cerr << "vloc_logger: cannot open " << args.Get("out") << " for writing (does its folder exist?)\n";
    return 1;
  }
  int queue = 10000;
  try {
    queue = args.GetInt("queue", 10000);
  } catch (const std::exception& e) {
    std::cerr << "vloc_logger: " << e.what() << "\n";
    return 1;
  }
  lcm::Subscription* sub = lcm.subscribe(args.Get("channels", ".*"), &Recorder::Handle, &recorder);
  sub->setQueueCapacity(queue);
  LOG(INFO) << "recording " << args.Get("channels", ".*") << " on " << url << " to " << args.Get("out")
            << " (queue " << queue << " messages)";
  while (!vloc::StopSignalPending()) {
    if (lcm.handleTimeout(100) < 0) {
      LOG(ERROR) << "LCM receive failed; stopping";
      break;
    }
  }
  // Drain what is already queued before closing.
  while (lcm.handleTimeout(0) > 0) {
  }
  recorder.Report();
  return 0;
}
