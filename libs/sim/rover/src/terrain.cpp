#include "vloc/sim/terrain.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "vloc/common/options.h"
#include "vloc/common/stopwatch.h"
#include "vloc/sim/noise.h"

namespace vloc::sim {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Independent noise streams of one terrain.
enum Stream : uint64_t { kRelief = 1, kCraters = 2, kRocks = 3, kAlbedo = 4, kRockShape = 5, kMicro = 6 };

uint64_t StreamSeed(uint64_t seed, Stream stream) { return Hash3(seed, stream, 0x7E44A1ULL); }

// Uniform [0,1) number `index` of a stream.
double Uniform(uint64_t stream_seed, uint64_t index, uint64_t field) {
  return HashToUnit(Hash3(stream_seed, index, field));
}

// Inverse CDF of a truncated power law with cumulative N(>D) ~ D^-exponent.
double PowerLawSample(double u, double d_min, double d_max, double exponent) {
  const double r = std::pow(d_min / d_max, exponent);
  return d_min * std::pow(1.0 - u * (1.0 - r), -1.0 / exponent);
}

}  // namespace

void TerrainOptions::Visit(OptionsReader& r) {
  r.Optional("seed", &seed, "selects the terrain; same seed, same terrain");
  r.Optional("size_m", &size_m, "m, side of the square height field");
  r.Optional("resolution_m", &resolution_m, "m, grid spacing", InRange(0.005, 1));
  r.Optional("origin_x_m", &origin_x_m, "m, world x of the west edge");
  r.Optional("origin_y_m", &origin_y_m, "m, world y of the south edge");
  r.Optional("zero_at_origin", &zero_at_origin, "shift heights so Height(0,0) = 0");
  r.Optional("relief_amplitude_m", &relief_amplitude_m, "m, amplitude of the largest relief octave", NonNegative());
  r.Optional("relief_wavelength_m", &relief_wavelength_m, "m, largest relief wavelength", Positive());
  r.Optional("relief_persistence", &relief_persistence, "amplitude ratio between octaves", InOpen(0, 1));
  r.Optional("crater_density", &crater_density, "craters wider than 1 m per 100 m^2", NonNegative());
  r.Optional("crater_min_diameter_m", &crater_min_diameter_m, "m", Positive());
  r.Optional("crater_max_diameter_m", &crater_max_diameter_m, "m");
  r.Optional("crater_depth_ratio_min", &crater_depth_ratio_min, "depth/diameter, degraded craters", Positive());
  r.Optional("crater_depth_ratio_max", &crater_depth_ratio_max, "depth/diameter, fresh craters", AtMost(0.5));
  r.Optional("crater_rim_ratio", &crater_rim_ratio, "rim height/diameter, fresh craters");
  r.Optional("rock_density", &rock_density, "rocks wider than 0.1 m per 100 m^2", NonNegative());
  r.Optional("rock_min_diameter_m", &rock_min_diameter_m, "m", Positive());
  r.Optional("rock_max_diameter_m", &rock_max_diameter_m, "m");
  r.Optional("clear_radius_m", &clear_radius_m, "m, no large crater or rock this close to the origin");
  r.Optional("albedo_mean", &albedo_mean, "mean regolith albedo", InOpen(0, 1));
  r.Optional("albedo_contrast", &albedo_contrast, "relative std of the albedo texture", InRightOpen(0, 1));
  r.Optional("albedo_wavelength_m", &albedo_wavelength_m, "m, largest albedo wavelength");
  r.Optional("albedo_finest_m", &albedo_finest_m, "m, finest albedo wavelength", Positive());
  r.Optional("albedo_persistence", &albedo_persistence, "amplitude ratio between albedo octaves", InOpen(0, 1));
  r.Optional("micro_slope", &micro_slope, "rms slope per octave of the sub-grid micro-relief", InRightOpen(0, 1));
  r.Optional("micro_wavelength_m", &micro_wavelength_m, "m, largest micro-relief wavelength");
  r.Optional("micro_finest_m", &micro_finest_m, "m, finest micro-relief wavelength", Positive());
  r.Optional("sun_azimuth_deg", &sun_azimuth_deg, "deg, toward the sun, counter-clockwise from east");
  r.Optional("sun_elevation_deg", &sun_elevation_deg, "deg above the horizon", InLeftOpen(0.5, 90));
  r.Optional("ambient", &ambient, "radiance in shadow relative to full sun", InRange(0, 1));
  r.Optional("num_threads", &num_threads, "OpenMP threads", AtLeast(1));
  r.Relation("size_m", size_m >= 4 * resolution_m && size_m / resolution_m <= 20000,
             "must be 4 to 20000 cells of resolution_m");
  r.Relation("crater_max_diameter_m", crater_max_diameter_m >= crater_min_diameter_m,
             "must be >= crater_min_diameter_m");
  r.Relation("rock_max_diameter_m", rock_max_diameter_m >= rock_min_diameter_m, "must be >= rock_min_diameter_m");
  r.Relation("crater_depth_ratio_max", crater_depth_ratio_max >= crater_depth_ratio_min,
             "must be >= crater_depth_ratio_min");
  r.Relation("albedo_wavelength_m", albedo_wavelength_m > albedo_finest_m, "must exceed albedo_finest_m");
  r.Relation("micro_wavelength_m", micro_wavelength_m >= micro_finest_m, "must be >= micro_finest_m");
}

