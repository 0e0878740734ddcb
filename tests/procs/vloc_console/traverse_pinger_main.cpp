// vloc_traverse_pinger: publishes a TRAVERSE of N sites whose utime is the
// wall clock at publishing (us since the epoch), `rate` times a second for
// `seconds`: the page then knows how old each map it draws is
// (scripts/console_figures.py --ping: TRAVERSE published -> map drawn).
//   vloc_traverse_pinger --lcm-url URL [--sites 20] [--rate 5] [--seconds 20]
#include <chrono>
#include <iostream>
#include <thread>

#include "vloc/common/command_line.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/traverse_t.hpp"

namespace {

vloc::traverse_t Traverse(int sites) {
  vloc::traverse_t t{};
  t.num_sites = sites;
  for (int i = 0; i < sites; ++i) {
    vloc::PoseWithCovariance p;
    p.pose.translation() = Eigen::Vector3d(10.0 * i, 2.0 * std::sin(0.3 * i), 0);
    p.covariance = vloc::Matrix6d::Identity() * (0.01 + 0.001 * i);
    t.site_ids.push_back(i);
    t.poses.push_back(vloc::PoseToMessage(p, "world", "body"));
  }
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv, {"lcm-url", "sites", "rate", "seconds"}, &error)) {
    std::cerr << "vloc_traverse_pinger: " << error << "\n";
    return 1;
  }
  auto lcm = vloc::MakeLcmTransport(vloc::ResolveLcmUrl(args.Get("lcm-url")), &error);
  if (!lcm) {
    std::cerr << "vloc_traverse_pinger: " << error << "\n";
    return 1;
  }
  vloc::traverse_t t = Traverse(args.GetInt("sites", 20));
  const double period = 1.0 / std::max(0.1, args.GetDouble("rate", 5));
  const int count = static_cast<int>(args.GetDouble("seconds", 20) / period);
  for (int k = 0; k < count; ++k) {
    t.utime = std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
                  .count();
    vloc::Publish(*lcm, "TRAVERSE", t);
    std::this_thread::sleep_for(std::chrono::duration<double>(period));
  }
  std::cout << "published " << count << " TRAVERSE messages\n";
  return 0;
}
