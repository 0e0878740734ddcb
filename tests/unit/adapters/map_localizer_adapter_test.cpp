// map_localizer's adapter in-process over MockTransport: which sites it
// localises (a whole panorama and a prior pose), what it skips, replaces,
// ignores and drops. Textureless pairs over a featureless map: every site
// tried ends "no fix", counted in StatusLine; the test looks at the counts.
#include <gtest/gtest.h>

#include <string>

#include "map_localizer_adapter.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/testing/rover_inputs.h"

namespace vloc {
namespace {

// A flat grey map, 40 x 40 m at 0.2 m/px, around the origin.
maploc::MapRaster FlatMap() {
  maploc::MapRaster map;
  map.gray = cv::Mat(200, 200, CV_32F, cv::Scalar(100));
  map.valid = cv::Mat(200, 200, CV_8U, cv::Scalar(255));
  map.x_min = -20;
  map.y_max = 20;
  map.m_per_px = 0.2;
  return map;
}

struct Localizer {
  MockTransport bus;
  MapLocalizerAdapter adapter;
  explicit Localizer(const MapLocalizerProcOptions& options)
      : adapter(bus, options, LoadOptionsFile<NavcamModel>("config/navcam.yaml"), FlatMap()) {}
  static MapLocalizerProcOptions Defaults() {
    MapLocalizerProcOptions o;
    o.reload_map_on_change = false;
    return o;
  }
  void Pair(int site, int k, int num_pairs = 3) {
    StereoPair p = testing::TexturelessPair(site, k);
    p.num_pairs = num_pairs;
    Publish(bus, "NAVCAM_STEREO", StereoPairToMessage(p, ImageEncoding::kGray8));
    bus.HandleAll();
  }
  void Dr(int site) {
    PoseWithCovariance pose;
    pose.pose = MakePose(2.0 * site, 0, 0, 0, 0, 0);
    pose.covariance = Eigen::Matrix<double, 6, 6>::Identity() * 0.25;
    Publish(bus, "SITE_POSE_DR", SitePoseToMessage(site, site_pose_t::SOURCE_DEAD_RECKONING, pose));
    bus.HandleAll();
  }
  // StatusLine has "<count> <what>".
  bool Says(const std::string& part) const { return adapter.StatusLine().find(part) != std::string::npos; }
};

TEST(MapLocalizerAdapter, SiteIsTriedOnlyWithItsWholePanoramaAndAPrior) {
  Localizer l(Localizer::Defaults());
  l.Pair(0, 0);
  l.Pair(0, 1);
  l.Pair(0, 1);  // a repeat replaces its copy: still 2 of 3
  l.Dr(0);
  EXPECT_TRUE(l.Says("0 sites without a fix")) << l.adapter.StatusLine();
  EXPECT_TRUE(l.Says("1 repeated pairs replaced")) << l.adapter.StatusLine();
  l.Pair(0, 2);
  EXPECT_TRUE(l.Says("0 fixes, 1 sites without a fix")) << l.adapter.StatusLine();
  EXPECT_EQ(l.bus.Count("SITE_POSE_FIX"), 0);
  // A pair of the site after it was tried is ignored.
  l.Pair(0, 1);
  EXPECT_TRUE(l.Says("1 pairs of localised sites ignored")) << l.adapter.StatusLine();
  EXPECT_TRUE(l.Says("1 sites without a fix")) << l.adapter.StatusLine();
}

TEST(MapLocalizerAdapter, ImplausiblePairsAreSkipped) {
  MapLocalizerProcOptions o = Localizer::Defaults();
  o.max_pairs_per_site = 4;
  Localizer l(o);
  l.Pair(0, 3, 3);  // pair_index beyond num_pairs
  l.Pair(0, 0, 5);  // more pairs than max_pairs_per_site
  l.Pair(0, 0, 3);
  l.Pair(0, 1, 2);  // disagrees with the site's earlier pair (3)
  EXPECT_TRUE(l.Says("3 implausible pairs skipped")) << l.adapter.StatusLine();
  l.Pair(0, 1, 3);
  l.Pair(0, 2, 3);
  l.Dr(0);
  EXPECT_TRUE(l.Says("1 sites without a fix")) << l.adapter.StatusLine();
}

TEST(MapLocalizerAdapter, OnlySitesEveryFixEveryAreTried) {
  MapLocalizerProcOptions o = Localizer::Defaults();
  o.fix_every = 2;
  Localizer l(o);
  for (int site : {1, 2}) {
    l.Dr(site);
    for (int k = 0; k < 3; ++k) l.Pair(site, k);
  }
  EXPECT_TRUE(l.Says("1 sites without a fix")) << "site 2 only: " << l.adapter.StatusLine();
  EXPECT_TRUE(l.Says("poses kept for 0 graph / 1 DR sites of 2 received")) << l.adapter.StatusLine();
}

TEST(MapLocalizerAdapter, BeyondMaxSitesWaitingTheOldestIsDropped) {
  MapLocalizerProcOptions o = Localizer::Defaults();
  o.max_sites_waiting = 2;
  Localizer l(o);
  l.Pair(0, 0);  // one pair each: none completes
  l.Pair(1, 0);
  EXPECT_TRUE(l.Says("0 waiting sites dropped")) << l.adapter.StatusLine();
  l.Pair(2, 0);
  EXPECT_TRUE(l.Says("1 waiting sites dropped")) << l.adapter.StatusLine();
  l.Pair(3, 0);  // pushes out site 1
  EXPECT_TRUE(l.Says("2 waiting sites dropped")) << l.adapter.StatusLine();
}

}  // namespace
}  // namespace vloc