bool TerrainOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

Terrain::Terrain(const TerrainOptions& options) : options_(options) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument(error);
  const auto start = std::chrono::steady_clock::now();
  cells_ = static_cast<int>(std::ceil(options_.size_m / options_.resolution_m - 1e-9));
  n_ = cells_ + 1;
  inv_res_ = 1.0 / options_.resolution_m;
  SunFromOptions();

  BuildRelief();
  PlaceCraters();
  PlaceRocks();
  if (options_.zero_at_origin && Contains(0.0, 0.0)) {
    const float offset = static_cast<float>(Height(0.0, 0.0));
    for (float& h : heights_) h -= offset;
  }
  BuildMaxMips();
  BuildShadowHorizon();

  summary_.grid_vertices = n_;
  summary_.num_craters = static_cast<int>(craters_.size());
  summary_.num_rocks = static_cast<int>(rocks_.size());
  const auto [lo, hi] = std::minmax_element(heights_.begin(), heights_.end());
  summary_.min_height = *lo;
  summary_.max_height = *hi;
  summary_.build_seconds =
      SecondsSince(start);
}

Region Terrain::Bounds() const {
  return {options_.origin_x_m, options_.origin_y_m, options_.origin_x_m + cells_ * options_.resolution_m,
          options_.origin_y_m + cells_ * options_.resolution_m};
}

bool Terrain::Contains(double x, double y) const {
  const Region b = Bounds();
  return x >= b.x_min && x <= b.x_max && y >= b.y_min && y <= b.y_max;
}

void Terrain::BuildRelief() {
  heights_.assign(static_cast<size_t>(n_) * n_, 0.0f);
  const uint64_t seed = StreamSeed(options_.seed, kRelief);
  const double res = options_.resolution_m, x0 = options_.origin_x_m, y0 = options_.origin_y_m;
  const double amplitude = options_.relief_amplitude_m, wavelength = options_.relief_wavelength_m;
  const double persistence = options_.relief_persistence;
  // Octaves down to two grid cells. The long ones (>= 8 coarse steps) are
  // evaluated on a grid 4x coarser and interpolated (Catmull-Rom); only the
  // short ones are evaluated at every vertex.
  int octaves = 1;
  while (wavelength / std::pow(2.0, octaves) >= 2.0 * res) ++octaves;
  constexpr int kStep = 4;
  int coarse_octaves = 0;
  while (coarse_octaves < octaves && wavelength / std::pow(2.0, coarse_octaves) >= 8.0 * kStep * res) ++coarse_octaves;
  const int nc = n_ / kStep + 4;  // coarse nodes I = -1 .. nc-2 (margin for the 4-tap kernel)
  std::vector<double> coarse(static_cast<size_t>(nc) * nc, 0.0);
  if (coarse_octaves > 0) {
#pragma omp parallel for schedule(dynamic, 4) num_threads(options_.num_threads)
    for (int J = 0; J < nc; ++J) {
      for (int I = 0; I < nc; ++I) {
        coarse[static_cast<size_t>(J) * nc + I] = FractalOctaves(
            x0 + (I - 1) * kStep * res, y0 + (J - 1) * kStep * res, wavelength, 0, coarse_octaves, persistence, seed);
      }
    }
  }
  // Catmull-Rom weights for the kStep phases.
  double weights[kStep][4];
  for (int p = 0; p < kStep; ++p) {
    const double t = static_cast<double>(p) / kStep, t2 = t * t, t3 = t2 * t;
    weights[p][0] = 0.5 * (-t3 + 2 * t2 - t);
    weights[p][1] = 0.5 * (3 * t3 - 5 * t2 + 2);
    weights[p][2] = 0.5 * (-3 * t3 + 4 * t2 + t);
    weights[p][3] = 0.5 * (t3 - t2);
  }
#pragma omp parallel for schedule(dynamic, 16) num_threads(options_.num_threads)
  for (int j = 0; j < n_; ++j) {
    const double y = y0 + j * res;
    float* row = &heights_[static_cast<size_t>(j) * n_];
    const int J = j / kStep + 1;  // coarse node at or below j, with the margin
    const double* wy = weights[j % kStep];
    for (int i = 0; i < n_; ++i) {
      const double x = x0 + i * res;
      const int I = i / kStep + 1;
      const double* wx = weights[i % kStep];
      double low = 0.0;
      for (int b = 0; b < 4; ++b) {
        const double* c = &coarse[static_cast<size_t>(J - 1 + b) * nc + (I - 1)];
        low += wy[b] * (wx[0] * c[0] + wx[1] * c[1] + wx[2] * c[2] + wx[3] * c[3]);
      }
      const double high = FractalOctaves(x, y, wavelength, coarse_octaves, octaves, persistence, seed);
      row[i] = static_cast<float>(amplitude * (low + high));
    }
  }
}

