#include "vloc/common/command_line.h"

#include <algorithm>

#include "vloc/common/options.h"

namespace vloc {

bool CommandLine::Parse(int argc, char** argv, const std::vector<std::string>& known, std::string* error) {
  values_.clear();
  positional_.clear();
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg.rfind("--", 0) != 0 || arg.size() == 2) {
      positional_.push_back(arg);
      continue;
    }
    std::string name = arg.substr(2), value;
    const auto eq = name.find('=');
    bool has_value = false;
    if (eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
      has_value = true;
    }
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      if (error) {
        std::string list;
        for (const auto& k : known) list += " --" + k;
        *error = "unknown option --" + name + "; known options:" + list;
      }
      return false;
    }
    if (!has_value && i + 1 < argc && std::string(argv[i + 1]).rfind("--", 0) != 0) {
      value = argv[++i];
    }
    values_[name] = value;
  }
  return true;
}

std::string CommandLine::Get(const std::string& name, const std::string& fallback) const {
  auto it = values_.find(name);
  return it == values_.end() ? fallback : it->second;
}

double CommandLine::GetDouble(const std::string& name, double fallback) const {
  auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  try {
    return std::stod(it->second);
  } catch (const std::exception&) {
    throw ConfigError("--" + name + " expects a number, got '" + it->second + "'");
  }
}

int CommandLine::GetInt(const std::string& name, int fallback) const {
  auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  try {
    return std::stoi(it->second);
  } catch (const std::exception&) {
    throw ConfigError("--" + name + " expects an integer, got '" + it->second + "'");
  }
}

}  // namespace vloc
