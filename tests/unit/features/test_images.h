#pragma once
// Synthetic textured images for the matching tests (fixed seeds).

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <utility>
#include <vector>

namespace vloc::testing {

// Band-limited noise texture, CV_8UC1, mean ~128, std ~`contrast`.
inline cv::Mat TexturedImage(int width, int height, uint64_t seed, double blur_sigma = 1.5, double contrast = 45.0) {
  cv::RNG rng(seed);
  cv::Mat noise(height, width, CV_32F);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), blur_sigma);
  // Add a coarser layer so that SIFT finds blobs at several scales.
  cv::Mat coarse(height, width, CV_32F);
  rng.fill(coarse, cv::RNG::NORMAL, 0.0, 1.0);
  cv::GaussianBlur(coarse, coarse, cv::Size(0, 0), 4 * blur_sigma);
  cv::Scalar m1, s1, m2, s2;
  cv::meanStdDev(noise, m1, s1);
  cv::meanStdDev(coarse, m2, s2);
  cv::Mat mix = noise / s1[0] + 0.7 * coarse / s2[0];
  cv::Scalar m, s;
  cv::meanStdDev(mix, m, s);
  cv::Mat out;
  mix.convertTo(out, CV_8U, contrast / s[0], 128 - contrast * m[0] / s[0]);
  return out;
}

// A continuous texture (sum of Gaussian blobs) that can be rendered exactly
// under any geometric transform: no resampling error in the ground truth.
class BlobTexture {
 public:
  BlobTexture(double width, double height, int count, uint64_t seed, double min_sigma = 1.2, double max_sigma = 3.5) {
    cv::RNG rng(seed);
    for (int i = 0; i < count; ++i) {
      blobs_.push_back({rng.uniform(-10.0, width + 10), rng.uniform(-10.0, height + 10),
                        rng.uniform(min_sigma, max_sigma), rng.uniform(-1.0, 1.0)});
    }
  }
  double operator()(double x, double y) const {
    double v = 0;
    for (const auto& b : blobs_) {
      const double dx = x - b.x, dy = y - b.y, r2 = dx * dx + dy * dy, s2 = b.s * b.s;
      if (r2 < 16 * s2) v += b.a * std::exp(-0.5 * r2 / s2);
    }
    return 128 + 60 * v;
  }
  // Image whose pixel p shows the texture at source(p), CV_32F.
  template <class Map>
  cv::Mat Render(int width, int height, Map source) const {
    cv::Mat out(height, width, CV_32F);
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x) {
        const auto s = source(x, y);
        out.at<float>(y, x) = static_cast<float>((*this)(s.first, s.second));
      }
    return out;
  }

 private:
  struct Blob {
    double x, y, s, a;
  };
  std::vector<Blob> blobs_;
};

// Left and right views of a slanted plane, disparity d(x, y) = d0 + gx x + gy y
// at left pixel (x, y), grey noise of `noise` levels (seeded).
struct PlanePair {
  cv::Mat left, right, truth;  // CV_8UC1, CV_8UC1, CV_32F
};

inline PlanePair RenderPlane(int w, int h, double d0, double gx, double gy, double noise, uint64_t seed) {
  const BlobTexture tex(w + 80, h, w * h / 18, seed);
  PlanePair p;
  const cv::Mat l = tex.Render(w, h, [](int x, int y) { return std::make_pair<double, double>(x, y); });
  // Right pixel xr sees the left point xl with xl - d(xl, y) = xr.
  const cv::Mat r = tex.Render(w, h, [&](int x, int y) {
    return std::make_pair<double, double>((x + d0 + gy * y) / (1.0 - gx), y);
  });
  cv::RNG rng(seed + 1);
  cv::Mat nl(h, w, CV_32F), nr(h, w, CV_32F);
  rng.fill(nl, cv::RNG::NORMAL, 0.0, noise);
  rng.fill(nr, cv::RNG::NORMAL, 0.0, noise);
  cv::Mat(l + nl).convertTo(p.left, CV_8U);
  cv::Mat(r + nr).convertTo(p.right, CV_8U);
  p.truth = cv::Mat(h, w, CV_32F);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) p.truth.at<float>(y, x) = static_cast<float>(d0 + gx * x + gy * y);
  return p;
}

}  // namespace vloc::testing