namespace {

// A crater's height at rho radii from its centre (rho < 3): a parabolic
// bowl rounded into the rim over its outer 10 %, then the ejecta blanket
// falling off as rho^-3, reaching 0 at 3 radii.
double CraterProfile(const Crater& c, double rho) {
  if (rho < 1.0) {
    const double bowl = c.depth + c.rim_height;
    double h = -c.depth + bowl * rho * rho;
    if (rho > 0.9) {
      const double s = (rho - 0.9) / 0.1;
      h = h * (1 - 0.25 * s * s) + 0.25 * s * s * c.rim_height;
    }
    return h;
  }
  const double tail = 1.0 / 27.0;
  const double inv = 1.0 / rho;
  return c.rim_height * (inv * inv * inv - tail) / (1.0 - tail);
}

}  // namespace

void Terrain::PlaceCraters() {
  const uint64_t seed = StreamSeed(options_.seed, kCraters);
  const Region b = Bounds();
  const double area = (b.x_max - b.x_min) * (b.y_max - b.y_min);
  const double d_min = options_.crater_min_diameter_m, d_max = options_.crater_max_diameter_m;
  // N(>D) per 100 m^2 = density * D^-2 (D in m).
  const double expected = options_.crater_density * area / 100.0 * std::pow(d_min, -2.0) *
                          (1.0 - std::pow(d_min / d_max, 2.0));
  const int count = static_cast<int>(std::lround(expected));
  for (int k = 0; k < count; ++k) {
    Crater c;
    c.diameter = PowerLawSample(Uniform(seed, k, 0), d_min, d_max, 2.0);
    c.centre = Eigen::Vector2d(b.x_min + Uniform(seed, k, 1) * (b.x_max - b.x_min),
                               b.y_min + Uniform(seed, k, 2) * (b.y_max - b.y_min));
    if (c.centre.norm() < options_.clear_radius_m + 1.5 * c.diameter && c.diameter > 0.3) continue;
    const double freshness = Uniform(seed, k, 3);
    c.depth = c.diameter * (options_.crater_depth_ratio_min +
                            freshness * (options_.crater_depth_ratio_max - options_.crater_depth_ratio_min));
    c.rim_height = c.diameter * options_.crater_rim_ratio * (0.3 + 0.7 * freshness);
    craters_.push_back(c);
  }
  // Bigger craters first so small ones are superposed on them.
  std::stable_sort(craters_.begin(), craters_.end(),
                   [](const Crater& a, const Crater& b) { return a.diameter > b.diameter; });
  for (const Crater& c : craters_) AddCrater(c);
}

