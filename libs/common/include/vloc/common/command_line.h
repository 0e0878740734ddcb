#pragma once
// A small command-line parser for vloc executables:
//   prog [--name=value | --name value | --flag] ... [positional ...]

#include <map>
#include <string>
#include <vector>

namespace vloc {

class CommandLine {
 public:
  // `known` lists the accepted --names; any other name is an error that
  // Parse reports through `error` (one line), returning false.
  bool Parse(int argc, char** argv, const std::vector<std::string>& known, std::string* error);

  bool Has(const std::string& name) const { return values_.count(name) > 0; }
  std::string Get(const std::string& name, const std::string& fallback = "") const;
  // A value that is not a number throws ConfigError naming the flag (the
  // processes report it as their one error line).
  double GetDouble(const std::string& name, double fallback) const;
  int GetInt(const std::string& name, int fallback) const;
  const std::vector<std::string>& positional() const { return positional_; }

 private:
  std::map<std::string, std::string> values_;
  std::vector<std::string> positional_;
};

}  // namespace vloc
