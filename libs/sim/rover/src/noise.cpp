#include "vloc/sim/noise.h"

#include <algorithm>

namespace vloc::sim {
namespace {

inline double Fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

// Dot product of the lattice gradient at (ix, iy) with (dx, dy). Gradients
// are 16 unit directions picked by the hash.
inline double Grad(int64_t ix, int64_t iy, uint64_t seed, double dx, double dy) {
  static const double kGx[16] = {1.0, 0.9239, 0.7071, 0.3827, 0.0, -0.3827, -0.7071, -0.9239,
                                 -1.0, -0.9239, -0.7071, -0.3827, 0.0, 0.3827, 0.7071, 0.9239};
  static const double kGy[16] = {0.0, 0.3827, 0.7071, 0.9239, 1.0, 0.9239, 0.7071, 0.3827,
                                 0.0, -0.3827, -0.7071, -0.9239, -1.0, -0.9239, -0.7071, -0.3827};
  uint64_t h = (static_cast<uint64_t>(ix) * 0x9E3779B185EBCA87ULL) ^
               (static_cast<uint64_t>(iy) * 0xC2B2AE3D27D4EB4FULL) ^ seed;
  h ^= h >> 29;
  h *= 0xBF58476D1CE4E5B9ULL;
  h ^= h >> 32;
  const int k = static_cast<int>(h & 15u);
  return kGx[k] * dx + kGy[k] * dy;
}

// Each octave is rotated by a different angle so lattice axes never line up.
struct Rotations {
  double c[32], s[32];
  Rotations() {
    for (int k = 0; k < 32; ++k) {
      c[k] = std::cos(0.9 * k + 0.3);
      s[k] = std::sin(0.9 * k + 0.3);
    }
  }
};
const Rotations kRot;

inline double Octave(double x, double y, double frequency, int k, uint64_t seed) {
  const double rx = (kRot.c[k] * x - kRot.s[k] * y) * frequency + 0.37 * k;
  const double ry = (kRot.s[k] * x + kRot.c[k] * y) * frequency - 0.71 * k;
  return GradientNoise(rx, ry, seed + 0x632BE59BD9B4E019ULL * (k + 1));
}

}  // namespace

double GradientNoise(double x, double y, uint64_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const int64_t ix = static_cast<int64_t>(fx), iy = static_cast<int64_t>(fy);
  const double dx = x - fx, dy = y - fy;
  const double n00 = Grad(ix, iy, seed, dx, dy);
  const double n10 = Grad(ix + 1, iy, seed, dx - 1.0, dy);
  const double n01 = Grad(ix, iy + 1, seed, dx, dy - 1.0);
  const double n11 = Grad(ix + 1, iy + 1, seed, dx - 1.0, dy - 1.0);
  const double u = Fade(dx), v = Fade(dy);
  const double a = n00 + u * (n10 - n00);
  const double b = n01 + u * (n11 - n01);
  return a + v * (b - a);
}

double GradientNoiseWithGradient(double x, double y, uint64_t seed, double* d_x, double* d_y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const int64_t ix = static_cast<int64_t>(fx), iy = static_cast<int64_t>(fy);
  const double dx = x - fx, dy = y - fy;
  // Corner values and their gradients (the lattice gradient vectors).
  const double n00 = Grad(ix, iy, seed, dx, dy);
  const double n10 = Grad(ix + 1, iy, seed, dx - 1.0, dy);
  const double n01 = Grad(ix, iy + 1, seed, dx, dy - 1.0);
  const double n11 = Grad(ix + 1, iy + 1, seed, dx - 1.0, dy - 1.0);
  const double g00x = Grad(ix, iy, seed, 1, 0), g00y = Grad(ix, iy, seed, 0, 1);
  const double g10x = Grad(ix + 1, iy, seed, 1, 0), g10y = Grad(ix + 1, iy, seed, 0, 1);
  const double g01x = Grad(ix, iy + 1, seed, 1, 0), g01y = Grad(ix, iy + 1, seed, 0, 1);
  const double g11x = Grad(ix + 1, iy + 1, seed, 1, 0), g11y = Grad(ix + 1, iy + 1, seed, 0, 1);
  const double u = Fade(dx), v = Fade(dy);
  const double du = 30.0 * dx * dx * (dx - 1.0) * (dx - 1.0);
  const double dv = 30.0 * dy * dy * (dy - 1.0) * (dy - 1.0);
  const double a = n00 + u * (n10 - n00);
  const double b = n01 + u * (n11 - n01);
  const double a_x = g00x + u * (g10x - g00x) + du * (n10 - n00);
  const double b_x = g01x + u * (g11x - g01x) + du * (n11 - n01);
  const double a_y = g00y + u * (g10y - g00y);
  const double b_y = g01y + u * (g11y - g01y);
  *d_x = a_x + v * (b_x - a_x);
  *d_y = a_y + v * (b_y - a_y) + dv * (b - a);
  return a + v * (b - a);
}

void FractalSlope(double x, double y, double largest_wavelength, int octaves, double slope_per_octave,
                  uint64_t seed, double footprint, double* slope_x, double* slope_y) {
  double sx = 0.0, sy = 0.0, frequency = 1.0 / largest_wavelength;
  octaves = std::min(octaves, 32);
  // The derivative of gradient noise has a standard deviation of about 0.75.
  const double scale = slope_per_octave / 0.75;
  for (int k = 0; k < octaves; ++k) {
    double weight = 1.0;
    if (footprint > 0.0) {
      const double ratio = 1.0 / (frequency * footprint);
      if (ratio <= 2.0) break;
      if (ratio < 4.0) weight = (ratio - 2.0) * 0.5;
    }
    const double c = kRot.c[k], s = kRot.s[k];
    const double rx = (c * x - s * y) * frequency + 0.37 * k;
    const double ry = (s * x + c * y) * frequency - 0.71 * k;
    double gx, gy;
    GradientNoiseWithGradient(rx, ry, seed + 0x632BE59BD9B4E019ULL * (k + 1), &gx, &gy);
    // d/dx of lambda * N(R p / lambda) = R^T grad N.
    sx += weight * scale * (c * gx + s * gy);
    sy += weight * scale * (-s * gx + c * gy);
    frequency *= 2.0;
  }
  *slope_x = sx;
  *slope_y = sy;
}

double FractalOctaves(double x, double y, double largest_wavelength, int first_octave, int end_octave,
                      double persistence, uint64_t seed) {
  end_octave = std::min(end_octave, 32);
  double sum = 0.0;
  double amplitude = std::pow(persistence, first_octave);
  double frequency = std::ldexp(1.0 / largest_wavelength, first_octave);
  for (int k = first_octave; k < end_octave; ++k) {
    sum += amplitude * Octave(x, y, frequency, k, seed);
    amplitude *= persistence;
    frequency *= 2.0;
  }
  return sum;
}

double FractalNoise(double x, double y, double largest_wavelength, int octaves, double persistence,
                    uint64_t seed, double footprint) {
  double sum = 0.0, amplitude = 1.0, frequency = 1.0 / largest_wavelength;
  octaves = std::min(octaves, 32);
  for (int k = 0; k < octaves; ++k) {
    // Full weight when the wavelength is >= 4 footprints, none below 2.
    double weight = 1.0;
    if (footprint > 0.0) {
      const double ratio = 1.0 / (frequency * footprint);
      if (ratio <= 2.0) break;
      if (ratio < 4.0) weight = (ratio - 2.0) * 0.5;
    }
    sum += weight * amplitude * Octave(x, y, frequency, k, seed);
    amplitude *= persistence;
    frequency *= 2.0;
  }
  return sum;
}

}  // namespace vloc::sim