void Terrain::AddCrater(const Crater& c) {
  const double res = options_.resolution_m;
  const double radius = 0.5 * c.diameter, reach = 3.0 * radius;
  const int i0 = std::max(0, static_cast<int>(std::floor((c.centre.x() - reach - options_.origin_x_m) * inv_res_)));
  const int i1 = std::min(n_ - 1, static_cast<int>(std::ceil((c.centre.x() + reach - options_.origin_x_m) * inv_res_)));
  const int j0 = std::max(0, static_cast<int>(std::floor((c.centre.y() - reach - options_.origin_y_m) * inv_res_)));
  const int j1 = std::min(n_ - 1, static_cast<int>(std::ceil((c.centre.y() + reach - options_.origin_y_m) * inv_res_)));
  if (i0 > i1 || j0 > j1) return;
#pragma omp parallel for schedule(static) num_threads(options_.num_threads)
  for (int j = j0; j <= j1; ++j) {
    const double dy = options_.origin_y_m + j * res - c.centre.y();
    // Only the chord of the row inside 3 radii.
    const double half_chord2 = reach * reach - dy * dy;
    if (half_chord2 <= 0) continue;
    const double half_chord = std::sqrt(half_chord2);
    const int a0 = std::max(i0, static_cast<int>(std::floor((c.centre.x() - half_chord - options_.origin_x_m) * inv_res_)));
    const int a1 = std::min(i1, static_cast<int>(std::ceil((c.centre.x() + half_chord - options_.origin_x_m) * inv_res_)));
    for (int i = a0; i <= a1; ++i) {
      const double dx = options_.origin_x_m + i * res - c.centre.x();
      const double rho = std::sqrt(dx * dx + dy * dy) / radius;
      if (rho >= 3.0) continue;
      heights_[static_cast<size_t>(j) * n_ + i] += static_cast<float>(CraterProfile(c, rho));
    }
  }
}

void Terrain::PlaceRocks() {
  const uint64_t seed = StreamSeed(options_.seed, kRocks);
  const uint64_t shape_seed = StreamSeed(options_.seed, kRockShape);
  const Region b = Bounds();
  const double area = (b.x_max - b.x_min) * (b.y_max - b.y_min);
  const double d_min = options_.rock_min_diameter_m, d_max = options_.rock_max_diameter_m;
  // N(>D) per 100 m^2 = density * (D / 0.1 m)^-2.5.
  const double expected = options_.rock_density * area / 100.0 * std::pow(d_min / 0.1, -2.5) *
                          (1.0 - std::pow(d_min / d_max, 2.5));
  const int count = static_cast<int>(std::lround(expected));
  const double res = options_.resolution_m;
  for (int k = 0; k < count; ++k) {
    Rock rock;
    rock.diameter = PowerLawSample(Uniform(seed, k, 0), d_min, d_max, 2.5);
    rock.centre = Eigen::Vector2d(b.x_min + Uniform(seed, k, 1) * (b.x_max - b.x_min),
                                  b.y_min + Uniform(seed, k, 2) * (b.y_max - b.y_min));
    if (rock.diameter > 0.3 && rock.centre.norm() < options_.clear_radius_m + rock.diameter) continue;
    // Ellipsoid semi-axes: a (long, horizontal), b = a * [0.5, 1], c (vertical) = a * [0.35, 0.8];
    // buried by a fraction of c.
    const double a = 0.5 * rock.diameter;
    const double bb = a * (0.5 + 0.5 * Uniform(seed, k, 3));
    const double cc = a * (0.35 + 0.45 * Uniform(seed, k, 4));
    const double burial = cc * (0.1 + 0.5 * Uniform(seed, k, 5));
    const double angle = M_PI * Uniform(seed, k, 6);
    const double ca = std::cos(angle), sa = std::sin(angle);
    rock.height = cc - burial;
    const double base = Bilinear(heights_, rock.centre.x(), rock.centre.y());
    const int i0 = std::max(0, static_cast<int>(std::floor((rock.centre.x() - a - options_.origin_x_m) * inv_res_)));
    const int i1 = std::min(n_ - 1, static_cast<int>(std::ceil((rock.centre.x() + a - options_.origin_x_m) * inv_res_)));
    const int j0 = std::max(0, static_cast<int>(std::floor((rock.centre.y() - a - options_.origin_y_m) * inv_res_)));
    const int j1 = std::min(n_ - 1, static_cast<int>(std::ceil((rock.centre.y() + a - options_.origin_y_m) * inv_res_)));
    for (int j = j0; j <= j1; ++j) {
      const double dy = options_.origin_y_m + j * res - rock.centre.y();
      for (int i = i0; i <= i1; ++i) {
        const double dx = options_.origin_x_m + i * res - rock.centre.x();
        const double u = (ca * dx + sa * dy) / a, v = (-sa * dx + ca * dy) / bb;
        const double q = u * u + v * v;
        if (q >= 1.0) continue;
        // Lumpy surface: +-15 % of the height from noise at a third of the rock size.
        const double lump = 1.0 + 0.15 * GradientNoise(dx / (0.3 * a) + k, dy / (0.3 * a), shape_seed);
        const double top = base - burial + cc * std::sqrt(1.0 - q) * lump;
        float& h = heights_[static_cast<size_t>(j) * n_ + i];
        h = std::max(h, static_cast<float>(top));
      }
    }
    rocks_.push_back(rock);
  }
}

