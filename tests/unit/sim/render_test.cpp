// The Navcam renderer: the rendered stereo pair agrees with the terrain
// geometry (depth lands on the surface; stereo matching of the two images
// finds the disparity the depth predicts and triangulates back onto the
// terrain), lens distortion is rendered through the camera model, and the
// same seed gives the same bytes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "vloc/common/options.h"
#include "vloc/common/stats.h"
#include "vloc/crosssite/internal/frontend_steps.h"
#include "vloc/sim/navcam_renderer.h"
#include "vloc/sim/rover_world.h"
#include "vloc/sim/terrain.h"

namespace vloc::sim {
namespace {

const Terrain& TestTerrain() {
  static const auto terrain = [] {
    TerrainOptions options;
    options.size_m = 60.0;
    options.origin_x_m = -15.0;
    options.origin_y_m = -30.0;
    return std::make_unique<Terrain>(options);
  }();
  return *terrain;
}

// The Navcam at half resolution (same field of view, same baseline).
NavcamModel HalfNavcam() {
  NavcamModel model;
  for (PinholeCamera* c : {&model.rig.left, &model.rig.right}) {
    c->width = c->height = 512;
    c->fx = c->fy = 1189.0 / 2;
    c->cx = c->cy = 255.5;
  }
  return model;
}

TEST(SimRender, DepthLandsOnTheTerrain) {
  const NavcamModel model = HalfNavcam();
  const NavcamRenderer renderer(TestTerrain(), model, NavcamRenderOptions{});
  const Pose3 world_from_body = MakePose(0, 0, 0, 0.02, -0.03, 0.3);
  const RenderedPair pair = renderer.RenderPair(world_from_body, 0.2, 25 * M_PI / 180, 5, true);
  for (const RenderedImage* image : {&pair.left, &pair.right}) {
    int valid = 0;
    double worst = 0;
    for (int v = 0; v < 512; v += 8) {
      for (int u = 0; u < 512; u += 8) {
        const float z = image->depth.at<float>(v, u);
        if (z <= 0) continue;
        ++valid;
        const Eigen::Vector3d p = image->world_from_camera * (z * model.rig.left.Ray(Eigen::Vector2d(u, v)));
        worst = std::max(worst, std::abs(p.z() - TestTerrain().Height(p.x(), p.y())));
      }
    }
    EXPECT_GT(valid, 60 * 60);
    EXPECT_LT(worst, 1e-3);
  }
  cv::Scalar mean, stddev;
  cv::meanStdDev(pair.left.image, mean, stddev);
  EXPECT_GT(mean[0], 50);
  EXPECT_LT(mean[0], 200);
  // Texture near (bottom) and far (top) in the image.
  for (const cv::Rect& band : {cv::Rect(0, 400, 512, 100), cv::Rect(0, 40, 512, 60)}) {
    cv::Mat high_pass;
    cv::Mat region;
    pair.left.image(band).convertTo(region, CV_32F);
    cv::Mat blurred;
    cv::GaussianBlur(region, blurred, cv::Size(0, 0), 3.0);
    cv::meanStdDev(region - blurred, mean, stddev);
    EXPECT_GT(stddev[0], 3.0) << "too little fine texture in rows " << band.y << "..";
  }
}

// Stereo block matching (ZNCC, parabola sub-pixel) on the rendered pair
// finds the disparity that the rendered depth predicts, and triangulating
// the matched disparity returns the terrain height within the expected
// error sigma_z = z^2 / (f B) * sigma_d.
TEST(SimRender, StereoMatchingTriangulatesOntoTheTerrain) {
  const NavcamModel model = HalfNavcam();
  const NavcamRenderer renderer(TestTerrain(), model, NavcamRenderOptions{});
  const Pose3 world_from_body = MakePose(0, 0, 0, 0.0, 0.0, 0.0);
  const RenderedPair pair = renderer.RenderPair(world_from_body, 0.0, 25 * M_PI / 180, 9, true);
  const double f = model.rig.left.fx, baseline = model.rig.Baseline();
  const int half = 7;
  std::vector<double> disparity_errors, height_errors_in_sigma;
  for (int v = 40; v < 500; v += 23) {
    for (int u = 60; u < 480; u += 23) {
      const float z = pair.left.depth.at<float>(v, u);
      if (z <= 0 || z > 25) continue;
      const double d_true = f * baseline / z;
      const int d_lo = static_cast<int>(std::floor(d_true)) - 6, d_hi = static_cast<int>(std::ceil(d_true)) + 6;
      if (u - d_hi - half - 1 < 0) continue;
      const cv::Mat templ = pair.left.image(cv::Rect(u - half, v - half, 2 * half + 1, 2 * half + 1));
      const cv::Mat strip = pair.right.image(cv::Rect(u - d_hi - half, v - half, d_hi - d_lo + 2 * half + 1, 2 * half + 1));
      cv::Mat score;
      cv::matchTemplate(strip, templ, score, cv::TM_CCOEFF_NORMED);
      cv::Point best;
      double best_score;
      cv::minMaxLoc(score, nullptr, &best_score, nullptr, &best);
      if (best_score < 0.6 || best.x == 0 || best.x == score.cols - 1) continue;
      const float s0 = score.at<float>(0, best.x - 1), s1 = score.at<float>(0, best.x), s2 = score.at<float>(0, best.x + 1);
      const double offset = 0.5 * (s0 - s2) / (s0 - 2 * s1 + s2);
      // Column best.x in the strip is disparity d_hi - best.x.
      const double d_match = d_hi - (best.x + offset);
      disparity_errors.push_back(std::abs(d_match - d_true));
      const double z_match = f * baseline / d_match;
      const Eigen::Vector3d p = pair.left.world_from_camera * (z_match * model.rig.left.Ray(Eigen::Vector2d(u, v)));
      const double sigma_z = z * z / (f * baseline) * 0.3;  // 0.3 px matching error
      // Height error from a depth error along a ray that meets the ground obliquely.
      const Eigen::Vector3d ray = (pair.left.world_from_camera.linear() * model.rig.left.Ray(Eigen::Vector2d(u, v))).normalized();
      const double sigma_h = sigma_z * std::abs(ray.z()) * model.rig.left.Ray(Eigen::Vector2d(u, v)).norm() + 1e-3;
      height_errors_in_sigma.push_back(std::abs(p.z() - TestTerrain().Height(p.x(), p.y())) / sigma_h);
    }
  }
  ASSERT_GT(disparity_errors.size(), 200u);
  std::printf("stereo check: %zu points, median |d error| %.3f px, 90%% %.3f px, median height error %.2f sigma\n",
              disparity_errors.size(), Median(disparity_errors), Quantile(disparity_errors, 0.9),
              Median(height_errors_in_sigma));
  EXPECT_LT(Median(disparity_errors), 0.3);
  EXPECT_LT(Quantile(disparity_errors, 0.9), 1.0);
  EXPECT_LT(Median(height_errors_in_sigma), 1.5);
}

TEST(SimRender, RendersThroughLensDistortion) {
  NavcamModel model = HalfNavcam();
  model.rig.left.k1 = -0.12;
  model.rig.left.k2 = 0.03;
  model.rig.left.p1 = 2e-4;
  const NavcamRenderer renderer(TestTerrain(), model, NavcamRenderOptions{});
  const Pose3 world_from_left = MakePose(0, 0, 0, 0, 0, 0) * model.mast.BodyFromLeft(0.0, 0.45, model.rig);
  const RenderedImage image = renderer.Render(model.rig.left, world_from_left, 3, true);
  double worst = 0;
  int checked = 0;
  for (int v = 10; v < 502; v += 31) {
    for (int u = 10; u < 502; u += 31) {
      const float z = image.depth.at<float>(v, u);
      if (z <= 0) continue;
      // The hit of raw pixel (u, v) projects back to (u, v) through the distortion model.
      const Eigen::Vector2d ideal = model.rig.left.Undistort(Eigen::Vector2d(u, v));
      const Eigen::Vector3d p_world = world_from_left * (z * model.rig.left.Ray(ideal));
      const auto px = model.rig.left.Project(world_from_left.inverse() * p_world);
      ASSERT_TRUE(px.has_value());
      worst = std::max(worst, (*px - Eigen::Vector2d(u, v)).norm());
      ++checked;
      EXPECT_NEAR(p_world.z(), TestTerrain().Height(p_world.x(), p_world.y()), 1e-3);
    }
  }
  EXPECT_GT(checked, 200);
  EXPECT_LT(worst, 0.01);
  // Distortion changes the picture: the same view without it differs.
  NavcamRenderOptions no_distortion;
  no_distortion.apply_distortion = false;
  const NavcamRenderer plain(TestTerrain(), model, no_distortion);
  const RenderedImage undistorted = plain.Render(model.rig.left, world_from_left, 3, false);
  EXPECT_GT(cv::norm(image.image, undistorted.image, cv::NORM_L1) / (512.0 * 512.0), 2.0);
}

// The rover's deck: a side view looking down sees it at the bottom of the
// image, at under 2 m, and the same pixels at any rover pose; a view straight
// ahead does not.
TEST(SimRender, DeckInSideViewsAtTheSamePixelsEverywhere) {
  const NavcamModel model = HalfNavcam();
  NavcamRenderOptions options;
  options.deck = true;
  options.add_noise = false;
  const NavcamRenderer renderer(TestTerrain(), model, options);
  const double side_pan = 78 * M_PI / 180, tilt = 25 * M_PI / 180;
  const RenderedPair a = renderer.RenderPair(MakePose(0, 0, 0, 0, 0, 0), side_pan, tilt, 1, true);
  const RenderedPair b = renderer.RenderPair(MakePose(6, -3, 0.2, 0, 0, 0.4), side_pan, tilt, 1, true);
  const RenderedPair ahead = renderer.RenderPair(MakePose(0, 0, 0, 0, 0, 0), 0.0, tilt, 1, true);
  const int n = cv::countNonZero(a.left.deck);
  std::printf("deck: %d of %d px of the side view (%.1f %%)\n", n, 512 * 512, 100.0 * n / (512 * 512));
  EXPECT_GT(n, 512 * 20);                                    // at least 20 rows' worth
  EXPECT_EQ(cv::countNonZero(a.left.deck.rowRange(0, 256)), 0);  // only in the lower half
  EXPECT_EQ(cv::countNonZero(ahead.left.deck), 0);
  cv::Mat depth_on_deck;
  a.left.depth.copyTo(depth_on_deck, a.left.deck);
  double nearest = 0, farthest = 0;
  cv::minMaxLoc(depth_on_deck, &nearest, &farthest, nullptr, nullptr, a.left.deck);
  EXPECT_GT(nearest, 0.3);
  EXPECT_LT(farthest, 1.5);                                  // the deck is within reach of the mast
  // Same pixels, same values at both rover poses (the sun is fixed, the deck level in both).
  EXPECT_EQ(cv::countNonZero(a.left.deck != b.left.deck), 0);
  cv::Mat diff;
  cv::absdiff(a.left.image, b.left.image, diff);
  double worst = 0;
  cv::minMaxLoc(diff, nullptr, &worst, nullptr, nullptr, a.left.deck);
  EXPECT_LE(worst, 1.0);
}

// The front end's mask of the rover's body (frontend.vehicle_boxes_m, the
// deck's box as config/procs/feature_frontend.yaml gives it) covers every
// deck pixel the renderer draws, with a margin of a few px and no more: the
// ground next to the deck stays matchable.
TEST(SimRender, FrontendVehicleMaskCoversTheRenderedDeck) {
  const NavcamModel model = HalfNavcam();
  NavcamRenderOptions options;
  options.deck = true;
  options.add_noise = false;
  const NavcamRenderer renderer(TestTerrain(), model, options);
  VehicleOptions frontend;
  frontend.vehicle_boxes_m = {options.deck_rear_m, options.deck_front_m, -options.deck_half_width_m,
                              options.deck_half_width_m, 0.3, options.deck_top_m};
  frontend.vehicle_margin_px = 3;
  int deck_views = 0;
  for (double pan_deg : {-100.0, -78.0, -40.0, 0.0, 40.0, 78.0, 100.0, 180.0}) {
    const double pan = pan_deg * M_PI / 180, tilt = 25 * M_PI / 180;
    const RenderedPair pair = renderer.RenderPair(MakePose(3, 2, 0.1, 0.02, -0.01, 0.7), pan, tilt, 1, true);
    const cv::Mat mask = frontend_internal::VehicleMask(model, {pan, tilt}, frontend);
    const int deck = cv::countNonZero(pair.left.deck);
    SCOPED_TRACE("pan " + std::to_string(pan_deg) + " deg");
    if (deck == 0) {
      EXPECT_TRUE(mask.empty() || cv::countNonZero(mask) < 512 * 8);  // at most the margin where the deck just misses
      continue;
    }
    ++deck_views;
    ASSERT_FALSE(mask.empty());
    EXPECT_EQ(cv::countNonZero(pair.left.deck & ~mask), 0);  // every deck pixel masked
    // Masked but not deck: the margin (3 px + half the 4 px ray grid) along the deck's edge, and the box's
    // sides below the deck top; well under the deck's own area.
    const int extra = cv::countNonZero(mask & ~pair.left.deck);
    std::printf("pan %.0f deg: deck %d px, masked beyond it %d px\n", pan_deg, deck, extra);
    EXPECT_LT(extra, deck / 2 + 512 * 8);
  }
  EXPECT_GE(deck_views, 2);  // both side views see the deck
}

TEST(SimRender, SameSeedSameBytes) {
  const NavcamModel model = HalfNavcam();
  NavcamRenderOptions options;
  options.num_threads = 2;
  const NavcamRenderer renderer(TestTerrain(), model, options);
  options.num_threads = 1;
  const NavcamRenderer single(TestTerrain(), model, options);
  const Pose3 world_from_body = MakePose(1, 0.5, 0, 0, 0, -0.2);
  const RenderedPair a = renderer.RenderPair(world_from_body, 0.1, 0.4, 77);
  const RenderedPair b = single.RenderPair(world_from_body, 0.1, 0.4, 77);
  EXPECT_EQ(cv::norm(a.left.image, b.left.image, cv::NORM_L1), 0.0);
  EXPECT_EQ(cv::norm(a.right.image, b.right.image, cv::NORM_L1), 0.0);
  const RenderedPair c = renderer.RenderPair(world_from_body, 0.1, 0.4, 78);
  EXPECT_GT(cv::norm(a.left.image, c.left.image, cv::NORM_L1), 0.0);  // other noise
  // Noise level: difference of two noise seeds ~ sqrt(2) x per-image noise.
  cv::Mat diff;
  cv::subtract(a.left.image, c.left.image, diff, cv::noArray(), CV_32F);
  cv::Scalar mean, stddev;
  cv::meanStdDev(diff, mean, stddev);
  EXPECT_GT(stddev[0], 1.0);
  EXPECT_LT(stddev[0], 4.0);
}

TEST(SimRender, LookingAtTheSkyGivesBlackLevel) {
  const NavcamModel model = HalfNavcam();
  NavcamRenderOptions options;
  options.add_noise = false;
  const NavcamRenderer renderer(TestTerrain(), model, options);
  const RenderedPair pair = renderer.RenderPair(MakePose(0, 0, 0, 0, 0, 0), 0.0, -60 * M_PI / 180 + 0.1, 1, true);
  EXPECT_EQ(pair.left.sky_pixels, 512 * 512);
  EXPECT_EQ(cv::countNonZero(pair.left.image != static_cast<int>(options.black_level_dn)), 0);
  EXPECT_EQ(cv::countNonZero(pair.left.depth), 0);
}


}  // namespace
}  // namespace vloc::sim

