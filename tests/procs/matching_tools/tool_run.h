#pragma once
// Running an operator's tool to completion and reading its YAML output
// (matching_tools_proc_test, pds_tools_proc_test).
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <regex>
#include <string>
#include <vector>

#include "vloc/testing/subprocess.h"

namespace vloc::testing {

// A folder under the test's TMPDIR (removed with it: tests/support/run_with_tmpdir.sh).
inline std::string ToolTempDir(const std::string& name) {
  std::string tmpl = (std::filesystem::temp_directory_path() / (name + "_XXXXXX")).string();
  const char* d = mkdtemp(tmpl.data());
  return d ? std::string(d) : std::filesystem::temp_directory_path().string();
}

struct ToolRun {
  int exit_code = -1;
  std::string output;  // stdout and stderr
};

inline ToolRun RunTool(const std::vector<std::string>& argv) {
  Subprocess p(argv);
  const auto code = p.WaitExit(240);
  return {code ? *code : -1, p.output()};
}

// The first number after "key:" in a tool's output, NaN when absent.
inline double Number(const std::string& text, const std::string& key) {
  std::smatch m;
  if (!std::regex_search(text, m, std::regex(key + ": *([-0-9.eE+]+)"))) return NAN;
  return std::stod(m[1]);
}

}  // namespace vloc::testing
