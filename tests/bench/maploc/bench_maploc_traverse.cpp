// A 50-site simulated traverse: the relative chain (cross-site results with
// known noise: per leg 1 % of its length per horizontal axis, 0.2 deg of
// heading; plus dead reckoning at 5 %/m, 0.002 rad/m as weak edges) alone, against the same chain in the traverse pose graph with an
// absolute fix attempted at every fifth site (real fixes: the site's Navcam
// panorama rendered, its ground orthophoto registered to a 20 cm/px aerial
// map under another sun, from the graph's predicted pose and covariance).
// Prints per site the distance driven and the horizontal error of both, and
// the summary (end error, worst error, sites where the fused estimate is
// worse than the chain).
//   bench_maploc_traverse [--sites 50] [--fix-every 5] [--seed 3] [--leg-noise 0.01] [--leg-heading-deg 0.2] [--downsample 1]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>

#include "vloc/maploc/ground_ortho.h"
#include "vloc/maploc/map_registration.h"
#include "vloc/posegraph/traverse_graph.h"
#include "vloc/testing/maploc_scenario.h"

namespace vloc {
namespace {

double Arg(int argc, char** argv, const char* name, double fallback) {
  for (int i = 1; i + 1 < argc; ++i)
    if (!std::strcmp(argv[i], name)) return std::atof(argv[i + 1]);
  return fallback;
}

struct ChainNoise {
  double position_fraction = 0.01;  // 1-sigma per horizontal axis, fraction of the leg length
  double heading_rad = 0.2 * M_PI / 180;  // 1-sigma per leg ...
  double heading_per_metre = 0;            // ... plus this per metre of the leg (rad/m)
  double tilt_rad = 0.05 * M_PI / 180;
};

// Dead reckoning as the graph's per-metre DR model describes it (PoseGraphOptions defaults:
// 5 % of the distance per horizontal axis, 0.002 rad/m of heading, 0.005 rad of tilt).
ChainNoise DeadReckoningNoise() {
  ChainNoise n;
  n.position_fraction = 0.05;
  n.heading_rad = 0;
  n.heading_per_metre = 0.002;
  n.tilt_rad = 0.005;
  return n;
}

// previous_from_current of the truth with the chain's noise, and its covariance.
PoseWithCovariance NoisyLeg(const Pose3& previous, const Pose3& current, const ChainNoise& n, std::mt19937* rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  const Pose3 rel = previous.inverse() * current;
  const double len = std::max(0.5, rel.translation().norm());
  const double sp = n.position_fraction * len, sz = 0.5 * sp;
  Vector6d sigma;
  sigma << sp, sp, sz, n.tilt_rad, n.tilt_rad, n.heading_rad + n.heading_per_metre * len;
  Vector6d e;
  for (int k = 0; k < 6; ++k) e(k) = sigma(k) * g(*rng);
  PoseWithCovariance out;
  out.pose = MakePose(ExpSO3(e.tail<3>()) * rel.linear(), rel.translation() + e.head<3>());
  out.covariance = sigma.array().square().matrix().asDiagonal();
  return out;
}

posegraph::PoseGraphOptions GraphOptions() {
  posegraph::PoseGraphOptions o;
  o.dr_covariance = "per_metre";  // weak DR edges: the chain is the visual edges
  return o;
}

double HorizontalError(const posegraph::TraverseGraph& g, int site, const Pose3& truth) {
  return (g.Site(site)->world_from_body.pose.translation() - truth.translation()).head<2>().norm();
}

int Run(int argc, char** argv) {
  testing::MaplocScenarioOptions s;
  s.num_sites = static_cast<int>(Arg(argc, argv, "--sites", 50));
  s.seed = static_cast<uint64_t>(Arg(argc, argv, "--seed", 3));
  s.terrain_size_m = 200;
  s.terrain_origin_x_m = -100;
  s.terrain_origin_y_m = -100;
  const int fix_every = static_cast<int>(Arg(argc, argv, "--fix-every", 5));
  ChainNoise noise;
  noise.position_fraction = Arg(argc, argv, "--leg-noise", noise.position_fraction);
  noise.heading_rad = Arg(argc, argv, "--leg-heading-deg", 0.2) * M_PI / 180;
  const sim::RoverWorld world(testing::MaplocWorldOptions(s));
  const maploc::MapRaster map = testing::RenderMapOf(world.options().terrain, s);
  maploc::GroundOrthoOptions ortho_options;
  ortho_options.m_per_px = s.map_m_per_px;
  ortho_options.downsample = static_cast<int>(Arg(argc, argv, "--downsample", 1));  // 512 px = the real 1024 px / 2
  const maploc::RegistrationOptions reg;
  posegraph::TraverseGraph chain(GraphOptions()), fused(GraphOptions());
  std::mt19937 rng(s.seed);
  const auto& sites = world.traverse().sites;
  int fixes = 0, attempts = 0, worse = 0;
  double worst_chain = 0, worst_fused = 0;
  std::printf("site  distance_m  chain_err_m  fused_err_m  fix\n");
  PoseWithCovariance dr;  // dead reckoning with its own noise (weak per-metre edges in both graphs)
  for (size_t i = 0; i < sites.size(); ++i) {
    const Pose3& truth = sites[i].world_from_body;
    if (i == 0) dr.pose = truth;
    else dr.pose = dr.pose * NoisyLeg(sites[i - 1].world_from_body, truth, DeadReckoningNoise(), &rng).pose;
    for (posegraph::TraverseGraph* g : {&chain, &fused}) g->AddDeadReckoning(static_cast<int>(i), dr);
    if (i > 0) {
      const PoseWithCovariance leg = NoisyLeg(sites[i - 1].world_from_body, truth, noise, &rng);
      for (posegraph::TraverseGraph* g : {&chain, &fused}) g->AddRelative(static_cast<int>(i) - 1, static_cast<int>(i), leg);
    }
    chain.Optimize();
    fused.Optimize();
    std::string fix_text = "-";
    if (i > 0 && static_cast<int>(i) % fix_every == 0) {
      ++attempts;
      const PoseWithCovariance predicted = fused.Site(static_cast<int>(i))->world_from_body;
      const Eigen::Vector3d rpy = RollPitchYawFromRotation(truth.linear());
      const maploc::MapRaster ortho = maploc::BuildGroundOrtho(world.RenderSite(static_cast<int>(i)),
                                                               world.options().navcam, rpy.x(), rpy.y(), ortho_options);
      const maploc::MapFix fix = maploc::RegisterToMap(ortho, map, maploc::SitePriorFromPose(predicted), reg);
      fix_text = fix.usable ? "fix" : "no fix (" + fix.message + ")";
      if (fix.usable) {
        ++fixes;
        fused.AddAbsoluteFix(static_cast<int>(i), maploc::FixToPose(fix, predicted, reg));
        fused.Optimize();
      }
    }
    const double ec = HorizontalError(chain, static_cast<int>(i), truth);
    const double ef = HorizontalError(fused, static_cast<int>(i), truth);
    worst_chain = std::max(worst_chain, ec);
    worst_fused = std::max(worst_fused, ef);
    if (ef > ec + 0.05) ++worse;
    std::printf("%4zu  %10.1f  %11.3f  %11.3f  %s\n", i, sites[i].distance_from_start_m, ec, ef, fix_text.c_str());
    std::fflush(stdout);
  }
  // Final (smoothed) errors of every site after the last update.
  int worse_final = 0;
  double worst_final = 0;
  for (size_t i = 0; i < sites.size(); ++i) {
    const double ec = HorizontalError(chain, static_cast<int>(i), sites[i].world_from_body);
    const double ef = HorizontalError(fused, static_cast<int>(i), sites[i].world_from_body);
    worst_final = std::max(worst_final, ef);
    if (ef > ec + 0.05) ++worse_final;
  }
  const Pose3& end = sites.back().world_from_body;
  std::printf("summary: %zu sites, %.1f m driven, %d/%d fixes; end error chain %.3f m (%.2f %%), with fixes %.3f m "
              "(%.2f %%); worst online error chain %.3f m, with fixes %.3f m; sites online worse than the chain by "
              "> 5 cm: %d; after the last update worst %.3f m, worse than the chain: %d\n",
              sites.size(), sites.back().distance_from_start_m, fixes, attempts,
              HorizontalError(chain, static_cast<int>(sites.size()) - 1, end),
              100 * HorizontalError(chain, static_cast<int>(sites.size()) - 1, end) / sites.back().distance_from_start_m,
              HorizontalError(fused, static_cast<int>(sites.size()) - 1, end),
              100 * HorizontalError(fused, static_cast<int>(sites.size()) - 1, end) / sites.back().distance_from_start_m,
              worst_chain, worst_fused, worse, worst_final, worse_final);
  return 0;
}

}  // namespace
}  // namespace vloc

int main(int argc, char** argv) { return vloc::Run(argc, argv); }
