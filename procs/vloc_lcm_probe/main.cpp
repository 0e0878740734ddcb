// vloc_lcm_probe: checks that an LCM network carries vloc's image-sized
// messages without loss, end to end.
//   vloc_lcm_probe send    [--channel C] [--count N] [--size BYTES] [--rate HZ] [--lcm-url URL]
//   vloc_lcm_probe receive [--channel C] [--count N] [--timeout S] [--lcm-url URL]
// The sender publishes image_t messages whose pixels follow a pattern known
// from the message index; the receiver checks every byte and prints a YAML
// summary. receive exits 0 only when all N messages arrived intact.

#include <glog/logging.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <set>
#include <thread>

#include "vloc/common/logging.h"
#include "vloc/image_t.hpp"
#include "vloc/lcm_io/process.h"
#include "vloc/lcm_io/typed.h"

namespace {

uint8_t PatternByte(int64_t index, size_t offset) {
  return static_cast<uint8_t>((offset * 7u + (offset >> 10) * 13u + static_cast<size_t>(index) * 31u) & 0xffu);
}

vloc::image_t MakeProbe(int64_t index, int size) {
  vloc::image_t msg;
  msg.utime = index;
  msg.frame_id = "probe";
  msg.width = size;
  msg.height = 1;
  msg.encoding = vloc::image_t::ENCODING_GRAY8;
  msg.size = size;
  msg.data.resize(static_cast<size_t>(size));
  for (size_t i = 0; i < msg.data.size(); ++i) msg.data[i] = PatternByte(index, i);
  return msg;
}

bool ProbeIntact(const vloc::image_t& msg) {
  if (msg.frame_id != "probe" || msg.size != static_cast<int>(msg.data.size())) return false;
  for (size_t i = 0; i < msg.data.size(); ++i)
    if (msg.data[i] != PatternByte(msg.utime, i)) return false;
  return true;
}

int Send(vloc::ProcessSetup& setup, const std::string& channel, int count, int size, double rate) {
  const auto period = std::chrono::duration<double>(rate > 0 ? 1.0 / rate : 0.0);
  auto next = std::chrono::steady_clock::now();
  int sent = 0;
  for (int i = 0; i < count && !vloc::StopSignalPending(); ++i) {
    if (vloc::Publish(*setup.transport, channel, MakeProbe(i, size))) ++sent;
    next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
    std::this_thread::sleep_until(next);
  }
  std::cout << "sent: " << sent << "\nbytes_each: " << size << std::endl;
  return sent == count ? 0 : 1;
}

int Receive(vloc::ProcessSetup& setup, const std::string& channel, int count, double timeout_s) {
  std::set<int64_t> seen;
  int corrupt = 0, duplicates = 0;
  auto stats = vloc::Subscribe<vloc::image_t>(
      *setup.transport, channel,
      [&](const std::string&, const vloc::image_t& msg) {
        if (!ProbeIntact(msg)) {
          ++corrupt;
          return;
        }
        if (!seen.insert(msg.utime).second) ++duplicates;
      },
      /*queue_capacity=*/1000);
  std::cout << "ready" << std::endl;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  vloc::RunUntilSignal(*setup.transport, 50, {}, [&] {
    return static_cast<int>(seen.size()) >= count || std::chrono::steady_clock::now() > deadline;
  });
  const int received = static_cast<int>(seen.size());
  std::cout << "received: " << received << "\nexpected: " << count << "\nlost: " << (count - received)
            << "\ncorrupt: " << corrupt << "\nduplicates: " << duplicates
            << "\nwrong_type: " << stats->decode_failures << std::endl;
  return (received == count && corrupt == 0) ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(
      argc, argv,
      {"vloc_lcm_probe", {"channel", "count", "size", "rate", "timeout"}, /*config_required=*/false,
       "send|receive [--channel C] [--count N] [--size BYTES] [--rate HZ] [--timeout S] [--lcm-url URL]"});
  if (!setup) return 1;
  if (setup->args.positional().size() != 1) {
    std::cerr << "vloc_lcm_probe: give exactly one mode, send or receive\n";
    return 1;
  }
  try {
    const std::string mode = setup->args.positional()[0];
    const std::string channel = setup->args.Get("channel", "VLOC_PROBE");
    const int count = setup->args.GetInt("count", 100);
    if (mode == "send")
      return Send(*setup, channel, count, setup->args.GetInt("size", 1 << 20), setup->args.GetDouble("rate", 50));
    if (mode == "receive") return Receive(*setup, channel, count, setup->args.GetDouble("timeout", 30));
    std::cerr << "vloc_lcm_probe: unknown mode '" << mode << "'; use send or receive\n";
  } catch (const std::exception& e) {
    std::cerr << "vloc_lcm_probe: " << e.what() << "\n";
  }
  return 1;
}