void Terrain::BuildMaxMips() {
  max_levels_.clear();
  MaxLevel level0;
  level0.width = cells_;
  level0.max_height.resize(static_cast<size_t>(cells_) * cells_);
#pragma omp parallel for schedule(static) num_threads(options_.num_threads)
  for (int j = 0; j < cells_; ++j) {
    const float* r0 = &heights_[static_cast<size_t>(j) * n_];
    const float* r1 = r0 + n_;
    float* out = &level0.max_height[static_cast<size_t>(j) * cells_];
    for (int i = 0; i < cells_; ++i) out[i] = std::max(std::max(r0[i], r0[i + 1]), std::max(r1[i], r1[i + 1]));
  }
  max_levels_.push_back(std::move(level0));
  while (max_levels_.back().width > 1) {
    const MaxLevel& prev = max_levels_.back();
    MaxLevel next;
    next.width = (prev.width + 1) / 2;
    next.max_height.assign(static_cast<size_t>(next.width) * next.width, -std::numeric_limits<float>::infinity());
    for (int j = 0; j < prev.width; ++j) {
      for (int i = 0; i < prev.width; ++i) {
        float& m = next.max_height[static_cast<size_t>(j / 2) * next.width + i / 2];
        m = std::max(m, prev.max_height[static_cast<size_t>(j) * prev.width + i]);
      }
    }
    max_levels_.push_back(std::move(next));
  }
}

void Terrain::SunFromOptions() {
  const double az = options_.sun_azimuth_deg * kDegToRad, el = options_.sun_elevation_deg * kDegToRad;
  sun_direction_ = Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
}

void Terrain::SetSun(double azimuth_deg, double elevation_deg) {
  if (azimuth_deg == options_.sun_azimuth_deg && elevation_deg == options_.sun_elevation_deg) return;
  TerrainOptions moved = options_;
  moved.sun_azimuth_deg = azimuth_deg;
  moved.sun_elevation_deg = elevation_deg;
  std::string error;
  if (!moved.Check(&error)) throw std::invalid_argument("Terrain::SetSun: " + error);
  options_ = moved;
  SunFromOptions();
  BuildShadowHorizon();
}

void Terrain::BuildShadowHorizon() {
  // horizon(p) = max over points q toward the sun of H(q) - |q - p| tan(el):
  // p is lit when H(p) >= horizon(p). Swept column by column (or row by
  // row) from the sun-ward edge, interpolating linearly between vertices.
  horizon_.assign(heights_.size(), -std::numeric_limits<float>::infinity());
  const double sx = sun_direction_.x(), sy = sun_direction_.y();
  const double horizontal = std::hypot(sx, sy);
  if (horizontal < 1e-9) return;  // sun at zenith: no cast shadows
  const double tan_el = sun_direction_.z() / horizontal;
  const bool along_x = std::abs(sx) >= std::abs(sy);
  const double major = along_x ? sx : sy, minor = along_x ? sy : sx;
  const int step = major > 0 ? 1 : -1;             // toward the sun along the sweep axis
  const double shift = minor / std::abs(major);    // cross-axis offset per step (cells)
  const float drop = static_cast<float>(options_.resolution_m * std::hypot(1.0, shift) * tan_el);
  auto index = [&](int a, int b) -> size_t {       // a: sweep axis, b: cross axis
    return along_x ? static_cast<size_t>(b) * n_ + a : static_cast<size_t>(a) * n_ + b;
  };
  const int first = step > 0 ? n_ - 2 : 1, last = step > 0 ? -1 : n_;
  for (int a = first; a != last; a -= step) {
    const int prev = a + step;
#pragma omp parallel for schedule(static) num_threads(options_.num_threads)
    for (int b = 0; b < n_; ++b) {
      const double pb = b + shift;
      if (pb < 0 || pb > n_ - 1) continue;  // sun-ward ray leaves the field: nothing occludes
      const int b0 = std::min(static_cast<int>(pb), n_ - 2);
      const float w = static_cast<float>(pb - b0);
      const size_t i0 = index(prev, b0), i1 = index(prev, b0 + 1);
      const float occ0 = std::max(heights_[i0], horizon_[i0]);
      const float occ1 = std::max(heights_[i1], horizon_[i1]);
      horizon_[index(a, b)] = (1 - w) * occ0 + w * occ1 - drop;
    }
  }
}

