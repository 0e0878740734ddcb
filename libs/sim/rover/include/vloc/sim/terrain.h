#pragma once
// The simulated lunar-like terrain of the rover world.
//
// A height field (default 204.8 m x 204.8 m at 4 cm, world frame: x east,
// y north, z up, metres) made of fractal relief, craters with raised rims and
// scattered half-buried rocks, plus a procedural regolith albedo evaluated
// at any point down to millimetre scale, a sun and its cast shadows. Built
// deterministically from `TerrainOptions::seed`: same options, same heights.
//
//   vloc::sim::Terrain terrain(options);          // throws std::invalid_argument
//   double z = terrain.Height(x, y);              // bilinear, metres
//   Eigen::Vector3d n = terrain.Normal(x, y);     // unit, up-pointing
//   double a = terrain.Albedo(x, y, footprint);   // 0..1, band-limited to footprint (m)
//   double L = terrain.Radiance(x, y, footprint); // albedo x (ambient + sun x lit), 0..~1
//   auto hit = terrain.Raycast(origin, direction, max_range);
//   cv::Mat ortho = terrain.RenderOrthoimage({-10, -10, 10, 10}, 0.02);
//
// Height(0, 0) is 0 by default (the world origin is the first rover site).

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

namespace vloc {
class OptionsReader;
}

namespace vloc::sim {

struct TerrainOptions {
  uint64_t seed = 1;                 // selects the terrain; same seed, same terrain
  double size_m = 204.8;             // m, side of the square height field
  double resolution_m = 0.04;        // m, grid spacing of the height field
  double origin_x_m = -40.0;         // m, world x of the field's west edge
  double origin_y_m = -102.4;        // m, world y of the field's south edge
  bool zero_at_origin = true;        // shift heights so Height(0, 0) = 0

  double relief_amplitude_m = 0.6;   // m, amplitude of the largest relief octave
  double relief_wavelength_m = 80.0; // m, wavelength of the largest relief octave
  double relief_persistence = 0.56;  // amplitude ratio between successive octaves (2^-Hurst)

  double crater_density = 0.5;       // craters wider than 1 m per 100 m^2 (cumulative ~ D^-2)
  double crater_min_diameter_m = 0.6;   // m, smallest crater
  double crater_max_diameter_m = 24.0;  // m, largest crater
  double crater_depth_ratio_min = 0.05; // depth / diameter of the most degraded craters
  double crater_depth_ratio_max = 0.18; // depth / diameter of the freshest craters
  double crater_rim_ratio = 0.035;      // rim height / diameter of a fresh crater

  double rock_density = 5.0;         // rocks wider than 0.1 m per 100 m^2 (cumulative ~ D^-2.5)
  double rock_min_diameter_m = 0.06; // m, smallest rock
  double rock_max_diameter_m = 0.9;  // m, largest rock
  double clear_radius_m = 2.0;       // m, no crater or rock wider than 0.3 m this close to the origin

  double albedo_mean = 0.12;         // mean regolith albedo (0..1)
  double albedo_contrast = 0.14;     // relative standard deviation of the albedo texture
  double albedo_wavelength_m = 8.0;  // m, largest albedo texture wavelength
  double albedo_finest_m = 0.001;    // m, finest albedo texture wavelength
  double albedo_persistence = 0.95;  // amplitude ratio between octaves (near 1: texture at every scale)

  double micro_slope = 0.06;         // rms slope added per octave by sub-grid micro-relief (bump shading)
  double micro_wavelength_m = 0.16;  // m, largest micro-relief wavelength
  double micro_finest_m = 0.001;     // m, finest micro-relief wavelength

  double sun_azimuth_deg = 135.0;    // deg, direction toward the sun, counter-clockwise from east
  double sun_elevation_deg = 30.0;   // deg, sun elevation above the horizon
  double ambient = 0.04;             // radiance of a shadowed surface relative to a sun-facing one

  int num_threads = 2;               // OpenMP threads for building the terrain

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// A crater as placed on the terrain (world frame).
struct Crater {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  // m
  double diameter = 0;                               // m, rim to rim
  double depth = 0;                                  // m, floor below the surroundings
  double rim_height = 0;                             // m, rim above the surroundings
};

// A rock as placed on the terrain (world frame): a half-buried ellipsoid.
struct Rock {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  // m
  double diameter = 0;                               // m, longest horizontal axis
  double height = 0;                                 // m, top above the surrounding ground
};

// Axis-aligned world region, metres.
struct Region {
  double x_min = 0, y_min = 0, x_max = 0, y_max = 0;
};

struct RayHit {
  double range = 0;                                // m, along the unit direction
  Eigen::Vector3d point = Eigen::Vector3d::Zero(); // m, world
};

// What building the terrain did.
struct TerrainSummary {
  int grid_vertices = 0;       // per side
  int num_craters = 0;
  int num_rocks = 0;
  double min_height = 0;       // m
  double max_height = 0;       // m
  double build_seconds = 0;    // wall time
};

class Terrain {
 public:
  // Builds the whole field (a few seconds at the default size on 2 cores).
  // Throws std::invalid_argument naming the bad option.
  explicit Terrain(const TerrainOptions& options);

