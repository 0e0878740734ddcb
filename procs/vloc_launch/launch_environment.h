#pragma once
// Command-line and environment set-up of vloc_launch, apart from main().

#include <string>
#include <vector>

#include "vloc/common/command_line.h"

namespace vloc {

// Every value of a repeatable flag (--group a --group b,c) -> {a, b, c}.
std::vector<std::string> CollectFlagValues(int argc, char** argv, const std::string& flag);

// argv with --lcm-url=$VLOC_LCM_URL appended when no --lcm-url is given
// and VLOC_LCM_URL is set, so the launcher and its children share one bus.
std::vector<std::string> ArgsWithDefaultLcmUrl(int argc, char** argv);

struct LaunchPaths {
  std::string bin_dir;   // ${VLOC_BIN}, absolute
  std::string root;      // ${VLOC_ROOT}, absolute
  std::string log_dir;   // ${VLOC_LOG_DIR}, absolute, created
};

// Resolves and exports the variables group files use, before the file is
// read: VLOC_BIN (--bin-dir, $VLOC_BIN, $VLOC_BIN_DIR, else the launcher's
// own folder), VLOC_ROOT ($VLOC_ROOT, else the working directory),
// VLOC_LOG_DIR (--log-dir, $VLOC_LOG_DIR, else ./logs), and VLOC_LCM_URL
// and LCM_DEFAULT_URL (the URL the launcher uses). Returns false with one
// line in *error when the log directory cannot be created.
bool SetupLaunchEnvironment(const CommandLine& args, const std::string& lcm_url, LaunchPaths* paths,
                            std::string* error);

}  // namespace vloc