double Terrain::Bilinear(const std::vector<float>& field, double x, double y) const {
  double gx = (x - options_.origin_x_m) * inv_res_, gy = (y - options_.origin_y_m) * inv_res_;
  gx = std::clamp(gx, 0.0, static_cast<double>(cells_));
  gy = std::clamp(gy, 0.0, static_cast<double>(cells_));
  const int i = std::min(static_cast<int>(gx), cells_ - 1), j = std::min(static_cast<int>(gy), cells_ - 1);
  const double u = gx - i, v = gy - j;
  const float* r0 = &field[static_cast<size_t>(j) * n_ + i];
  const float* r1 = r0 + n_;
  return (1 - v) * ((1 - u) * r0[0] + u * r0[1]) + v * ((1 - u) * r1[0] + u * r1[1]);
}

double Terrain::Height(double x, double y) const { return Bilinear(heights_, x, y); }

Eigen::Vector3d Terrain::Normal(double x, double y) const {
  double gx = (x - options_.origin_x_m) * inv_res_, gy = (y - options_.origin_y_m) * inv_res_;
  gx = std::clamp(gx, 0.0, static_cast<double>(cells_));
  gy = std::clamp(gy, 0.0, static_cast<double>(cells_));
  const int i = std::min(static_cast<int>(gx), cells_ - 1), j = std::min(static_cast<int>(gy), cells_ - 1);
  const double u = gx - i, v = gy - j;
  auto h = [&](int a, int b) {
    a = std::clamp(a, 0, n_ - 1);
    b = std::clamp(b, 0, n_ - 1);
    return static_cast<double>(heights_[static_cast<size_t>(b) * n_ + a]);
  };
  // Per-vertex central-difference gradients, blended bilinearly.
  auto grad = [&](int a, int b) {
    return Eigen::Vector2d(h(a + 1, b) - h(a - 1, b), h(a, b + 1) - h(a, b - 1));
  };
  const Eigen::Vector2d g = (1 - v) * ((1 - u) * grad(i, j) + u * grad(i + 1, j)) +
                            v * ((1 - u) * grad(i, j + 1) + u * grad(i + 1, j + 1));
  const double scale = 0.5 * inv_res_;
  return Eigen::Vector3d(-g.x() * scale, -g.y() * scale, 1.0).normalized();
}

Eigen::Vector3d Terrain::ShadingNormal(double x, double y, double footprint) const {
  return ShadingNormal(x, y, footprint, Normal(x, y));
}

Eigen::Vector3d Terrain::ShadingNormal(double x, double y, double footprint, const Eigen::Vector3d& n) const {
  if (options_.micro_slope <= 0) return n;
  const int octaves =
      1 + static_cast<int>(std::floor(std::log2(options_.micro_wavelength_m / options_.micro_finest_m) + 1e-9));
  double sx, sy;
  FractalSlope(x, y, options_.micro_wavelength_m, octaves, options_.micro_slope,
               StreamSeed(options_.seed, kMicro), footprint, &sx, &sy);
  // Tilt the macro normal by the micro slope (small-slope approximation).
  return Eigen::Vector3d(n.x() - sx * n.z(), n.y() - sy * n.z(), n.z()).normalized();
}

