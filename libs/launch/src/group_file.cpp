#include "vloc/launch/group_file.h"

#include <algorithm>
#include <csignal>
#include <cstdlib>
#include <functional>
#include <set>

#include "vloc/common/options.h"
#include "vloc/common/printable.h"

namespace vloc {

std::vector<std::string> GroupFile::Groups() const {
  std::vector<std::string> groups;
  for (const auto& p : processes) {
    bool seen = false;
    for (const auto& g : groups) seen = seen || g == p.group;
    if (!seen) groups.push_back(p.group);
  }
  return groups;
}

std::vector<std::string> GroupFile::Hosts() const {
  std::vector<std::string> hosts;
  for (const auto& p : processes)
    if (!p.host.empty() && std::find(hosts.begin(), hosts.end(), p.host) == hosts.end()) hosts.push_back(p.host);
  return hosts;
}

GroupFile SelectHost(const GroupFile& file, const std::string& host) {
  const std::vector<std::string> hosts = file.Hosts();
  std::string list;
  for (const auto& h : hosts) list += " " + h;
  if (hosts.empty())
    throw ConfigError(file.path + ": no process names a host, so there is no part for host '" + host +
                      "'; add host: keys or run without --host");
  if (std::find(hosts.begin(), hosts.end(), host) == hosts.end())
    throw ConfigError(file.path + ": no process runs on host '" + host + "'; hosts in the file:" + list);
  GroupFile part;
  part.path = file.path;
  for (const auto& p : file.processes) {
    if (p.host != host) continue;
    ProcessSpec spec = p;
    spec.depends_on.clear();
    for (const auto& d : p.depends_on) {
      const ProcessSpec* dep = file.Find(d);
      if (dep && dep->host != host) {
        spec.remote_depends_on.push_back({dep->host, d});
        continue;
      }
      spec.depends_on.push_back(d);
    }
    part.processes.push_back(spec);
  }
  return part;
}

const ProcessSpec* GroupFile::Find(const std::string& name) const {
  for (const auto& p : processes)
    if (p.name == name) return &p;
  return nullptr;
}

VariableLookup EnvironmentLookup() {
  return [](const std::string& name) -> std::optional<std::string> {
    const char* value = std::getenv(name.c_str());
    if (!value) return std::nullopt;
    return std::string(value);
  };
}

bool ExpandVariables(const std::string& text, const VariableLookup& lookup, std::string* out,
                     std::string* error) {
  std::string result;
  for (size_t i = 0; i < text.size(); ++i) {
    if (text[i] != '$') {
      result += text[i];
      continue;
    }
    if (i + 1 < text.size() && text[i + 1] == '$') {
      result += '$';
      ++i;
      continue;
    }
    if (i + 1 >= text.size() || text[i + 1] != '{') {
      result += '$';
      continue;
    }
    const size_t close = text.find('}', i + 2);
    if (close == std::string::npos)
      return Fail(error, "'" + text + "': '${' without a closing '}'");
    std::string name = text.substr(i + 2, close - i - 2);
    std::optional<std::string> fallback;
    const size_t dash = name.find(":-");
    if (dash != std::string::npos) {
      fallback = name.substr(dash + 2);
      name = name.substr(0, dash);
    }
    if (name.empty()) return Fail(error, "'" + text + "': empty variable name in ${}");
    std::optional<std::string> value = lookup ? lookup(name) : std::nullopt;
    if (!value || value->empty()) value = fallback ? fallback : value;
    if (!value)
      return Fail(error, "'" + text + "': variable " + name +
                             " is not set; export it or write ${" + name + ":-default}");
    result += *value;
    i = close;
  }
  *out = result;
  return true;
}

namespace {

const std::vector<std::pair<std::string, int>>& SignalTable() {
  static const std::vector<std::pair<std::string, int>> table = {
      {"SIGINT", SIGINT},   {"SIGTERM", SIGTERM}, {"SIGHUP", SIGHUP},
      {"SIGQUIT", SIGQUIT}, {"SIGUSR1", SIGUSR1}, {"SIGUSR2", SIGUSR2},
      {"SIGKILL", SIGKILL}};
  return table;
}

// A process entry as read by OptionsReader (strings still to be checked).
struct RawProcess {
  ProcessSpec spec;
  std::string restart = "on-failure";
  std::string stop_signal = "SIGTERM";

