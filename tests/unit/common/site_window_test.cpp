// KeepNewestSites: a map or set keyed by site id keeps its newest (highest)
// ids, whatever order and however many ids arrive.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "vloc/common/site_window.h"

namespace vloc {
namespace {

TEST(KeepNewestSites, KeepsTheHighestIdsOfAMap) {
  std::map<int, std::string> by_site;
  for (int site = 0; site < 10; ++site) {
    by_site[site] = "pose " + std::to_string(site);
    KeepNewestSites(&by_site, 3);
    EXPECT_LE(by_site.size(), 3u);
  }
  ASSERT_EQ(by_site.size(), 3u);
  EXPECT_EQ(by_site.begin()->first, 7);
  EXPECT_EQ(by_site.rbegin()->second, "pose 9");
}

TEST(KeepNewestSites, AFloodOfShuffledIdsStaysBoundedAndReportsWhatWentOut) {
  std::vector<int> ids(100000);
  for (int i = 0; i < static_cast<int>(ids.size()); ++i) ids[static_cast<size_t>(i)] = i;
  std::shuffle(ids.begin(), ids.end(), std::mt19937(3));
  std::set<int> seen;
  size_t erased = 0;
  for (int id : ids) {
    seen.insert(id);
    erased += KeepNewestSites(&seen, 64);
  }
  EXPECT_EQ(seen.size(), 64u);
  EXPECT_EQ(erased, ids.size() - 64);
  EXPECT_EQ(*seen.begin(), 100000 - 64);
}

TEST(KeepNewestSites, ASmallMapIsLeftAlone) {
  std::map<int, int> by_site{{5, 1}, {2, 2}};
  EXPECT_EQ(KeepNewestSites(&by_site, 2), 0u);
  EXPECT_EQ(by_site.size(), 2u);
  EXPECT_EQ(KeepNewestSites(&by_site, 0), 2u);
  EXPECT_TRUE(by_site.empty());
}

}  // namespace
}  // namespace vloc
