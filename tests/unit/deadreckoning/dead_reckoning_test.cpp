// Dead reckoning against a synthesized traverse with known truth: exact with
// ideal sensors, within its covariance with noise, and robust to replay
// defects (duplicates, reordering, gaps, time jumps).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "vloc/deadreckoning/dead_reckoning.h"

namespace vloc {
namespace {

constexpr double kGravity = 1.62;

// A traverse: stop, turn, drive over a gently rolling slope, stop ... Truth
// is integrated at 1 kHz; the IMU reports mean body rates (100 Hz) and the
// specific force; the wheels report cumulative distance (20 Hz).
struct Traverse {
  std::vector<ImuSample> imu;
  std::vector<WheelOdometrySample> wheel;
  std::vector<SiteEvent> events;
  std::vector<Pose3> site_truth;     // at each ARRIVED
  std::vector<double> site_distance; // m, driven so far
  std::vector<std::pair<int64_t, Pose3>> truth;  // at IMU times
};

struct SensorErrors {
  double gyro_bias = 0;       // rad/s on every axis
  double gyro_noise = 0;      // rad/s per sample, 1-sigma
  double wheel_scale = 1.0;   // odometer reads true distance * this
  uint64_t seed = 1;
};

Traverse MakeTraverse(const SensorErrors& err) {
  Traverse tr;
  std::mt19937_64 rng(err.seed);
  std::normal_distribution<double> n(0.0, 1.0);
  const int64_t t0 = 5'000'000;
  const double dt_fine = 0.001;
  // Segments: {duration s, yaw rate rad/s, speed m/s}.
  struct Seg { double duration, yaw_rate, speed; bool arrive_after; };
  std::vector<Seg> segs;
  for (int site = 0; site < 3; ++site) {
    segs.push_back({4.0, 0.0, 0.0, false});   // standing, imaging
    segs.push_back({6.0, site == 1 ? -0.06 : 0.05, 0.0, false});  // point turn
    segs.push_back({100.0, 0.0, 0.1, true});  // drive 10 m, then arrive
  }
  segs.push_back({4.0, 0.0, 0.0, false});
  double yaw = 0.3, s = 0;
  Eigen::Vector3d p(0, 0, 0);
  // Terrain attitude: roll/pitch as smooth functions of distance driven.
  auto roll_of = [](double d) { return 0.04 * std::sin(0.3 * d); };
  auto pitch_of = [](double d) { return 0.06 * std::sin(0.2 * d + 0.5) - 0.02; };
  auto rot = [&](double d, double y) { return RotationFromRollPitchYaw(roll_of(d), pitch_of(d), y); };
  double t = 0;
  int site = 0;
  tr.events.push_back({t0, 0, SiteEventType::kArrived, 7});
  tr.site_truth.push_back(MakePose(rot(0, yaw), p));
  tr.site_distance.push_back(0);
  Eigen::Matrix3d R_prev_imu = rot(0, yaw);
  double wheel_reading = 0;
  int step = 0;
  auto record = [&](double time) {
    const int64_t utime = t0 + static_cast<int64_t>(std::llround(time * 1e6));
    const Eigen::Matrix3d R = rot(s, yaw);
    if (step % 10 == 0) {
      ImuSample im;
      im.utime = utime;
      im.angular_velocity = (step == 0 ? Eigen::Vector3d(Eigen::Vector3d::Zero()) : Eigen::Vector3d(LogSO3(R_prev_imu.transpose() * R) / 0.01)) +
                            Eigen::Vector3d::Constant(err.gyro_bias) +
                            err.gyro_noise * Eigen::Vector3d(n(rng), n(rng), n(rng));
      im.linear_acceleration = R.transpose() * Eigen::Vector3d(0, 0, kGravity);
      tr.imu.push_back(im);
      tr.truth.emplace_back(utime, MakePose(R, p));
      R_prev_imu = R;
    }
    if (step % 50 == 0) tr.wheel.push_back({utime, wheel_reading, 0.0});
  };
  record(0);
  for (const Seg& seg : segs) {
    const int steps = static_cast<int>(std::llround(seg.duration / dt_fine));
    for (int k = 0; k < steps; ++k) {
      // Smooth speed profile (sin^2 ramps) so accelerations stay tiny.
      const double phase = (k + 0.5) / steps;
      const double v = seg.speed * 2.0 * std::pow(std::sin(M_PI * phase), 2);
      const double yr = seg.yaw_rate * 2.0 * std::pow(std::sin(M_PI * phase), 2);
      // Midpoint integration of the body-x motion.
      const double ds = v * dt_fine;
      const Eigen::Matrix3d R_mid = rot(s + 0.5 * ds, yaw + 0.5 * yr * dt_fine);
      p += R_mid.col(0) * ds;
      s += ds;
      yaw += yr * dt_fine;
      wheel_reading += ds * err.wheel_scale;
      t += dt_fine;
      ++step;
      record(t);
      if (!tr.wheel.empty() && tr.wheel.back().utime == t0 + static_cast<int64_t>(std::llround(t * 1e6)))
        tr.wheel.back().speed = v;
    }
    if (seg.arrive_after) {
      ++site;
      const int64_t utime = t0 + static_cast<int64_t>(std::llround(t * 1e6)) + 1000;
      tr.events.push_back({utime, site, SiteEventType::kArrived, 7});
      tr.site_truth.push_back(MakePose(rot(s, yaw), p));
      tr.site_distance.push_back(s);
    }
  }
  return tr;
}

struct FeedResult {
  std::vector<PoseWithCovariance> sites;
  int periodic = 0;
  PoseWithCovariance final_pose;
};

// Feeds the streams merged in time order (wheel before IMU at equal times).
FeedResult Feed(DeadReckoning& dr, const Traverse& tr) {
  FeedResult run;
  size_t i = 0, w = 0, e = 0;
  while (i < tr.imu.size() || w < tr.wheel.size() || e < tr.events.size()) {
    const int64_t ti = i < tr.imu.size() ? tr.imu[i].utime : INT64_MAX;
    const int64_t tw = w < tr.wheel.size() ? tr.wheel[w].utime : INT64_MAX;
    const int64_t te = e < tr.events.size() ? tr.events[e].utime : INT64_MAX;
    if (te <= ti && te <= tw) {
      dr.AddSiteEvent(tr.events[e++]);
    } else if (tw <= ti) {
      dr.AddWheel(tr.wheel[w++]);
    } else {
      dr.AddImu(tr.imu[i++]);
    }
    while (dr.PopPeriodicPose()) ++run.periodic;
    for (const auto& [site, pose] : dr.PopSitePoses()) run.sites.push_back(pose);
  }
  run.final_pose = dr.Current();
  return run;
}

DeadReckoningOptions Options() {
  DeadReckoningOptions o;
  o.gravity_mps2 = kGravity;
  o.initial_yaw_rad = 0.3;
  return o;
}

double RotationError(const Pose3& a, const Pose3& b) { return LogSO3(a.linear() * b.linear().transpose()).norm(); }

TEST(DeadReckoning, DefaultOptionsPassCheck) {
  std::string error;
  EXPECT_TRUE(DeadReckoningOptions().Check(&error)) << error;
}

TEST(DeadReckoning, IdealSensorsReproduceTruth) {
  const Traverse tr = MakeTraverse({});
  DeadReckoning dr(Options());
  const FeedResult run = Feed(dr, tr);
  ASSERT_EQ(run.sites.size(), 4u);
  for (size_t k = 0; k < run.sites.size(); ++k) {
    // 30 m of 3-D driving: 20 Hz wheel samples with mid-interval attitude.
    EXPECT_LT((run.sites[k].pose.translation() - tr.site_truth[k].translation()).norm(), 1e-3) << "site " << k;
    EXPECT_LT(RotationError(run.sites[k].pose, tr.site_truth[k]), 1e-5) << "site " << k;
  }
  // 10 Hz of message time over ~364 s.
  const double duration = (tr.imu.back().utime - tr.imu.front().utime) * 1e-6;
  EXPECT_NEAR(run.periodic, duration / 0.1 + 1, 2);
  EXPECT_EQ(dr.stats().imu_dropped + dr.stats().wheel_dropped, 0);
  EXPECT_NEAR(dr.stats().distance_m, 30.0, 1e-6);
}

TEST(DeadReckoning, CovarianceGrowsWithDistanceAndTime) {
  const Traverse tr = MakeTraverse({});
  DeadReckoning dr(Options());
  const FeedResult run = Feed(dr, tr);
  double last_pos = 0, last_yaw = 0;
  for (size_t k = 1; k < run.sites.size(); ++k) {
    const double pos = std::sqrt(run.sites[k].covariance.block<3, 3>(0, 0).trace());
    const double yaw = std::sqrt(run.sites[k].covariance(5, 5));
    EXPECT_GT(pos, last_pos);
    EXPECT_GT(yaw, last_yaw);
    last_pos = pos;
    last_yaw = yaw;
  }
  // Along-track sigma ~ 12 % of 10 m after the first leg (plus heading and noise terms).
  const double first_leg = std::sqrt(run.sites[1].covariance.block<3, 3>(0, 0).trace());
  std::printf("site 1 position sigma %.3f m, yaw sigma %.5f rad\n", first_leg, std::sqrt(run.sites[1].covariance(5, 5)));
  EXPECT_GT(first_leg, 0.12 * 10.0);
  EXPECT_LT(first_leg, 0.16 * 10.0);
}

TEST(DeadReckoning, NoisySensorsDriftWithinCovariance) {
  // 5 % odometer over-read and a 3e-5 rad/s gyro bias (6 deg/h) with noise.
  SensorErrors err;
  err.wheel_scale = 1.05;
  err.gyro_bias = 3e-5;
  err.gyro_noise = 4.4e-4;  // 4.4e-5 rad/s/sqrt(Hz) at 100 Hz
  const Traverse tr = MakeTraverse(err);
  DeadReckoningOptions o = Options();
  o.gyro_bias_sigma = 3e-5;
  DeadReckoning dr(o);
  const FeedResult run = Feed(dr, tr);
  ASSERT_EQ(run.sites.size(), 4u);
  for (size_t k = 1; k < run.sites.size(); ++k) {
    const Eigen::Vector3d e = tr.site_truth[k].translation() - run.sites[k].pose.translation();
    const Eigen::Matrix3d P = run.sites[k].covariance.block<3, 3>(0, 0);
    const double nees = e.dot(P.ldlt().solve(e));
    EXPECT_LT(nees, 16.27) << "site " << k << " chi2(3) 99.9 %";
    // The 5 % scale error shows as drift of about 5 % of the distance.
    EXPECT_NEAR(e.norm() / tr.site_distance[k], 0.05, 0.02) << "site " << k;
  }
}

TEST(DeadReckoning, SurvivesDuplicatesReorderingAndGaps) {
  const Traverse clean = MakeTraverse({});
  Traverse tr = clean;
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  // Duplicate 3 % of IMU and wheel samples, swap 2 % of neighbouring IMU samples, drop a 2 s IMU block
  // while standing, duplicate one arrival.
  std::vector<ImuSample> imu;
  int duplicated_imu = 0, swapped = 0;
  for (size_t k = 0; k < tr.imu.size(); ++k) {
    const int64_t t = tr.imu[k].utime - tr.imu[0].utime;
    if (t > 1'000'000 && t < 3'000'000) continue;  // gap while standing at site 0
    imu.push_back(tr.imu[k]);
    if (u(rng) < 0.03) {
      imu.push_back(tr.imu[k]);
      ++duplicated_imu;
    }
  }
  for (size_t k = 1; k + 1 < imu.size(); k += 2) {
    if (u(rng) < 0.02) {
      std::swap(imu[k], imu[k + 1]);
      ++swapped;
    }
  }
  std::vector<WheelOdometrySample> wheel;
  int duplicated_wheel = 0;
  for (const auto& w : tr.wheel) {
    wheel.push_back(w);
    if (u(rng) < 0.03) {
      wheel.push_back(w);
      ++duplicated_wheel;
    }
  }
  tr.imu = imu;
  tr.wheel = wheel;
  tr.events.insert(tr.events.begin() + 2, tr.events[1]);
  DeadReckoning dr(Options());
  // Feed in the given (defective) order: merge by position, not by sorting.
  FeedResult run;
  size_t i = 0, w = 0, e = 0;
  while (i < tr.imu.size()) {
    while (w < tr.wheel.size() && tr.wheel[w].utime <= tr.imu[i].utime) dr.AddWheel(tr.wheel[w++]);
    while (e < tr.events.size() && tr.events[e].utime <= tr.imu[i].utime) dr.AddSiteEvent(tr.events[e++]);
    dr.AddImu(tr.imu[i++]);
    for (const auto& [site, pose] : dr.PopSitePoses()) run.sites.push_back(pose);
  }
  while (e < tr.events.size()) dr.AddSiteEvent(tr.events[e++]);
  for (const auto& [site, pose] : dr.PopSitePoses()) run.sites.push_back(pose);
  // A swap of a sample with its own duplicate costs one drop, not two.
  EXPECT_GE(dr.stats().imu_dropped, duplicated_imu);
  EXPECT_LE(dr.stats().imu_dropped, duplicated_imu + swapped);
  EXPECT_GT(swapped, 10);
  EXPECT_EQ(dr.stats().wheel_dropped, duplicated_wheel);
  EXPECT_EQ(dr.stats().imu_gaps, 1);
  EXPECT_EQ(dr.stats().site_events_dropped, 1);
  ASSERT_EQ(run.sites.size(), 4u);
  // Swapped samples lose ~20 ms of rotation each: small.
  EXPECT_LT((run.sites.back().pose.translation() - clean.site_truth.back().translation()).norm(), 0.05);
}

TEST(DeadReckoning, BackwardTimeJumpRestarts) {
  const Traverse tr = MakeTraverse({});
  DeadReckoning dr(Options());
  Feed(dr, tr);
  // The same log replayed again: time jumps back by the whole traverse.
  Traverse again = tr;
  again.events.clear();
  const FeedResult run = Feed(dr, again);
  EXPECT_EQ(dr.stats().resets, 1);
  EXPECT_LT((run.final_pose.pose.translation() - tr.site_truth.back().translation()).norm(), 1e-3);
}

TEST(DeadReckoning, StartPoseIsTakenOnlyBeforeMoving) {
  const Traverse tr = MakeTraverse({});
  DeadReckoningOptions o = Options();
  o.initial_yaw_rad = 0.0;  // wrong: the traverse starts at 0.3 rad
  DeadReckoning dr(o);
  dr.AddImu(tr.imu[0]);
  EXPECT_TRUE(dr.SetStartPose(MakePose(0, 0, 0, 0, 0, 0.3)));
  // Feed everything but the first IMU sample again (it is dropped as a duplicate).
  const FeedResult run = Feed(dr, tr);
  ASSERT_EQ(run.sites.size(), 4u);
  EXPECT_LT((run.sites.back().pose.translation() - tr.site_truth.back().translation()).norm(), 1e-3);
  EXPECT_FALSE(dr.SetStartPose(MakePose(1, 0, 0, 0, 0, 0)));
}

TEST(DeadReckoning, GravityUpdateCorrectsTilt) {
  // Start tilted wrongly (first sample not at rest), then stand still: roll/pitch converge to truth.
  DeadReckoning dr(Options());
  const Eigen::Matrix3d R = RotationFromRollPitchYaw(0.05, -0.08, 0.3);
  ImuSample first;
  first.utime = 1'000'000;
  first.linear_acceleration = Eigen::Vector3d(0.5, 0, 0.5);  // moving: not gravity-like
  dr.AddImu(first);
  for (int k = 1; k <= 300; ++k) {
    ImuSample s;
    s.utime = 1'000'000 + k * 10'000;
    s.linear_acceleration = R.transpose() * Eigen::Vector3d(0, 0, kGravity);
    dr.AddImu(s);
  }
  EXPECT_EQ(dr.stats().gravity_updates, 1);
  const Eigen::Vector3d rpy = RollPitchYawFromRotation(dr.Current().pose.linear());
  EXPECT_NEAR(rpy.x(), 0.05, 2e-3);
  EXPECT_NEAR(rpy.y(), -0.08, 2e-3);
}

// State a message can add is bounded (issue 30): the arrivals remembered to
// drop repeats are the newest site_window ids, and so are those waiting for
// attitude. Arrivals out of order within the window are still reported.
std::vector<int> SiteIds(DeadReckoning& dr) {
  std::vector<int> ids;
  for (const auto& [site, pose] : dr.PopSitePoses()) ids.push_back(site);
  return ids;
}

TEST(DeadReckoningSiteWindow, RepeatsAndArrivalsOlderThanTheWindowAreDropped) {
  Traverse tr = MakeTraverse({});
  DeadReckoningOptions o = Options();
  o.site_window = 3;
  DeadReckoning dr(o);
  const FeedResult run = Feed(dr, tr);  // sites 0..3: the window holds 1, 2, 3
  ASSERT_EQ(run.sites.size(), 4u);
  const int64_t t = tr.imu.back().utime;
  dr.AddSiteEvent({t, 2, SiteEventType::kArrived, 7});  // a repeat inside the window
  dr.AddSiteEvent({t, 0, SiteEventType::kArrived, 7});  // older than the window
  EXPECT_TRUE(SiteIds(dr).empty());
  EXPECT_EQ(dr.stats().site_events_dropped, 2);
  // Out of order but newer than the window's oldest: reported; then the window is 3, 5, 6.
  for (const int site : {6, 5}) dr.AddSiteEvent({t, site, SiteEventType::kArrived, 7});
  EXPECT_EQ(SiteIds(dr), (std::vector<int>{6, 5}));
  dr.AddSiteEvent({t, 4, SiteEventType::kArrived, 7});  // newer than 3: a first arrival
  EXPECT_EQ(SiteIds(dr), std::vector<int>{4});
  for (const int site : {3, 2, 5}) dr.AddSiteEvent({t, site, SiteEventType::kArrived, 7});
  EXPECT_TRUE(SiteIds(dr).empty());
  EXPECT_EQ(dr.stats().site_events_dropped, 5);
}

TEST(DeadReckoningSiteWindow, AFloodOfSiteIdsIsBoundedAndTheDefaultWindowKeepsANormalTraverse) {
  // The default window (1000) changes nothing for a traverse: every site reported, once.
  const Traverse tr = MakeTraverse({});
  DeadReckoning normal(Options());
  const FeedResult run = Feed(normal, tr);
  ASSERT_EQ(run.sites.size(), 4u);
  EXPECT_EQ(normal.stats().site_events_dropped, 0);
  // 20,000 new ids, each followed by the oldest id remembered: every new
  // one reported once, every repeat dropped.
  const int64_t t = tr.imu.back().utime;
  size_t reported = 0;
  for (int site = 4; site < 20'004; ++site) {
    normal.AddSiteEvent({t, site, SiteEventType::kArrived, 7});
    normal.AddSiteEvent({t, std::max(0, site - 999), SiteEventType::kArrived, 7});
    reported += SiteIds(normal).size();
  }
  EXPECT_EQ(reported, 20'000u);
  EXPECT_EQ(normal.stats().site_events_dropped, 20'000);
}

TEST(DeadReckoningSiteWindow, ArrivalsWaitingForAttitudeAreCapped) {
  Traverse tr = MakeTraverse({});
  tr.events.clear();
  DeadReckoningOptions o = Options();
  o.site_window = 3;
  DeadReckoning dr(o);
  // Ten arrivals before any IMU sample: the newest three wait.
  for (int site = 0; site < 10; ++site) dr.AddSiteEvent({tr.imu.front().utime, site, SiteEventType::kArrived, 7});
  EXPECT_TRUE(SiteIds(dr).empty());
  EXPECT_EQ(dr.stats().site_events_dropped, 7);
  std::vector<int> ids;
  size_t i = 0;
  while (ids.empty() && i < tr.imu.size()) {  // until the first stop aligns roll/pitch
    dr.AddImu(tr.imu[i++]);
    ids = SiteIds(dr);
  }
  EXPECT_EQ(ids, (std::vector<int>{7, 8, 9}));
}

}  // namespace
}  // namespace vloc