  void Visit(OptionsReader& r, bool is_defaults) {
    if (!is_defaults) {
      // Optional here so that a misspelt key is reported before a missing one.
      r.Optional("name", &spec.name, "unique process name");
      r.Optional("command", &spec.command, "program path or name on PATH");
    }
    r.Optional("args", &spec.args, "arguments");
    r.Optional("group", &spec.group, "group name");
    r.Optional("depends_on", &spec.depends_on, "processes that must run first");
    r.Optional("start_delay", &spec.start_delay, "s, after dependencies run", NonNegative());
    r.Optional("restart", &restart, "never | on-failure | always");
    r.Optional("max_restarts", &spec.max_restarts, "restarts before giving up, -1 = no limit", AtLeast(-1));
    r.Optional("backoff_initial", &spec.backoff_initial, "s, first restart delay", Positive());
    r.Optional("backoff_max", &spec.backoff_max, "s, longest restart delay");
    r.Optional("stop_signal", &stop_signal, "SIGINT | SIGTERM | ...");
    r.Optional("stop_timeout", &spec.stop_timeout, "s, before SIGKILL", Positive());
    r.Optional("working_dir", &spec.working_dir, "working directory");
    r.Optional("nice", &spec.nice, "scheduling niceness: 0 = the launcher's, up to 19 = yields the CPU to the rest",
               InRange(0, 19));
    r.Optional("autostart", &spec.autostart, "start with its group");
    r.Optional("exit_when_done", &spec.exit_when_done, "its end ends the launcher (--exit-when-done)");
    r.Optional("exit_grace", &spec.exit_grace, "s, after that end, before stopping the rest", NonNegative());
    r.Optional("exit_idle", &spec.exit_idle,
               "s, the grace ends sooner once the rest has used under 5 % of a core this long; 0 = off", NonNegative());
    r.Optional("host", &spec.host, "host or role it runs on (vloc_launch --host)");
    r.Relation("backoff_max", spec.backoff_max >= spec.backoff_initial, "must be >= backoff_initial");
  }
};

std::map<std::string, std::string> ReadEnv(const YAML::Node& node, const std::string& context) {
  std::map<std::string, std::string> env;
  if (!node || node.IsNull()) return env;
  if (!node.IsMap()) throw ConfigError(context + ".env: expected a map of NAME: value");
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    if (!kv.second.IsScalar())
      throw ConfigError(context + ".env." + key + ": expected a string value");
    env[key] = kv.second.as<std::string>();
  }
  return env;
}

void Expand(std::string* text, const VariableLookup& lookup, const std::string& where) {
  std::string error;
  if (!ExpandVariables(*text, lookup, text, &error)) throw ConfigError(where + ": " + error);
}

std::string ProcessContext(const std::string& context, size_t index, const YAML::Node& node) {
  std::string name;
  if (node.IsMap() && node["name"] && node["name"].IsScalar()) name = node["name"].as<std::string>();
  return context + ": process " + (name.empty() ? "#" + std::to_string(index + 1) : "'" + Printable(name) + "'");
}

}  // namespace

int ParseSignalName(const std::string& name) {
  std::string upper;
  for (char c : name) upper += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (upper.rfind("SIG", 0) != 0) upper = "SIG" + upper;
  for (const auto& [n, s] : SignalTable())
    if (n == upper) return s;
  try {
    size_t used = 0;
    const int number = std::stoi(name, &used);
    if (used == name.size() && number > 0 && number < 65) return number;
  } catch (const std::exception&) {
  }
  return -1;
}

std::string SignalName(int signal_number) {
  for (const auto& [n, s] : SignalTable())
    if (s == signal_number) return n;
  return "signal " + std::to_string(signal_number);
}

