// The backend processes over real LCM (ports 7762-7763): crosssite_ba fed a
// synthetic TIE_POINTS message answers on SITE_POSE_VISUAL with the true
// pose within its covariance; dead_reckoning fed IMU / wheel / site events
// answers with DR_POSE and SITE_POSE_DR.
#include <gtest/gtest.h>

#include <chrono>
#include <optional>
#include <thread>

#include "vloc/ba/synthetic.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/process.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/localization_t.hpp"
#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

using testing::BinPath;
using testing::Subprocess;
using testing::TestLcmUrl;

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Publishes `send` every second until `done` or the timeout.
bool PumpUntil(Transport& transport, double timeout_s, const std::function<void()>& send,
               const std::function<bool()>& done) {
  const double deadline = Now() + timeout_s;
  double next_send = 0;
  while (Now() < deadline) {
    if (Now() >= next_send) {
      send();
      next_send = Now() + 1.0;
    }
    transport.Handle(100);
    if (done()) return true;
  }
  return false;
}

TEST(CrossSiteBaProcess, LocalizesSyntheticSiteAndReportsFailures) {
  const std::string url = TestLcmUrl(7762);
  Subprocess proc({BinPath("crosssite_ba"), "--config", "config/procs/crosssite_ba.yaml", "--lcm-url", url});
  ASSERT_TRUE(proc.WaitForOutput("waiting for TIE_POINTS", 30)) << proc.output();
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  std::vector<localization_t> received;
  Subscribe<localization_t>(*transport, "SITE_POSE_VISUAL",
                            [&](const std::string&, const localization_t& m) { received.push_back(m); });

  const NavcamModel navcam = LoadOptionsFile<NavcamModel>("config/navcam.yaml");
  const Pose3 previous = MakePose(3.0, -1.0, 0.2, 0.02, -0.01, 0.3);
  const Pose3 current = previous * MakePose(10.0, 0.5, 0.1, 0.01, 0.02, 0.05);
  const Pose3 current_dr = current * MakePose(0.6, -0.7, 0.1, 0.0, 0.01, 0.05);
  SyntheticTiePointOptions so;
  so.seed = 21;
  SyntheticTiePoints syn = MakeSyntheticTiePoints(navcam, previous, current, current_dr, so);
  syn.set.utime = 123456789;
  const tie_points_t good = TiePointsToMessage(syn.set);
  ASSERT_TRUE(PumpUntil(
      *transport, 30, [&] { Publish(*transport, "TIE_POINTS", good); }, [&] { return !received.empty(); }))
      << proc.output();
  const localization_t& m = received.front();
  EXPECT_EQ(int(m.status), int(localization_t::STATUS_OK)) << m.message;
  EXPECT_EQ(m.site_id, 2);
  EXPECT_EQ(m.reference_site_id, 1);
  EXPECT_EQ(m.utime, 123456789);
  const PoseWithCovariance pose = PoseFromMessage(m.pose);
  Vector6d e;
  e.head<3>() = current.translation() - pose.pose.translation();
  e.tail<3>() = LogSO3(current.linear() * pose.pose.linear().transpose());
  EXPECT_LT(e.head<3>().norm(), 0.1);  // 1 % of the 10 m spacing
  EXPECT_LT(e.dot(pose.covariance.ldlt().solve(e)), 22.46);  // chi2(6) 99.9 %
  EXPECT_GT(m.num_tie_points_used, 190);
  EXPECT_GT(m.num_observations, 760);
  EXPECT_LT(m.final_rms_px, 0.5);
  EXPECT_GT(m.iterations, 0);

  // Too few tie points for the next site: failure status, dead reckoning stands.
  so.num_points = 3;
  SyntheticTiePoints few = MakeSyntheticTiePoints(navcam, current, current * MakePose(8, 0, 0, 0, 0, 0),
                                                  current * MakePose(8.5, 0.3, 0, 0, 0, 0.02), so);
  few.set.previous_site_id = 2;
  few.set.current_site_id = 3;
  const tie_points_t bad = TiePointsToMessage(few.set);
  const size_t before = received.size();
  ASSERT_TRUE(PumpUntil(
      *transport, 30, [&] { Publish(*transport, "TIE_POINTS", bad); },
      [&] { return received.size() > before && received.back().site_id == 3; }))
      << proc.output();
  EXPECT_EQ(int(received.back().status), int(localization_t::STATUS_TOO_FEW_POINTS)) << received.back().message;
  EXPECT_FALSE(received.back().message.empty());

  // A corrupt message (an observation naming a pair that does not exist): BAD_INPUT, DR pose stands.
  tie_points_t corrupt = TiePointsToMessage(syn.set);
  corrupt.current_site_id = 4;
  corrupt.points[0].observations[0].pair_index = 99;
  ASSERT_TRUE(PumpUntil(
      *transport, 30, [&] { Publish(*transport, "TIE_POINTS", corrupt); },
      [&] { return received.back().site_id == 4; }))
      << proc.output();
  EXPECT_EQ(int(received.back().status), int(localization_t::STATUS_BAD_INPUT)) << received.back().message;
  EXPECT_LT((PoseFromMessage(received.back().pose).pose.translation() - current_dr.translation()).norm(), 1e-9);
  proc.Signal(SIGTERM);
  EXPECT_EQ(proc.WaitExit(20), 0) << proc.output();
}