double Terrain::Albedo(double x, double y, double footprint) const {
  const int octaves = static_cast<int>(std::ceil(std::log2(options_.albedo_wavelength_m / options_.albedo_finest_m)));
  const double p = options_.albedo_persistence;
  const double norm = 1.0 / (0.3 * std::sqrt((1.0 - std::pow(p, 2 * octaves)) / (1.0 - p * p)));
  const double n = FractalNoise(x, y, options_.albedo_wavelength_m, octaves, p,
                                StreamSeed(options_.seed, kAlbedo), footprint);
  return std::clamp(options_.albedo_mean * (1.0 + options_.albedo_contrast * norm * n), 0.0, 1.0);
}

double Terrain::SunVisibility(double x, double y) const {
  const double margin = Height(x, y) - Bilinear(horizon_, x, y);
  // Soft over +-5 mm so edges are not jagged.
  return std::clamp(0.5 + margin / 0.01, 0.0, 1.0);
}

double Terrain::Radiance(double x, double y, double footprint) const {
  const double cosine = std::max(0.0, ShadingNormal(x, y, footprint).dot(sun_direction_));
  const double direct = cosine * SunVisibility(x, y);
  return Albedo(x, y, footprint) * (options_.ambient + (1.0 - options_.ambient) * direct);
}

bool Terrain::IntersectCell(int ci, int cj, double o_x, double o_y, double o_z, double d_x, double d_y,
                            double d_z, double t_a, double t_b, double* t_hit) const {
  const float* r0 = &heights_[static_cast<size_t>(cj) * n_ + ci];
  const float* r1 = r0 + n_;
  const double A = r0[0], B = r0[1] - r0[0], C = r1[0] - r0[0], D = r0[0] - r0[1] - r1[0] + r1[1];
  const double u0 = o_x + t_a * d_x - ci, v0 = o_y + t_a * d_y - cj, z0 = o_z + t_a * d_z;
  // f(tau) = z(tau) - H(u(tau), v(tau)) = a tau^2 + b tau + c.
  const double c = z0 - (A + B * u0 + C * v0 + D * u0 * v0);
  if (c <= 0) {
    *t_hit = t_a;
    return true;
  }
  const double b = d_z - (B * d_x + C * d_y + D * (u0 * d_y + v0 * d_x));
  const double a = -D * d_x * d_y;
  const double tau_max = t_b - t_a;
  double tau = -1;
  if (std::abs(a) < 1e-12) {
    if (b < 0) tau = -c / b;
  } else {
    const double disc = b * b - 4 * a * c;
    if (disc >= 0) {
      const double sq = std::sqrt(disc);
      const double q = -0.5 * (b + (b >= 0 ? sq : -sq));
      double r1 = q / a, r2 = (q != 0) ? c / q : r1;
      if (r1 > r2) std::swap(r1, r2);
      tau = r1 >= 0 ? r1 : r2;
    }
  }
  if (tau < 0 || tau > tau_max) return false;
  *t_hit = t_a + tau;
  return true;
}

// The part [t0, t1] of the ray (grid coordinates: x, y in cells, z in
// metres) inside the terrain's box: the grid and below its highest point;
// false when it misses the box.
bool Terrain::ClipToTerrainBox(double o_x, double o_y, double o_z, double d_x, double d_y, double d_z, double* t0,
                               double* t1) const {
  const double size = cells_;
  auto clip = [&](double o, double d, double lo, double hi) {
    if (std::abs(d) < 1e-15) return o >= lo && o <= hi;
    double ta = (lo - o) / d, tb = (hi - o) / d;
    if (ta > tb) std::swap(ta, tb);
    *t0 = std::max(*t0, ta);
    *t1 = std::min(*t1, tb);
    return *t0 <= *t1;
  };
  const float z_top = max_levels_.back().max_height[0];
  if (!clip(o_x, d_x, 0.0, size) || !clip(o_y, d_y, 0.0, size)) return false;
  if (d_z >= 0 && o_z + *t0 * d_z > z_top) return false;
  if (d_z < 0) *t0 = std::max(*t0, (z_top - o_z) / d_z);
  return *t0 <= *t1;
}

