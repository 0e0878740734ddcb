// A Navcam manifest's pair indices: a site's num_pairs is its number of rows,
// so an index at or beyond that count (pair 99 of a site of 6 rows), or a
// repeated one, would be rejected by every consumer; the reader refuses the
// row in one line naming its line in the file, and keeps the rest.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "driver_fixtures.h"
#include "navcam_manifest.h"

namespace vloc {
namespace {

int CountContaining(const std::vector<std::string>& lines, const std::string& text) {
  int n = 0;
  for (const auto& l : lines) n += l.find(text) != std::string::npos;
  return n;
}

std::string Join(const std::vector<std::string>& lines) {
  std::string s;
  for (const auto& l : lines) s += l + "\n";
  return s;
}

// Writes `rows` ("site pair" per row, one second apart) with one image pair for all.
std::string WriteManifest(const std::string& dir, const std::vector<std::pair<int, int>>& rows) {
  cv::imwrite(dir + "/L.png", testing::FixtureImage(10));
  cv::imwrite(dir + "/R.png", testing::FixtureImage(11));
  std::ofstream f(dir + "/manifest.yaml");
  f << "angle_unit: deg\npairs:\n";
  double t = 100;
  for (const auto& [site, pair] : rows)
    f << "  - {site: " << site << ", pair: " << pair << ", pan: 0, tilt: 20, time: " << t++
      << ", left: L.png, right: R.png}\n";
  return dir + "/manifest.yaml";
}

TEST(NavcamManifestPairs, APairIndexBeyondTheSitesRowsIsRefusedNamingItsLine) {
  const std::string dir = testing::MakeFixtureDir("pair99");
  // Site 0: pairs 0..4 and 99 (6 rows, row 6 on line 8).
  const NavcamManifest m = ReadNavcamManifest(WriteManifest(dir, {{0, 0}, {0, 1}, {0, 2}, {0, 3}, {0, 4}, {0, 99}}));
  ASSERT_TRUE(m.readable);
  ASSERT_EQ(m.problems.size(), 1u) << Join(m.problems);
  EXPECT_EQ(CountContaining(m.problems, "manifest.yaml line 8, row 6 (site 0 pair 99): pair index 99 is not below "
                                        "num_pairs 6"),
            1)
      << Join(m.problems);
  ASSERT_EQ(m.entries.size(), 5u);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(m.entries[static_cast<size_t>(i)].pair_index, i);
  std::filesystem::remove_all(dir);
}

TEST(NavcamManifestPairs, RepeatedAndCascadingIndicesAreRefusedUntilEveryIndexFits) {
  const std::string dir = testing::MakeFixtureDir("pair_repeat");
  // Site 1: pair 0 twice (the second refused). Site 2: pairs 0, 5, 2 (3 rows): 5 is refused, then
  // 2 no longer fits the 2 rows left. Site 3: pair 70 of its 1 row.
  const NavcamManifest m =
      ReadNavcamManifest(WriteManifest(dir, {{1, 0}, {1, 0}, {1, 1}, {2, 0}, {2, 5}, {2, 2}, {3, 70}}));
  ASSERT_TRUE(m.readable);
  EXPECT_EQ(m.problems.size(), 4u) << Join(m.problems);
  EXPECT_EQ(CountContaining(m.problems, "line 4, row 2 (site 1 pair 0): pair index 0 repeats an earlier row"), 1)
      << Join(m.problems);
  EXPECT_EQ(CountContaining(m.problems, "line 7, row 5 (site 2 pair 5): pair index 5 is not below num_pairs 3"),
            1)
      << Join(m.problems);
  EXPECT_EQ(CountContaining(m.problems, "line 8, row 6 (site 2 pair 2): pair index 2 is not below num_pairs 2"),
            1)
      << Join(m.problems);
  EXPECT_EQ(CountContaining(m.problems, "line 9, row 7 (site 3 pair 70): pair index 70 is not below num_pairs 1"), 1)
      << Join(m.problems);
  ASSERT_EQ(m.entries.size(), 3u);  // (1, 0), (1, 1), (2, 0)
  EXPECT_EQ(m.entries[1].pair_index, 1);
  EXPECT_EQ(m.entries[2].site_id, 2);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vloc
