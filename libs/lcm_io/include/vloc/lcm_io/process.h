#pragma once
// The common start-up and main loop of every vloc process:
//   auto setup = vloc::SetupProcess(argc, argv, {...});
//   if (!setup) return 1;
//   auto options = vloc::LoadProcessOptions<XOptions>(*setup);
//   if (!options) return 1;
//   ... build library objects and subscribe on *setup->transport ...
//   return vloc::RunUntilSignal(*setup->transport, 100, on_idle);

#include <glog/logging.h>
#include <yaml-cpp/yaml.h>

#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vloc/common/command_line.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/transport.h"

namespace vloc {

struct ProcessSetupOptions {
  std::string name;                       // process name, for messages
  std::vector<std::string> extra_flags;   // --flags beyond config, lcm-url, help
  bool config_required = true;            // --config must be given
  std::string usage;                      // one line of usage text
  std::vector<std::string> offline_flags; // any of these given (and no --lcm-url): run on memq://,
                                          // e.g. a simulator writing straight to a log needs no network
};

struct ProcessSetup {
  std::string name;                       // process name, for messages
  CommandLine args;
  std::string config_path;                // empty when no --config
  YAML::Node config;                      // the config file without its lcm_url key
  std::string lcm_url;                    // the URL in use
  std::unique_ptr<Transport> transport;
};

// Parses --config FILE, --lcm-url URL and the extra flags, loads the
// config (its optional top-level `lcm_url` key is taken out) and starts LCM
// (URL: --lcm-url, else the config's lcm_url, else $LCM_DEFAULT_URL, else
// the default). On any error prints one line naming the problem and returns
// nullopt; the caller exits with status 1. Blocks SIGINT and SIGTERM so
// RunUntilSignal can wait for them.
std::optional<ProcessSetup> SetupProcess(int argc, char** argv, const ProcessSetupOptions& options);

// Loads the process's options from its config (unknown keys rejected,
// ranges checked), lets `adjust` apply command-line overrides (it may throw
// ConfigError; Check() runs again after it and names what the command line
// broke), and logs the effective values. On an error prints one line
// "<name>: <what>" and returns nullopt; the caller exits with status 1.
template <class Options>
std::optional<Options> LoadProcessOptions(const ProcessSetup& setup,
                                          const std::function<void(Options&)>& adjust = {}) {
  try {
    std::string echo;
    Options options = LoadOptions<Options>(setup.config, setup.config_path.empty() ? "defaults" : setup.config_path,
                                           &echo);
    if (adjust) {
      adjust(options);
      std::string error;
      if (!options.Check(&error)) throw ConfigError("command line: " + error);
    }
    LOG(INFO) << setup.name << " options:\n" << echo;
    return options;
  } catch (const ConfigError& e) {
    std::cerr << setup.name << ": " << e.what() << "\n";
    return std::nullopt;
  }
}

// Where a process keeps the state it reloads after a restart. An absolute
// `configured` path is used as is; a relative one is placed in the folder
// given by --state-dir, else in $VLOC_LOG_DIR (vloc_launch sets it to the
// group's log folder, so two groups on one machine never share a file);
// with neither, "" (no state kept) and *note says why. Empty stays empty.
std::string ResolveStatePath(const std::string& configured, const CommandLine& args, std::string* note);

// Dispatches messages until SIGINT or SIGTERM arrives (or `should_stop`
// returns true), calling on_idle after every wait of up to timeout_ms.
// Returns the exit code (0 after a signal). Logs kReadyLine first: the
// process has subscribed, so messages published from then on reach it
// (whoever injects messages, e.g. lcm-logplayer in a test, waits for it;
// "started" comes before the subscriptions).
inline constexpr const char* kReadyLine = "subscribed, handling LCM messages";
int RunUntilSignal(Transport& transport, int timeout_ms, const std::function<void()>& on_idle = {},
                   const std::function<bool()>& should_stop = {});

// Blocks SIGINT/SIGTERM for this thread (and threads it starts later) and
// returns true once one is pending (non-blocking check).
void BlockStopSignals();
bool StopSignalPending();

}  // namespace vloc