  const TerrainOptions& options() const { return options_; }
  const TerrainSummary& summary() const { return summary_; }
  const std::vector<Crater>& craters() const { return craters_; }
  const std::vector<Rock>& rocks() const { return rocks_; }
  Region Bounds() const;
  bool Contains(double x, double y) const;

  // Bilinear height (m); outside the field the edge value is used.
  double Height(double x, double y) const;
  // Unit normal (bilinear blend of per-vertex normals).
  Eigen::Vector3d Normal(double x, double y) const;
  // Normal including the sub-grid micro-relief, band-limited to `footprint` (m).
  Eigen::Vector3d ShadingNormal(double x, double y, double footprint = 0.0) const;
  // The same, given Normal(x, y) already computed.
  Eigen::Vector3d ShadingNormal(double x, double y, double footprint, const Eigen::Vector3d& normal) const;
  // Regolith albedo at (x, y); `footprint` (m) is the size of the area the
  // sample stands for (texture finer than that fades out; 0 = all detail).
  double Albedo(double x, double y, double footprint = 0.0) const;
  // 1 in sunlight, 0 in a cast shadow (soft over about a centimetre).
  double SunVisibility(double x, double y) const;
  // Unit vector toward the sun, world frame.
  const Eigen::Vector3d& SunDirection() const { return sun_direction_; }
  // Moves the sun (deg, as in TerrainOptions) and recomputes the cast shadows (about 0.2 s at the default size).
  // Not thread-safe against concurrent rendering.
  void SetSun(double azimuth_deg, double elevation_deg);
  // Reflected radiance for a unit sun irradiance: albedo x (ambient + lit x
  // max(0, n.s)), Lambertian, with n = ShadingNormal.
  double Radiance(double x, double y, double footprint = 0.0) const;

  // First intersection of the ray origin + t * direction (unit) with the
  // height field for 0 <= t <= max_range; nullopt when it leaves the field
  // or the range first.
  std::optional<RayHit> Raycast(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                double max_range) const;

  // Top-down view, north up: pixel (0, 0) is the north-west corner of
  // `region`; CV_8UC1, gray = radiance scaled so the mean albedo in full sun
  // at normal incidence is 200.
  cv::Mat RenderOrthoimage(const Region& region, double m_per_px) const;

  // Grid access (vertex (i, j) at x = origin_x + i * resolution, y = origin_y + j * resolution).
  int vertices_per_side() const { return n_; }
  float VertexHeight(int i, int j) const { return heights_[static_cast<size_t>(j) * n_ + i]; }

 private:
  void BuildRelief();
  void PlaceCraters();
  void AddCrater(const Crater& c);  // its bowl, rim and ejecta added to the heights
  void PlaceRocks();
  void BuildMaxMips();
  void SunFromOptions();
  void BuildShadowHorizon();
  double Bilinear(const std::vector<float>& field, double x, double y) const;
  bool ClipToTerrainBox(double o_x, double o_y, double o_z, double d_x, double d_y, double d_z, double* t0,
                        double* t1) const;
  bool IntersectCell(int ci, int cj, double o_x, double o_y, double o_z, double d_x, double d_y,
                     double d_z, double t_a, double t_b, double* t_hit) const;

  TerrainOptions options_;
  TerrainSummary summary_;
  int n_ = 0;        // vertices per side
  int cells_ = 0;    // cells per side (n_ - 1)
  double inv_res_ = 0;
  std::vector<float> heights_;   // n_ x n_, row j = y
  std::vector<float> horizon_;   // n_ x n_, height of the sun-ward horizon line above each vertex
  struct MaxLevel {
    int width = 0;
    std::vector<float> max_height;
  };
  std::vector<MaxLevel> max_levels_;  // level L cell covers 2^L x 2^L grid cells
  std::vector<Crater> craters_;
  std::vector<Rock> rocks_;
  Eigen::Vector3d sun_direction_ = Eigen::Vector3d::UnitZ();
};

}  // namespace vloc::sim
