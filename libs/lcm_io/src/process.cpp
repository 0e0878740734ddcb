#include "vloc/lcm_io/process.h"

#include <glog/logging.h>
#include <signal.h>

#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <iostream>

#include "vloc/common/options.h"

namespace vloc {

void BlockStopSignals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
}

bool StopSignalPending() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  timespec zero{0, 0};
  return sigtimedwait(&set, nullptr, &zero) > 0;
}

std::optional<ProcessSetup> SetupProcess(int argc, char** argv, const ProcessSetupOptions& options) {
  ProcessSetup setup;
  setup.name = options.name;
  std::vector<std::string> known = {"config", "lcm-url", "help"};
  known.insert(known.end(), options.extra_flags.begin(), options.extra_flags.end());
  std::string error;
  if (!setup.args.Parse(argc, argv, known, &error)) {
    std::cerr << options.name << ": " << error << "\n";
    return std::nullopt;
  }
  if (setup.args.Has("help")) {
    std::cerr << "usage: " << options.name << " " << options.usage << "\n";
    return std::nullopt;
  }
  setup.config_path = setup.args.Get("config");
  if (setup.config_path.empty() && options.config_required) {
    std::cerr << options.name << ": --config FILE is required (see config/procs/)\n";
    return std::nullopt;
  }
  std::string configured_url;
  if (!setup.config_path.empty()) {
    try {
      setup.config = LoadYamlFile(setup.config_path);
    } catch (const ConfigError& e) {
      std::cerr << options.name << ": " << e.what() << "\n";
      return std::nullopt;
    }
    if (!setup.config.IsMap()) {
      std::cerr << options.name << ": config " << setup.config_path
                << " is not a map of keys; start from config/procs/" << options.name << ".yaml\n";
      return std::nullopt;
    }
    if (setup.config.IsMap() && setup.config["lcm_url"]) {
      configured_url = setup.config["lcm_url"].as<std::string>("");
      setup.config.remove("lcm_url");
    }
  }
  if (setup.args.Has("lcm-url")) {
    configured_url = setup.args.Get("lcm-url");
  } else {
    for (const auto& flag : options.offline_flags)
      if (setup.args.Has(flag)) configured_url = "memq://";
  }
  setup.lcm_url = ResolveLcmUrl(configured_url);
  BlockStopSignals();
  setup.transport = MakeLcmTransport(setup.lcm_url, &error);
  if (!setup.transport) {
    std::cerr << options.name << ": " << error << "\n";
    return std::nullopt;
  }
  LOG(INFO) << options.name << " started, LCM URL " << setup.lcm_url
            << (setup.config_path.empty() ? "" : ", config " + setup.config_path);
  return setup;
}

std::string ResolveStatePath(const std::string& configured, const CommandLine& args, std::string* note) {
  if (configured.empty()) return "";
  const std::filesystem::path path(configured);
  if (path.is_absolute()) return configured;
  std::string dir = args.Get("state-dir");
  if (dir.empty())
    if (const char* env = std::getenv("VLOC_LOG_DIR"); env && *env) dir = env;
  if (dir.empty()) {
    if (note)
      *note = "no --state-dir and no VLOC_LOG_DIR: " + configured + " is not kept (a restart starts afresh)";
    return "";
  }
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  return (std::filesystem::path(dir) / path).string();
}

int RunUntilSignal(Transport& transport, int timeout_ms, const std::function<void()>& on_idle,
                   const std::function<bool()>& should_stop) {
  LOG(INFO) << kReadyLine;
  while (true) {
    if (StopSignalPending()) {
      LOG(INFO) << "stop signal received, shutting down";
      return 0;
    }
    if (should_stop && should_stop()) return 0;
    const int handled = transport.Handle(timeout_ms);
    if (handled == Transport::kEndOfLog) {
      LOG(INFO) << "end of the log being read (file:// provider): every message handled; exiting";
      return 0;
    }
    if (handled < 0) {
      LOG(ERROR) << "LCM transport error; exiting";
      return 2;
    }
    if (on_idle) on_idle();
  }
}

}  // namespace vloc
