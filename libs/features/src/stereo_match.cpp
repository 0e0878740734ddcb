#include "vloc/features/stereo_match.h"

#include <algorithm>
#include <cmath>

#include "vloc/common/options.h"

namespace vloc {

void ZnccOptions::Visit(OptionsReader& r) {
  r.Optional("window", &window, "px, side of the correlation window", Odd() && AtLeast(3));
  r.Optional("min_score", &min_score, "minimum ZNCC of the accepted peak", InOpen(-1, 1));
  r.Optional("min_peak_margin", &min_peak_margin, "best minus second peak (>= 3 steps away)", NonNegative());
  r.Optional("min_template_std", &min_template_std, "grey level, minimum template std (texture)");
  r.Optional("step", &step, "px, sampling step along the epipolar segment", InLeftOpen(0, 2));
}

bool ZnccOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

void MedianFilterOptions::Visit(OptionsReader& r) {
  r.Optional("radius", &radius, "px, neighbourhood radius in the left image", Positive());
  r.Optional("min_neighbours", &min_neighbours, "points with fewer neighbours are kept", AtLeast(1));
  r.Optional("abs_tolerance", &abs_tolerance, "px, allowed disparity deviation from the median", NonNegative());
  r.Optional("rel_tolerance", &rel_tolerance, "fraction of the median disparity added to the tolerance", NonNegative());
}

bool MedianFilterOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

namespace {

// Samples the window around (x, y) into `out`; false when outside.
bool SamplePatch(const cv::Mat& image, double x, double y, int half, float* out) {
  if (x - half < 0 || y - half < 0 || x + half > image.cols - 1.001 || y + half > image.rows - 1.001) return false;
  const double fx = x - std::floor(x), fy = y - std::floor(y);
  const int x0 = static_cast<int>(std::floor(x)) - half, y0 = static_cast<int>(std::floor(y)) - half;
  const int n = 2 * half + 1;
  const bool integer = fx < 1e-6 && fy < 1e-6;
  for (int r = 0; r < n; ++r) {
    const float* p0 = image.ptr<float>(y0 + r) + x0;
    if (integer) {
      std::copy(p0, p0 + n, out + r * n);
      continue;
    }
    const float* p1 = image.ptr<float>(std::min(y0 + r + 1, image.rows - 1)) + x0;
    const float w00 = static_cast<float>((1 - fx) * (1 - fy)), w01 = static_cast<float>(fx * (1 - fy));
    const float w10 = static_cast<float>((1 - fx) * fy), w11 = static_cast<float>(fx * fy);
    for (int c = 0; c < n; ++c) out[r * n + c] = w00 * p0[c] + w01 * p0[c + 1] + w10 * p1[c] + w11 * p1[c + 1];
  }
  return true;
}

// Normalises a patch to zero mean and unit norm; returns its std.
double Normalise(float* p, int count) {
  double sum = 0, sum2 = 0;
  for (int i = 0; i < count; ++i) sum += p[i];
  const double mean = sum / count;
  for (int i = 0; i < count; ++i) {
    p[i] = static_cast<float>(p[i] - mean);
    sum2 += static_cast<double>(p[i]) * p[i];
  }
  const double norm = std::sqrt(sum2);
  if (norm > 1e-9) {
    const float inv = static_cast<float>(1.0 / norm);
    for (int i = 0; i < count; ++i) p[i] *= inv;
  }
  return std::sqrt(sum2 / count);
}

// Normalise on kLanes patches at once and each one's dot product with the normalised template: the
// scalar code's operations in each lane, in its order (its sums in double run one after another, so four
// patches share each sum's latency), bit for bit. cand: kLanes patches of n, one after another; valid:
// the patches inside the image; x: n values of scratch. scores[l]: the ZNCC, or -2 where invalid or flat.
constexpr int kLanes = 4;
typedef double Doubles __attribute__((vector_size(32)));
typedef float Floats __attribute__((vector_size(16)));

__attribute__((target_clones("avx2", "default"))) void ScorePatches(const float* tmpl, const float* cand, int n,
                                                                  const bool* valid, Floats* x, double* scores) {
  for (int i = 0; i < n; ++i) x[i] = Floats{cand[i], cand[n + i], cand[2 * n + i], cand[3 * n + i]};
  Doubles sum = {};
  for (int i = 0; i < n; ++i) sum += __builtin_convertvector(x[i], Doubles);
  const Doubles mean = sum / static_cast<double>(n);
  Doubles sum2 = {};
  for (int i = 0; i < n; ++i) {
    x[i] = __builtin_convertvector(__builtin_convertvector(x[i], Doubles) - mean, Floats);
    const Doubles d = __builtin_convertvector(x[i], Doubles);
    sum2 += d * d;
  }
  Floats inv;
  bool use[kLanes];
  for (int l = 0; l < kLanes; ++l) {
    const double norm = std::sqrt(sum2[l]);
    inv[l] = norm > 1e-9 ? static_cast<float>(1.0 / norm) : 1.0f;  // x * 1 is x: the scalar code's skip
    use[l] = valid[l] && std::sqrt(sum2[l] / n) >= 1e-3;
  }
  Doubles dot = {};
  for (int i = 0; i < n; ++i) dot += __builtin_convertvector(tmpl[i] * (x[i] * inv), Doubles);
  for (int l = 0; l < kLanes; ++l) scores[l] = use[l] ? dot[l] : -2.0;
}

}  // namespace

ZnccMatch ZnccAlongSegment(const cv::Mat& left, const cv::Mat& right, const Eigen::Vector2d& left_px,
                           const Eigen::Vector2d& seg_start, const Eigen::Vector2d& seg_end,
                           const ZnccOptions& o) {
  CV_Assert(left.type() == CV_32FC1 && right.type() == CV_32FC1);
  ZnccMatch result;
  const int half = o.window / 2, n = o.window * o.window;
  std::vector<float> tmpl(n), cand(kLanes * n);
  std::vector<Floats> lanes(n);
  if (!SamplePatch(left, left_px.x(), left_px.y(), half, tmpl.data())) {
    result.why = "template outside the left image";
    return result;
  }
  if (Normalise(tmpl.data(), n) < o.min_template_std) {
    result.why = "too little texture";
    return result;
  }
  const Eigen::Vector2d d = seg_end - seg_start;
  const double length = d.norm();
  const int steps = std::max(1, static_cast<int>(std::ceil(length / o.step)));
  std::vector<double> scores(steps + 1 + kLanes, -2.0);
  for (int k0 = 0; k0 <= steps; k0 += kLanes) {
    bool valid[kLanes];
    for (int l = 0; l < kLanes; ++l) {
      const Eigen::Vector2d p = seg_start + d * (static_cast<double>(k0 + l) / steps);
      valid[l] = k0 + l <= steps && SamplePatch(right, p.x(), p.y(), half, cand.data() + l * n);
    }
    ScorePatches(tmpl.data(), cand.data(), n, valid, lanes.data(), scores.data() + k0);
  }
  scores.resize(steps + 1);
  const int best = static_cast<int>(std::max_element(scores.begin(), scores.end()) - scores.begin());
  if (scores[best] < o.min_score) {
    result.why = "correlation below min_score";
    result.score = scores[best];
    return result;
  }
  double second = -2;
  for (int k = 0; k <= steps; ++k) {
    if (std::abs(k - best) < 3) continue;
    // Only count local maxima as competing peaks.
    const bool peak = (k == 0 || scores[k] >= scores[k - 1]) && (k == steps || scores[k] >= scores[k + 1]);
    if (peak) second = std::max(second, scores[k]);
  }
  if (scores[best] - second < o.min_peak_margin) {
    result.why = "ambiguous correlation peak";
    result.score = scores[best];
    return result;
  }
  double offset = 0;
  if (best > 0 && best < steps && scores[best - 1] > -2 && scores[best + 1] > -2) {
    const double a = scores[best - 1], b = scores[best], c = scores[best + 1];
    const double den = a - 2 * b + c;
    if (den < -1e-12) offset = std::clamp(0.5 * (a - c) / den, -0.5, 0.5);
  }
  result.ok = true;
  result.score = scores[best];
  result.right = seg_start + d * ((best + offset) / steps);
  return result;
}

std::vector<bool> MedianDisparityFilter(const std::vector<Eigen::Vector2d>& pts, const std::vector<double>& disp,
                                        const MedianFilterOptions& o) {
  const size_t n = pts.size();
  std::vector<bool> keep(n, true);
  // Grid of cell = radius for the neighbour search.
  const double cell = o.radius;
  std::vector<std::pair<long long, int>> keys(n);
  auto key_of = [&](int cx, int cy) { return (static_cast<long long>(cx) << 32) ^ static_cast<unsigned>(cy); };
  for (size_t i = 0; i < n; ++i) {
    keys[i] = {key_of(static_cast<int>(std::floor(pts[i].x() / cell)), static_cast<int>(std::floor(pts[i].y() / cell))),
               static_cast<int>(i)};
  }
  std::sort(keys.begin(), keys.end());
  std::vector<double> neigh;
  for (size_t i = 0; i < n; ++i) {
    const int cx = static_cast<int>(std::floor(pts[i].x() / cell)), cy = static_cast<int>(std::floor(pts[i].y() / cell));
    neigh.clear();
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        const long long k = key_of(cx + dx, cy + dy);
        auto it = std::lower_bound(keys.begin(), keys.end(), std::make_pair(k, -1));
        for (; it != keys.end() && it->first == k; ++it) {
          const int j = it->second;
          if (static_cast<size_t>(j) == i) continue;
          if ((pts[j] - pts[i]).squaredNorm() <= o.radius * o.radius) neigh.push_back(disp[j]);
        }
      }
    }
    if (static_cast<int>(neigh.size()) < o.min_neighbours) continue;
    std::nth_element(neigh.begin(), neigh.begin() + neigh.size() / 2, neigh.end());
    const double median = neigh[neigh.size() / 2];
    keep[i] = std::abs(disp[i] - median) <= o.abs_tolerance + o.rel_tolerance * std::abs(median);
  }
  return keep;
}

}  // namespace vloc
