#pragma once
// Order statistics the evaluations, tools and tests share, so every report
// means the same by "median": the sample's order statistic at rank
// floor(q * n) (for an even count the upper of the two middle values).

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace vloc {

// The q-quantile (0 <= q <= 1) of `v`; NaN when `v` is empty.
template <typename T>
double Quantile(std::vector<T> v, double q) {
  if (v.empty()) return NAN;
  const double rank = std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size());
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(rank));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return static_cast<double>(v[k]);
}

// Quantile(v, 0.5); NaN when `v` is empty.
template <typename T>
double Median(std::vector<T> v) {
  return Quantile(std::move(v), 0.5);
}

}  // namespace vloc
