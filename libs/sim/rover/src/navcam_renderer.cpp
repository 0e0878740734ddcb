#include "vloc/sim/navcam_renderer.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <stdexcept>

#include "vloc/common/options.h"
#include "vloc/common/stopwatch.h"
#include "vloc/sim/noise.h"

namespace vloc::sim {

void NavcamRenderOptions::Visit(OptionsReader& r) {
  r.Optional("exposure_gain_dn", &exposure_gain_dn, "DN per unit radiance", Positive());
  r.Optional("black_level_dn", &black_level_dn, "DN with no light", InRightOpen(0, 255));
  r.Optional("read_noise_dn", &read_noise_dn, "DN, 1-sigma read noise", NonNegative());
  r.Optional("shot_noise_dn2_per_dn", &shot_noise_dn2_per_dn, "DN^2 shot-noise variance per DN", NonNegative());
  r.Optional("add_noise", &add_noise, "false: noise-free images");
  r.Optional("apply_distortion", &apply_distortion, "render through the lens distortion");
  r.Optional("max_range_m", &max_range_m, "m, rays beyond see sky", Positive());
  r.Optional("max_footprint_samples", &max_footprint_samples, "shading samples along a grazing pixel's footprint",
             AtLeast(1));
  r.Optional("photometric", &photometric, "reflectance model", OneOf({"lambert", "lunar_lambert"}));
  r.Optional("lunar_lambert_l", &lunar_lambert_l, "L of the lunar-Lambert model", InRange(0, 1));
  r.Optional("opposition_b0", &opposition_b0, "opposition surge amplitude", NonNegative());
  r.Optional("opposition_h", &opposition_h, "opposition surge width (rad)", Positive());
  r.Optional("sky_dn", &sky_dn, "DN of sky pixels", InRange(0, 255));
  r.Optional("vignetting", &vignetting, "fraction of light lost at the corner", InRightOpen(0, 1));
  r.Optional("adc_bits", &adc_bits, "bits per sample (12: square-root companded to 8)", Is(8) || Is(12));
  r.Optional("hot_pixel_fraction", &hot_pixel_fraction, "fraction of pixels stuck at 255", InRightOpen(0, 0.01));
  r.Optional("deck", &deck, "draw the rover's deck (side and low views see it)");
  r.Optional("deck_top_m", &deck_top_m, "m, deck height above the body origin");
  r.Optional("deck_front_m", &deck_front_m, "m, deck front edge along body x");
  r.Optional("deck_rear_m", &deck_rear_m, "m, deck rear edge along body x");
  r.Optional("deck_half_width_m", &deck_half_width_m, "m, deck half width across");
  r.Optional("num_threads", &num_threads, "OpenMP threads", AtLeast(1));
  r.Relation("deck", !deck || (deck_top_m > 0 && deck_front_m > deck_rear_m && deck_half_width_m > 0),
             "needs deck_top_m > 0, deck_front_m > deck_rear_m and deck_half_width_m > 0");
}

bool NavcamRenderOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

bool SameCamera(const PinholeCamera& a, const PinholeCamera& b) {
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy && a.cx == b.cx &&
         a.cy == b.cy && a.k1 == b.k1 && a.k2 == b.k2 && a.p1 == b.p1 && a.p2 == b.p2 && a.k3 == b.k3;
}

NavcamRenderer::NavcamRenderer(const Terrain& terrain, const NavcamModel& model,
                               const NavcamRenderOptions& options)
    : terrain_(terrain), model_(model), options_(options) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument(error);
  if (!model_.Check(&error)) throw std::invalid_argument("navcam model: " + error);
  left_rays_ = PixelRays(model_.rig.left);
  right_rays_ = PixelRays(model_.rig.right);
}

std::vector<Eigen::Vector3f> NavcamRenderer::PixelRays(const PinholeCamera& camera) const {
  std::vector<Eigen::Vector3f> rays(static_cast<size_t>(camera.width) * camera.height);
  const bool distort = options_.apply_distortion && camera.HasDistortion();
#pragma omp parallel for schedule(static) num_threads(options_.num_threads)
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      Eigen::Vector2d px(u, v);
      if (distort) px = camera.Undistort(px);
      rays[static_cast<size_t>(v) * camera.width + u] = camera.Ray(px).cast<float>();
    }
  }
  return rays;
}

double Reflectance(const NavcamRenderOptions& o, double mu0, double mu, double g) {
  if (o.photometric == "lambert") return std::max(0.0, mu0);
  if (mu0 <= 0) return 0.0;
  const double lunar = 2.0 * o.lunar_lambert_l * mu0 / (mu0 + std::max(mu, 0.05)) + (1.0 - o.lunar_lambert_l) * mu0;
  const double surge = o.opposition_b0 / (1.0 + std::tan(0.5 * std::abs(g)) / o.opposition_h);
  return lunar * (1.0 + surge);
}

