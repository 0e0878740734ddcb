// vloc_accuracy: theoretical cross-site localization accuracy (Wan et al.,
// section 3) for a mission planner, with an optional Monte Carlo check.
//   vloc_accuracy --config config/accuracy/forward_forward.yaml [--monte-carlo N --seed S]
//     [--error-model previous|current|both] [--current-frame world|site] [--paper-eq8]
#include <cstdio>
#include <iostream>

#include "vloc/ba/accuracy.h"
#include "vloc/common/command_line.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  vloc::CommandLine args;
  std::string error;
  const char* usage =
      "usage: vloc_accuracy --config FILE [--monte-carlo N] [--seed S] [--error-model previous|current|both] "
      "[--current-frame world|site] [--paper-eq8]";
  if (!args.Parse(argc, argv, {"config", "monte-carlo", "seed", "error-model", "current-frame", "paper-eq8", "help"}, &error)) {
    std::fprintf(stderr, "vloc_accuracy: %s\n%s\n", error.c_str(), usage);
    return 1;
  }
  if (args.Has("help") || !args.Has("config")) {
    std::fprintf(args.Has("help") ? stdout : stderr, "%s\n", usage);
    return args.Has("help") ? 0 : 1;
  }
  vloc::AccuracyOptions options;
  try {
    YAML::Node root = vloc::LoadYamlFile(args.Get("config"));
    if (args.Has("error-model")) root["error_model"] = args.Get("error-model");
    if (args.Has("current-frame")) root["current_frame"] = args.Get("current-frame");
    if (args.Has("paper-eq8")) root["paper_eq8_offdiagonal"] = true;
    std::string echo;
    options = vloc::LoadOptions<vloc::AccuracyOptions>(root, args.Get("config"), &echo);
    LOG(INFO) << "effective options:\n" << echo;
  } catch (const vloc::ConfigError& e) {
    std::fprintf(stderr, "vloc_accuracy: %s\n", e.what());
    return 1;
  }
  const vloc::AccuracyResult result = vloc::ComputeLocalizationAccuracy(options);
  std::cout << vloc::FormatAccuracyReport(options, result);
  if (!result.usable) return 1;
  const int trials = args.GetInt("monte-carlo", 0);
  if (trials > 0) {
    const auto mc = vloc::MonteCarloLocalizationAccuracy(options, trials, static_cast<uint64_t>(args.GetInt("seed", 1)));
    std::printf("monte carlo (%d trials, seed %d): sigma_x = %.4f m, sigma_y = %.4f m, sigma_xy = %.4f m, "
                "accuracy %.3f %% (analytic %.3f %%), mean error (%.4f, %.4f) m\n",
                mc.trials, args.GetInt("seed", 1), std::sqrt(mc.cov_site(0, 0)), std::sqrt(mc.cov_site(1, 1)),
                mc.sigma_position, mc.accuracy_percent, result.accuracy_percent, mc.mean_error.x(),
                mc.mean_error.y());
  }
  return 0;
}
