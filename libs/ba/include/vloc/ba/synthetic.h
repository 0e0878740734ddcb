#pragma once
// Synthetic tie points for tests and benchmarks: random ground points seen
// by Navcam stereo pairs at two sites, projected through the real camera
// model (ideal pixels) with Gaussian noise. Truth is returned alongside.

#include <cstdint>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/rover_data.h"

namespace vloc {

struct SyntheticTiePointOptions {
  int num_pairs = 7;               // stereo pairs per site
  double pan_step = 0.6;           // rad between pairs, centred on straight ahead
  double tilt = 0.35;              // rad, mast tilt (down) of every pair
  int num_points = 200;            // tie points wanted
  double min_range = 3.0;          // m, ground points this far ahead of the previous site ...
  double max_range = 25.0;         // m, ... up to this far
  double half_width = 12.0;        // m, lateral extent of the ground patch
  double ground_roughness = 0.3;   // m, uniform +- height of the ground points
  double noise_px = 0.3;           // px, 1-sigma image noise (also the observations' sigma)
  double outlier_fraction = 0.0;   // fraction of points whose current-site observations are wrong by 10-40 px
  uint64_t seed = 1;
  bool collinear = false;          // put every point on one 3-D line (degenerate geometry)
  // Forward-backward capture (Wan et al. 2.1): the current site also looks
  // back (one more pair, pan 180 deg); the first `backward_points` tie points
  // lie on the ground between the sites and are seen by that pair, the rest
  // by the forward pairs as usual.
  bool backward_pair = false;
  int backward_points = 0;
};

struct SyntheticTiePoints {
  TiePointSet set;                            // previous pose = truth, current DR pose = as given
  Pose3 world_from_current_true = Pose3::Identity();
  std::vector<Eigen::Vector3d> points_world;  // truth, per tie point
};

// The previous site is at world_from_previous (held fixed); the current site
// truly at world_from_current; the set's dead-reckoning pose is
// world_from_current_dr with covariance dr_covariance.
SyntheticTiePoints MakeSyntheticTiePoints(const NavcamModel& navcam, const Pose3& world_from_previous,
                                          const Pose3& world_from_current, const Pose3& world_from_current_dr,
                                          const SyntheticTiePointOptions& options);

}  // namespace vloc
