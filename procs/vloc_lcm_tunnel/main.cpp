// vloc_lcm_tunnel: joins two LCM buses over a reliable link (ZeroMQ over
// TCP), one tunnel on each host, e.g. over a radio that loses packets:
//   ground$  vloc_lcm_tunnel --config config/procs/vloc_lcm_tunnel.yaml --name ground  --bind tcp://*:7720
//   vehicle$ vloc_lcm_tunnel --config config/procs/vloc_lcm_tunnel.yaml --name vehicle --connect tcp://GROUND:7720
// Channels go by regular expression each way (send_channels /
// receive_channels), through bounded per-channel queues, urgent channels
// (poses, status, orders) before images, under an optional bandwidth cap;
// every drop is counted and named; nothing is republished onto the bus it
// came from; either end may restart. Status on TUNNEL_STATUS once a second.

#include <glog/logging.h>

#include <atomic>
#include <thread>

#include "tunnel_adapter.h"
#include "vloc/common/logging.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(
      argc, argv,
      {"vloc_lcm_tunnel", {"name", "bind", "connect", "bandwidth-cap-mbps"}, /*config_required=*/false,
       "[--config FILE] [--name NAME] (--bind tcp://*:PORT | --connect tcp://HOST:PORT) [--bandwidth-cap-mbps M] "
       "[--lcm-url URL]"});
  if (!setup) return 1;
  auto options = vloc::LoadProcessOptions<vloc::tunnel::TunnelOptions>(*setup, [&](vloc::tunnel::TunnelOptions& o) {
    const auto& a = setup->args;
    if (a.Has("name")) o.name = a.Get("name");
    if (a.Has("bind")) o.bind = a.Get("bind"), o.connect.clear();
    if (a.Has("connect")) o.connect = a.Get("connect"), o.bind.clear();
    if (a.Has("bandwidth-cap-mbps")) o.bandwidth_cap_mbps = a.GetDouble("bandwidth-cap-mbps", 0);
  });
  if (!options) return 1;
  if (options->bind.empty() && options->connect.empty()) {
    std::cerr << "vloc_lcm_tunnel: no endpoint: give --bind tcp://*:PORT on one end and --connect tcp://HOST:PORT on "
                 "the other (or bind / connect in the config)\n";
    return 1;
  }
  vloc::TunnelAdapter adapter(*setup->transport, *options);
  std::string error;
  if (!adapter.Start(&error)) {
    std::cerr << "vloc_lcm_tunnel: " << error << "\n";
    return 1;
  }
  std::atomic<bool> stop{false};
  std::thread link([&] { adapter.RunLink(stop); });
  const int rc = vloc::RunUntilSignal(*setup->transport, 100, {}, [&] { return adapter.LoopDetected(); });
  stop = true;
  link.join();
  LOG(INFO) << adapter.Summary();
  if (adapter.LoopDetected()) {
    std::cerr << "vloc_lcm_tunnel: " << adapter.LoopProblem() << "\n";
    return 1;
  }
  return rc;
}
