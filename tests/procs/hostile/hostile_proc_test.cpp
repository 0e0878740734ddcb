// Hostile input, process by process, over real LCM (ports 7871-7886): for
// every channel a process subscribes to, random bytes, truncations, wrong
// types, extreme numbers (NaN, inf, +-1e308, integer extremes), absurd
// string lengths and counts, and time running backwards and far ahead (see
// vloc/testing/hostile.h; seeds fixed, each case's bytes follow from its
// name). Afterwards each process must be alive, must do its job on a good
// log as an undisturbed run of the same process does, must publish no
// non-finite number, and must stop cleanly on SIGTERM.
//
// Rover back end: the hostile messages are interleaved with a recorded log
// (variants of each good message next to it), and the outputs for the
// log's own sites must equal the undisturbed run's. Front end, mosaicker and
// launcher: hostile first, then a good input they must still handle.
#include "hostile_bus.h"

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <set>

#include "vloc/frontend_status_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/localization_t.hpp"
#include "vloc/proc_status_t.hpp"
#include "vloc/procman_order_t.hpp"
#include "vloc/procman_status_t.hpp"
#include "vloc/site_event_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/stereo_image_t.hpp"
#include "vloc/traverse_t.hpp"
#include "vloc/uav_gps_t.hpp"
#include "vloc/testing/rover_inputs.h"
#include "vloc/uav_state_t.hpp"