namespace {

// The top-level keys are known ones.
void CheckTopKeys(const YAML::Node& root, const std::string& context) {
  if (!root.IsMap()) throw ConfigError(context + ": expected a map with a 'processes' list");
  static const std::set<std::string> kTopKeys = {"group", "env", "defaults", "processes"};
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>();
    if (!kTopKeys.count(key))
      throw ConfigError(context + ": unknown top-level key '" + key +
                        "'; known keys: group, env, defaults, processes");
  }
}

// What every process starts from: the file's group, its env, and the
// defaults (the keys of a process but name and command, checked here; their
// env apart).
struct FileDefaults {
  std::string group;
  std::map<std::string, std::string> env;
  YAML::Node keys, env_node;
};
FileDefaults ReadDefaults(const YAML::Node& root, const std::string& context) {
  FileDefaults d;
  d.group = root["group"] ? root["group"].as<std::string>("") : "";
  if (d.group.empty()) d.group = "default";
  d.env = ReadEnv(root["env"], context);
  d.keys = root["defaults"] ? root["defaults"] : YAML::Node(YAML::NodeType::Map);
  if (!d.keys.IsMap()) throw ConfigError(context + ".defaults: expected a map of process keys");
  YAML::Node checked = YAML::Clone(d.keys);
  d.env_node = checked["env"];
  checked.remove("env");
  RawProcess check;
  OptionsReader reader(checked, context + ".defaults");
  check.Visit(reader, /*is_defaults=*/true);
  reader.Finish();
  return d;
}

// The checks of one process's values, its restart policy and stop signal
// resolved into `spec`.
void CheckProcess(const RawProcess& raw, const GroupFile& file, const std::string& default_group,
                  const std::string& where, ProcessSpec* spec) {
  if (spec->name.empty()) throw ConfigError(where + ": no 'name'; give every process a unique name");
  if (spec->name.find('/') != std::string::npos || spec->name.find(' ') != std::string::npos ||
      HasControlCharacters(spec->name))
    throw ConfigError(where + ": name must not contain '/', spaces or control characters (it names the log file)");
  if (file.Find(spec->name)) throw ConfigError(where + ": duplicate name; process names must be unique");
  if (spec->command.empty())
    throw ConfigError(where + ": no 'command'; add command: <program path or name on PATH>");
  if (spec->group.empty()) spec->group = default_group;
  if (HasControlCharacters(spec->group))
    throw ConfigError(where + ".group: '" + Printable(spec->group) + "' must not contain control characters");
  if (spec->host.find_first_of(" /,") != std::string::npos)
    throw ConfigError(where + ".host: '" + spec->host + "' must not contain spaces, '/' or ','");
  if (raw.restart == "never") spec->restart = RestartPolicy::kNever;
  else if (raw.restart == "on-failure") spec->restart = RestartPolicy::kOnFailure;
  else if (raw.restart == "always") spec->restart = RestartPolicy::kAlways;
  else
    throw ConfigError(where + ".restart: '" + raw.restart + "' is not never, on-failure or always");
  spec->stop_signal = ParseSignalName(raw.stop_signal);
  if (spec->stop_signal <= 0)
    throw ConfigError(where + ".stop_signal: unknown signal '" + raw.stop_signal + "'; use SIGINT or SIGTERM");
  // Every value against the bound on its Visit line ("where: stop_timeout = 0: must be > 0").
  std::string bound_error;
  OptionsReader checker = OptionsReader::Checker(&bound_error);
  RawProcess checked = raw;
  checked.Visit(checker, /*is_defaults=*/false);
  if (!bound_error.empty()) throw ConfigError(where + ": " + bound_error);
}

