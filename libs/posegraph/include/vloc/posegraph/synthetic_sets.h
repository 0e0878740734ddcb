#pragma once
// Synthetic 3D pose-graph benchmarks in g2o text, the shapes of SE-Sync's
// collection made here (its torus, grid and sphere are not in ../shared/data):
//   - torus: a spiral around the tube of a torus (rings x per_ring poses),
//     odometry along it, a loop to the same place on the previous ring with
//     probability loop_probability (100 x 50, 0.82: 5,000 poses, ~9,050 edges
//     like SE-Sync's torus3D);
//   - cube: a snake through a side^3 grid, loops to grid neighbours
//     (20^3, 0.96: 8,000 poses, ~22,200 edges like grid3D);
//   - sphere: latitude rings (g2o's create_sphere), loops to the previous
//     ring (50 x 50, 1.0: sphere2500's 2,500 poses and 4,949 edges).
// Every measurement is the true relative pose with noise drawn from the
// translation and rotation blocks (sigma_t, sigma_r, each edge's scaled by a
// factor in [0.5, 2]); the information written carries those blocks, laid
// out as `information` says:
//   - "isotropic": block diagonal, each block a multiple of I;
//   - "correlated": block diagonal blocks with correlations, and cross terms
//     between them: positive definite;
//   - "indefinite": the same blocks, cross terms 1.5 x the blocks' geometric
//     mean: the 6 x 6 matrix is not positive definite, its blocks are (the
//     layout of real files such as SE-Sync's cubicle; SE-Sync reads only the
//     blocks).
// The vertices hold chained noisy odometry (what a file gives a solver).
#include <cstdint>
#include <string>
#include <vector>

namespace vloc::posegraph {

struct SyntheticSet {
  std::string name;
  std::string shape;               // "torus" | "cube" | "sphere"
  int rings = 100;                 // torus / sphere rings; cube: side
  int per_ring = 50;               // torus / sphere poses per ring (cube: unused)
  double loop_probability = 1.0;   // chance that each candidate loop edge is kept
  double sigma_t = 0.05;           // m, translation noise per axis
  double sigma_r = 0.02;           // rad, rotation noise per axis
  std::string information = "isotropic";  // "isotropic" | "correlated" | "indefinite"
  uint32_t seed = 1;
};

// The sets the benchmark and tests use: torus, torus_indefinite, cube,
// sphere_heavy (0.1 rad rotation noise).
const std::vector<SyntheticSet>& StandardSyntheticSets();

// The set as g2o text (VERTEX_SE3:QUAT / EDGE_SE3:QUAT, FIX 0).
std::string SyntheticG2o(const SyntheticSet& set);

}  // namespace vloc::posegraph
