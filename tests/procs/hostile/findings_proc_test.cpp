// One process-level test per finding of the hostile review (issue 13), over
// real LCM (ports 7887-7899) and real files; each failed on the code before
// the fix:
//  1. a string length of 0x80000000 killed four processes;
//  2. traverse_graph aborted on a DR position of (-1e308, 1e308, 0);
//  3. dead_reckoning hung publishing after an IMU time of INT64_MAX;
//  4. one IMU rate of 1e308 made every later SITE_POSE_DR NaN;
//  5. crosssite_ba dropped tie points silently while busy;
//  6. a restarted crosssite_ba started its chain again from dead reckoning;
//  7. empty or missing configs ran on defaults; tools said nothing on bad logs;
//  8. NaN tie points gave a Ceres dump; previous == current site was accepted;
//     the mosaicker did not log the first undecodable frame.
// (Finding 9, non positive definite information matrices, is a unit test
// of the pose graph: tests/unit/posegraph.)
#include "hostile_bus.h"

#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "vloc/imu_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/localization_t.hpp"
#include "vloc/procman_order_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/tie_points_t.hpp"
#include "vloc/traverse_t.hpp"

namespace vloc {
namespace {

using namespace vloc::testing;
namespace fs = std::filesystem;

std::string SourceFile(const std::string& rel) { return std::string(VLOC_SOURCE_DIR) + "/" + rel; }
const char* kTiePointsLog = "tests/data/logs/rover_tiepoints_13sites.lcmlog";
const char* kDrLog = "tests/data/logs/rover_dr_3sites.lcmlog";

template <class Msg>
std::vector<uint8_t> Bytes(const Msg& msg) {
  std::vector<uint8_t> b(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

struct Scratch {
  explicit Scratch(const std::string& name) : dir(::testing::TempDir() + "/findings_" + name + "_" + std::to_string(getpid())) {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() { fs::remove_all(dir); }
  std::string Write(const std::string& name, const std::string& text) const {
    std::ofstream(dir + "/" + name) << text;
    return dir + "/" + name;
  }
  std::string dir;
};

int CountOccurrences(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// Sets the length field of the first string in `bytes` (a message of `type`) to `length`.
void PoisonFirstString(const std::string& type, std::vector<uint8_t>* bytes, uint32_t length) {
  for (const LcmFieldSpan& s : LcmSchema::Vloc().Spans(type, bytes->data(), bytes->size())) {
    if (s.kind != LcmFieldSpan::Kind::kStringLength) continue;
    for (int k = 0; k < 4; ++k) (*bytes)[s.offset + static_cast<size_t>(k)] = static_cast<uint8_t>(length >> (24 - 8 * k));
    return;
  }
  ADD_FAILURE() << type << " has no string";
}

// ---- 1 ------------------------------------------------------------------

TEST(Finding1, AStringLengthOf2To31KillsNoProcess) {
  Scratch scratch("f1");
  const std::string url = TestLcmUrl(7887);
  const std::string group = scratch.Write("group.yaml", "group: g\nprocesses:\n  - {name: s, command: sleep, args: [\"60\"]}\n");
  std::vector<std::unique_ptr<Subprocess>> procs;
  procs.push_back(StartProc({BinPath("crosssite_ba"), "--config", "config/procs/crosssite_ba.yaml", "--lcm-url", url,
                             "--state-dir", scratch.dir}));
  procs.push_back(StartProc({BinPath("traverse_graph"), "--config", "config/procs/traverse_graph.yaml", "--lcm-url",
                             url, "--state-dir", scratch.dir}));
  procs.push_back(StartProc({BinPath("feature_frontend"), "--config", "config/procs/feature_frontend.yaml",
                             "--lcm-url", url}));
  procs.push_back(StartProc({BinPath("vloc_launch"), "--config", group, "--lcm-url", url, "--log-dir", scratch.dir}));
  Bus bus(url, "NONE");
  const auto log = ReadEvents(SourceFile(kTiePointsLog), "TIE_POINTS|SITE_POSE_DR|SITE_POSE_VISUAL");
  std::map<std::string, std::vector<uint8_t>> first;
  for (const Event& e : log)
    if (!first.count(e.channel)) first[e.channel] = e.bytes;
  procman_order_t order;
  order.target = "s";
  first["PROCMAN_ORDERS"] = Bytes(order);
  const std::map<std::string, std::string> types = {{"TIE_POINTS", "tie_points_t"},
                                                    {"SITE_POSE_DR", "site_pose_t"},
                                                    {"SITE_POSE_VISUAL", "localization_t"},
                                                    {"PROCMAN_ORDERS", "procman_order_t"}};
  for (auto& [channel, bytes] : first) {
    PoisonFirstString(types.at(channel), &bytes, 0x80000000u);
    bus.Send(channel, bytes);
  }
  bus.Pump(2000);
  for (auto& p : procs) {
    EXPECT_FALSE(p->WaitExit(0.1)) << "died:\n" << p->output();
    p->Signal(SIGTERM);
    EXPECT_EQ(p->WaitExit(20), std::optional<int>(0)) << p->output();
  }
  EXPECT_NE(procs[0]->output().find("string length"), std::string::npos) << "the reason is logged";
}

// ---- 2 ------------------------------------------------------------------

TEST(Finding2, TraverseGraphRejectsAPositionOf1e308AndCarriesOn) {
  Scratch scratch("f2");
  const std::string url = TestLcmUrl(7888);
  Bus bus(url, "TRAVERSE");
  auto proc = StartProc({BinPath("traverse_graph"), "--config", "config/procs/traverse_graph.yaml", "--lcm-url", url,
                         "--state-dir", scratch.dir});
  PoseWithCovariance pose;
  pose.covariance = Matrix6d::Identity() * 0.01;
  site_pose_t bad = SitePoseToMessage(0, site_pose_t::SOURCE_DEAD_RECKONING, pose);
  bad.pose.position[0] = -1e308;
  bad.pose.position[1] = 1e308;
  bus.Send("SITE_POSE_DR", Bytes(bad));
  bus.Send("SITE_POSE_DR", Bytes(SitePoseToMessage(0, site_pose_t::SOURCE_DEAD_RECKONING, pose)));
  pose.pose = MakePose(10, 0, 0, 0, 0, 0);
  bus.Send("SITE_POSE_DR", Bytes(SitePoseToMessage(1, site_pose_t::SOURCE_DEAD_RECKONING, pose)));
  bus.Send("SITE_POSE_FIX", Bytes(SitePoseToMessage(1, site_pose_t::SOURCE_DEAD_RECKONING, pose)));
  ASSERT_TRUE(bus.PumpUntil([&] { return bus.Count("TRAVERSE") >= 3; }, 30)) << proc->output();
  std::string first;
  EXPECT_EQ(bus.NonFinite(&first), 0) << first;
  EXPECT_FALSE(proc->WaitExit(0.1)) << proc->output();
  EXPECT_NE(proc->output().find("beyond"), std::string::npos) << proc->output();
  proc->Signal(SIGTERM);
  EXPECT_EQ(proc->WaitExit(20), std::optional<int>(0)) << proc->output();
  EXPECT_TRUE(fs::exists(scratch.dir + "/traverse.graph")) << "the graph is saved in the state folder";
}

// ---- 3 and 4 --------------------------------------------------------------

// Replays the DR log into dead_reckoning, with `poison` inserted after the
// IMU sample at index `at` (counted over IMU samples).
struct DrRun {
  std::map<int, site_pose_t> sites;
  int dr_poses = 0;
  std::optional<int> exit;
  std::string output;
};
DrRun RunDeadReckoning(int port, const std::vector<imu_t>& poison, size_t at) {
  const auto log = ReadEvents(SourceFile(kDrLog), "IMU|WHEEL_ODOM|ROVER_SITE|SITE_POSE_GT");
  const std::string url = TestLcmUrl(port);
  Bus bus(url, "SITE_POSE_DR|DR_POSE");
  auto proc = StartProc({BinPath("dead_reckoning"), "--config", "config/procs/dead_reckoning.yaml", "--lcm-url", url});
  bus.Watch(proc.get());
  size_t imu = 0;
  for (const Event& e : log) {
    bus.Send(e.channel, e.bytes);
    if (e.channel == "IMU" && imu++ == at)
      for (const imu_t& p : poison) bus.Send("IMU", Bytes(p));
  }
  bus.PumpUntil([&] { return bus.Count("SITE_POSE_DR") >= 3; }, 120);
  bus.Pump(1000);
  DrRun run;
  for (const site_pose_t& m : DecodeAll<site_pose_t>(bus.got(), "SITE_POSE_DR")) run.sites[m.site_id] = m;
  run.dr_poses = bus.Count("DR_POSE");
  proc->Signal(SIGTERM);
  run.exit = proc->WaitExit(10);
  run.output = proc->output();
  return run;
}

TEST(Finding3And4, ImpossibleImuSamplesNeitherHangNorPoisonDeadReckoning) {
  const auto imus = DecodeAll<imu_t>(ReadEvents(SourceFile(kDrLog), "IMU"), "IMU");
  ASSERT_GT(imus.size(), 1000u);
  const size_t at = imus.size() / 2;
  imu_t far_future = imus[at];
  far_future.utime = std::numeric_limits<int64_t>::max();
  imu_t huge_rate = imus[at];
  huge_rate.utime += 1;  // otherwise in order: only the rate is wrong
  huge_rate.angular_velocity[2] = 1e308;
  const DrRun clean = RunDeadReckoning(7889, {}, imus.size());
  const DrRun poisoned = RunDeadReckoning(7890, {far_future, huge_rate}, at);
  ASSERT_EQ(clean.sites.size(), 3u) << clean.output;
  ASSERT_EQ(poisoned.exit, std::optional<int>(0)) << "hung or crashed:\n" << poisoned.output.substr(0, 3000);
  // No flood: the periodic poses are those of the clean run.
  EXPECT_LE(poisoned.dr_poses, clean.dr_poses + 2);
  for (const auto& [id, m] : clean.sites) {
    ASSERT_TRUE(poisoned.sites.count(id));
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(std::isfinite(poisoned.sites.at(id).pose.position[k]));
      EXPECT_DOUBLE_EQ(poisoned.sites.at(id).pose.position[k], m.pose.position[k]) << "site " << id;
    }
  }
  EXPECT_NE(poisoned.output.find("rejected"), std::string::npos) << "the reason is logged";
}

// ---- 5 ------------------------------------------------------------------

TEST(Finding5, CrossSiteBaAnswersEveryTiePointMessageOfABurst) {
  Scratch scratch("f5");
  const auto log = ReadEvents(SourceFile(kTiePointsLog), "TIE_POINTS");
  ASSERT_FALSE(log.empty());
  const std::string url = TestLcmUrl(7891);
  Bus bus(url, "SITE_POSE_VISUAL");
  auto proc = StartProc({BinPath("crosssite_ba"), "--config", "config/procs/crosssite_ba.yaml", "--lcm-url", url,
                         "--state-dir", scratch.dir});
  bus.Watch(proc.get());
  const int burst = 120;
  for (int k = 0; k < burst; ++k) bus.Send("TIE_POINTS", log[static_cast<size_t>(k) % log.size()].bytes);
  EXPECT_TRUE(bus.PumpUntil([&] { return bus.Count("SITE_POSE_VISUAL") >= burst; }, 240))
      << bus.Count("SITE_POSE_VISUAL") << " of " << burst << " answered\n" << proc->output().substr(0, 2000);
  proc->Signal(SIGTERM);
  EXPECT_EQ(proc->WaitExit(20), std::optional<int>(0));
  EXPECT_NE(proc->output().find("dropped (queue full) 0"), std::string::npos) << proc->output();
}

// ---- 6 ------------------------------------------------------------------

TEST(Finding6, ARestartedCrossSiteBaKeepsItsChain) {
  Scratch scratch("f6");
  const auto log = ReadEvents(SourceFile(kTiePointsLog), "TIE_POINTS|SITE_POSE_DR");
  const int pairs = static_cast<int>(DecodeAll<tie_points_t>(log, "TIE_POINTS").size());
  ASSERT_GE(pairs, 10);
  auto start = [&](int port, const std::string& state) {
    return StartProc({BinPath("crosssite_ba"), "--config", "config/procs/crosssite_ba.yaml", "--lcm-url",
                      TestLcmUrl(port), "--state-dir", state});
  };
  auto results = [](const Bus& bus) {
    std::map<int, localization_t> out;
    for (const auto& m : DecodeAll<localization_t>(bus.got(), "SITE_POSE_VISUAL")) out[m.site_id] = m;
    return out;
  };
  // Undisturbed.
  Bus clean_bus(TestLcmUrl(7892), "SITE_POSE_VISUAL");
  {
    auto proc = start(7892, scratch.dir + "/clean");
    clean_bus.Watch(proc.get());
    for (const Event& e : log) clean_bus.Send(e.channel, e.bytes);
    ASSERT_TRUE(clean_bus.PumpUntil([&] { return clean_bus.Count("SITE_POSE_VISUAL") >= pairs; }, 180));
    proc->Signal(SIGTERM);
    proc->WaitExit(20);
    clean_bus.Watch(nullptr);
  }
  // SIGKILL after half the pairs, restart on the same state folder, the rest.
  Bus bus(TestLcmUrl(7893), "SITE_POSE_VISUAL");
  size_t split = 0;
  for (int seen = 0; split < log.size() && seen < pairs / 2; ++split) seen += log[split].channel == "TIE_POINTS";
  {
    auto proc = start(7893, scratch.dir + "/killed");
    bus.Watch(proc.get());
    for (size_t i = 0; i < split; ++i) bus.Send(log[i].channel, log[i].bytes);
    ASSERT_TRUE(bus.PumpUntil([&] { return bus.Count("SITE_POSE_VISUAL") >= pairs / 2; }, 120));
    proc->Signal(SIGKILL);
    proc->WaitExit(10);
    bus.Watch(nullptr);
  }
  auto proc = start(7893, scratch.dir + "/killed");
  bus.Watch(proc.get());
  EXPECT_NE(proc->output().find("reloaded"), std::string::npos) << proc->output();
  for (size_t i = split; i < log.size(); ++i) bus.Send(log[i].channel, log[i].bytes);
  ASSERT_TRUE(bus.PumpUntil([&] { return bus.Count("SITE_POSE_VISUAL") >= pairs; }, 180));
  proc->Signal(SIGTERM);
  EXPECT_EQ(proc->WaitExit(20), std::optional<int>(0));
  const auto want = results(clean_bus), got = results(bus);
  int compared = 0;
  for (const auto& [site, w] : want) {
    if (w.status != localization_t::STATUS_OK || !got.count(site)) continue;
    ++compared;
    const pose_t &a = got.at(site).pose, &b = w.pose;
    EXPECT_LT(std::hypot(a.position[0] - b.position[0], a.position[1] - b.position[1], a.position[2] - b.position[2]),
              1e-6)
        << "site " << site << " after the restart";
  }
  EXPECT_GE(compared, pairs - 3);
}

// ---- 7 ------------------------------------------------------------------

TEST(Finding7, EmptyOrMissingConfigsStopEveryProcessWithOneLine) {
  Scratch scratch("f7");
  const std::string empty = scratch.Write("empty.yaml", "");
  for (const std::string name : {"dead_reckoning", "feature_frontend", "crosssite_ba", "traverse_graph", "uav_mosaicker"}) {
    for (const bool with_file : {true, false}) {
      std::vector<std::string> argv = {BinPath(name), "--lcm-url", TestLcmUrl(7894)};
      if (with_file) argv.insert(argv.end(), {"--config", empty});
      Subprocess p(argv);
      const auto code = p.WaitExit(20);
      ASSERT_TRUE(code) << name << " ran on defaults";
      EXPECT_NE(*code, 0) << name << (with_file ? " with an empty config" : " without --config");
      const auto errors = ErrorLines(p.output());
      ASSERT_EQ(errors.size(), 1u) << name << ":\n" << p.output();
      EXPECT_NE(errors[0].find(with_file ? "empty" : "--config"), std::string::npos) << errors[0];
    }
  }
  Subprocess accuracy({BinPath("vloc_accuracy"), "--config", empty});
  EXPECT_NE(accuracy.WaitExit(20), std::optional<int>(0)) << accuracy.output();
  EXPECT_NE(accuracy.output().find("empty"), std::string::npos) << accuracy.output();
}

TEST(Finding7, ToolsSayWhatIsWrongWithABadLog) {
  Scratch scratch("f7tools");
  const std::string good = SourceFile(kDrLog);
  std::ifstream in(good, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string truncated = scratch.Write("truncated.lcmlog", bytes.substr(0, bytes.size() / 2 + 7));
  const std::string empty = scratch.Write("empty.lcmlog", "");
  std::string noise(20000, '\0');
  for (size_t i = 0; i < noise.size(); ++i) noise[i] = static_cast<char>((i * 2654435761u) >> 13);
  const std::string binary = scratch.Write("binary.lcmlog", noise);
  for (const std::string& log : {truncated, empty, binary}) {
    Subprocess eval({BinPath("vloc_eval"), log, "--out", scratch.dir + "/eval", "--no-plots", "--quiet"});
    const auto code = eval.WaitExit(60);
    ASSERT_TRUE(code);
    EXPECT_NE(*code, 0) << log << ":\n" << eval.output();
    EXPECT_NE(eval.output().find(log), std::string::npos) << "names the file:\n" << eval.output();
  }
  Subprocess filter({BinPath("vloc_logfilter"), truncated, scratch.dir + "/out.lcmlog"});
  const auto code = filter.WaitExit(60);
  ASSERT_TRUE(code);
  EXPECT_NE(*code, 0) << filter.output();
  EXPECT_NE(filter.output().find("truncated"), std::string::npos) << filter.output();
  EXPECT_GT(fs::file_size(scratch.dir + "/out.lcmlog"), 0u) << "what came before the cut is kept";
}

// ---- 8 ------------------------------------------------------------------

TEST(Finding8, BadTiePointsGiveOneLineAndABadInputAnswer) {
  Scratch scratch("f8");
  const auto log = ReadEvents(SourceFile(kTiePointsLog), "TIE_POINTS");
  auto sets = DecodeAll<tie_points_t>(log, "TIE_POINTS");
  ASSERT_FALSE(sets.empty());
  tie_points_t nan_points = sets.front();
  for (auto& p : nan_points.points)
    for (auto& o : p.observations) o.u = std::numeric_limits<double>::quiet_NaN();
  tie_points_t same_site = sets.front();
  same_site.previous_site_id = same_site.current_site_id;
  const std::string url = TestLcmUrl(7895);
  Bus bus(url, "SITE_POSE_VISUAL");
  auto proc = StartProc({BinPath("crosssite_ba"), "--config", "config/procs/crosssite_ba.yaml", "--lcm-url", url,
                         "--state-dir", scratch.dir});
  const size_t before = proc->output().size();
  bus.Send("TIE_POINTS", Bytes(nan_points));
  bus.Send("TIE_POINTS", Bytes(same_site));
  ASSERT_TRUE(bus.PumpUntil([&] { return bus.Count("SITE_POSE_VISUAL") >= 2; }, 60)) << proc->output();
  for (const auto& m : DecodeAll<localization_t>(bus.got(), "SITE_POSE_VISUAL"))
    EXPECT_NE(int(m.status), int(localization_t::STATUS_OK)) << m.message;
  proc->Signal(SIGTERM);
  proc->WaitExit(20);
  const std::string said = proc->output().substr(before);
  EXPECT_EQ(CountOccurrences(said, "Ceres"), 0) << said;
  EXPECT_LE(CountOccurrences(said, "\n"), 8) << "a few lines, not a dump:\n" << said;
  EXPECT_NE(said.find("different"), std::string::npos) << said;
}

TEST(Finding8, TheMosaickerLogsTheFirstUndecodableFrame) {
  const std::string url = TestLcmUrl(7896);
  Bus bus(url, "UAV_STATE");
  auto proc = StartProc({BinPath("uav_mosaicker"), "--config", "config/procs/uav_mosaicker.yaml", "--lcm-url", url});
  image_t frame;
  frame.utime = 1000;
  frame.frame_id = "uav_nadir";
  frame.width = 640;
  frame.height = 480;
  frame.encoding = image_t::ENCODING_JPEG;
  frame.data.assign(500, 0x42);
  frame.size = static_cast<int32_t>(frame.data.size());
  bus.Send("UAV_CAMERA", Bytes(frame));
  ASSERT_TRUE(bus.PumpUntil([&] { return bus.Count("UAV_STATE") >= 1; }, 30)) << proc->output();
  proc->Signal(SIGTERM);
  EXPECT_EQ(proc->WaitExit(20), std::optional<int>(0));
  EXPECT_NE(proc->output().find("frame not decodable"), std::string::npos) << proc->output();
}

}  // namespace
}  // namespace vloc