std::optional<RayHit> Terrain::Raycast(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                       double max_range) const {
  // Grid coordinates: x, y in cells, z in metres; t in metres along the ray.
  const double o_x = (origin.x() - options_.origin_x_m) * inv_res_;
  const double o_y = (origin.y() - options_.origin_y_m) * inv_res_;
  const double o_z = origin.z();
  const double d_x = direction.x() * inv_res_, d_y = direction.y() * inv_res_, d_z = direction.z();
  const double size = cells_;
  double t0 = 0.0, t1 = max_range;
  if (!ClipToTerrainBox(o_x, o_y, o_z, d_x, d_y, d_z, &t0, &t1)) return std::nullopt;
  const int top = static_cast<int>(max_levels_.size()) - 1;
  const double eps = 1e-6;
  // Reciprocals once per ray (multiplications in the loop, not divisions).
  const double inv_d_x = d_x != 0 ? 1.0 / d_x : 0.0, inv_d_y = d_y != 0 ? 1.0 / d_y : 0.0;
  const bool pos_x = d_x > 0, pos_y = d_y > 0;
  double t = t0;
  // Start at ~5 m cells: rays begin near the camera, where coarser levels only cost descents.
  int level = std::min(top, 7);
  while (t <= t1) {
    const double px = o_x + t * d_x, py = o_y + t * d_y;
    const MaxLevel& lv = max_levels_[level];
    const double s = std::ldexp(1.0, level), inv_s = std::ldexp(1.0, -level);
    const int ci = std::clamp(static_cast<int>(std::floor(px * inv_s)), 0, lv.width - 1);
    const int cj = std::clamp(static_cast<int>(std::floor(py * inv_s)), 0, lv.width - 1);
    double te = t1;
    if (d_x != 0) {
      const double bx = pos_x ? std::min((ci + 1) * s, size) : ci * s;
      te = std::min(te, (bx - o_x) * inv_d_x);
    }
    if (d_y != 0) {
      const double by = pos_y ? std::min((cj + 1) * s, size) : cj * s;
      te = std::min(te, (by - o_y) * inv_d_y);
    }
    te = std::max(te, t);
    const double z_low = o_z + (d_z < 0 ? te : t) * d_z;
    if (z_low > lv.max_height[static_cast<size_t>(cj) * lv.width + ci]) {
      const double t_next = te + eps;
      if (level < top) {
        // Go up a level when the ray leaves the parent cell.
        const double inv_s2 = 0.5 * inv_s;
        const int pi = static_cast<int>(std::floor((o_x + t_next * d_x) * inv_s2));
        const int pj = static_cast<int>(std::floor((o_y + t_next * d_y) * inv_s2));
        if (pi != ci / 2 || pj != cj / 2) ++level;
      }
      t = t_next;
      continue;
    }
    if (level > 0) {
      --level;
      continue;
    }
    double t_hit;
    if (IntersectCell(ci, cj, o_x, o_y, o_z, d_x, d_y, d_z, t, te, &t_hit)) {
      RayHit hit;
      hit.range = t_hit;
      hit.point = origin + t_hit * direction;
      return hit;
    }
    const double t_next = te + eps;
    const int pi = static_cast<int>(std::floor((o_x + t_next * d_x) * 0.5));
    const int pj = static_cast<int>(std::floor((o_y + t_next * d_y) * 0.5));
    if (top > 0 && (pi != ci / 2 || pj != cj / 2)) level = 1;
    t = t_next;
  }
  return std::nullopt;
}

cv::Mat Terrain::RenderOrthoimage(const Region& region, double m_per_px) const {
  if (!(m_per_px > 0) || !(region.x_max > region.x_min) || !(region.y_max > region.y_min))
    throw std::invalid_argument("RenderOrthoimage: region must be non-empty and m_per_px > 0");
  const int cols = static_cast<int>(std::ceil((region.x_max - region.x_min) / m_per_px));
  const int rows = static_cast<int>(std::ceil((region.y_max - region.y_min) / m_per_px));
  cv::Mat image(rows, cols, CV_8UC1);
  const double gain = 200.0 / options_.albedo_mean;
#pragma omp parallel for schedule(dynamic, 8) num_threads(options_.num_threads)
  for (int r = 0; r < rows; ++r) {
    const double y = region.y_max - (r + 0.5) * m_per_px;
    uint8_t* out = image.ptr<uint8_t>(r);
    for (int c = 0; c < cols; ++c) {
      const double x = region.x_min + (c + 0.5) * m_per_px;
      out[c] = Contains(x, y) ? cv::saturate_cast<uint8_t>(gain * Radiance(x, y, m_per_px)) : 0;
    }
  }
  return image;
}

}  // namespace vloc::sim