namespace {

// Where a ray (body frame) meets the deck's top, as its distance along the ray; nothing when it misses.
std::optional<double> HitDeck(const NavcamRenderOptions& o, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) {
  if (dir.z() >= -1e-9 || origin.z() <= o.deck_top_m) return std::nullopt;
  const double t = (o.deck_top_m - origin.z()) / dir.z();
  const Eigen::Vector3d p = origin + t * dir;
  if (p.x() < o.deck_rear_m || p.x() > o.deck_front_m || std::abs(p.y()) > o.deck_half_width_m) return std::nullopt;
  return t;
}

// Solar cells (dark) in a grid of bright frames, 15 cm apart (body frame, m).
double DeckAlbedo(const Eigen::Vector3d& p) {
  const double cell = 0.15, frame = 0.012;
  const double fx = std::fmod(std::abs(p.x()), cell), fy = std::fmod(std::abs(p.y()), cell);
  return fx < frame || fy < frame ? 0.7 : 0.12;
}


// The terrain's radiance at a hit, summed over `samples` points along the
// line of sight (divide by it). The pixel's footprint on the ground (m) is
// range / f across the line of sight, stretched by 1 / cos along it; a long
// footprint is shaded at several points along the line of sight, each
// filtered to its part (anisotropic filtering): one isotropic sample either
// aliases along the view or blurs the far ground across it.
struct Shading {
  double radiance = 0;
  int samples = 1;
};
Shading ShadeTerrain(const Terrain& terrain, const NavcamRenderOptions& o, bool lambert, const RayHit& hit,
                     const Eigen::Vector3d& dir, double ray_norm, double inv_f) {
  const Eigen::Vector3d& sun = terrain.SunDirection();
  const double ambient = terrain.options().ambient;
  const Eigen::Vector3d& p = hit.point;
  const Eigen::Vector3d n = terrain.Normal(p.x(), p.y());
  const double cos_view = std::max(0.05, std::abs(dir.dot(n)));
  const double across = hit.range * ray_norm * inv_f;
  const double along_length = across / cos_view;
  Eigen::Vector3d along = dir - dir.dot(n) * n;
  const double along_norm = along.norm();
  Shading shade;
  shade.samples = along_norm > 1e-6 ? std::clamp(static_cast<int>(std::ceil(along_length / (2 * across))), 1,
                                                 o.max_footprint_samples)
                                    : 1;
  const int samples = shade.samples;
  if (samples > 1) along /= along_norm;
  const double footprint = std::max(across, along_length / samples);
  const double visibility = terrain.SunVisibility(p.x(), p.y());
  for (int k = 0; k < samples; ++k) {
    const double offset = samples > 1 ? ((k + 0.5) / samples - 0.5) * along_length : 0.0;
    const double qx = p.x() + offset * along.x(), qy = p.y() + offset * along.y();
    const double albedo = terrain.Albedo(qx, qy, footprint);
    const Eigen::Vector3d shading_normal = terrain.ShadingNormal(qx, qy, footprint, n);
    const double mu0 = std::max(0.0, shading_normal.dot(sun));
    const double direct =
        (lambert ? mu0 : Reflectance(o, mu0, -dir.dot(shading_normal), std::acos(std::clamp(-dir.dot(sun), -1.0, 1.0)))) *
        visibility;
    shade.radiance += albedo * (ambient + (1.0 - ambient) * direct);
  }
  return shade;
}

// What the sensor makes of `signal` DN at pixel (u, v) (index v * width +
// u; corner2: the squared distance of the principal point from the
// corner): vignetting, black level, read and shot noise, 12-bit companding,
// stuck pixels (hot_seed: the sensor's), 8 bits.
uint8_t SensorValue(const NavcamRenderOptions& o, const PinholeCamera& camera, double corner2, int u, int v,
                    size_t index, double signal, uint64_t noise_seed, uint64_t hot_seed) {
  if (o.vignetting > 0) {
    const double r2 = ((u - camera.cx) * (u - camera.cx) + (v - camera.cy) * (v - camera.cy)) / corner2;
    signal *= 1.0 - o.vignetting * r2;
  }
  double dn = o.black_level_dn + signal;
  if (o.add_noise) {
    const double sigma = std::sqrt(o.read_noise_dn * o.read_noise_dn + o.shot_noise_dn2_per_dn * signal);
    dn += sigma * HashToGaussian(Hash3(noise_seed, index, 0xCA3E7AULL));
  }
  if (o.adc_bits == 12) dn = 255.0 * std::sqrt(std::clamp(dn, 0.0, 4095.0) / 4095.0);  // companding
  if (o.hot_pixel_fraction > 0 && HashToUnit(Hash3(hot_seed, index, 0x407ULL)) < o.hot_pixel_fraction) dn = 255;
  return static_cast<uint8_t>(std::clamp(std::lround(dn), 0L, 255L));
}

}  // namespace