TEST(DeadReckoningProcess, PublishesPeriodicAndSitePoses) {
  const std::string url = TestLcmUrl(7763);
  Subprocess proc({BinPath("dead_reckoning"), "--config", "config/procs/dead_reckoning.yaml", "--lcm-url", url});
  ASSERT_TRUE(proc.WaitForOutput(kReadyLine, 30)) << proc.output();
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  std::vector<pose_t> poses;
  std::vector<site_pose_t> sites;
  Subscribe<pose_t>(*transport, "DR_POSE", [&](const std::string&, const pose_t& m) { poses.push_back(m); });
  Subscribe<site_pose_t>(*transport, "SITE_POSE_DR",
                         [&](const std::string&, const site_pose_t& m) { sites.push_back(m); });
  // Wait until the process hears us: send the arrival at site 0 until its pose comes back
  // (IMU samples, level and still, give it attitude).
  const Eigen::Matrix3d R = RotationFromRollPitchYaw(0.03, -0.02, 0.0);
  int64_t t = 1'000'000;
  auto send_imu = [&](int n, double speed) {
    for (int k = 0; k < n; ++k, t += 10'000) {
      ImuSample s;
      s.utime = t;
      s.linear_acceleration = R.transpose() * Eigen::Vector3d(0, 0, 1.62);
      Publish(*transport, "IMU", ImuToMessage(s));
      if (k % 5 == 0) {
        static double distance = 0;
        distance += speed * 0.05;
        Publish(*transport, "WHEEL_ODOM", WheelOdometryToMessage({t, distance, speed}));
      }
      transport->Handle(0);
      std::this_thread::sleep_for(std::chrono::microseconds(300));  // pacing, not waiting
    }
  };
  ASSERT_TRUE(PumpUntil(
      *transport, 30,
      [&] {
        send_imu(100, 0.0);
        Publish(*transport, "ROVER_SITE", SiteEventToMessage({t, 0, SiteEventType::kArrived, 7}));
      },
      [&] { return !sites.empty(); }))
      << proc.output();
  EXPECT_EQ(sites.front().site_id, 0);
  EXPECT_EQ(int(sites.front().source), int(site_pose_t::SOURCE_DEAD_RECKONING));
  const PoseWithCovariance site0 = PoseFromMessage(sites.front().pose);
  EXPECT_LT(site0.pose.translation().norm(), 1e-9);
  EXPECT_LT(LogSO3(site0.pose.linear() * R.transpose()).norm(), 1e-6);  // roll/pitch from gravity
  // Drive 2 m straight at 0.1 m/s (20 s of message time) and arrive at site 1.
  send_imu(2000, 0.1);
  ASSERT_TRUE(PumpUntil(
      *transport, 30,
      [&] { Publish(*transport, "ROVER_SITE", SiteEventToMessage({t, 1, SiteEventType::kArrived, 7})); },
      [&] { return sites.size() >= 2; }))
      << proc.output();
  const PoseWithCovariance site1 = PoseFromMessage(sites.back().pose);
  EXPECT_EQ(sites.back().site_id, 1);
  // UDP on loopback may lose a few samples; the cumulative odometer makes that harmless.
  EXPECT_NEAR((site1.pose.translation() - site0.pose.translation()).norm(), 2.0, 0.02);
  EXPECT_GT(poses.size(), 150u);  // 10 Hz over > 20 s of message time
  proc.Signal(SIGTERM);
  EXPECT_EQ(proc.WaitExit(20), 0) << proc.output();
}

}  // namespace
}  // namespace vloc
