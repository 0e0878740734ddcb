#include "launch_environment.h"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <sstream>

namespace vloc {
namespace {

std::string EnvOr(const char* name, const std::string& fallback) {
  const char* v = std::getenv(name);
  return v && *v ? std::string(v) : fallback;
}

}  // namespace

std::vector<std::string> CollectFlagValues(int argc, char** argv, const std::string& flag) {
  std::vector<std::string> values;
  const std::string dashed = "--" + flag;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    std::string value;
    if (arg == dashed && i + 1 < argc && std::string(argv[i + 1]).rfind("--", 0) != 0) value = argv[++i];
    else if (arg.rfind(dashed + "=", 0) == 0) value = arg.substr(dashed.size() + 1);
    else continue;
    std::stringstream parts(value);
    std::string part;
    while (std::getline(parts, part, ','))
      if (!part.empty()) values.push_back(part);
  }
  return values;
}

std::vector<std::string> ArgsWithDefaultLcmUrl(int argc, char** argv) {
  std::vector<std::string> args(argv, argv + argc);
  bool has_url = false;
  for (const auto& a : args) has_url = has_url || a == "--lcm-url" || a.rfind("--lcm-url=", 0) == 0;
  const char* env_url = std::getenv("VLOC_LCM_URL");
  if (!has_url && env_url && *env_url) args.push_back(std::string("--lcm-url=") + env_url);
  return args;
}

bool SetupLaunchEnvironment(const CommandLine& args, const std::string& lcm_url, LaunchPaths* paths,
                            std::string* error) {
  namespace fs = std::filesystem;
  std::error_code ec;
  std::string self_dir = fs::read_symlink("/proc/self/exe", ec).parent_path().string();
  paths->bin_dir = fs::absolute(args.Get("bin-dir", EnvOr("VLOC_BIN", EnvOr("VLOC_BIN_DIR", self_dir))), ec)
                       .lexically_normal()
                       .string();
  paths->root = fs::absolute(EnvOr("VLOC_ROOT", fs::current_path(ec).string()), ec).lexically_normal().string();
  if (paths->bin_dir.size() > 1 && paths->bin_dir.back() == '/') paths->bin_dir.pop_back();
  if (paths->root.size() > 1 && paths->root.back() == '/') paths->root.pop_back();
  std::string log_dir = args.Get("log-dir", EnvOr("VLOC_LOG_DIR", "logs"));
  fs::create_directories(log_dir, ec);
  if (ec) {
    *error = "cannot create log directory " + log_dir + ": " + ec.message() + "; pass a writable --log-dir";
    return false;
  }
  paths->log_dir = fs::absolute(log_dir, ec).lexically_normal().string();
  setenv("VLOC_BIN", paths->bin_dir.c_str(), 1);
  setenv("VLOC_ROOT", paths->root.c_str(), 1);
  setenv("VLOC_LOG_DIR", paths->log_dir.c_str(), 1);
  setenv("VLOC_LCM_URL", lcm_url.c_str(), 1);
  setenv("LCM_DEFAULT_URL", lcm_url.c_str(), 1);
  return true;
}

}  // namespace vloc