namespace vloc::sim {
namespace {

// Two sites 10 m apart, forward-looking 7-pair panoramas (the front end's
// test scene), at a quarter of the Navcam resolution.
TEST(SimRoverWorld, TwoSitesTenMetresApartRenderTheirPanoramas) {
  RoverWorldOptions options;
  options.terrain.size_m = 60.0;
  options.terrain.origin_x_m = -15.0;
  options.terrain.origin_y_m = -30.0;
  for (PinholeCamera* c : {&options.navcam.rig.left, &options.navcam.rig.right}) {
    c->width = c->height = 256;
    c->fx = c->fy = 1189.0 / 4;
    c->cx = c->cy = 127.5;
  }
  options.traverse.plan.sites_xy = {0, 0, 10, 0};
  const RoverWorld world(options);
  ASSERT_EQ(world.traverse().sites.size(), 2u);
  const Pose3& site1 = world.traverse().sites[1].world_from_body;
  EXPECT_NEAR((site1.translation().head<2>() - Eigen::Vector2d(10, 0)).norm(), 0.0, 0.3);
  EXPECT_NEAR(Heading(site1), 0.0, 1e-3);
  const std::vector<StereoPair> pairs = world.RenderSite(1);
  ASSERT_EQ(pairs.size(), 7u);
  for (const StereoPair& pair : pairs) {
    EXPECT_EQ(pair.site_id, 1);
    EXPECT_EQ(pair.left.size(), cv::Size(256, 256));
    EXPECT_EQ(pair.utime, world.traverse().sites[1].exposures[pair.pair_index].utime);
  }
  const std::vector<StereoPair> again = world.RenderSite(1);
  EXPECT_EQ(cv::norm(pairs[3].left, again[3].left, cv::NORM_L1), 0.0);
  EXPECT_THROW(world.RenderSite(2), std::invalid_argument);
}


// The photometric models (issue 16): Lambert is mu0; lunar-Lambert with L = 1
// is Lommel-Seeliger, 2 mu0 / (mu0 + mu), which does not darken towards the
// limb; the opposition surge brightens zero phase by 1 + B0 and fades with g.
TEST(SimRender, PhotometricModels) {
  NavcamRenderOptions o;
  EXPECT_DOUBLE_EQ(Reflectance(o, 0.5, 0.9, 0.3), 0.5);
  EXPECT_DOUBLE_EQ(Reflectance(o, -0.2, 0.9, 0.3), 0.0);
  o.photometric = "lunar_lambert";
  o.lunar_lambert_l = 1.0;
  EXPECT_NEAR(Reflectance(o, 0.5, 0.5, 1.0), 1.0, 1e-12);        // 2 x 0.5 / 1
  EXPECT_NEAR(Reflectance(o, 0.2, 0.2, 1.0), 1.0, 1e-12);        // same at the limb: no limb darkening
  o.opposition_b0 = 1.0;
  o.opposition_h = 0.06;
  EXPECT_NEAR(Reflectance(o, 0.5, 0.5, 0.0), 2.0, 1e-12);        // 1 + B0 at zero phase
  const double at_10deg = Reflectance(o, 0.5, 0.5, 10 * M_PI / 180);
  EXPECT_LT(at_10deg, 1.5);                                       // h = 0.06: mostly gone by 10 deg
  EXPECT_GT(at_10deg, 1.0);
  std::string error;
  o.photometric = "hapke";
  EXPECT_FALSE(o.Check(&error));
}

// Camera effects: 12-bit companding, vignetting and hot pixels do what they say.
TEST(SimRender, CameraEffects) {
  const NavcamModel model = HalfNavcam();
  const Pose3 world_from_body = MakePose(0, 0, 0, 0.02, -0.03, 0.3);
  NavcamRenderOptions plain;
  plain.add_noise = false;
  const RenderedPair base = NavcamRenderer(TestTerrain(), model, plain).RenderPair(world_from_body, 0.0, 0.4, 1);
  // Companding: 12-bit DN = 16 x the 8-bit ones, then 255 sqrt(dn / 4095).
  NavcamRenderOptions twelve = plain;
  twelve.adc_bits = 12;
  twelve.exposure_gain_dn *= 16;
  twelve.black_level_dn *= 16;
  const RenderedPair companded = NavcamRenderer(TestTerrain(), model, twelve).RenderPair(world_from_body, 0.0, 0.4, 1);
  const cv::Mat& b = base.left.image;
  const cv::Mat& c = companded.left.image;
  int checked = 0;
  for (int v = 0; v < b.rows; v += 7)
    for (int u = 0; u < b.cols; u += 7) {
      const int dn8 = b.at<uint8_t>(v, u);
      if (dn8 < 20 || dn8 > 250) continue;
      EXPECT_NEAR(c.at<uint8_t>(v, u), 255.0 * std::sqrt(16.0 * dn8 / 4095.0), 4.0) << u << "," << v;
      ++checked;
    }
  EXPECT_GT(checked, 1000);
  // Vignetting 0.3: the corners lose about 30 % against the centre, relative to the plain render.
  NavcamRenderOptions vignetted = plain;
  vignetted.vignetting = 0.3;
  vignetted.black_level_dn = plain.black_level_dn = 0;
  const cv::Mat v0 = NavcamRenderer(TestTerrain(), model, plain).RenderPair(world_from_body, 0.0, 0.4, 1).left.image;
  const cv::Mat v1 = NavcamRenderer(TestTerrain(), model, vignetted).RenderPair(world_from_body, 0.0, 0.4, 1).left.image;
  const cv::Rect centre(236, 236, 40, 40), corner(472, 472, 40, 40);
  EXPECT_NEAR(cv::mean(v1(centre))[0] / cv::mean(v0(centre))[0], 1.0, 0.02);
  EXPECT_NEAR(cv::mean(v1(corner))[0] / cv::mean(v0(corner))[0], 0.72, 0.05);
  // Hot pixels: the same pixels stuck at 255 in every exposure of that camera.
  NavcamRenderOptions hot = plain;
  hot.exposure_gain_dn = 200;  // dark: nothing else reaches 255
  hot.hot_pixel_fraction = 0.001;
  const NavcamRenderer hot_renderer(TestTerrain(), model, hot);
  const cv::Mat h1 = hot_renderer.RenderPair(world_from_body, 0.0, 0.4, 1).left.image;
  const cv::Mat h2 = hot_renderer.RenderPair(world_from_body, 0.3, 0.4, 2).left.image;
  const int stuck = cv::countNonZero(h1 == 255);
  EXPECT_NEAR(stuck, 0.001 * h1.total(), 0.4 * 0.001 * h1.total());
  EXPECT_EQ(cv::countNonZero((h1 == 255) != (h2 == 255)), 0);
}

// The sun moves between sites: azimuth and elevation steps, and the cast
// shadows follow (lower sun, more shadow).
TEST(SimRoverWorld, SunAndExposureChangeBetweenSites) {
  RoverWorldOptions options;
  options.terrain.size_m = 60.0;
  options.terrain.origin_x_m = -15.0;
  options.terrain.origin_y_m = -30.0;
  options.terrain.sun_elevation_deg = 30.0;
  options.lighting.azimuth_step_deg = 30.0;
  options.lighting.elevation_step_deg = -12.0;
  options.lighting.exposure_jitter = 0.2;
  for (PinholeCamera* c : {&options.navcam.rig.left, &options.navcam.rig.right}) {
    c->width = c->height = 256;
    c->fx = c->fy = 1189.0 / 4;
    c->cx = c->cy = 127.5;
  }
  options.traverse.plan.sites_xy = {0, 0, 10, 0, 20, 0};
  const RoverWorld world(options);
  EXPECT_NEAR(world.SunAtSite(2).x(), options.terrain.sun_azimuth_deg + 60.0, 1e-12);
  EXPECT_NEAR(world.SunAtSite(2).y(), 6.0, 1e-12);
  EXPECT_NEAR(world.SunAtSite(3).y(), options.lighting.min_elevation_deg, 1e-12);  // clamped
  for (int s = 0; s < 3; ++s) EXPECT_LE(std::abs(world.GainAtSite(s) - 1.0), 0.2 + 1e-12);
  EXPECT_NE(world.GainAtSite(0), world.GainAtSite(1));
  // Shadowed ground in a 20 m square: at 6 deg far more than at 30 deg.
  auto shadowed = [&](int site) {
    world.RenderSite(site);  // moves the terrain's sun to the site's
    int dark = 0, n = 0;
    for (double x = -5; x < 15; x += 0.25)
      for (double y = -10; y < 10; y += 0.25, ++n) dark += world.terrain().SunVisibility(x, y) < 0.5 ? 1 : 0;
    return static_cast<double>(dark) / n;
  };
  const double at30 = shadowed(0), at6 = shadowed(2);
  EXPECT_GT(at6, 0.004);
  EXPECT_GT(at6, 4 * at30) << "shadow fraction " << at30 << " at 30 deg, " << at6 << " at 6 deg";
  // A profile file lays its keys over the base config.
  const auto hard = LoadOptionsFile<LightingOptions>("config/procs/sim_rover_hard.yaml", "lighting");
  EXPECT_DOUBLE_EQ(hard.azimuth_step_deg, 30.0);
  const auto extreme = LoadOptionsFile<TerrainOptions>("config/procs/sim_rover_extreme.yaml", "terrain");
  EXPECT_DOUBLE_EQ(extreme.sun_elevation_deg, 10.0);
  EXPECT_DOUBLE_EQ(extreme.resolution_m, 0.04);  // from config/sim/terrain.yaml, through two includes
}

}  // namespace
}  // namespace vloc::sim