namespace vloc {
namespace {

using namespace vloc::testing;

std::string SourceFile(const std::string& rel) { return std::string(VLOC_SOURCE_DIR) + "/" + rel; }

// Valid messages of every type but `type`, for the wrong-type cases.
std::vector<std::vector<uint8_t>> OthersThan(const std::string& type, const std::vector<Event>& pool) {
  std::vector<std::vector<uint8_t>> out;
  std::set<std::string> seen{type};
  for (const Event& e : pool) {
    int64_t hash = 0;
    for (int k = 0; k < 8 && e.bytes.size() >= 8; ++k) hash = (hash << 8) | e.bytes[static_cast<size_t>(k)];
    const std::string t = LcmSchema::Vloc().TypeOfFingerprint(hash);
    if (!t.empty() && seen.insert(t).second) out.push_back(e.bytes);
  }
  return out;
}

std::string TypeOf(const std::vector<uint8_t>& bytes) {
  int64_t hash = 0;
  for (int k = 0; k < 8 && bytes.size() >= 8; ++k) hash = (hash << 8) | bytes[static_cast<size_t>(k)];
  return LcmSchema::Vloc().TypeOfFingerprint(hash);
}

// Plans `per_channel` hostile messages for each channel of `log`, attached
// to evenly spaced good events of that channel: plan[i] = variants sent
// next to good event i.
std::map<size_t, std::vector<HostileMessage>> PlanHostile(const std::vector<Event>& log, int per_channel,
                                                          const std::vector<Event>& type_pool) {
  std::map<std::string, std::vector<size_t>> by_channel;
  for (size_t i = 0; i < log.size(); ++i) by_channel[log[i].channel].push_back(i);
  std::map<size_t, std::vector<HostileMessage>> plan;
  for (const auto& [channel, indices] : by_channel) {
    const int templates = std::min<int>(static_cast<int>(indices.size()), std::max(1, per_channel / 6));
    const int per_template = (per_channel + templates - 1) / templates;
    for (int t = 0; t < templates; ++t) {
      const size_t i = indices[static_cast<size_t>(t) * indices.size() / static_cast<size_t>(templates)];
      const std::string type = TypeOf(log[i].bytes);
      plan[i] = MakeHostileMessages(channel + "#" + std::to_string(i), type, log[i].bytes,
                                    OthersThan(type, type_pool), per_template);
    }
  }
  return plan;
}

struct LogRun {
  std::unique_ptr<Bus> bus;
  Outcome outcome;
};

// Starts `argv`, plays `log` into it with the planned hostile messages
// before (`before`) or after each good event, waits for `done`, stops it.
LogRun RunWithLog(const std::string& name, const std::vector<std::string>& argv, const std::string& url,
                  const std::string& outputs, const std::vector<Event>& log,
                  const std::map<size_t, std::vector<HostileMessage>>& plan, bool before,
                  const std::function<bool(const Bus&)>& done, double timeout_s) {
  LogRun run;
  run.outcome.process = name;
  run.bus = std::make_unique<Bus>(url, outputs);
  auto proc = StartProc(argv);
  run.bus->Watch(proc.get());
  for (size_t i = 0; i < log.size(); ++i) {
    auto it = plan.find(i);
    if (before && it != plan.end())
      for (const HostileMessage& h : it->second) run.bus->Send(log[i].channel, h.bytes), ++run.outcome.hostile_sent, run.outcome.sent.push_back(h.name);
    run.bus->Send(log[i].channel, log[i].bytes);
    if (!before && it != plan.end())
      for (const HostileMessage& h : it->second) run.bus->Send(log[i].channel, h.bytes), ++run.outcome.hostile_sent, run.outcome.sent.push_back(h.name);
  }
  EXPECT_TRUE(run.bus->PumpUntil([&] { return done(*run.bus); }, timeout_s))
      << name << ": " << run.bus->got().size() << " outputs received";
  run.bus->PumpUntilQuiet(3.0, timeout_s);  // the rest of the answers (hostile ones add to the count)
  run.outcome.alive_after_hostile = !proc->WaitExit(0.2);
  run.outcome.nonfinite_outputs = run.bus->NonFinite(&run.outcome.first_nonfinite);
  Stop(proc.get(), &run.outcome);
  if (const char* dump = std::getenv("VLOC_HOSTILE_DUMP"))  // debugging: the process's whole output
    std::ofstream(std::string(dump) + "/" + name + (run.outcome.hostile_sent ? ".hostile" : ".clean") + ".log")
        << proc->output();
  if (run.outcome.hostile_sent > 0) {
    Report(run.outcome);
    ExpectSurvived(run.outcome, *proc);
  }
  return run;
}

// The last message of `channel` per key.
template <class Msg, class Key>
std::map<Key, Msg> LastBy(const std::vector<Event>& events, const std::string& channel,
                          const std::function<std::optional<Key>(const Msg&)>& key) {
  std::map<Key, Msg> out;
  for (const Msg& m : DecodeAll<Msg>(events, channel))
    if (auto k = key(m)) out[*k] = m;
  return out;
}

double Distance(const pose_t& a, const pose_t& b) {
  return std::hypot(a.position[0] - b.position[0], a.position[1] - b.position[1], a.position[2] - b.position[2]);
}

constexpr int kPerChannel = 300;

TEST(Hostile, DeadReckoningKeepsItsTrackThroughHostileInput) {
  const auto log = ReadEvents(SourceFile("tests/data/logs/rover_dr_3sites.lcmlog"),
                              "IMU|WHEEL_ODOM|ROVER_SITE|SITE_POSE_GT");
  ASSERT_GT(log.size(), 100u);
  const std::string config = "config/procs/dead_reckoning.yaml";
  auto argv = [&](int port) {
    return std::vector<std::string>{BinPath("dead_reckoning"), "--config", config, "--lcm-url", TestLcmUrl(port)};
  };
  auto three_sites = [](const Bus& b) { return b.Count("SITE_POSE_DR") >= 3; };
  const LogRun clean = RunWithLog("dead_reckoning", argv(7871), TestLcmUrl(7871), "SITE_POSE_DR|DR_POSE", log, {},
                                  false, three_sites, 120);
  const auto plan = PlanHostile(log, kPerChannel, log);
  // After each good message: a variant one microsecond earlier is then out of order, not new.
  const LogRun hostile = RunWithLog("dead_reckoning", argv(7872), TestLcmUrl(7872), "SITE_POSE_DR|DR_POSE", log,
                                    plan, false, three_sites, 180);
  std::function<std::optional<int>(const site_pose_t&)> site = [](const site_pose_t& m) {
    return std::optional<int>(m.site_id);
  };
  const auto want = LastBy<site_pose_t, int>(clean.bus->got(), "SITE_POSE_DR", site);
  const auto got = LastBy<site_pose_t, int>(hostile.bus->got(), "SITE_POSE_DR", site);
  ASSERT_GE(want.size(), 3u);
  for (const auto& [id, w] : want) {
    ASSERT_TRUE(got.count(id)) << "no SITE_POSE_DR for site " << id << " after the hostile input";
    EXPECT_LT(Distance(got.at(id).pose, w.pose), 1e-9) << "site " << id;
    EXPECT_NEAR(got.at(id).pose.covariance[0], w.pose.covariance[0], 1e-12) << "site " << id;
  }
}

TEST(Hostile, CrossSiteBaLocalizesTheSameSitesThroughHostileInput) {
  const auto log = ReadEvents(SourceFile("tests/data/logs/rover_tiepoints_13sites.lcmlog"), "TIE_POINTS|SITE_POSE_DR");
  const auto pool = ReadEvents(SourceFile("tests/data/logs/rover_tiepoints_13sites.lcmlog"), ".*");
  const int pairs = static_cast<int>(DecodeAll<tie_points_t>(log, "TIE_POINTS").size());
  ASSERT_GE(pairs, 10);
  auto argv = [&](int port, const std::string& state) {
    return std::vector<std::string>{BinPath("crosssite_ba"), "--config", "config/procs/crosssite_ba.yaml",
                                    "--lcm-url", TestLcmUrl(port), "--state-dir", state};
  };
  const std::string dir = ::testing::TempDir() + "/hostile_ba_" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  const auto plan = PlanHostile(log, kPerChannel, pool);
  // A last pair 1000 -> 1001 after everything: once it is answered, so is all before it.
  auto with_sentinel = log;
  tie_points_t sentinel = DecodeAll<tie_points_t>(log, "TIE_POINTS").front();
  sentinel.previous_site_id = 1000;
  sentinel.current_site_id = 1001;
  std::vector<uint8_t> sentinel_bytes(static_cast<size_t>(sentinel.getEncodedSize()));
  sentinel.encode(sentinel_bytes.data(), 0, static_cast<int>(sentinel_bytes.size()));
  with_sentinel.push_back({"TIE_POINTS", sentinel_bytes});
  auto sentinel_answered = [](const Bus& b) {
    for (const auto& m : DecodeAll<localization_t>(b.got(), "SITE_POSE_VISUAL"))
      if (m.site_id == 1001) return true;
    return false;
  };
  const LogRun clean = RunWithLog("crosssite_ba", argv(7873, dir + "/clean"), TestLcmUrl(7873), "SITE_POSE_VISUAL",
                                  with_sentinel, {}, true, sentinel_answered, 180);
  // Before each good message: its variants' results are then overwritten by the good one's.
  const LogRun hostile = RunWithLog("crosssite_ba", argv(7874, dir + "/hostile"), TestLcmUrl(7874),
                                    "SITE_POSE_VISUAL", with_sentinel, plan, true, sentinel_answered, 240);
  std::function<std::optional<std::pair<int, int>>(const localization_t&)> ok_pair = [](const localization_t& m) {
    return m.status == localization_t::STATUS_OK ? std::optional(std::make_pair(m.reference_site_id, m.site_id))
                                                 : std::nullopt;
  };
  const auto want = LastBy<localization_t, std::pair<int, int>>(clean.bus->got(), "SITE_POSE_VISUAL", ok_pair);
  const auto got = LastBy<localization_t, std::pair<int, int>>(hostile.bus->got(), "SITE_POSE_VISUAL", ok_pair);
  ASSERT_GE(want.size(), 5u);
  for (const auto& [key, w] : want) {
    std::string answers;
    for (const auto& m : DecodeAll<localization_t>(hostile.bus->got(), "SITE_POSE_VISUAL"))
      if (m.site_id == key.second) answers += " [" + std::to_string(m.reference_site_id) + "->" + std::to_string(m.site_id) + " status " + std::to_string(m.status) + ": " + m.message + "]";
    ASSERT_TRUE(got.count(key)) << "pair " << key.first << "->" << key.second << " not localized after hostile input:" << answers;
    // Ceres with two threads: the same problem agrees to a micrometre, not bit for bit.
    EXPECT_LT(Distance(got.at(key).relative_pose, w.relative_pose), 1e-4) << key.first << "->" << key.second;
  }
  std::filesystem::remove_all(dir);
}

TEST(Hostile, TraverseGraphOptimisesTheSameTraverseThroughHostileInput) {
  const std::string path = SourceFile("tests/data/logs/rover_tiepoints_13sites.lcmlog");
  const auto log = ReadEvents(path, "SITE_POSE_DR|SITE_POSE_VISUAL");
  const auto pool = ReadEvents(path, ".*");
  // Absolute fixes are hostile only: a template fix for a site the traverse never reaches.
  site_pose_t fix;
  fix.utime = 1000;
  fix.site_id = 999;
  fix.pose.orientation[0] = 1;
  fix.pose.covariance[0] = fix.pose.covariance[7] = fix.pose.covariance[14] = 1.0;
  std::vector<uint8_t> fix_bytes(static_cast<size_t>(fix.getEncodedSize()));
  fix.encode(fix_bytes.data(), 0, static_cast<int>(fix_bytes.size()));
  const auto plan = PlanHostile(log, kPerChannel, pool);
  // The fixes ride along with every other good message, on their own channel.
  const auto fixes = MakeHostileMessages("SITE_POSE_FIX", "site_pose_t", fix_bytes, OthersThan("site_pose_t", pool),
                                         kPerChannel);
  std::map<size_t, std::vector<HostileMessage>> fix_plan;
  for (size_t f = 0, i = 0; f < fixes.size() && i < log.size(); i += 2)
    for (int k = 0; k < 12 && f < fixes.size(); ++k) fix_plan[i].push_back(fixes[f++]);
  const std::string dir = ::testing::TempDir() + "/hostile_graph_" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  auto argv = [&](int port, const std::string& state) {
    return std::vector<std::string>{BinPath("traverse_graph"), "--config", "config/procs/traverse_graph.yaml",
                                    "--lcm-url", TestLcmUrl(port), "--state-dir", state};
  };
  const int inputs = static_cast<int>(log.size());
  const LogRun clean = RunWithLog("traverse_graph", argv(7875, dir + "/clean"), TestLcmUrl(7875), "TRAVERSE", log,
                                  {}, false, [&](const Bus& b) { return b.Count("TRAVERSE") >= inputs / 2; }, 120);
  // The fixes: sent between the good messages as their own hostile batches.
  LogRun hostile;
  {
    hostile.outcome.process = "traverse_graph";
    hostile.bus = std::make_unique<Bus>(TestLcmUrl(7876), "TRAVERSE");
    auto proc = StartProc(argv(7876, dir + "/hostile"));
    hostile.bus->Watch(proc.get());
    for (size_t i = 0; i < log.size(); ++i) {
      hostile.bus->Send(log[i].channel, log[i].bytes);
      if (plan.count(i))
        for (const HostileMessage& h : plan.at(i)) hostile.bus->Send(log[i].channel, h.bytes), ++hostile.outcome.hostile_sent, hostile.outcome.sent.push_back(h.name);
      if (fix_plan.count(i))
        for (const HostileMessage& h : fix_plan.at(i)) hostile.bus->Send("SITE_POSE_FIX", h.bytes), ++hostile.outcome.hostile_sent, hostile.outcome.sent.push_back(h.name);
    }
    hostile.bus->PumpUntilQuiet(3.0, 120);
    hostile.outcome.alive_after_hostile = !proc->WaitExit(0.2);
    hostile.outcome.nonfinite_outputs = hostile.bus->NonFinite(&hostile.outcome.first_nonfinite);
    Stop(proc.get(), &hostile.outcome);
    Report(hostile.outcome);
    ExpectSurvived(hostile.outcome, *proc);
  }
  const auto want_all = DecodeAll<traverse_t>(clean.bus->got(), "TRAVERSE");
  const auto got_all = DecodeAll<traverse_t>(hostile.bus->got(), "TRAVERSE");
  ASSERT_FALSE(want_all.empty());
  ASSERT_FALSE(got_all.empty());
  const traverse_t& want = want_all.back();
  const traverse_t& got = got_all.back();
  std::map<int, pose_t> got_by_site;
  for (int k = 0; k < got.num_sites; ++k) got_by_site[got.site_ids[k]] = got.poses[k];
  for (int k = 0; k < want.num_sites; ++k) {
    const int id = want.site_ids[k];
    ASSERT_TRUE(got_by_site.count(id)) << "site " << id << " missing from the hostile run's traverse";
    // Extra leaf sites (hostile ids) change the optimiser's path, not its optimum: 2 mm.
    EXPECT_LT(Distance(got_by_site[id], want.poses[k]), 2e-3) << "site " << id;
  }
  std::filesystem::remove_all(dir);
}

// Two textureless sites, as feature_frontend_proc_test sends them.
std::vector<Event> TexturelessSites(int first_site) {
  std::vector<Event> out;
  auto bytes = [](const auto& msg) {
    std::vector<uint8_t> b(static_cast<size_t>(msg.getEncodedSize()));
    msg.encode(b.data(), 0, static_cast<int>(b.size()));
    return b;
  };
  for (int site = first_site; site < first_site + 2; ++site) {
    PoseWithCovariance pose;
    pose.pose = MakePose(10.0 * site, 0, 0, 0, 0, 0);
    out.push_back({"SITE_POSE_DR", bytes(SitePoseToMessage(site, site_pose_t::SOURCE_DEAD_RECKONING, pose))});
    for (int k = 0; k < 3; ++k)
      out.push_back({"NAVCAM_STEREO", bytes(StereoPairToMessage(TexturelessPair(site, k), ImageEncoding::kPng))});
  }
  return out;
}

TEST(Hostile, FeatureFrontendStillAnswersASitePairAfterHostileInput) {
  // Hostile variants of sites 0 and 1 are often valid data: the good sites are new ones.
  const auto good = TexturelessSites(10);
  const auto pool = ReadEvents(SourceFile("tests/data/logs/rover_tiepoints_13sites.lcmlog"), ".*");
  // Hostile first (templates: the good messages with small images), then the good sites.
  std::vector<Event> templates = TexturelessSites(0);
  {
    const SiteEvent arrived{500000, 7, SiteEventType::kArrived, 3};
    const site_event_t m = SiteEventToMessage(arrived);
    std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
    m.encode(b.data(), 0, static_cast<int>(b.size()));
    templates.push_back({"ROVER_SITE", b});
  }
  for (Event& e : templates) {
    if (e.channel != "NAVCAM_STEREO") continue;
    stereo_image_t m;
    ASSERT_TRUE(Decode(e.bytes.data(), e.bytes.size(), &m));
    for (image_t* im : {&m.left, &m.right}) {
      const image_t small = ImageToMessage(cv::Mat(16, 16, CV_8UC1, cv::Scalar(100)), ImageEncoding::kGray8, im->utime,
                                           im->frame_id);
      *im = small;
    }
    e.bytes.resize(static_cast<size_t>(m.getEncodedSize()));
    m.encode(e.bytes.data(), 0, static_cast<int>(e.bytes.size()));
  }
  const auto plan = PlanHostile(templates, kPerChannel, pool);
  Outcome o;
  o.process = "feature_frontend";
  const std::string url = TestLcmUrl(7877);
  Bus bus(url, "FRONTEND_STATUS|TIE_POINTS");
  auto proc = StartProc({BinPath("feature_frontend"), "--config", "config/procs/feature_frontend.yaml", "--lcm-url",
                         url});
  bus.Watch(proc.get());
  for (const auto& [i, cases] : plan)
    for (const HostileMessage& h : cases) bus.Send(templates[i].channel, h.bytes), ++o.hostile_sent, o.sent.push_back(h.name);
  bus.Pump(2000);
  o.alive_after_hostile = !proc->WaitExit(0.2);
  for (const Event& e : good) bus.Send(e.channel, e.bytes);
  auto answered = [&] {
    for (const auto& m : DecodeAll<frontend_status_t>(bus.got(), "FRONTEND_STATUS"))
      if (m.previous_site_id == 10 && m.current_site_id == 11) return true;
    return false;
  };
  EXPECT_TRUE(bus.PumpUntil(answered, 120))
      << proc->output().substr(proc->output().size() > 6000 ? proc->output().size() - 6000 : 0);
  o.nonfinite_outputs = bus.NonFinite(&o.first_nonfinite);
  Stop(proc.get(), &o);
  Report(o);
  ExpectSurvived(o, *proc);
}

std::string FixturePath(const std::string& name) {
  const char* build = std::getenv("VLOC_BUILD_DIR");
  return std::string(build ? build : ".") + "/fixtures/" + name;
}

TEST(Hostile, UavMosaickerStillTracksAFlightAfterHostileInput) {
  const std::string path = FixturePath("uav_short.lcmlog");
  ASSERT_TRUE(std::filesystem::exists(path)) << "fixture missing: " << path;
  const auto good = ReadEvents(path, "UAV_CAMERA|UAV_GPS");
  const auto pool = ReadEvents(SourceFile("tests/data/logs/rover_tiepoints_13sites.lcmlog"), ".*");
  const int frames = static_cast<int>(DecodeAll<image_t>(good, "UAV_CAMERA").size());
  ASSERT_GT(frames, 30);
  // Templates: the first frame and fix; hostile first, then the whole flight.
  std::vector<Event> templates;
  for (const Event& e : good)
    if (std::none_of(templates.begin(), templates.end(), [&](const Event& t) { return t.channel == e.channel; }))
      templates.push_back(e);
  const auto plan = PlanHostile(templates, kPerChannel, pool);
  Outcome o;
  o.process = "uav_mosaicker";
  const std::string url = TestLcmUrl(7878);
  Bus bus(url, "UAV_STATE");
  auto proc = StartProc({BinPath("uav_mosaicker"), "--config", "config/procs/uav_mosaicker.yaml", "--lcm-url", url});
  bus.Watch(proc.get());
  for (const auto& [i, cases] : plan)
    for (const HostileMessage& h : cases) bus.Send(templates[i].channel, h.bytes), ++o.hostile_sent, o.sent.push_back(h.name);
  bus.Pump(3000);
  o.alive_after_hostile = !proc->WaitExit(0.2);
  const size_t before = bus.got().size();
  // Paced by the mosaicker's answers (one frame in flight): a loaded machine slows it down but drops nothing.
  for (const Event& e : good) {
    const size_t answered = bus.got().size();
    bus.Send(e.channel, e.bytes);
    if (e.channel == "UAV_CAMERA") bus.PumpUntil([&] { return bus.got().size() > answered; }, 10);
  }
  EXPECT_TRUE(bus.PumpUntil([&] { return static_cast<int>(bus.got().size() - before) >= frames; }, 120));
  int tracked = 0;
  for (size_t k = before; k < bus.got().size(); ++k) {
    uav_state_t s;
    if (Decode(bus.got()[k].bytes.data(), bus.got()[k].bytes.size(), &s))
      tracked += s.status == uav_state_t::STATUS_TRACKING || s.status == uav_state_t::STATUS_RECOVERED;
  }
  // As on a clean start (log_injection_test): a few calibrating frames, then every frame tracked.
  EXPECT_GE(tracked, frames - 15) << proc->output().substr(proc->output().size() > 3000 ? proc->output().size() - 3000 : 0);
  o.nonfinite_outputs = bus.NonFinite(&o.first_nonfinite);
  Stop(proc.get(), &o);
  Report(o);
  ExpectSurvived(o, *proc);
}

TEST(Hostile, LauncherStillObeysOrdersAfterHostileOnes) {
  const std::string dir = ::testing::TempDir() + "/hostile_launch_" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir + "/logs");
  std::ofstream(dir + "/group.yaml") << "group: g\ndefaults: {stop_timeout: 2}\nprocesses:\n"
                                        "  - {name: sleeper, command: sleep, args: [\"60\"]}\n";
  const std::string url = TestLcmUrl(7879);
  Bus bus(url, "PROCMAN_STATUS");
  Outcome o;
  o.process = "vloc_launch";
  auto proc = std::make_unique<Subprocess>(std::vector<std::string>{
      BinPath("vloc_launch"), "--config", dir + "/group.yaml", "--lcm-url", url, "--log-dir", dir + "/logs"});
  bus.Watch(proc.get());
  auto state_of = [&](const std::string& name) -> int {
    const auto all = DecodeAll<procman_status_t>(bus.got(), "PROCMAN_STATUS");
    if (all.empty()) return -1;
    for (const auto& p : all.back().procs)
      if (p.name == name) return p.state;
    return -1;
  };
  ASSERT_TRUE(bus.PumpUntil([&] { return state_of("sleeper") == proc_status_t::STATE_RUNNING; }, 30))
      << proc->output();
  // Template: an order for a process the group does not have.
  procman_order_t order;
  order.host = "";
  order.target = "nobody";
  order.target_kind = procman_order_t::TARGET_PROCESS;
  order.action = procman_order_t::ACTION_STOP;
  std::vector<uint8_t> bytes(static_cast<size_t>(order.getEncodedSize()));
  order.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  const auto pool = ReadEvents(SourceFile("tests/data/logs/rover_tiepoints_13sites.lcmlog"), ".*");
  for (const HostileMessage& h :
       MakeHostileMessages("PROCMAN_ORDERS", "procman_order_t", bytes, OthersThan("procman_order_t", pool), kPerChannel))
    bus.Send("PROCMAN_ORDERS", h.bytes), ++o.hostile_sent, o.sent.push_back(h.name);
  bus.Pump(2000);
  o.alive_after_hostile = !proc->WaitExit(0.2);
  EXPECT_EQ(state_of("sleeper"), int(proc_status_t::STATE_RUNNING));
  order.target = "sleeper";
  bytes.resize(static_cast<size_t>(order.getEncodedSize()));
  order.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  bus.Send("PROCMAN_ORDERS", bytes);
  EXPECT_TRUE(bus.PumpUntil([&] { return state_of("sleeper") == proc_status_t::STATE_STOPPED; }, 20))
      << proc->output();
  o.nonfinite_outputs = bus.NonFinite(&o.first_nonfinite);
  proc->Signal(SIGTERM);
  o.exit_code = proc->WaitExit(20);
  Report(o);
  ExpectSurvived(o, *proc);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vloc
