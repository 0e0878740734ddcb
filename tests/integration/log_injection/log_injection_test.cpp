// Log injection: recorded simulator logs are replayed with lcm-logplayer
// into the real vloc processes over real LCM (ports 7840-7859), and what the
// processes publish is checked against the ground truth in the same log.

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <map>

#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/process.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/localization_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/testing/subprocess.h"
#include "vloc/uav_state_t.hpp"

namespace vloc {
namespace {

using testing::BinPath;
using testing::Subprocess;
using testing::TestLcmUrl;

std::string FixturePath(const std::string& name) {
  const char* build = std::getenv("VLOC_BUILD_DIR");
  return std::string(build ? build : ".") + "/fixtures/" + name;
}

// Every message of type Msg on `channel` in a log.
template <class Msg>
std::vector<Msg> ReadLog(const std::string& path, const std::string& channel) {
  std::vector<Msg> out;
  lcm::LogFile log(path, "r");
  EXPECT_TRUE(log.good()) << path;
  while (const lcm::LogEvent* ev = log.readNextEvent()) {
    if (ev->channel != channel) continue;
    Msg msg;
    if (msg.decode(ev->data, 0, ev->datalen) == ev->datalen) out.push_back(msg);
  }
  return out;
}

// Collects messages of one type from a live LCM URL.
template <class Msg>
class Collector {
 public:
  Collector(const std::string& url, const std::string& channel) {
    std::string error;
    transport_ = MakeLcmTransport(url, &error);
    EXPECT_TRUE(transport_) << error;
    stats_ = Subscribe<Msg>(*transport_, channel, [this](const std::string&, const Msg& m) { got_.push_back(m); },
                            10000);
  }
  // Handles messages until `done` or the timeout.
  bool PumpUntil(const std::function<bool()>& done, double timeout_s) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (!done()) {
      if (std::chrono::steady_clock::now() > deadline) return false;
      transport_->Handle(50);
    }
    return true;
  }
  const std::vector<Msg>& got() const { return got_; }

