// The cross-site bundle adjustment on synthetic tie points with known truth.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "vloc/ba/crosssite_ba.h"
#include "vloc/ba/synthetic.h"
#include "vloc/common/options.h"

namespace vloc {
namespace {

NavcamModel Navcam() { return LoadOptionsFile<NavcamModel>("config/navcam.yaml"); }

const Pose3 kPrevious = MakePose(3.0, -1.0, 0.2, 0.02, -0.01, 0.3);
const Pose3 kCurrent = kPrevious * MakePose(10.0, 0.5, 0.1, 0.01, 0.02, 0.05);
// Dead reckoning off by ~1 m and 3 degrees of heading (10 % of 10 m).
const Pose3 kCurrentDr = kCurrent * MakePose(0.6, -0.7, 0.1, 0.0, 0.01, 0.05);

// Error of an estimate in the covariance convention: [dt, dr], R_true = exp(dr) R_est.
Vector6d PoseError(const Pose3& truth, const Pose3& estimate) {
  Vector6d e;
  e.head<3>() = truth.translation() - estimate.translation();
  e.tail<3>() = LogSO3(truth.linear() * estimate.linear().transpose());
  return e;
}

TEST(CrossSiteBa, DefaultOptionsPassCheck) {
  std::string error;
  EXPECT_TRUE(CrossSiteBaOptions().Check(&error)) << error;
}

TEST(CrossSiteBa, RecoversPerturbedSiteWithinItsCovariance) {
  const NavcamModel navcam = Navcam();
  CrossSiteBaOptions options;
  options.inflate_by_variance_factor = false;  // test the a-priori covariance against the known noise
  double sum_nees = 0;
  const int runs = 10;
  for (int seed = 1; seed <= runs; ++seed) {
    SyntheticTiePointOptions so;
    so.seed = seed;
    so.noise_px = 0.3;
    const SyntheticTiePoints syn = MakeSyntheticTiePoints(navcam, kPrevious, kCurrent, kCurrentDr, so);
    ASSERT_EQ(syn.set.points.size(), 200u);
    const CrossSiteBaSummary s = SolveCrossSiteBa(syn.set, navcam, options);
    ASSERT_TRUE(s.usable) << s.BriefReport();
    EXPECT_EQ(s.num_tie_points_used + s.num_tie_points_rejected, 200);
    EXPECT_LE(s.num_tie_points_rejected, 3);  // 4-sigma rejection of Gaussian noise: rare
    const Vector6d e = PoseError(kCurrent, s.world_from_current.pose);
    const double nees = e.dot(s.world_from_current.covariance.ldlt().solve(e));
    sum_nees += nees;
    EXPECT_LT(nees, 22.46) << "seed " << seed << ": chi2(6) 99.9 % bound; " << s.BriefReport();
    // Position error under 1 % of the 10 m site spacing.
    EXPECT_LT(e.head<3>().norm(), 0.1) << s.BriefReport();
    // Residuals match the 0.3 px noise once the adjusted unknowns are discounted.
    const double dof = 2.0 * s.num_observations - 6 - 3 * s.num_tie_points_used;
    EXPECT_NEAR(s.final_normalised_rms, std::sqrt(dof / (2.0 * s.num_observations)), 0.1);
    EXPECT_LT(s.final_rms_px, s.initial_rms_px + 1e-9);
  }
  // Mean NEES of 10 chi2(6) draws: expectation 6, std 1.1.
  std::printf("mean NEES over %d runs: %.2f (chi2(6) expectation 6)\n", runs, sum_nees / runs);
  EXPECT_LT(sum_nees / runs, 10.0);
  EXPECT_GT(sum_nees / runs, 3.0);
}

// Far terrain (a ridge 300-3000 m away: the previous site's stereo rays
// closer than min_intersection_parallax_rad) beside 30 ground points 5-25 m
// away, 10 seeds: with far_points the ridge enters as inverse depths and
// the rotation comes out closer to the truth than from the ground alone;
// the covariance stays consistent with the errors.
TEST(CrossSiteBa, FarPointsEnterAsInverseDepthsAndFixTheRotation) {
  const NavcamModel navcam = Navcam();
  double sum_rot_near = 0, sum_rot_far = 0, sum_nees = 0;
  const int runs = 10;
  for (int seed = 1; seed <= runs; ++seed) {
    SyntheticTiePointOptions near_o;
    near_o.seed = seed;
    near_o.tilt = 0.15;
    near_o.num_points = 30;
    near_o.min_range = 5.0;
    SyntheticTiePointOptions far_o = near_o;
    far_o.seed = 100 + seed;
    far_o.num_points = 60;
    far_o.min_range = 300.0;
    far_o.max_range = 3000.0;
    far_o.half_width = 600.0;
    far_o.ground_roughness = 40.0;
    SyntheticTiePoints syn = MakeSyntheticTiePoints(navcam, kPrevious, kCurrent, kCurrentDr, near_o);
    const SyntheticTiePoints ridge = MakeSyntheticTiePoints(navcam, kPrevious, kCurrent, kCurrentDr, far_o);
    ASSERT_GE(ridge.set.points.size(), 40u);
    for (TiePoint tp : ridge.set.points) {
      tp.id += 10000;
      // A calibration bias of 0.15 px in the right images' columns, a tenth of the ridge's disparities: far
      // points take their bearings only.
      for (TieObservation& o : tp.observations)
        if (o.camera == CameraSide::kRight) o.uv.x() += 0.15;
      syn.set.points.push_back(tp);
    }
    CrossSiteBaOptions options;
    options.inflate_by_variance_factor = false;
    options.far_points = false;
    const CrossSiteBaSummary near_only = SolveCrossSiteBa(syn.set, navcam, options);
    options.far_points = true;
    const CrossSiteBaSummary with_far = SolveCrossSiteBa(syn.set, navcam, options);
    ASSERT_TRUE(near_only.usable) << near_only.BriefReport();
    ASSERT_TRUE(with_far.usable) << with_far.BriefReport();
    // Most of the ridge is too far for the stereo (its nearest points intersect): unusable without far_points.
    EXPECT_EQ(near_only.num_far_points, 0);
    EXPECT_GE(with_far.num_far_points, static_cast<int>(ridge.set.points.size()) / 2) << with_far.BriefReport();
    EXPECT_GE(near_only.num_tie_points_unusable - with_far.num_tie_points_unusable, with_far.num_far_points);
    EXPECT_LE(with_far.num_tie_points_unusable, 2) << with_far.BriefReport();
    EXPECT_LE(with_far.num_tie_points_rejected, 3);
    const Vector6d e_near = PoseError(kCurrent, near_only.world_from_current.pose);
    const Vector6d e = PoseError(kCurrent, with_far.world_from_current.pose);
    sum_rot_near += e_near.tail<3>().squaredNorm();
    sum_rot_far += e.tail<3>().squaredNorm();
    sum_nees += e.dot(with_far.world_from_current.covariance.ldlt().solve(e));
    EXPECT_LT(e.head<3>().norm(), 0.1) << with_far.BriefReport();
  }
  const double rms_near = std::sqrt(sum_rot_near / runs), rms_far = std::sqrt(sum_rot_far / runs);
  std::printf("rotation error RMS over %d runs: ground alone %.4f deg, with the ridge %.4f deg; mean NEES %.2f\n",
              runs, rms_near * 180 / M_PI, rms_far * 180 / M_PI, sum_nees / runs);
  EXPECT_LT(rms_far, 0.7 * rms_near);
  EXPECT_LT(sum_nees / runs, 10.0);
  EXPECT_GT(sum_nees / runs, 3.0);
}

TEST(CrossSiteBa, RigAndMastConstraintsHoldExactly) {
  const NavcamModel navcam = Navcam();
  SyntheticTiePointOptions so;
  so.seed = 11;
  const SyntheticTiePoints syn = MakeSyntheticTiePoints(navcam, kPrevious, kCurrent, kCurrentDr, so);
  const CrossSiteBaSummary s = SolveCrossSiteBa(syn.set, navcam, CrossSiteBaOptions());
  ASSERT_TRUE(s.usable) << s.BriefReport();
  ASSERT_EQ(s.world_from_left_current.size(), 7u);
  for (size_t i = 0; i < 7; ++i) {
    const Pose3 rig = s.world_from_left_current[i].inverse() * s.world_from_right_current[i];
    EXPECT_LT((rig.matrix() - navcam.rig.left_from_right.matrix()).norm(), 1e-12);
    const Pose3 mast = s.world_from_current.pose.inverse() * s.world_from_left_current[i];
    const Pose3 expected = navcam.mast.BodyFromLeft(syn.set.current_pointing[i].pan,
                                                    syn.set.current_pointing[i].tilt, navcam.rig);
    EXPECT_LT((mast.matrix() - expected.matrix()).norm(), 1e-12);
    // Previous site held fixed.
    const Pose3 prev = s.world_from_left_previous[i];
    EXPECT_LT((prev.matrix() - (kPrevious * navcam.mast.BodyFromLeft(syn.set.previous_pointing[i].pan,
                                                                       syn.set.previous_pointing[i].tilt, navcam.rig))
                                   .matrix())
                  .norm(),
              1e-12);
  }
  // The relative pose is previous^-1 * current.
  EXPECT_LT(((kPrevious.inverse() * s.world_from_current.pose).matrix() - s.previous_from_current.pose.matrix()).norm(),
            1e-12);
}

TEST(CrossSiteBa, RejectsGrossOutliers) {
  const NavcamModel navcam = Navcam();
  SyntheticTiePointOptions so;
  so.seed = 5;
  so.outlier_fraction = 0.15;
  const SyntheticTiePoints syn = MakeSyntheticTiePoints(navcam, kPrevious, kCurrent, kCurrentDr, so);
  const CrossSiteBaSummary s = SolveCrossSiteBa(syn.set, navcam, CrossSiteBaOptions());
  ASSERT_TRUE(s.usable) << s.BriefReport();
  EXPECT_GE(s.num_tie_points_rejected, 20);  // ~30 outliers of 10-40 px
  EXPECT_LT(PoseError(kCurrent, s.world_from_current.pose).head<3>().norm(), 0.1) << s.BriefReport();
}

TEST(CrossSiteBa, TooFewPointsFailsAndKeepsDeadReckoning) {
  const NavcamModel navcam = Navcam();
  SyntheticTiePointOptions so;
  so.num_points = 4;
  const SyntheticTiePoints syn = MakeSyntheticTiePoints(navcam, kPrevious, kCurrent, kCurrentDr, so);
  const CrossSiteBaSummary s = SolveCrossSiteBa(syn.set, navcam, CrossSiteBaOptions());
  EXPECT_FALSE(s.usable);
  EXPECT_EQ(s.status, CrossSiteBaStatus::kTooFewPoints) << s.BriefReport();
  EXPECT_LT((s.world_from_current.pose.matrix() - kCurrentDr.matrix()).norm(), 1e-12);
  EXPECT_FALSE(s.message.empty());
}

TEST(CrossSiteBa, CollinearPointsAreIllConditioned) {
  const NavcamModel navcam = Navcam();
  SyntheticTiePointOptions so;
  so.collinear = true;
  so.num_points = 60;
  so.seed = 2;
  const SyntheticTiePoints syn = MakeSyntheticTiePoints(navcam, kPrevious, kCurrent, kCurrentDr, so);
  ASSERT_GE(syn.set.points.size(), 30u);
  const CrossSiteBaSummary s = SolveCrossSiteBa(syn.set, navcam, CrossSiteBaOptions());
  EXPECT_FALSE(s.usable);
  EXPECT_EQ(s.status, CrossSiteBaStatus::kIllConditioned) << s.BriefReport();
  EXPECT_GT(s.condition_number, CrossSiteBaOptions().max_condition_number);
}

TEST(CrossSiteBa, BadInputIsReportedNotThrown) {
  const NavcamModel navcam = Navcam();
  SyntheticTiePoints syn = MakeSyntheticTiePoints(navcam, kPrevious, kCurrent, kCurrentDr, SyntheticTiePointOptions());
  syn.set.previous_site_pose.pose.translation().x() = std::nan("");
  CrossSiteBaSummary s = SolveCrossSiteBa(syn.set, navcam, CrossSiteBaOptions());
  EXPECT_EQ(s.status, CrossSiteBaStatus::kBadInput);
  // Observations naming pairs that do not exist are dropped, the rest kept.
  syn = MakeSyntheticTiePoints(navcam, kPrevious, kCurrent, kCurrentDr, SyntheticTiePointOptions());
  syn.set.points[0].observations[0].pair_index = 42;
  syn.set.points[1].observations[3].sigma = -1;
  s = SolveCrossSiteBa(syn.set, navcam, CrossSiteBaOptions());
  EXPECT_TRUE(s.usable) << s.BriefReport();
  EXPECT_EQ(s.num_bad_observations, 2);
}

}  // namespace
}  // namespace vloc
