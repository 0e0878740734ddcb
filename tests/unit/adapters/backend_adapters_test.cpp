// The rover back end's adapters in-process over MockTransport: what
// crosssite_ba, traverse_graph and dead_reckoning do with missing,
// repeated, out-of-order and bad inputs. crosssite_ba is fed tie-point sets
// with no pairs and no points: every adjustment fails and publishes the
// chained dead-reckoning pose, which shows where the chain took the previous
// site and the motion from.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "crosssite_ba_adapter.h"
#include "dead_reckoning_adapter.h"
#include "traverse_graph_adapter.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"

namespace vloc {
namespace {

bool Has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

template <class Msg>
Msg LastOf(const MockTransport& bus, const std::string& channel) {
  const std::vector<uint8_t>* bytes = bus.Last(channel);
  Msg msg;
  EXPECT_TRUE(bytes && Decode(bytes->data(), bytes->size(), &msg)) << "nothing decodable on " << channel;
  return msg;
}

PoseWithCovariance PoseAt(double x, double y = 0, double yaw = 0, int64_t utime = 0) {
  PoseWithCovariance p;
  p.utime = utime;
  p.pose = MakePose(x, y, 0, 0, 0, yaw);
  p.covariance = Eigen::Matrix<double, 6, 6>::Identity() * 0.01;
  return p;
}

void PublishDr(MockTransport& bus, int site, const PoseWithCovariance& pose) {
  Publish(bus, "SITE_POSE_DR", SitePoseToMessage(site, site_pose_t::SOURCE_DEAD_RECKONING, pose));
  bus.HandleAll();
}

// ---------------------------------------------------------------- crosssite_ba

struct Ba {
  MockTransport bus;
  CrossSiteBaAdapter adapter;
  explicit Ba(CrossSiteBaProcOptions options = Defaults())
      : adapter(bus, options, LoadOptionsFile<NavcamModel>("config/navcam.yaml")) {}
  static CrossSiteBaProcOptions Defaults() {
    CrossSiteBaProcOptions o;
    o.state_path = "";  // nothing written
    return o;
  }
  // A tie-point set previous -> current with no points, the poses the front end would send.
  localization_t Ties(int previous, int current, const PoseWithCovariance& previous_pose,
                      const PoseWithCovariance& current_dr) {
    TiePointSet set;
    set.utime = 1000 * current;
    set.previous_site_id = previous;
    set.current_site_id = current;
    set.previous_site_pose = previous_pose;
    set.current_site_pose_dr = current_dr;
    Publish(bus, "TIE_POINTS", TiePointsToMessage(set));
    bus.HandleAll();
    return LastOf<localization_t>(bus, "SITE_POSE_VISUAL");
  }
};

Eigen::Vector3d Position(const pose_t& m) { return PoseFromMessage(m).pose.translation(); }

TEST(CrossSiteBaAdapter, MotionComesFromSitePoseDrWhenBothSitesHaveIt) {
  Ba ba;
  PublishDr(ba.bus, 0, PoseAt(0));
  PublishDr(ba.bus, 1, PoseAt(10));
  const localization_t m = ba.Ties(0, 1, PoseAt(0), PoseAt(12));  // the message's DR says 12 m
  EXPECT_EQ(int(m.status), int(localization_t::STATUS_BAD_INPUT)) << m.message;  // no pairs, no points
  EXPECT_EQ(m.site_id, 1);
  EXPECT_EQ(m.reference_site_id, 0);
  EXPECT_TRUE(Position(m.pose).isApprox(Eigen::Vector3d(10, 0, 0), 1e-9)) << Position(m.pose).transpose();
  EXPECT_EQ(ba.adapter.failed(), 1);
}

TEST(CrossSiteBaAdapter, WithoutSitePoseDrTheMessagesMotionIsUsed) {
  Ba ba;
  PublishDr(ba.bus, 0, PoseAt(0));  // site 1's DR pose never came
  const localization_t m = ba.Ties(0, 1, PoseAt(0), PoseAt(12));
  EXPECT_TRUE(Position(m.pose).isApprox(Eigen::Vector3d(12, 0, 0), 1e-9)) << Position(m.pose).transpose();
}

TEST(CrossSiteBaAdapter, PreviousSiteIsHeldAtTheOwnEstimate) {
  for (const bool chain : {true, false}) {
    CrossSiteBaProcOptions o = Ba::Defaults();
    o.chain_previous = chain;
    Ba ba(o);
    ba.Ties(0, 1, PoseAt(0), PoseAt(10));  // estimate of site 1: (10, 0)
    // The message holds site 1 at 50 m (a front end that lost track), 10 m of motion.
    const localization_t m = ba.Ties(1, 2, PoseAt(50), PoseAt(60));
    const double expected_x = chain ? 20 : 60;
    EXPECT_NEAR(Position(m.pose).x(), expected_x, 1e-9) << "chain_previous " << chain;
  }
}

TEST(CrossSiteBaAdapter, RevisitTakesTheMessagesMotionAndKeepsTheSitesEstimate) {
  Ba ba;
  for (int site = 0; site < 4; ++site) PublishDr(ba.bus, site, PoseAt(10.0 * site));
  ba.Ties(0, 1, PoseAt(0), PoseAt(10));
  ba.Ties(1, 2, PoseAt(10), PoseAt(20));
  ba.Ties(2, 3, PoseAt(20), PoseAt(30));  // estimate of site 3: (30, 0)
  // The revisit 0 -> 3, predicted from the pose graph at 28 m: the message's
  // motion, not SITE_POSE_DR's 30 m.
  const localization_t revisit = ba.Ties(0, 3, PoseAt(0), PoseAt(28));
  EXPECT_NEAR(Position(revisit.pose).x(), 28, 1e-9);
  // Site 3 already had an estimate: the chain goes on from 30 m.
  PublishDr(ba.bus, 4, PoseAt(40));
  const localization_t next = ba.Ties(3, 4, PoseAt(30), PoseAt(40));
  EXPECT_NEAR(Position(next.pose).x(), 40, 1e-9);
}

TEST(CrossSiteBaAdapter, BadTiePointMessageIsAnsweredBadInputWithTheDrPose) {
  Ba ba;
  PublishDr(ba.bus, 1, PoseAt(10, 2));
  TiePointSet set;
  set.previous_site_id = 0;
  set.current_site_id = 1;
  set.previous_site_pose = PoseAt(0);
  set.current_site_pose_dr = PoseAt(12);
  TiePoint tp;
  tp.observations.push_back({SiteRole::kPrevious, 5, CameraSide::kLeft, {10, 10}, 0.5});  // pair 5 of 0 pairs
  set.points.push_back(tp);
  Publish(ba.bus, "TIE_POINTS", TiePointsToMessage(set));
  ba.bus.HandleAll();
  const localization_t m = LastOf<localization_t>(ba.bus, "SITE_POSE_VISUAL");
  EXPECT_EQ(int(m.status), int(localization_t::STATUS_BAD_INPUT));
  EXPECT_TRUE(Has(m.message, "tie-point message unusable: tie point")) << m.message;
  EXPECT_TRUE(Position(m.pose).isApprox(Eigen::Vector3d(10, 2, 0), 1e-9)) << "SITE_POSE_DR of site 1";
  EXPECT_EQ(ba.adapter.failed(), 1);
}

TEST(CrossSiteBaAdapter, NegativeSiteIdIsRejectedAndSiteZeroAgainStartsANewTraverse) {
  Ba ba;
  PublishDr(ba.bus, -3, PoseAt(0));
  EXPECT_TRUE(Has(ba.adapter.StatusLine(), "rejected 1")) << ba.adapter.StatusLine();
  PublishDr(ba.bus, 0, PoseAt(0));
  PublishDr(ba.bus, 1, PoseAt(10));
  ba.Ties(0, 1, PoseAt(0), PoseAt(10));
  // A new traverse: site 0 again, elsewhere. Site 1's old DR pose must not be used.
  PublishDr(ba.bus, 0, PoseAt(100));
  EXPECT_TRUE(Has(ba.adapter.StatusLine(), "poses kept for 1 DR / 0 estimated sites")) << ba.adapter.StatusLine();
  const localization_t m = ba.Ties(0, 1, PoseAt(100), PoseAt(105));
  EXPECT_NEAR(Position(m.pose).x(), 105, 1e-9);
}

TEST(CrossSiteBaAdapter, OnlyTheNewestSiteWindowSitesAreKept) {
  CrossSiteBaProcOptions o = Ba::Defaults();
  o.site_window = 2;
  Ba ba(o);
  for (int site = 0; site < 5; ++site) PublishDr(ba.bus, site, PoseAt(10.0 * site));
  EXPECT_TRUE(Has(ba.adapter.StatusLine(), "poses kept for 2 DR")) << ba.adapter.StatusLine();
  // Sites 1 and 2 are out of the window: the message's motion (12 m) stands.
  EXPECT_NEAR(Position(ba.Ties(1, 2, PoseAt(10), PoseAt(22)).pose).x(), 22, 1e-9);
}

// -------------------------------------------------------------- traverse_graph

struct Graph {
  MockTransport bus;
  TraverseGraphAdapter adapter;
  Graph() : adapter(bus, TraverseGraphProcOptions{}) {}
  void Visual(int reference, int site, int8_t status, const PoseWithCovariance& relative) {
    localization_t m;
    m.utime = 1000 * site;
    m.site_id = site;
    m.reference_site_id = reference;
    m.status = status;
    m.message = "test";
    m.pose = PoseToMessage(relative, "world", "body");
    m.relative_pose = PoseToMessage(relative, "site", "site");
    m.condition_number = 1;
    Publish(bus, "SITE_POSE_VISUAL", m);
    bus.HandleAll();
  }
  traverse_t Last() const { return LastOf<traverse_t>(bus, "TRAVERSE"); }
};

TEST(TraverseGraphAdapter, EveryDrPosePublishesTheTraverse) {
  Graph g;
  for (int site = 0; site < 3; ++site) PublishDr(g.bus, site, PoseAt(10.0 * site, 0, 0, 1000000 * (site + 1)));
  EXPECT_EQ(g.bus.Count("TRAVERSE"), 3);
  const traverse_t t = g.Last();
  ASSERT_EQ(t.num_sites, 3);
  EXPECT_EQ(t.site_ids[2], 2);
  EXPECT_NEAR(PoseFromMessage(t.poses[2]).pose.translation().x(), 20, 1e-6);
  EXPECT_EQ(t.num_visual_edges, 0);
}

TEST(TraverseGraphAdapter, FailedBaResultIsSkipped) {
  Graph g;
  PublishDr(g.bus, 0, PoseAt(0));
  PublishDr(g.bus, 1, PoseAt(10));
  g.Visual(0, 1, localization_t::STATUS_TOO_FEW_POINTS, PoseAt(9));
  EXPECT_EQ(g.bus.Count("TRAVERSE"), 2) << "no update for a failed adjustment";
  EXPECT_TRUE(Has(g.adapter.StatusLine(), "1 failed BA results skipped")) << g.adapter.StatusLine();
}

// A BA result before its site's DR pose places the site from the reference;
// a repeated result for the same pair replaces the edge.
TEST(TraverseGraphAdapter, VisualEdgeBeforeTheSitesDrPosePlacesTheSite) {
  Graph g;
  PublishDr(g.bus, 0, PoseAt(0));
  g.Visual(0, 1, localization_t::STATUS_OK, PoseAt(9.5));
  ASSERT_EQ(g.bus.Count("TRAVERSE"), 2);
  ASSERT_EQ(g.Last().num_sites, 2);
  EXPECT_NEAR(PoseFromMessage(g.Last().poses[1]).pose.translation().x(), 9.5, 1e-6);
  EXPECT_EQ(g.Last().num_visual_edges, 1);
  g.Visual(0, 1, localization_t::STATUS_OK, PoseAt(9.6));  // the same pair again
  EXPECT_EQ(g.Last().num_visual_edges, 1) << "a repeated result replaces the edge";
  PublishDr(g.bus, 1, PoseAt(10));
  EXPECT_EQ(g.Last().num_sites, 2);
  EXPECT_EQ(g.Last().num_visual_edges, 1);
}

// A BA result whose reference site is not in the graph waits (no update)
// and joins when that site's DR pose comes.
TEST(TraverseGraphAdapter, VisualEdgeBeforeItsReferenceSiteWaits) {
  Graph g;
  PublishDr(g.bus, 1, PoseAt(10));
  const int before = g.bus.Count("TRAVERSE");
  g.Visual(0, 1, localization_t::STATUS_OK, PoseAt(9.5));
  EXPECT_EQ(g.bus.Count("TRAVERSE"), before) << "pending: nothing to optimise yet";
  EXPECT_TRUE(Has(g.adapter.StatusLine(), "0 measurements rejected")) << g.adapter.StatusLine();
  PublishDr(g.bus, 0, PoseAt(0));
  EXPECT_EQ(g.Last().num_sites, 2);
  EXPECT_EQ(g.Last().num_visual_edges, 1);
}

TEST(TraverseGraphAdapter, SiteZeroAgainStartsANewGraph) {
  Graph g;
  for (int site = 0; site < 3; ++site) PublishDr(g.bus, site, PoseAt(10.0 * site));
  PublishDr(g.bus, 0, PoseAt(100));
  EXPECT_EQ(g.Last().num_sites, 1);
  EXPECT_EQ(g.adapter.graph().num_sites(), 1);
}

// -------------------------------------------------------------- dead_reckoning

struct Dr {
  MockTransport bus;
  DeadReckoningAdapter adapter;
  std::vector<site_pose_t> site_poses;
  explicit Dr(DeadReckoningProcOptions options = {}) : adapter(bus, options) {
    Subscribe<site_pose_t>(bus, "SITE_POSE_DR",
                           [this](const std::string&, const site_pose_t& m) { site_poses.push_back(m); });
  }
  // The rover standing still: IMU at 100 Hz (gravity up, no rotation) and
  // its wheels at 10 Hz, from `from_s` to `to_s` of message time.
  void StandStill(double from_s, double to_s) {
    for (int i = static_cast<int>(from_s * 100); i < static_cast<int>(to_s * 100); ++i) {
      ImuSample imu;
      imu.utime = 10000LL * i;
      imu.linear_acceleration = Eigen::Vector3d(0, 0, 1.62);
      Publish(bus, "IMU", ImuToMessage(imu));
      if (i % 10 == 0) {
        WheelOdometrySample wheel;
        wheel.utime = imu.utime;
        Publish(bus, "WHEEL_ODOM", WheelOdometryToMessage(wheel));
      }
    }
    bus.HandleAll();
  }
  void Arrived(int site, double t_s) {
    SiteEvent e;
    e.utime = static_cast<int64_t>(t_s * 1e6);
    e.site_id = site;
    e.event = SiteEventType::kArrived;
    Publish(bus, "ROVER_SITE", SiteEventToMessage(e));
    bus.HandleAll();
  }
};

TEST(DeadReckoningAdapter, ArrivalBeforeAnyImuWaitsForAttitudeThenPublishesOnce) {
  Dr dr;
  dr.Arrived(0, 0.0);
  EXPECT_TRUE(dr.site_poses.empty()) << "no attitude yet";
  dr.StandStill(0.0, 1.0);
  EXPECT_TRUE(dr.site_poses.empty()) << "1 s of standing still is not yet attitude (settle 0.5 s + 1 s)";
  dr.StandStill(1.0, 2.0);
  ASSERT_EQ(dr.site_poses.size(), 1u);
  EXPECT_EQ(dr.site_poses[0].site_id, 0);
  EXPECT_EQ(int(dr.site_poses[0].source), int(site_pose_t::SOURCE_DEAD_RECKONING));
  dr.Arrived(0, 2.0);  // a repeated arrival
  EXPECT_EQ(dr.site_poses.size(), 1u);
  EXPECT_EQ(dr.adapter.estimator().stats().site_events_dropped, 1);
  dr.Arrived(1, 2.0);
  ASSERT_EQ(dr.site_poses.size(), 2u);
  EXPECT_EQ(dr.site_poses[1].site_id, 1);
  EXPECT_EQ(dr.adapter.published_sites(), 2);
}

TEST(DeadReckoningAdapter, PosesArePublishedEveryPeriodOfMessageTime) {
  DeadReckoningProcOptions o;
  o.dead_reckoning.publish_period_s = 0.1;
  Dr dr(o);
  dr.StandStill(0.0, 2.0);
  EXPECT_NEAR(dr.adapter.published_poses(), 20, 2);
  EXPECT_EQ(dr.bus.Count("DR_POSE"), dr.adapter.published_poses());
}

TEST(DeadReckoningAdapter, StartPoseIsTakenFromSiteZeroOnly) {
  DeadReckoningProcOptions o;
  o.start_pose_channel = "SITE_POSE_GT";
  Dr dr(o);
  Publish(dr.bus, "SITE_POSE_GT", SitePoseToMessage(3, site_pose_t::SOURCE_GROUND_TRUTH, PoseAt(50, 50)));
  Publish(dr.bus, "SITE_POSE_GT", SitePoseToMessage(0, site_pose_t::SOURCE_GROUND_TRUTH, PoseAt(5, 6)));
  Publish(dr.bus, "SITE_POSE_GT", SitePoseToMessage(0, site_pose_t::SOURCE_GROUND_TRUTH, PoseAt(7, 8)));
  dr.bus.HandleAll();
  dr.StandStill(0.0, 2.0);
  dr.Arrived(0, 2.0);
  ASSERT_EQ(dr.site_poses.size(), 1u);
  const Eigen::Vector3d p = Position(dr.site_poses[0].pose);
  EXPECT_NEAR(p.x(), 5, 1e-6);
  EXPECT_NEAR(p.y(), 6, 1e-6);
}

}  // namespace
}  // namespace vloc
