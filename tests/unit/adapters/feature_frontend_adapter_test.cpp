// The feature front end's policy, in-process over MockTransport (no process,
// no LCM): which sites are matched, what is dropped and reported
// MISSING_INPUT, what is refused. Textureless 1024 x 1024 pairs
// (testing::TexturelessPair): every match answers LOW_TEXTURE quickly, and
// the test looks only at which site pairs the front end ran on.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "frontend_adapter.h"
#include "vloc/common/options.h"
#include "vloc/frontend_status_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/testing/rover_inputs.h"

namespace vloc {
namespace {

FeatureFrontendProcOptions Options() {
  auto o = LoadOptionsFile<FeatureFrontendProcOptions>("config/procs/feature_frontend.yaml");
  o.loop_max_distance_m = 0;  // revisits off unless a test turns them on
  o.traverse_channel = "";
  return o;
}

// The adapter on a MockTransport, the messages it receives, and every
// FRONTEND_STATUS it publishes, in order.
struct Frontend {
  MockTransport bus;
  FeatureFrontendAdapter adapter;
  std::vector<frontend_status_t> statuses;

  explicit Frontend(const FeatureFrontendProcOptions& options) : adapter(options, bus) {
    adapter.Subscribe();
    Subscribe<frontend_status_t>(bus, "FRONTEND_STATUS",
                                 [this](const std::string&, const frontend_status_t& m) { statuses.push_back(m); });
  }
  // Pair k of `site`, saying the site has `num_pairs`.
  void Pair(int site, int k, int num_pairs = 3) {
    StereoPair p = testing::TexturelessPair(site, k);
    p.num_pairs = num_pairs;
    Publish(bus, "NAVCAM_STEREO", StereoPairToMessage(p, ImageEncoding::kGray8));
    bus.HandleAll();
  }
  // The dead-reckoning pose of `site` at (x, y).
  void Dr(int site, double x, double y = 0) {
    PoseWithCovariance pose;
    pose.pose = MakePose(x, y, 0, 0, 0, 0);
    pose.covariance = Eigen::Matrix<double, 6, 6>::Identity() * 0.01;
    Publish(bus, "SITE_POSE_DR", SitePoseToMessage(site, site_pose_t::SOURCE_DEAD_RECKONING, pose));
    bus.HandleAll();
  }
  void Dr(int site) { Dr(site, 10.0 * site); }
  void ImagingDone(int site, int num_pairs) {
    SiteEvent e;
    e.utime = 1000000LL * (site * 10 + 9);
    e.site_id = site;
    e.event = SiteEventType::kImagingDone;
    e.num_pairs = num_pairs;
    Publish(bus, "ROVER_SITE", SiteEventToMessage(e));
    bus.HandleAll();
  }
  // A whole site: DR pose and 3 pairs.
  void Site(int site) {
    Dr(site);
    for (int k = 0; k < 3; ++k) Pair(site, k);
  }
};

// The status is for the site pair previous -> current.
void ExpectSites(const frontend_status_t& status, int previous, int current) {
  EXPECT_EQ(status.previous_site_id, previous) << status.message;
  EXPECT_EQ(status.current_site_id, current) << status.message;
}

bool Has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(FeatureFrontendAdapter, SiteIsMatchedOnlyWhenAllPairsAndItsDrPoseAreThere) {
  Frontend f(Options());
  f.Site(0);
  EXPECT_TRUE(f.statuses.empty()) << "the first site has nothing to be matched with";
  ASSERT_EQ(f.adapter.previous_site_id(), 0);
  // Site 1: two of its three pairs, then the third, and only then its DR pose.
  f.Pair(1, 0);
  f.Pair(1, 1);
  f.Pair(1, 0);  // a repeated pair replaces its copy: still 2 of 3
  EXPECT_TRUE(f.statuses.empty());
  f.Pair(1, 2);
  EXPECT_TRUE(f.statuses.empty()) << "all pairs, but no dead-reckoning pose yet";
  f.Dr(1);
  ASSERT_EQ(f.statuses.size(), 1u);
  ExpectSites(f.statuses[0], 0, 1);
  EXPECT_EQ(int(f.statuses[0].status), int(frontend_status_t::STATUS_LOW_TEXTURE)) << f.statuses[0].message;
  EXPECT_EQ(f.adapter.sites_processed(), 1);
  EXPECT_EQ(f.adapter.sites_dropped(), 0);
  // A pair of site 1 arriving after it was matched is ignored.
  f.Pair(1, 1);
  EXPECT_EQ(f.statuses.size(), 1u);
  EXPECT_EQ(f.bus.Count("TIE_POINTS"), 0) << "LOW_TEXTURE is not usable: no tie points";
}

TEST(FeatureFrontendAdapter, SiteMissingAPairIsDroppedWhenALaterSiteIsComplete) {
  Frontend f(Options());
  f.Site(0);
  f.Dr(1);
  f.Pair(1, 0);
  f.Pair(1, 2);
  EXPECT_TRUE(f.statuses.empty()) << "pair 1 may still come";
  f.Site(2);
  ASSERT_EQ(f.statuses.size(), 2u);
  const frontend_status_t& dropped = f.statuses[0];
  EXPECT_EQ(int(dropped.status), int(frontend_status_t::STATUS_MISSING_INPUT));
  ExpectSites(dropped, 0, 1);
  EXPECT_TRUE(Has(dropped.message, "2 of 3 pairs (missing 1), with dead-reckoning pose")) << dropped.message;
  EXPECT_TRUE(Has(dropped.message, "incomplete while site 2 is complete")) << dropped.message;
  // Site 2 is matched against site 0, the last site processed.
  ExpectSites(f.statuses[1], 0, 2);
  EXPECT_EQ(f.adapter.sites_dropped(), 1);
  EXPECT_EQ(f.adapter.sites_processed(), 1);
}

TEST(FeatureFrontendAdapter, SiteWithoutDrPoseIsDroppedWhenALaterSiteIsComplete) {
  Frontend f(Options());
  f.Site(0);
  for (int k = 0; k < 3; ++k) f.Pair(1, k);
  f.ImagingDone(1, 3);
  EXPECT_TRUE(f.statuses.empty()) << "the DR pose may still come";
  f.Site(2);
  ASSERT_EQ(f.statuses.size(), 2u);
  EXPECT_EQ(int(f.statuses[0].status), int(frontend_status_t::STATUS_MISSING_INPUT));
  EXPECT_EQ(f.statuses[0].current_site_id, 1);
  EXPECT_TRUE(Has(f.statuses[0].message, "3 of 3 pairs, no dead-reckoning pose")) << f.statuses[0].message;
  EXPECT_EQ(f.statuses[1].current_site_id, 2);
}

TEST(FeatureFrontendAdapter, ImagingDoneWithoutAnyImageIsDroppedWhenTheNextSiteBegins) {
  Frontend f(Options());
  f.Site(0);
  f.Dr(1);
  f.ImagingDone(1, 3);
  EXPECT_TRUE(f.statuses.empty()) << "its images may still be on their way";
  f.Dr(2);  // the rover reached site 2
  ASSERT_EQ(f.statuses.size(), 1u);
  EXPECT_EQ(int(f.statuses[0].status), int(frontend_status_t::STATUS_MISSING_INPUT));
  EXPECT_EQ(f.statuses[0].current_site_id, 1);
  EXPECT_TRUE(Has(f.statuses[0].message, "0 of 3 pairs (missing 0, 1, 2)")) << f.statuses[0].message;
  EXPECT_TRUE(Has(f.statuses[0].message, "none of its images arrived before site 2 began")) << f.statuses[0].message;
}

// IMAGING_DONE closes a site: with its DR pose and at least one pair it is
// matched with what arrived (not dropped).
TEST(FeatureFrontendAdapter, ImagingDoneWithAPairMissingIsMatchedWithWhatArrived) {
  Frontend f(Options());
  f.Site(0);
  f.Dr(1);
  f.Pair(1, 0);
  f.Pair(1, 1);
  EXPECT_TRUE(f.statuses.empty());
  f.ImagingDone(1, 3);
  ASSERT_EQ(f.statuses.size(), 1u);
  EXPECT_NE(int(f.statuses[0].status), int(frontend_status_t::STATUS_MISSING_INPUT)) << f.statuses[0].message;
  EXPECT_EQ(f.statuses[0].current_site_id, 1);
  EXPECT_EQ(f.adapter.sites_processed(), 1);
  EXPECT_EQ(f.adapter.sites_dropped(), 0);
}

TEST(FeatureFrontendAdapter, PairsBeyondMaxPairsPerSiteAreRefused) {
  FeatureFrontendProcOptions o = Options();
  o.max_pairs_per_site = 4;
  Frontend f(o);
  f.Site(0);
  f.Dr(1);
  f.Pair(1, 0, /*num_pairs=*/5);  // refused: the handler rejects it
  EXPECT_TRUE(Has(f.adapter.StatusLine(), "rejected 1")) << f.adapter.StatusLine();
  // IMAGING_DONE's count is capped at max_pairs_per_site: site 1 waits for 4 pairs, not 40.
  f.ImagingDone(1, 40);
  f.Dr(2);
  ASSERT_EQ(f.statuses.size(), 1u);
  EXPECT_EQ(f.statuses[0].current_site_id, 1);
  EXPECT_TRUE(Has(f.statuses[0].message, "0 of 4 pairs (missing 0, 1, 2, 3)")) << f.statuses[0].message;
}

TEST(FeatureFrontendAdapter, BeyondMaxSitesCollectingTheOldestGoes) {
  FeatureFrontendProcOptions o = Options();
  o.max_sites_collecting = 2;
  Frontend f(o);
  f.Site(0);
  f.Pair(1, 0);  // sites 1..3 each get one pair of three: none completes
  f.Pair(2, 0);
  EXPECT_TRUE(f.statuses.empty()) << "two sites may wait";
  f.Pair(3, 0);
  ASSERT_EQ(f.statuses.size(), 1u);
  EXPECT_EQ(int(f.statuses[0].status), int(frontend_status_t::STATUS_MISSING_INPUT));
  EXPECT_EQ(f.statuses[0].current_site_id, 1);
  EXPECT_TRUE(Has(f.statuses[0].message, "too many sites wait")) << f.statuses[0].message;
  f.Pair(4, 0);
  ASSERT_EQ(f.statuses.size(), 2u);
  EXPECT_EQ(f.statuses[1].current_site_id, 2);
  EXPECT_EQ(f.adapter.sites_dropped(), 2);
}

// Revisits on: a site back within loop_max_distance_m of a site at least
// loop_min_site_gap ids earlier is also matched against it (poses from dead
// reckoning while no TRAVERSE came).
TEST(FeatureFrontendAdapter, RevisitIsMatchedAgainstTheEarlierSite) {
  FeatureFrontendProcOptions o = Options();
  o.loop_max_distance_m = 6.0;
  o.loop_min_site_gap = 3;
  Frontend f(o);
  const double xy[4][2] = {{0, 0}, {10, 0}, {10, 10}, {2, 1}};  // site 3 is 2.2 m from site 0
  for (int site = 0; site < 4; ++site) {
    f.Dr(site, xy[site][0], xy[site][1]);
    for (int k = 0; k < 3; ++k) f.Pair(site, k);
  }
  ASSERT_EQ(f.statuses.size(), 4u);  // 0->1, 1->2, 2->3, and the revisit 0->3
  ExpectSites(f.statuses[2], 2, 3);
  ExpectSites(f.statuses[3], 0, 3);
  EXPECT_EQ(f.adapter.loops_tried(), 1);
  EXPECT_EQ(f.adapter.sites_processed(), 3);
}

TEST(FeatureFrontendAdapter, ManualTiesForSitesNoLongerKeptAnswerMissingInput) {
  Frontend f(Options());
  f.Site(0);
  f.Site(1);
  f.Site(2);
  ASSERT_EQ(f.statuses.size(), 2u);
  f.adapter.OnManualTies(0, 2, {}, 123);  // site 0's images went when site 2 came (revisits off)
  ASSERT_EQ(f.statuses.size(), 2u);       // published, delivered on the next HandleAll
  f.bus.HandleAll();
  ASSERT_EQ(f.statuses.size(), 3u);
  EXPECT_EQ(int(f.statuses[2].status), int(frontend_status_t::STATUS_MISSING_INPUT));
  EXPECT_TRUE(Has(f.statuses[2].message, "the images of site 0 are no longer kept")) << f.statuses[2].message;
}

}  // namespace
}  // namespace vloc
