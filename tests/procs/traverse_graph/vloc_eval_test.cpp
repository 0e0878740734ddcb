// vloc_eval on a small log whose errors are known by construction: sites
// 10 m apart along x; DR off by 0.1 m * site to the north; each visual pair
// off by 2 cm along the reference x axis with a 2 cm sigma; the optimised
// traverse off by 1 cm north everywhere; a UAV 1 % high and 0.5 m east.
#include <gtest/gtest.h>

#include <lcm/lcm-cpp.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "vloc/common/camera.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/localization_t.hpp"
#include "vloc/sim/terrain.h"
#include "vloc/tie_points_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/testing/subprocess.h"
#include "vloc/traverse_t.hpp"
#include "vloc/uav_state_t.hpp"

namespace vloc {
namespace {

template <class Msg>
void Write(lcm::LogFile& log, const std::string& channel, const Msg& msg, int64_t t) {
  std::vector<uint8_t> buf(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
  lcm::LogEvent ev;
  ev.eventnum = 0;
  ev.timestamp = t;
  ev.channel = channel;
  ev.datalen = static_cast<int32_t>(buf.size());
  ev.data = buf.data();
  ASSERT_EQ(log.writeEvent(&ev), 0);
}

PoseWithCovariance At(double x, double y, double z = 0.0) {
  PoseWithCovariance p;
  p.pose = MakePose(x, y, z, 0, 0, 0);
  return p;
}

std::vector<std::map<std::string, std::string>> ReadCsv(const std::string& path) {
  std::ifstream f(path);
  std::string line;
  std::getline(f, line);
  std::vector<std::string> header;
  std::stringstream hs(line);
  for (std::string h; std::getline(hs, h, ',');) header.push_back(h);
  std::vector<std::map<std::string, std::string>> rows;
  while (std::getline(f, line)) {
    std::map<std::string, std::string> row;
    std::stringstream ls(line);
    std::string v;
    for (size_t i = 0; i < header.size() && std::getline(ls, v, ','); ++i) row[header[i]] = v;
    rows.push_back(row);
  }
  return rows;
}

TEST(VlocEval, KnownErrorsComeOutOfTheReport) {
  const auto dir = std::filesystem::temp_directory_path() / "vloc_eval_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string log_path = (dir / "run.lcmlog").string();
  {
    lcm::LogFile log(log_path, "w");
    ASSERT_TRUE(log.good());
    int64_t t = 1;
    traverse_t traverse{};
    for (int i = 0; i < 5; ++i) {
      Write(log, "SITE_POSE_GT", SitePoseToMessage(i, site_pose_t::SOURCE_GROUND_TRUTH, At(10.0 * i, 0)), t++);
      Write(log, "SITE_POSE_DR", SitePoseToMessage(i, site_pose_t::SOURCE_DEAD_RECKONING, At(10.0 * i, 0.1 * i)), t++);
      if (i > 0) {
        localization_t m{};
        m.site_id = i;
        m.reference_site_id = i - 1;
        m.status = localization_t::STATUS_OK;
        PoseWithCovariance rel = At(10.02, 0);
        rel.covariance.topLeftCorner<3, 3>() = 0.02 * 0.02 * Eigen::Matrix3d::Identity();
        rel.covariance.bottomRightCorner<3, 3>() = 1e-6 * Eigen::Matrix3d::Identity();
        m.relative_pose = PoseToMessage(rel, "body", "body");
        m.pose = PoseToMessage(At(10.0 * i + 0.02 * i, 0), "world", "body");
        Write(log, "SITE_POSE_VISUAL", m, t++);
      }
      traverse.site_ids.push_back(i);
      PoseWithCovariance opt = At(10.0 * i, 0.01);
      opt.pose = MakePose(10.0 * i, 0.01, 0.0, 0.0, 0.01, 0.0);  // pitched 0.01 rad: tilt error 0.573 deg
      opt.covariance = 1e-4 * Matrix6d::Identity();
      traverse.poses.push_back(PoseToMessage(opt, "world", "body"));
      traverse.num_sites = i + 1;
      Write(log, "TRAVERSE", traverse, t++);
    }
    // A failed pair is listed but not counted.
    localization_t failed{};
    failed.site_id = 4;
    failed.reference_site_id = 3;
    failed.status = localization_t::STATUS_TOO_FEW_POINTS;
    failed.relative_pose = PoseToMessage(At(0, 0), "body", "body");
    failed.pose = PoseToMessage(At(0, 0), "world", "body");
    Write(log, "SITE_POSE_VISUAL", failed, t++);
    for (int k = 0; k <= 10; ++k) {
      const int64_t utime = 1000000 + 100000LL * k;
      pose_t gt = PoseToMessage(At(5.0 + k, 3.0, 100.0), "world", "uav");
      gt.utime = utime;
      Write(log, "UAV_GT", gt, t++);
      uav_state_t s{};
      s.utime = utime;
      s.status = uav_state_t::STATUS_TRACKING;
      s.height = 101.0;
      s.route_local[0] = k + 0.5;
      s.route_local[1] = 0.0;
      Write(log, "UAV_STATE", s, t++);
    }
  }
  const std::string out = (dir / "eval").string();
  testing::Subprocess proc({testing::BinPath("vloc_eval"), log_path, "--out", out});
  ASSERT_EQ(proc.WaitExit(60), 0) << proc.output();
  EXPECT_NE(proc.output().find("dead reckoning"), std::string::npos) << proc.output();
  EXPECT_NE(proc.output().find("100 %"), std::string::npos) << proc.output();  // progress

  auto sites = ReadCsv(out + "/sites.csv");
  ASSERT_EQ(sites.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_NEAR(std::stod(sites[i]["distance_m"]), 10.0 * i, 1e-9);
    EXPECT_NEAR(std::stod(sites[i]["dr_err_m"]), 0.1 * i, 1e-9);
    EXPECT_NEAR(std::stod(sites[i]["opt_err_m"]), 0.01, 1e-9);
    EXPECT_NEAR(std::stod(sites[i]["opt_z"]), 0.0, 1e-9);
    EXPECT_NEAR(std::stod(sites[i]["opt_tilt_err_deg"]), 0.01 * 180 / M_PI, 1e-5);
    EXPECT_NEAR(std::stod(sites[i]["opt_sigma_z"]), 0.01, 1e-9);
    EXPECT_NEAR(std::stod(sites[i]["dr_tilt_err_deg"]), 0.0, 1e-6);  // the DR poses are level
    if (i > 0) {
      EXPECT_NEAR(std::stod(sites[i]["dr_err_pct"]), 1.0, 1e-6);  // 0.1 m per 10 m
      EXPECT_NEAR(std::stod(sites[i]["vis_err_m"]), 0.02 * i, 1e-9);
    }
  }
  auto pairs = ReadCsv(out + "/pairs.csv");
  ASSERT_EQ(pairs.size(), 5u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(std::stod(pairs[i]["err_m"]), 0.02, 1e-6);
    EXPECT_NEAR(std::stod(pairs[i]["err_pct"]), 0.2, 1e-4);
    EXPECT_NEAR(std::stod(pairs[i]["nees"]), 1.0, 1e-3);
  }
  EXPECT_EQ(pairs[4]["status"], "1");
  auto uav = ReadCsv(out + "/uav.csv");
  ASSERT_EQ(uav.size(), 11u);
  EXPECT_NEAR(std::stod(uav.back()["height_err_m"]), 1.0, 1e-9);
  EXPECT_NEAR(std::stod(uav.back()["route_err_m"]), 0.5, 1e-9);
  EXPECT_NEAR(std::stod(uav.back()["flown_m"]), 10.0, 1e-9);
  std::ifstream report(out + "/report.md");
  std::stringstream text;
  text << report.rdbuf();
  EXPECT_NE(text.str().find("| dead reckoning | 0.400 | 1.00 |"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("| optimised graph | 0.010 | 0.03 | 0.00 | 0.000 | 0.573 |"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("| height error RMS % of true height | 1.00 |"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("| route error % of distance flown | 5.00 |"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("median new-site error 0.200 %"), std::string::npos) << text.str();
  EXPECT_TRUE(std::filesystem::exists(out + "/traverse_map.png")) << proc.output();
  EXPECT_TRUE(std::filesystem::exists(out + "/uav_height.png")) << proc.output();
  // A missing log: one clear line, exit 1.
  testing::Subprocess bad({testing::BinPath("vloc_eval"), (dir / "missing.lcmlog").string(), "--out", out});
  EXPECT_EQ(bad.WaitExit(30), 1);
  EXPECT_NE(bad.output().find("missing.lcmlog"), std::string::npos) << bad.output();
  std::filesystem::remove_all(dir);
}

// --terrain renders the simulated terrain over the sites' bounding box plus
// a 12 m margin and writes its world file: two sites at (0, 0) and (10, 0)
// at 0.25 m/px give x -12 .. 22, y -12 .. 12, top-left pixel centre
// (-11.875, 11.875). A terrain file that cannot be read leaves the plots
// without a background (one line), not the evaluation.
TEST(VlocEval, OrthoimageOfTheTerrainUnderTheMap) {
  const auto dir = std::filesystem::temp_directory_path() / "vloc_eval_ortho_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string log_path = (dir / "run.lcmlog").string();
  {
    lcm::LogFile log(log_path, "w");
    ASSERT_TRUE(log.good());
    for (int i = 0; i < 2; ++i)
      Write(log, "SITE_POSE_GT", SitePoseToMessage(i, site_pose_t::SOURCE_GROUND_TRUTH, At(10.0 * i, 0)), i + 1);
  }
  {
    std::ofstream t(dir / "terrain.yaml");
    t << "size_m: 51.2\nresolution_m: 0.08\norigin_x_m: -20.0\norigin_y_m: -20.0\nnum_threads: 1\n";
  }
  const std::string out = (dir / "eval").string();
  testing::Subprocess proc({testing::BinPath("vloc_eval"), log_path, "--out", out, "--quiet", "--terrain",
                            (dir / "terrain.yaml").string(), "--ortho-m-per-px", "0.25"});
  ASSERT_EQ(proc.WaitExit(60), 0) << proc.output();
  ASSERT_TRUE(std::filesystem::exists(out + "/ortho.png")) << proc.output();
  EXPECT_GT(std::filesystem::file_size(out + "/ortho.png"), 1000u);
  std::ifstream pgw(out + "/ortho.pgw");
  std::vector<double> w;
  for (double v; pgw >> v;) w.push_back(v);
  ASSERT_EQ(w.size(), 6u);
  EXPECT_NEAR(w[0], 0.25, 1e-9);
  EXPECT_NEAR(w[1], 0.0, 1e-12);
  EXPECT_NEAR(w[2], 0.0, 1e-12);
  EXPECT_NEAR(w[3], -0.25, 1e-9);
  EXPECT_NEAR(w[4], -11.875, 1e-9);
  EXPECT_NEAR(w[5], 11.875, 1e-9);
  EXPECT_NE(proc.output().find("136 x 96 px"), std::string::npos) << proc.output();
  EXPECT_TRUE(std::filesystem::exists(out + "/traverse_map.png")) << proc.output();

  testing::Subprocess bad({testing::BinPath("vloc_eval"), log_path, "--out", out, "--quiet", "--terrain",
                           (dir / "missing.yaml").string()});
  EXPECT_EQ(bad.WaitExit(60), 0) << bad.output();
  EXPECT_NE(bad.output().find("no orthoimage under the map"), std::string::npos) << bad.output();
  EXPECT_FALSE(std::filesystem::exists(out + "/ortho.png"));  // the stale one is gone
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vloc

namespace vloc {
namespace {

// --terrain with --navcam checks every TIE_POINTS set against the terrain:
// tie points made from the terrain itself (a grid of current-left pixels,
// their true points projected into the previous left camera) come out
// 0 px off, except 5 moved 3 px down, which are the set's wrong ones; the
// stereo ranges are the true ones (0 %).
TEST(VlocEval, TiePointsAgainstTheTerrain) {
  const auto dir = std::filesystem::temp_directory_path() / "vloc_eval_ties_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string terrain_path = (dir / "terrain.yaml").string();
  {
    std::ofstream t(terrain_path);
    t << "size_m: 51.2\nresolution_m: 0.08\norigin_x_m: -20.0\norigin_y_m: -20.0\nnum_threads: 1\n";
  }
  const sim::Terrain terrain(LoadOptionsFile<sim::TerrainOptions>(terrain_path));
  const NavcamModel navcam = LoadOptionsFile<NavcamModel>("config/navcam.yaml");
  const double tilt = 25 * M_PI / 180;
  const Pose3 previous = MakePose(0, 0, terrain.Height(0, 0), 0, 0, 0);
  const Pose3 current = MakePose(-3, 0.5, terrain.Height(-3, 0.5), 0, 0, 0.1);  // behind, looking the same way
  const Pose3 body_from_left = navcam.mast.BodyFromLeft(0.0, tilt, navcam.rig);
  TiePointSet set;
  set.previous_site_id = 0;
  set.current_site_id = 1;
  set.previous_pointing = {{0.0, tilt}};
  set.current_pointing = {{0.0, tilt}};
  const Pose3 world_from_cl = current * body_from_left, world_from_pl = previous * body_from_left;
  for (int v = 100; v < 1000 && set.points.size() < 40; v += 40) {
    for (int u = 60; u < 1000 && set.points.size() < 40; u += 80) {
      const Eigen::Vector2d cur_px(u, v);
      const Eigen::Vector3d dir = (world_from_cl.linear() * navcam.rig.left.Ray(cur_px)).normalized();
      const auto hit = terrain.Raycast(world_from_cl.translation(), dir, 100.0);
      if (!hit) continue;
      const auto prev_px = navcam.rig.left.ProjectIdeal(world_from_pl.inverse() * hit->point);
      if (!prev_px || !navcam.rig.left.InImage(*prev_px)) continue;
      TiePoint tp;
      tp.id = static_cast<int>(set.points.size());
      tp.p_previous = previous.inverse() * hit->point;
      tp.p_current = current.inverse() * hit->point;
      const Eigen::Vector2d moved = tp.id < 5 ? Eigen::Vector2d(0, 3) : Eigen::Vector2d::Zero();
      TieObservation prev_obs, cur_obs;
      prev_obs.site = SiteRole::kPrevious;
      prev_obs.uv = *prev_px + moved;
      cur_obs.site = SiteRole::kCurrent;
      cur_obs.uv = cur_px;
      tp.observations = {prev_obs, cur_obs};
      set.points.push_back(tp);
    }
  }
  ASSERT_GE(set.points.size(), 20u);
  const std::string log_path = (dir / "run.lcmlog").string();
  {
    lcm::LogFile log(log_path, "w");
    ASSERT_TRUE(log.good());
    PoseWithCovariance p, c;
    p.pose = previous;
    c.pose = current;
    Write(log, "SITE_POSE_GT", SitePoseToMessage(0, site_pose_t::SOURCE_GROUND_TRUTH, p), 1);
    Write(log, "SITE_POSE_GT", SitePoseToMessage(1, site_pose_t::SOURCE_GROUND_TRUTH, c), 2);
    Write(log, "TIE_POINTS", TiePointsToMessage(set), 3);
    PoseWithCovariance turned;  // site 2: where site 1 stands, looking back: nothing of site 1's view
    turned.pose = MakePose(-3, 0.5, terrain.Height(-3, 0.5), 0, 0, 0.1 + M_PI);
    Write(log, "SITE_POSE_GT", SitePoseToMessage(2, site_pose_t::SOURCE_GROUND_TRUTH, turned), 4);
  }
  const std::string out = (dir / "eval").string();
  testing::Subprocess proc({testing::BinPath("vloc_eval"), log_path, "--out", out, "--quiet", "--no-plots",
                            "--terrain", terrain_path, "--navcam", "config/navcam.yaml"});
  ASSERT_EQ(proc.WaitExit(60), 0) << proc.output();
  EXPECT_NE(proc.output().find("tie points against the terrain"), std::string::npos) << proc.output();
  auto sets = ReadCsv(out + "/tiepoints.csv");
  ASSERT_EQ(sets.size(), 1u);
  EXPECT_EQ(std::stoi(sets[0]["points"]), static_cast<int>(set.points.size()));
  EXPECT_GE(std::stoi(sets[0]["checked"]), static_cast<int>(set.points.size()) - 2);  // a few may be hidden
  EXPECT_EQ(std::stoi(sets[0]["wrong"]), 5);
  EXPECT_NEAR(std::stod(sets[0]["cross_median_px"]), 0.0, 0.01);
  EXPECT_NEAR(std::stod(sets[0]["range_err_median_pct_current"]), 0.0, 0.01);
  EXPECT_NEAR(std::stod(sets[0]["range_err_median_pct_previous"]), 0.0, 0.01);
  int moved = 0;
  for (auto& row : ReadCsv(out + "/tiepoint_errors.csv"))
    if (std::abs(std::stod(row["err_v"]) - 3.0) < 0.01 && std::abs(std::stod(row["err_u"])) < 0.01) ++moved;
  EXPECT_EQ(moved, 5);
  // The view the pairs share: site 1, 3 m behind site 0 and looking the same way, sees most of site 0's ground
  // again; site 2 (turned round) none of site 1's, and the summary names it as a pair without tie points.
  auto shared = ReadCsv(out + "/shared_view.csv");
  ASSERT_EQ(shared.size(), 2u);
  EXPECT_GT(std::stoi(shared[0]["samples"]), 300);
  EXPECT_GT(std::stod(shared[0]["shared_pct"]), 60.0);
  const double ratio = std::stod(shared[0]["median_range_ratio"]);  // site 1 is 3 m farther from every point
  EXPECT_GT(ratio, 1.1);
  EXPECT_LT(ratio, 2.5);
  // Both look down the same way from 3 m apart: the ground's two views differ by a small tilt.
  EXPECT_GE(std::stod(shared[0]["median_tilt"]), 1.0);
  EXPECT_LT(std::stod(shared[0]["median_tilt"]), 2.0);
  EXPECT_LE(std::stoi(shared[0]["matchable"]), std::stoi(shared[0]["shared"]));
  EXPECT_GT(std::stoi(shared[0]["matchable"]), 0.8 * std::stoi(shared[0]["shared"]));
  EXPECT_LT(std::stod(shared[1]["shared_pct"]), 1.0);
  EXPECT_NE(proc.output().find("pairs without: 1 -> 2: 0.0 %, matchable 0.0 %"), std::string::npos) << proc.output();
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vloc