 private:
  std::unique_ptr<Transport> transport_;
  std::shared_ptr<SubscriptionStats> stats_;
  std::vector<Msg> got_;
};

// Starts a vloc process and waits until it has subscribed (messages
// replayed before that would be lost).
std::unique_ptr<Subprocess> StartProcess(const std::string& name, const std::string& config, const std::string& url) {
  auto p = std::make_unique<Subprocess>(
      std::vector<std::string>{BinPath(name), "--config", config, "--lcm-url", url});
  EXPECT_TRUE(p->WaitForOutput(kReadyLine, 60)) << p->output();
  return p;
}

TEST(LogInjection, UavMosaickerOnAReplayedFlight) {
  const std::string log = FixturePath("uav_short.lcmlog");
  ASSERT_TRUE(std::filesystem::exists(log)) << "fixture missing: " << log;
  const std::string url = TestLcmUrl(7841);
  auto mosaicker = StartProcess("uav_mosaicker", "config/procs/uav_mosaicker.yaml", url);
  Collector<uav_state_t> states(url, "UAV_STATE");
  const auto truth = ReadLog<pose_t>(log, "UAV_GT");
  const auto frames = ReadLog<image_t>(log, "UAV_CAMERA");
  ASSERT_GT(frames.size(), 30u);
  Subprocess player({"/usr/bin/lcm-logplayer", "--lcm-url=" + url, "--speed=1", "-e", "UAV_CAMERA|UAV_GPS", log});
  ASSERT_TRUE(states.PumpUntil([&] { return states.got().size() >= frames.size(); }, 120))
      << "UAV_STATE for " << states.got().size() << " of " << frames.size() << " frames\n"
      << mosaicker->output();
  std::map<int64_t, double> true_height;
  for (const auto& p : truth) true_height[p.utime] = p.position[2];
  double sum_sq = 0;
  int tracked = 0;
  for (const auto& s : states.got()) {
    if (s.status != uav_state_t::STATUS_TRACKING && s.status != uav_state_t::STATUS_RECOVERED) continue;
    ASSERT_TRUE(true_height.count(s.utime)) << "no UAV_GT at " << s.utime;
    const double rel = (s.height - true_height[s.utime]) / true_height[s.utime];
    sum_sq += rel * rel;
    ++tracked;
  }
  // The flight calibrates on the marker for a few frames, then tracks all.
  EXPECT_GE(tracked, static_cast<int>(frames.size()) - 15);
  // Height from the affine scale: the target is 2 % RMS of the true height.
  EXPECT_LT(std::sqrt(sum_sq / std::max(1, tracked)), 0.02);
  mosaicker->Signal(SIGTERM);
  EXPECT_EQ(mosaicker->WaitExit(30), 0) << mosaicker->output();
}

TEST(LogInjection, DeadReckoningOnARecordedTraverse) {
  const std::string log = std::string(VLOC_SOURCE_DIR) + "/tests/data/logs/rover_dr_3sites.lcmlog";
  const std::string url = TestLcmUrl(7842);
  auto dr = StartProcess("dead_reckoning", "config/procs/dead_reckoning.yaml", url);
  Collector<site_pose_t> poses(url, "SITE_POSE_DR");
  const auto truth = ReadLog<site_pose_t>(log, "SITE_POSE_GT");
  ASSERT_GE(truth.size(), 3u);
  Subprocess player({"/usr/bin/lcm-logplayer", "--lcm-url=" + url, "--speed=20", "-e",
                     "IMU|WHEEL_ODOM|ROVER_SITE|SITE_POSE_GT", log});
  ASSERT_TRUE(poses.PumpUntil([&] { return poses.got().size() >= truth.size(); }, 120))
      << poses.got().size() << " site poses\n" << dr->output();
  double distance = 0;
  for (size_t i = 0; i < truth.size(); ++i) {
    const auto& gt = truth[i].pose.position;
    if (i > 0) {
      const auto& prev = truth[i - 1].pose.position;
      distance += std::hypot(gt[0] - prev[0], gt[1] - prev[1]);
    }
    const auto& est = poses.got()[i];
    ASSERT_EQ(est.site_id, truth[i].site_id);
    const double err = std::hypot(est.pose.position[0] - gt[0], est.pose.position[1] - gt[1]);
    // Within the 5-15 % drift of the simulated wheels and IMU ...
    EXPECT_LE(err, 0.15 * distance + 0.05) << "site " << i;
    // ... and within 3 sigma of the covariance it reports.
    const double sigma = std::sqrt(est.pose.covariance[0] + est.pose.covariance[7]);
    EXPECT_LE(err, 3 * sigma + 0.05) << "site " << i;
  }
}

TEST(LogInjection, CrossSiteBaOnRecordedTiePoints) {
  // Tie points the front end found on a 13-site simulated traverse, with the
  // dead reckoning, the ground truth and the BA results of that run.
  const std::string log = std::string(VLOC_SOURCE_DIR) + "/tests/data/logs/rover_tiepoints_13sites.lcmlog";
  const std::string url = TestLcmUrl(7843);
  auto ba = StartProcess("crosssite_ba", "config/procs/crosssite_ba.yaml", url);
  Collector<localization_t> results(url, "SITE_POSE_VISUAL");
  const auto truth = ReadLog<site_pose_t>(log, "SITE_POSE_GT");
  const auto recorded = ReadLog<localization_t>(log, "SITE_POSE_VISUAL");
  int recorded_ok = 0;
  for (const auto& r : recorded) recorded_ok += r.status == localization_t::STATUS_OK;
  ASSERT_GE(recorded_ok, 5);
  Subprocess player({"/usr/bin/lcm-logplayer", "--lcm-url=" + url, "--speed=100", "-e", "TIE_POINTS|SITE_POSE_DR",
                     log});
  ASSERT_TRUE(results.PumpUntil([&] { return results.got().size() >= recorded.size(); }, 180))
      << results.got().size() << " of " << recorded.size() << " results\n" << ba->output();
  std::map<int, Pose3> gt;
  for (const auto& t : truth) gt[t.site_id] = PoseFromMessage(t.pose).pose;
  int ok = 0;
  for (const auto& r : results.got()) {
    if (r.status != localization_t::STATUS_OK) continue;
    ++ok;
    ASSERT_TRUE(gt.count(r.site_id) && gt.count(r.reference_site_id));
    // The new site relative to the site it was matched against.
    const Pose3 true_rel = gt[r.reference_site_id].inverse() * gt[r.site_id];
    const Pose3 est_rel = PoseFromMessage(r.relative_pose).pose;
    const double spacing = true_rel.translation().head<2>().norm();
    const double err = (est_rel.translation() - true_rel.translation()).head<2>().norm();
    // Target: every site pair under 2 % of the site spacing.
    EXPECT_LT(err / spacing, 0.02) << "site " << r.site_id << ": " << r.message;
  }
  // The replay reproduces the recorded run's successes.
  EXPECT_GE(ok, recorded_ok - 1);
}

}  // namespace
}  // namespace vloc