// Process `index` of the list: the defaults under its own keys, its env
// over the defaults' over the file's, checked, its ${VARIABLES} expanded.
ProcessSpec ReadProcess(const YAML::Node& entry, size_t index, const FileDefaults& defaults, const GroupFile& file,
                        const std::string& context, const VariableLookup& lookup) {
  const std::string where = ProcessContext(context, index, entry);
  if (!entry.IsMap()) throw ConfigError(where + ": expected a map with name and command");
  YAML::Node merged = YAML::Clone(defaults.keys);
  merged.remove("env");
  for (const auto& kv : entry) {
    const std::string key = kv.first.as<std::string>();
    if (key != "env") merged[key] = kv.second;
  }
  RawProcess raw;
  raw.spec.group = defaults.group;
  OptionsReader reader(merged, where);
  raw.Visit(reader, /*is_defaults=*/false);
  reader.Finish();
  ProcessSpec spec = raw.spec;
  spec.env = defaults.env;
  for (const auto& [k, v] : ReadEnv(defaults.env_node, where)) spec.env[k] = v;
  for (const auto& [k, v] : ReadEnv(entry["env"], where)) spec.env[k] = v;
  CheckProcess(raw, file, defaults.group, where, &spec);
  Expand(&spec.command, lookup, where + ".command");
  for (auto& a : spec.args) Expand(&a, lookup, where + ".args");
  for (auto& [k, v] : spec.env) Expand(&v, lookup, where + ".env." + k);
  Expand(&spec.working_dir, lookup, where + ".working_dir");
  return spec;
}

// Hosts: none (one machine) or every process; exit_idle only on one
// machine (a launcher sees the CPU of its own processes alone).
void CheckHosts(const GroupFile& file, const std::string& context) {
  const auto hosts = file.Hosts();
  for (const auto& p : file.processes) {
    if (!hosts.empty() && p.host.empty())
      throw ConfigError(context + ": process '" + p.name + "' has no 'host' while others have (" + hosts.front() +
                        "); give every process a host, or set defaults.host");
    if (!hosts.empty() && p.exit_idle > 0)
      throw ConfigError(context + ": process '" + p.name + "': exit_idle needs a group on one machine (a launcher "
                        "sees only its own host's processes idle); use exit_grace alone");
  }
}

// Dependencies: known names, no self or cycle.
void CheckDependencies(const GroupFile& file, const std::string& context) {
  for (const auto& p : file.processes) {
    for (const auto& d : p.depends_on) {
      if (d == p.name) throw ConfigError(context + ": process '" + p.name + "' depends on itself");
      if (!file.Find(d))
        throw ConfigError(context + ": process '" + p.name + "' depends on unknown process '" + d +
                          "'; use a name from this file");
    }
  }
  std::map<std::string, int> mark;  // 0 new, 1 visiting, 2 done
  std::function<void(const ProcessSpec&, std::string)> visit = [&](const ProcessSpec& p, std::string path) {
    path += (path.empty() ? "" : " -> ") + p.name;
    if (mark[p.name] == 2) return;
    if (mark[p.name] == 1) throw ConfigError(context + ": circular depends_on: " + path);
    mark[p.name] = 1;
    for (const auto& d : p.depends_on) visit(*file.Find(d), path);
    mark[p.name] = 2;
  };
  for (const auto& p : file.processes) visit(p, "");
}

}  // namespace

GroupFile ParseGroupYaml(const YAML::Node& root, const std::string& context, const VariableLookup& lookup) {
  CheckTopKeys(root, context);
  const FileDefaults defaults = ReadDefaults(root, context);
  const YAML::Node list = root["processes"];
  if (!list || !list.IsSequence() || list.size() == 0)
    throw ConfigError(context + ": 'processes' must be a non-empty list of processes");
  GroupFile file;
  file.path = context;
  for (size_t i = 0; i < list.size(); ++i) file.processes.push_back(ReadProcess(list[i], i, defaults, file, context, lookup));
  CheckHosts(file, context);
  CheckDependencies(file, context);
  return file;
}

GroupFile ParseGroupFile(const std::string& path, const VariableLookup& lookup) {
  YAML::Node root = LoadYamlFile(path);  // throws ConfigError for unreadable / invalid YAML
  return ParseGroupYaml(root, path, lookup);
}

}  // namespace vloc
