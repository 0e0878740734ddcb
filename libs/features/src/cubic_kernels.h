#pragma once
// The cubic interpolation kernels of the LSM resamplers (lsm.cpp, row_lsm.cpp):
// weights and derivative weights of the four taps at floor(x) - 1 .. floor(x) + 2,
// t = x - floor(x). Templates over the phase's type: a float, or a GCC
// vector of floats (one phase a lane, the same operations in each).

namespace vloc::internal {

// Keys cubic convolution (a = -0.5), on the grey levels.
template <typename F>
inline void CubicWeights(F t, F w[4], F dw[4]) {
  const F t2 = t * t, t3 = t2 * t;
  w[0] = -0.5f * t3 + t2 - 0.5f * t;
  w[1] = 1.5f * t3 - 2.5f * t2 + 1.f;
  w[2] = -1.5f * t3 + 2.f * t2 + 0.5f * t;
  w[3] = 0.5f * t3 - 0.5f * t2;
  dw[0] = -1.5f * t2 + 2.f * t - 0.5f;
  dw[1] = 4.5f * t2 - 5.f * t;
  dw[2] = -4.5f * t2 + 4.f * t + 0.5f;
  dw[3] = 1.5f * t2 - t;
}

// Cubic B-spline, on B-spline coefficients. The interpolant passes through
// the samples and its error depends far less on the sub-pixel phase than
// Keys' kernel, whose phase-dependent smoothing biases LSM by up to
// +-0.02 px (towards phase 0.5).
template <typename F>
inline void BSplineWeights(F t, F w[4], F dw[4]) {
  const F u = 1.f - t, t2 = t * t, t3 = t2 * t;
  w[0] = u * u * u / 6.f;
  w[1] = (3.f * t3 - 6.f * t2 + 4.f) / 6.f;
  w[2] = (-3.f * t3 + 3.f * t2 + 3.f * t + 1.f) / 6.f;
  w[3] = t3 / 6.f;
  dw[0] = -0.5f * u * u;
  dw[1] = 1.5f * t2 - 2.f * t;
  dw[2] = -1.5f * t2 + t + 0.5f;
  dw[3] = 0.5f * t2;
}

}  // namespace vloc::internal
