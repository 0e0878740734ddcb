// vloc_logfilter: copies the events of an LCM log whose channel matches a
// regular expression, optionally within a time window, to a new log.
//   vloc_logfilter IN.lcmlog OUT.lcmlog [--channels REGEX] [--start S] [--end S]
// --start/--end are seconds after the first event. Prints what it kept per
// channel. Used to cut small fixtures for tests/data from simulator logs.

#include <lcm/lcm-cpp.hpp>

#include <iostream>
#include <map>
#include <regex>

#include "vloc/common/command_line.h"
#include "vloc/lcm_io/log_reader.h"

int main(int argc, char** argv) {
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv, {"channels", "start", "end", "help"}, &error) || args.positional().size() != 2 ||
      args.Has("help")) {
    if (!error.empty()) std::cerr << "vloc_logfilter: " << error << "\n";
    std::cerr << "usage: vloc_logfilter IN.lcmlog OUT.lcmlog [--channels REGEX] [--start S] [--end S]\n";
    return 1;
  }
  try {
    const std::regex channels(args.Get("channels", ".*"));
    const double start_s = args.GetDouble("start", 0.0);
    const double end_s = args.GetDouble("end", 1e18);
    vloc::LogReader in(args.positional()[0]);
    if (!in.good()) {
      std::cerr << "vloc_logfilter: " << in.error() << "\n";
      return 1;
    }
    lcm::LogFile out(args.positional()[1], "w");
    if (!out.good()) {
      std::cerr << "vloc_logfilter: cannot write log " << args.positional()[1] << "\n";
      return 1;
    }
    std::map<std::string, int> kept;
    int64_t first = -1;
    int64_t eventnum = 0;
    while (const lcm::LogEvent* ev = in.Next()) {
      if (first < 0) first = ev->timestamp;
      const double t = (ev->timestamp - first) * 1e-6;
      if (t < start_s || t > end_s || !std::regex_match(ev->channel, channels)) continue;
      lcm::LogEvent copy = *ev;
      copy.eventnum = eventnum++;
      out.writeEvent(&copy);
      ++kept[ev->channel];
    }
    for (const auto& [channel, n] : kept) std::cout << channel << ": " << n << "\n";
    if (const std::string problem = in.EndProblem(); !problem.empty()) {
      std::cerr << "vloc_logfilter: " << problem << "; " << args.positional()[1] << " holds what came before\n";
      return 1;
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "vloc_logfilter: " << e.what() << "\n";
    return 1;
  }
}
