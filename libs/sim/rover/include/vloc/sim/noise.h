#pragma once
// Deterministic procedural noise for the simulated worlds: integer hashing,
// 2-D gradient (Perlin-style) noise and band-limited fractal sums. Every
// function is pure (same inputs, same output on every machine and thread).

#include <cmath>
#include <cstdint>

namespace vloc::sim {

// 64-bit mix (splitmix64 finaliser).
inline uint64_t HashMix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

inline uint64_t Hash3(uint64_t a, uint64_t b, uint64_t c) {
  return HashMix(a ^ HashMix(b ^ HashMix(c)));
}

// Uniform in [0, 1) from a hash.
inline double HashToUnit(uint64_t h) { return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0); }

// Standard normal from a hash (Box-Muller on two derived uniforms).
inline double HashToGaussian(uint64_t h) {
  const double u1 = HashToUnit(HashMix(h)) + 1e-300;
  const double u2 = HashToUnit(HashMix(h ^ 0x5bd1e995ULL));
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

// 2-D gradient noise, roughly in [-0.7, 0.7], zero at lattice points, one
// lattice cell per unit. `seed` selects an independent field.
double GradientNoise(double x, double y, uint64_t seed);

// GradientNoise and its partial derivatives d/dx, d/dy.
double GradientNoiseWithGradient(double x, double y, uint64_t seed, double* d_x, double* d_y);

// Slope field of a self-similar micro-relief: the sum over octaves of
// wavelength `largest_wavelength / 2^k` (k < octaves) of the gradient of
// lambda_k * noise(p / lambda_k), so every octave adds the same slope.
// Octaves below 2 `footprint` fade out as in FractalNoise. Returns the
// height-field gradient (dz/dx, dz/dy) scaled so each octave's slope has a
// standard deviation of about `slope_per_octave`.
void FractalSlope(double x, double y, double largest_wavelength, int octaves, double slope_per_octave,
                  uint64_t seed, double footprint, double* slope_x, double* slope_y);

// Fractal sum of gradient noise: octaves of wavelength
// `largest_wavelength / 2^k` and amplitude `persistence^k`, k = 0..octaves-1.
// Octaves whose wavelength is below 2 * `footprint` (the size of the area a
// sample stands for, same unit as x and y) fade out, so a sample seen from
// far away is not aliased. Returns roughly zero-mean values; the standard
// deviation of a full sum with persistence p is about 0.3 / sqrt(1 - p^2).
double FractalNoise(double x, double y, double largest_wavelength, int octaves, double persistence,
                    uint64_t seed, double footprint = 0.0);

// The terms k = first_octave .. end_octave-1 of the same sum (no
// footprint fading): FractalNoise = FractalOctaves(0, a) + FractalOctaves(a, octaves).
double FractalOctaves(double x, double y, double largest_wavelength, int first_octave, int end_octave,
                      double persistence, uint64_t seed);

}  // namespace vloc::sim