RenderedImage NavcamRenderer::Render(const PinholeCamera& camera, const Pose3& world_from_camera,
                                     uint64_t noise_seed, bool with_depth, double gain_factor,
                                     const Pose3* world_from_body) const {
  const auto start = std::chrono::steady_clock::now();
  std::vector<Eigen::Vector3f> own_rays;
  const std::vector<Eigen::Vector3f>* rays = nullptr;
  if (SameCamera(camera, model_.rig.left)) {
    rays = &left_rays_;
  } else if (SameCamera(camera, model_.rig.right)) {
    rays = &right_rays_;
  } else {
    own_rays = PixelRays(camera);
    rays = &own_rays;
  }
  RenderedImage out;
  out.world_from_camera = world_from_camera;
  out.image.create(camera.height, camera.width, CV_8UC1);
  if (with_depth) out.depth = cv::Mat::zeros(camera.height, camera.width, CV_32F);
  const Eigen::Matrix3d R = world_from_camera.linear();
  const Eigen::Vector3d origin = world_from_camera.translation();
  const Eigen::Vector3d& sun = terrain_.SunDirection();
  const double ambient = terrain_.options().ambient;
  const double inv_f = 1.0 / std::sqrt(camera.fx * camera.fy);
  const bool lambert = options_.photometric == "lambert";
  const double corner2 = camera.cx * camera.cx + camera.cy * camera.cy;
  const uint64_t hot_seed = SameCamera(camera, model_.rig.right) ? 2 : 1;  // stuck pixels belong to the sensor
  const bool deck = options_.deck && world_from_body != nullptr;
  const Pose3 body_from_world = deck ? world_from_body->inverse() : Pose3::Identity();
  const Eigen::Vector3d origin_body = body_from_world * origin;
  const double deck_sun = deck ? std::max(0.0, (world_from_body->linear() * Eigen::Vector3d::UnitZ()).dot(sun)) : 0.0;
  if (deck) out.deck = cv::Mat::zeros(camera.height, camera.width, CV_8UC1);
  int sky = 0;
#pragma omp parallel for schedule(dynamic, 4) num_threads(options_.num_threads) reduction(+ : sky)
  for (int v = 0; v < camera.height; ++v) {
    uint8_t* row = out.image.ptr<uint8_t>(v);
    float* depth_row = with_depth ? out.depth.ptr<float>(v) : nullptr;
    for (int u = 0; u < camera.width; ++u) {
      const size_t index = static_cast<size_t>(v) * camera.width + u;
      const Eigen::Vector3d ray_cam = (*rays)[index].cast<double>();
      const double ray_norm = ray_cam.norm();
      const Eigen::Vector3d dir = R * (ray_cam / ray_norm);
      double signal = 0.0;
      const auto deck_t = deck ? HitDeck(options_, origin_body, body_from_world.linear() * dir) : std::nullopt;
      const auto hit = deck_t ? std::nullopt : terrain_.Raycast(origin, dir, options_.max_range_m);
      if (deck_t) {
        const Eigen::Vector3d q = origin_body + *deck_t * (body_from_world.linear() * dir);
        signal = options_.exposure_gain_dn * gain_factor * DeckAlbedo(q) * (ambient + (1.0 - ambient) * deck_sun);
        if (depth_row) depth_row[u] = static_cast<float>(*deck_t / ray_norm);
        out.deck.at<uint8_t>(v, u) = 255;
      } else if (hit) {
        const Shading shade = ShadeTerrain(terrain_, options_, lambert, *hit, dir, ray_norm, inv_f);
        signal = options_.exposure_gain_dn * gain_factor * shade.radiance / shade.samples;
        if (depth_row) depth_row[u] = static_cast<float>(hit->range / ray_norm);
      } else {
        ++sky;
        signal = options_.sky_dn * (options_.adc_bits == 12 ? 16.0 : 1.0) * gain_factor;
      }
      row[u] = SensorValue(options_, camera, corner2, u, v, index, signal, noise_seed, hot_seed);
    }
  }
  out.sky_pixels = sky;
  out.seconds = SecondsSince(start);
  return out;
}

RenderedPair NavcamRenderer::RenderPair(const Pose3& world_from_body, double pan, double tilt,
                                        uint64_t noise_seed, bool with_depth, double gain_factor) const {
  RenderedPair pair;
  const Pose3 world_from_left = world_from_body * model_.mast.BodyFromLeft(pan, tilt, model_.rig);
  const Pose3 world_from_right = world_from_body * model_.mast.BodyFromRight(pan, tilt, model_.rig);
  pair.left = Render(model_.rig.left, world_from_left, noise_seed, with_depth, gain_factor, &world_from_body);
  pair.right = Render(model_.rig.right, world_from_right, HashMix(noise_seed ^ 0x52494748ULL), with_depth, gain_factor,
                      &world_from_body);
  return pair;
}

}  // namespace vloc::sim
