// Group-file parsing: every key, defaults, variables, and one clear error
// line for each kind of mistake; the shipped group files parse.

#include <gtest/gtest.h>

#include <csignal>

#include "vloc/common/options.h"
#include "vloc/launch/group_file.h"

namespace vloc {
namespace {

VariableLookup Vars(std::map<std::string, std::string> vars) {
  return [vars](const std::string& name) -> std::optional<std::string> {
    auto it = vars.find(name);
    if (it == vars.end()) return std::nullopt;
    return it->second;
  };
}

GroupFile Parse(const std::string& text, const VariableLookup& lookup = Vars({})) {
  return ParseGroupYaml(YAML::Load(text), "test.yaml", lookup);
}

// The ConfigError message of parsing `text` ("" when it parses).
std::string ErrorOf(const std::string& text, const VariableLookup& lookup = Vars({})) {
  try {
    Parse(text, lookup);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(GroupFile, ReadsEveryKeyDefaultsAndVariables) {
  const GroupFile file = Parse(R"(
group: g1
env: {A: top, B: top}
defaults: {restart: always, stop_timeout: 2.5, env: {B: defaults}}
processes:
  - name: first
    command: ${BIN}/first
    args: [--config, "${ROOT}/x.yaml", "$$literal", "${MISSING:-fallback}"]
    env: {C: "${ROOT}"}
  - name: second
    command: sleep
    args: ["10"]
    group: g2
    depends_on: [first]
    start_delay: 0.25
    restart: never
    max_restarts: -1
    backoff_initial: 0.1
    backoff_max: 2
    stop_signal: SIGINT
    stop_timeout: 1
    working_dir: /tmp
    nice: 10
    exit_idle: 2.5
    autostart: false
    exit_when_done: true
    exit_grace: 3
)",
                               Vars({{"BIN", "/b"}, {"ROOT", "/r"}}));
  ASSERT_EQ(file.processes.size(), 2u);
  const ProcessSpec& a = file.processes[0];
  EXPECT_EQ(a.name, "first");
  EXPECT_EQ(a.command, "/b/first");
  EXPECT_EQ(a.args, (std::vector<std::string>{"--config", "/r/x.yaml", "$literal", "fallback"}));
  EXPECT_EQ(a.group, "g1");
  EXPECT_EQ(a.restart, RestartPolicy::kAlways);
  EXPECT_DOUBLE_EQ(a.stop_timeout, 2.5);
  EXPECT_EQ(a.stop_signal, SIGTERM);
  EXPECT_EQ(a.env.at("A"), "top");
  EXPECT_EQ(a.env.at("B"), "defaults");
  EXPECT_EQ(a.env.at("C"), "/r");
  const ProcessSpec& b = file.processes[1];
  EXPECT_EQ(b.group, "g2");
  EXPECT_EQ(b.depends_on, std::vector<std::string>{"first"});
  EXPECT_DOUBLE_EQ(b.start_delay, 0.25);
  EXPECT_EQ(b.restart, RestartPolicy::kNever);
  EXPECT_EQ(b.max_restarts, -1);
  EXPECT_DOUBLE_EQ(b.backoff_initial, 0.1);
  EXPECT_DOUBLE_EQ(b.backoff_max, 2.0);
  EXPECT_EQ(b.stop_signal, SIGINT);
  EXPECT_DOUBLE_EQ(b.stop_timeout, 1.0);
  EXPECT_EQ(b.working_dir, "/tmp");
  EXPECT_EQ(b.nice, 10);
  EXPECT_DOUBLE_EQ(b.exit_idle, 2.5);
  EXPECT_EQ(a.nice, 0);
  EXPECT_FALSE(b.autostart);
  EXPECT_TRUE(b.exit_when_done);
  EXPECT_DOUBLE_EQ(b.exit_grace, 3.0);
  EXPECT_EQ(file.Groups(), (std::vector<std::string>{"g1", "g2"}));
}

TEST(GroupFile, UnknownKeyIsOneLineNamingFileProcessKeyAndFix) {
  const std::string error = ErrorOf("processes:\n  - {name: sim, comand: /bin/true}\n");
  EXPECT_NE(error.find("test.yaml"), std::string::npos) << error;
  EXPECT_NE(error.find("'sim'"), std::string::npos) << error;
  EXPECT_NE(error.find("comand"), std::string::npos) << error;
  EXPECT_NE(error.find("did you mean 'command'"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos) << error;
}

TEST(GroupFile, MissingCommandIsOneLine) {
  const std::string error = ErrorOf("processes:\n  - {name: sim, args: [a]}\n");
  EXPECT_NE(error.find("'sim'"), std::string::npos) << error;
  EXPECT_NE(error.find("command"), std::string::npos) << error;
  EXPECT_NE(error.find("no 'command'"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos) << error;
}

TEST(GroupFile, EachMistakeIsReported) {
  EXPECT_NE(ErrorOf("procs: []").find("unknown top-level key 'procs'"), std::string::npos);
  EXPECT_NE(ErrorOf("processes: []").find("non-empty list"), std::string::npos);
  EXPECT_NE(ErrorOf("processes:\n  - {name: a, command: x}\n  - {name: a, command: y}\n").find("duplicate name"),
            std::string::npos);
  EXPECT_NE(ErrorOf("processes:\n  - {name: a, command: x, depends_on: [b]}\n").find("unknown process 'b'"),
            std::string::npos);
  EXPECT_NE(ErrorOf("processes:\n  - {name: a, command: x, depends_on: [b]}\n"
                    "  - {name: b, command: x, depends_on: [a]}\n")
                .find("circular depends_on"),
            std::string::npos);
  EXPECT_NE(ErrorOf("processes:\n  - {name: a, command: x, restart: sometimes}\n").find("never, on-failure"),
            std::string::npos);
  EXPECT_NE(ErrorOf("processes:\n  - {name: a, command: x, stop_signal: SIGFOO}\n").find("unknown signal"),
            std::string::npos);
  EXPECT_NE(ErrorOf("processes:\n  - {name: a, command: x, stop_timeout: 0}\n").find("stop_timeout"),
            std::string::npos);
  EXPECT_NE(ErrorOf("processes:\n  - {name: a, command: x, nice: -5}\n").find("nice = -5: must be in [0, 19]"),
            std::string::npos);
  EXPECT_NE(ErrorOf("processes:\n  - {name: a, command: x, exit_idle: -1}\n").find("exit_idle = -1: must be >= 0"),
            std::string::npos);
  EXPECT_NE(ErrorOf("processes:\n  - {name: a, command: x, host: v, exit_idle: 3}\n")
                .find("exit_idle needs a group on one machine"),
            std::string::npos);
  EXPECT_NE(ErrorOf("processes:\n  - {name: a, command: x, max_restarts: many}\n").find("expected an integer"),
            std::string::npos);
  EXPECT_NE(ErrorOf("processes:\n  - {name: a, command: \"${NOPE}/x\"}\n").find("variable NOPE is not set"),
            std::string::npos);
  EXPECT_NE(ErrorOf("defaults: {name: x}\nprocesses:\n  - {name: a, command: x}\n").find("unknown key"),
            std::string::npos);
  EXPECT_EQ(ErrorOf("processes:\n  - {name: a, command: x}\n"), "");
}

TEST(GroupFile, MissingFileIsOneLine) {
  try {
    ParseGroupFile("config/groups/no_such_group.yaml");
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("config/groups/no_such_group.yaml"), std::string::npos) << e.what();
  }
}

TEST(GroupFile, ExpandVariables) {
  std::string out, error;
  const auto vars = Vars({{"A", "1"}, {"EMPTY", ""}});
  ASSERT_TRUE(ExpandVariables("x${A}y$${A}$z${EMPTY:-d}", vars, &out, &error)) << error;
  EXPECT_EQ(out, "x1y${A}$zd");
  EXPECT_FALSE(ExpandVariables("${A", vars, &out, &error));
  EXPECT_NE(error.find("closing"), std::string::npos);
  EXPECT_FALSE(ExpandVariables("${B}", vars, &out, &error));
  EXPECT_NE(error.find("variable B is not set"), std::string::npos);
}

TEST(GroupFile, SignalNames) {
  EXPECT_EQ(ParseSignalName("SIGINT"), SIGINT);
  EXPECT_EQ(ParseSignalName("term"), SIGTERM);
  EXPECT_EQ(ParseSignalName("9"), 9);
  EXPECT_EQ(ParseSignalName("SIGNOPE"), -1);
  EXPECT_EQ(SignalName(SIGINT), "SIGINT");
}

// The shipped groups: the right executables, config paths, the logger
// first and the simulator / driver last with exit_when_done.
TEST(GroupFile, ShippedGroupFilesParse) {
  const auto vars = Vars({{"VLOC_BIN", "/bin_dir"}, {"VLOC_ROOT", "/root_dir"},
                          {"VLOC_LCM_URL", "udpm://239.255.76.67:7667?ttl=0"}, {"VLOC_LOG_DIR", "/logs"}});
  const std::map<std::string, std::vector<std::string>> expected = {
      {"rover_sim", {"logger", "dead_reckoning", "feature_frontend", "crosssite_ba", "traverse_graph", "sim_rover"}},
      {"rover_field",
       {"logger", "dead_reckoning", "feature_frontend", "crosssite_ba", "traverse_graph", "imu_odometry_driver",
        "navcam_driver"}},
      {"uav_sim", {"logger", "uav_mosaicker", "sim_uav"}},
      {"uav_field", {"logger", "uav_mosaicker", "uav_video_driver"}},
  };
  for (const auto& [group, names] : expected) {
    SCOPED_TRACE(group);
    const GroupFile file = ParseGroupFile("config/groups/" + group + ".yaml", vars);
    std::vector<std::string> got;
    for (const auto& p : file.processes) got.push_back(p.name);
    EXPECT_EQ(got, names);
    EXPECT_EQ(file.Groups(), std::vector<std::string>{group});
    const ProcessSpec& logger = file.processes.front();
    EXPECT_EQ(logger.command, "/bin_dir/vloc_logger");
    EXPECT_EQ(logger.args, (std::vector<std::string>{"--lcm-url", "udpm://239.255.76.67:7667?ttl=0", "--out",
                                                      "/logs/" + group + ".lcmlog"}));
    EXPECT_EQ(logger.args.back(), "/logs/" + group + ".lcmlog");
    EXPECT_EQ(logger.stop_signal, SIGINT);
    for (size_t i = 1; i < file.processes.size(); ++i) {
      const ProcessSpec& p = file.processes[i];
      EXPECT_EQ(p.command, "/bin_dir/" + p.name);
      // Config and URL first; simulators and the mosaicker add run-length or output options.
      const std::vector<std::string> head{"--config", "config/procs/" + p.name + ".yaml", "--lcm-url",
                                          "udpm://239.255.76.67:7667?ttl=0"};
      ASSERT_GE(p.args.size(), head.size());
      EXPECT_EQ(std::vector<std::string>(p.args.begin(), p.args.begin() + head.size()), head);
      EXPECT_EQ(p.working_dir, "/root_dir");
      EXPECT_FALSE(p.depends_on.empty());
    }
    EXPECT_TRUE(file.processes.back().exit_when_done);
  }
}

// A group split across hosts: each launcher's part, dependencies on the
// other host made remote, and the mistakes a split file can have.
TEST(GroupFile, SelectHostGivesEachLauncherItsPart) {
  const GroupFile file = Parse(R"(
defaults: {host: ground}
processes:
  - {name: log_v, command: /bin/true, host: vehicle}
  - {name: dr, command: /bin/true, host: vehicle, depends_on: [log_v]}
  - {name: log_g, command: /bin/true}
  - {name: frontend, command: /bin/true, depends_on: [log_g]}
  - {name: sim, command: /bin/true, host: vehicle, depends_on: [dr, frontend]}
)");
  EXPECT_EQ(file.Hosts(), (std::vector<std::string>{"vehicle", "ground"}));
  const GroupFile vehicle = SelectHost(file, "vehicle");
  std::vector<std::string> names;
  for (const auto& p : vehicle.processes) names.push_back(p.name);
  EXPECT_EQ(names, (std::vector<std::string>{"log_v", "dr", "sim"}));
  EXPECT_EQ(vehicle.Find("sim")->depends_on, std::vector<std::string>{"dr"});
  EXPECT_EQ(vehicle.Find("sim")->remote_depends_on,
            (std::vector<std::pair<std::string, std::string>>{{"ground", "frontend"}}));
  const GroupFile ground = SelectHost(file, "ground");
  ASSERT_EQ(ground.processes.size(), 2u);
  EXPECT_EQ(ground.processes[1].name, "frontend");
  EXPECT_EQ(ground.processes[1].depends_on, std::vector<std::string>{"log_g"});

  try {
    SelectHost(file, "laptop");
    ADD_FAILURE() << "no error for an unknown host";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("no process runs on host 'laptop'; hosts in the file: vehicle ground"),
              std::string::npos) << e.what();
  }
  const GroupFile single = Parse("processes: [{name: a, command: /bin/true}]");
  EXPECT_TRUE(single.Hosts().empty());
  EXPECT_THROW(SelectHost(single, "vehicle"), ConfigError);
  EXPECT_NE(ErrorOf("processes: [{name: a, command: /bin/true, host: v}, {name: b, command: /bin/true}]")
                .find("process 'b' has no 'host' while others have (v)"),
            std::string::npos);
  EXPECT_NE(ErrorOf("processes: [{name: a, command: /bin/true, host: 'a b'}]").find(".host: 'a b' must not"),
            std::string::npos);
}

// The shipped split group: every process has a host, the vehicle part
// holds the simulator and dead reckoning, the ground part the pipeline,
// and run whole it is the same pipeline as rover_sim.
TEST(GroupFile, ShippedSplitGroupParts) {
  const VariableLookup vars = Vars({{"VLOC_BIN", "/bin_dir"}, {"VLOC_ROOT", "/root_dir"},
                                    {"VLOC_LCM_URL", "udpm://239.255.76.67:7667?ttl=1"}, {"VLOC_LOG_DIR", "/logs"}});
  const GroupFile file = ParseGroupFile("config/groups/rover_split.yaml", vars);
  EXPECT_EQ(file.Hosts(), (std::vector<std::string>{"vehicle", "ground"}));
  auto names = [](const GroupFile& f) {
    std::vector<std::string> out;
    for (const auto& p : f.processes) out.push_back(p.name);
    return out;
  };
  EXPECT_EQ(names(SelectHost(file, "vehicle")),
            (std::vector<std::string>{"logger_vehicle", "dead_reckoning", "sim_rover"}));
  EXPECT_EQ(names(SelectHost(file, "ground")),
            (std::vector<std::string>{"logger", "feature_frontend", "crosssite_ba", "traverse_graph"}));
  const GroupFile whole = ParseGroupFile("config/groups/rover_sim.yaml", vars);
  for (const auto& p : whole.processes) {
    const ProcessSpec* split = file.Find(p.name);
    ASSERT_TRUE(split) << p.name;
    EXPECT_EQ(split->command, p.command);
  }
  EXPECT_TRUE(SelectHost(file, "vehicle").Find("sim_rover")->exit_when_done);
}

}  // namespace
}  // namespace vloc
