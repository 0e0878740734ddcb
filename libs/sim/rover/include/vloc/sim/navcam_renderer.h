#pragma once
// Renders what the Navcam stereo pair sees of a simulated Terrain.
//
// Each pixel casts one ray (through the lens distortion of the camera model
// when it has one) into the height field; the hit is shaded Lambertian with
// the terrain's sun and cast shadows, the albedo texture is band-limited to
// the pixel footprint, and sensor noise (read + shot) and 8-bit quantisation
// are applied. Pixels that see no terrain (sky, off the field) are black
// level + noise. Noise is a pure function of (noise_seed, pixel): same
// inputs, same bytes, whatever the thread count.
//
//   vloc::sim::NavcamRenderer renderer(terrain, navcam_model, options);
//   vloc::sim::RenderedPair pair = renderer.RenderPair(world_from_body, pan, tilt, seed, true);
//   pair.left.image   // CV_8UC1, raw (distorted) image
//   pair.left.depth   // CV_32F, z in the left camera frame (m), 0 where nothing was hit
//
// Frames: world_from_body as in vloc/common/pose.h; the cameras sit where
// MastKinematics::BodyFromLeft/BodyFromRight put them.

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/pose.h"
#include "vloc/sim/terrain.h"

namespace vloc {
class OptionsReader;
}

namespace vloc::sim {

struct NavcamRenderOptions {
  double exposure_gain_dn = 1600.0;      // DN per unit radiance (radiance = albedo x illumination)
  double black_level_dn = 4.0;           // DN, output with no light
  double read_noise_dn = 1.0;            // DN, 1-sigma Gaussian read noise
  double shot_noise_dn2_per_dn = 0.02;   // DN^2 of shot-noise variance per DN of signal
  bool add_noise = true;                 // false: noise-free images (still quantised)
  bool apply_distortion = true;          // render through the camera's lens distortion
  double max_range_m = 200.0;            // m, rays beyond this see sky
  int max_footprint_samples = 6;         // a grazing pixel's ground footprint is long along the line of sight:
                                         // shaded at up to this many points along it, each filtered to its share
                                         // (1 = one isotropic sample, which blurs the far ground across the view)
  // What real Navcam images have that the defaults leave out (issue 16; all off by default):
  std::string photometric = "lambert";   // "lambert" or "lunar_lambert" (McEwen 1991: regolith, limb-darkening
                                         // free: 2 L mu0 / (mu0 + mu) + (1 - L) mu0), with the opposition surge below
  double lunar_lambert_l = 0.8;          // L of the lunar-Lambert model (1 = pure Lommel-Seeliger)
  double opposition_b0 = 0.0;            // amplitude of the opposition surge (Hapke B0; lunar regolith ~1)
  double opposition_h = 0.06;            // angular width of the surge (Hapke h, rad)
  double sky_dn = 0.0;                   // DN of pixels that see no terrain (0 = the Moon's black sky; Mars ~ 100)
  double vignetting = 0.0;               // fraction of light lost at the image corner (radial, quadratic)
  int adc_bits = 8;                      // 8 (linear) or 12: exposure_gain_dn, black level and noise in 12-bit DN,
                                         // then companded to 8 bits by a square-root table (like MSL's Navcams)
  double hot_pixel_fraction = 0.0;       // fraction of pixels stuck at 255 (fixed per camera)
  // The rover's own deck (RenderPair only): a flat slab of solar cells at deck_top_m above the body origin,
  // from deck_rear_m to deck_front_m along the body x axis and +-deck_half_width_m across. Side and low views
  // see it at the image bottom, at the same place at every site.
  bool deck = false;
  double deck_top_m = 0.9;
  double deck_front_m = 0.3;
  double deck_rear_m = -1.1;
  double deck_half_width_m = 0.75;
  int num_threads = 2;                   // OpenMP threads

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// Reflectance for a unit sun irradiance of a surface element with incidence cosine mu0 and emission cosine mu, at
// phase angle g (rad, between the directions to the sun and to the camera): Lambert (mu0) or lunar-Lambert with
// the opposition surge, as options.photometric says.
double Reflectance(const NavcamRenderOptions& options, double mu0, double mu, double g);

struct RenderedImage {
  cv::Mat image;        // CV_8UC1
  cv::Mat depth;        // CV_32F, camera-frame z (m) of each pixel's hit, 0 = none; empty unless asked
  Pose3 world_from_camera = Pose3::Identity();
  int sky_pixels = 0;   // pixels that hit no terrain
  cv::Mat deck;         // CV_8UC1, 255 where the rover's own deck is seen; empty unless the deck is drawn
  double seconds = 0;   // wall time of the render
};

struct RenderedPair {
  RenderedImage left;
  RenderedImage right;
};

class NavcamRenderer {
 public:
  // Throws std::invalid_argument when the options or the model are invalid.
  // The terrain must outlive the renderer.
  NavcamRenderer(const Terrain& terrain, const NavcamModel& model, const NavcamRenderOptions& options);

  // Renders one camera at world_from_camera (camera: x right, y down, z forward).
  // gain_factor: this exposure's gain relative to exposure_gain_dn (auto-exposure differing between sites).
  // world_from_body (optional): the rover body, to draw its deck when options.deck.
  RenderedImage Render(const PinholeCamera& camera, const Pose3& world_from_camera, uint64_t noise_seed,
                       bool with_depth = false, double gain_factor = 1.0, const Pose3* world_from_body = nullptr) const;

  // Renders the stereo pair for the rover at world_from_body with the mast
  // at pan/tilt (rad, as in MastKinematics). The right image uses a noise
  // seed derived from noise_seed.
  RenderedPair RenderPair(const Pose3& world_from_body, double pan, double tilt, uint64_t noise_seed,
                          bool with_depth = false, double gain_factor = 1.0) const;

  const NavcamModel& model() const { return model_; }
  const NavcamRenderOptions& options() const { return options_; }

 private:
  // Unit-z camera rays (x, y, 1) of every raw pixel, row-major.
  std::vector<Eigen::Vector3f> PixelRays(const PinholeCamera& camera) const;

  const Terrain& terrain_;
  NavcamModel model_;
  NavcamRenderOptions options_;
  std::vector<Eigen::Vector3f> left_rays_, right_rays_;
};

// Same camera model (size, intrinsics, distortion)?
bool SameCamera(const PinholeCamera& a, const PinholeCamera& b);

}  // namespace vloc::sim
