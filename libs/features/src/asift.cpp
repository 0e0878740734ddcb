#include "vloc/features/asift.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <unordered_map>

#include "vloc/common/options.h"

namespace vloc {

void AsiftOptions::Visit(OptionsReader& r) {
  r.Optional("tilts", &tilts, "transition tilts to simulate (1 = original image)", NonEmpty() && Each(InRange(1, 8)));
  r.Optional("longitude_step_deg", &longitude_step_deg, "deg, longitude step at tilt t is this / t", Positive());
  r.Optional("longitude_min_deg", &longitude_min_deg, "deg, lowest simulated longitude");
  r.Optional("longitude_max_deg", &longitude_max_deg, "deg, simulated longitudes are below this");
  r.Optional("max_features_per_view", &max_features_per_view, "SIFT features per view (0 = all)", NonNegative());
  r.Optional("sift_octave_layers", &sift_octave_layers, "SIFT layers per octave", AtLeast(1));
  r.Optional("sift_contrast_threshold", &sift_contrast_threshold, "SIFT contrast threshold");
  r.Optional("sift_edge_threshold", &sift_edge_threshold, "SIFT edge threshold");
  r.Optional("sift_sigma", &sift_sigma, "SIFT base blur");
  r.Optional("num_threads", &num_threads, "OpenMP threads over views", AtLeast(1));
  r.Relation("longitude_max_deg", longitude_max_deg > longitude_min_deg, "must exceed longitude_min_deg");
}

bool AsiftOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

std::vector<AffineView> AsiftOptions::Views() const {
  std::vector<AffineView> views;
  for (double t : tilts) {
    if (t < 1.0 + 1e-6) {
      views.push_back({1.0, 0.0});
      continue;
    }
    const double step = longitude_step_deg / t;
    for (double phi = longitude_min_deg; phi < longitude_max_deg - 1e-9; phi += step)
      views.push_back({t, phi * M_PI / 180.0});
  }
  return views;
}

cv::Matx23d AffineViewTransform(const cv::Size& size, const AffineView& view, cv::Size* view_size) {
  // Rotation by phi about the image centre into a canvas that holds the whole
  // rotated image, then x compressed by 1/t.
  const double c = std::cos(view.longitude), s = std::sin(view.longitude);
  const double w = size.width, h = size.height;
  const double rw = std::abs(w * c) + std::abs(h * s), rh = std::abs(w * s) + std::abs(h * c);
  // x' = c x + s y + tx ; y' = -s x + c y + ty  (rotating the image by -phi)
  const double cx = (w - 1) / 2, cy = (h - 1) / 2;
  const double tx = (rw - 1) / 2 - (c * cx + s * cy);
  const double ty = (rh - 1) / 2 - (-s * cx + c * cy);
  // The canvas (ceil(rw) px wide) is resized to the view width; cv::resize
  // maps pixel centres: u = (x + 0.5) / f - 0.5 with f = canvas / view
  // width (about t). Taking u = x / t put keypoints of tilted views
  // (t - 1) / 2 canvas px off along the tilt (0.5 px at t = 2).
  const int canvas_w = static_cast<int>(std::ceil(rw));
  const int view_w = std::max(1, static_cast<int>(std::ceil(rw / view.tilt)));
  if (view_size) *view_size = cv::Size(view_w, static_cast<int>(std::ceil(rh)));
  const double inv_f = static_cast<double>(view_w) / canvas_w;
  return cv::Matx23d(c * inv_f, s * inv_f, (tx + 0.5) * inv_f - 0.5, -s, c, ty);
}

namespace {

struct ViewFeatures {
  std::vector<cv::KeyPoint> keypoints;
  std::vector<Eigen::Vector2d> points;
  cv::Mat descriptors;
};

ViewFeatures DetectView(const cv::Mat& image, const cv::Mat& mask, const AffineView& view, const AsiftOptions& o) {
  ViewFeatures out;
  cv::Mat img = image, msk = mask;
  cv::Matx23d A = cv::Matx23d(1, 0, 0, 0, 1, 0);
  if (view.tilt > 1.0 + 1e-6) {
    const double c = std::cos(view.longitude), s = std::sin(view.longitude);
    const double w = image.cols, h = image.rows;
    const double rw = std::abs(w * c) + std::abs(h * s), rh = std::abs(w * s) + std::abs(h * c);
    const double cx = (w - 1) / 2, cy = (h - 1) / 2;
    const cv::Matx23d R(c, s, (rw - 1) / 2 - (c * cx + s * cy), -s, c, (rh - 1) / 2 - (-s * cx + c * cy));
    const cv::Size rsize(static_cast<int>(std::ceil(rw)), static_cast<int>(std::ceil(rh)));
    cv::Mat rotated, rmask;
    cv::warpAffine(image, rotated, R, rsize, cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
    cv::Mat full_mask = mask.empty() ? cv::Mat(image.size(), CV_8UC1, cv::Scalar(255)) : mask;
    cv::warpAffine(full_mask, rmask, R, rsize, cv::INTER_NEAREST, cv::BORDER_CONSTANT, 0);
    const double sigma_x = 0.8 * std::sqrt(view.tilt * view.tilt - 1.0);
    cv::GaussianBlur(rotated, rotated, cv::Size(0, 0), sigma_x, 0.01);
    cv::Size vsize;
    A = AffineViewTransform(image.size(), view, &vsize);
    cv::resize(rotated, img, vsize, 0, 0, cv::INTER_LINEAR);
    cv::resize(rmask, msk, vsize, 0, 0, cv::INTER_NEAREST);
    // Keep keypoints away from the canvas border.
    cv::erode(msk, msk, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(7, 7)));
  }
  auto sift = cv::SIFT::create(o.max_features_per_view, o.sift_octave_layers, o.sift_contrast_threshold,
                               o.sift_edge_threshold, o.sift_sigma);
  sift->detectAndCompute(img, msk, out.keypoints, out.descriptors);
  // Back to original pixels: invert A.
  cv::Matx23d Ainv;
  cv::invertAffineTransform(A, Ainv);
  out.points.reserve(out.keypoints.size());
  for (const auto& kp : out.keypoints) {
    out.points.emplace_back(Ainv(0, 0) * kp.pt.x + Ainv(0, 1) * kp.pt.y + Ainv(0, 2),
                            Ainv(1, 0) * kp.pt.x + Ainv(1, 1) * kp.pt.y + Ainv(1, 2));
  }
  return out;
}

}  // namespace

FeatureSet DetectAsift(const cv::Mat& image, const cv::Mat& mask, const std::vector<AffineView>& views,
                       const AsiftOptions& o) {
  CV_Assert(image.type() == CV_8UC1);
  CV_Assert(mask.empty() || (mask.type() == CV_8UC1 && mask.size() == image.size()));
  std::vector<ViewFeatures> per_view(views.size());
  const int n = static_cast<int>(views.size());
#pragma omp parallel for schedule(dynamic, 1) num_threads(o.num_threads)
  for (int v = 0; v < n; ++v) per_view[v] = DetectView(image, mask, views[v], o);
  FeatureSet set;
  set.views = views;
  std::vector<cv::Mat> descs;
  for (int v = 0; v < n; ++v) {
    auto& f = per_view[v];
    for (size_t i = 0; i < f.keypoints.size(); ++i) {
      set.keypoints.push_back(f.keypoints[i]);
      set.points.push_back(f.points[i]);
      set.view.push_back(v);
    }
    if (!f.descriptors.empty()) descs.push_back(f.descriptors);
  }
  if (!descs.empty()) cv::vconcat(descs, set.descriptors);
  return set;
}

void GatedMatchOptions::Visit(OptionsReader& r) {
  r.Optional("gate_radius", &gate_radius, "px, search radius around the predicted position", Positive());
  r.Optional("ratio", &ratio, "Lowe ratio test threshold", InLeftOpen(0, 1));
  r.Optional("distinct_radius", &distinct_radius, "px, candidates this close to the best are the same point",
             NonNegative());
  r.Optional("max_descriptor_distance", &max_descriptor_distance, "L2 descriptor distance limit (0 = none)");
  r.Optional("num_threads", &num_threads, "OpenMP threads over the query features", AtLeast(1));
}

bool GatedMatchOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

namespace {

double DescriptorDistanceSq(const float* a, const float* b, int dim) {
  double s = 0;
  for (int k = 0; k < dim; ++k) {
    const double d = a[k] - b[k];
    s += d * d;
  }
  return s;
}

// True when every value of `descriptors` is an integer in [0, 255] (OpenCV's
// SIFT stores its uchar-rounded values as floats) and the squared distance
// of two rows, at most dim * 255^2, stays below 2^24: then
// every partial sum of DescriptorDistanceSq is an integer a float holds
// exactly, and summing in float, in any order, gives the same value.
bool SmallIntegerDescriptors(const cv::Mat& descriptors) {
  if (descriptors.type() != CV_32F || static_cast<double>(descriptors.cols) * 255.0 * 255.0 >= 16777216.0) return false;
  for (int r = 0; r < descriptors.rows; ++r) {
    const float* p = descriptors.ptr<float>(r);
    for (int k = 0; k < descriptors.cols; ++k)
      if (!(p[k] >= 0.f && p[k] <= 255.f) || p[k] != std::nearbyint(p[k])) return false;
  }
  return true;
}

// DescriptorDistanceSq for SmallIntegerDescriptors: 8 float partial sums the
// compiler vectorises; exact, so the same value.
double DescriptorDistanceSqExactFloat(const float* a, const float* b, int dim) {
  float acc[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int k = 0;
  for (; k + 8 <= dim; k += 8)
    for (int l = 0; l < 8; ++l) {
      const float d = a[k + l] - b[k + l];
      acc[l] += d * d;
    }
  float s = 0;
  for (; k < dim; ++k) s += (a[k] - b[k]) * (a[k] - b[k]);
  for (int l = 0; l < 8; ++l) s += acc[l];
  return s;
}

// Keeps the best match per train location (within 1 px) and per query location.
std::vector<FeatureMatch> UniqueMatches(std::vector<FeatureMatch> matches, const FeatureSet& query,
                                        const FeatureSet& train) {
  std::sort(matches.begin(), matches.end(),
            [](const FeatureMatch& a, const FeatureMatch& b) { return a.distance < b.distance; });
  std::unordered_map<long long, int> used_train, used_query;
  auto key = [](const Eigen::Vector2d& p) {
    return (static_cast<long long>(std::lround(p.x())) << 32) ^ static_cast<unsigned>(std::lround(p.y()));
  };
  std::vector<FeatureMatch> out;
  for (const auto& m : matches) {
    const long long kt = key(train.points[m.train]), kq = key(query.points[m.query]);
    if (used_train.count(kt) || used_query.count(kq)) continue;
    used_train[kt] = 1;
    used_query[kq] = 1;
    out.push_back(m);
  }
  return out;
}

}  // namespace

std::vector<FeatureMatch> GatedMatch(const FeatureSet& query, const std::vector<Eigen::Vector2d>& predicted,
                                     const FeatureSet& train, const GatedMatchOptions& o) {
  CV_Assert(predicted.size() == query.size());
  if (query.size() == 0 || train.size() == 0) return {};
  const int dim = query.descriptors.cols;
  const bool exact_float = SmallIntegerDescriptors(query.descriptors) && SmallIntegerDescriptors(train.descriptors);
  const auto distance_sq = exact_float ? DescriptorDistanceSqExactFloat : DescriptorDistanceSq;
  const double cell = o.gate_radius;
  std::unordered_map<long long, std::vector<int>> grid;
  auto key = [](int cx, int cy) { return (static_cast<long long>(cx) << 32) ^ static_cast<unsigned>(cy); };
  for (size_t j = 0; j < train.size(); ++j) {
    const auto& p = train.points[j];
    grid[key(static_cast<int>(std::floor(p.x() / cell)), static_cast<int>(std::floor(p.y() / cell)))].push_back(
        static_cast<int>(j));
  }
  const int nq = static_cast<int>(query.size());
  std::vector<FeatureMatch> best_of(nq, FeatureMatch{-1, -1, 0});
  const double r2 = o.gate_radius * o.gate_radius;
#pragma omp parallel for schedule(dynamic, 64) num_threads(o.num_threads)
  for (int q = 0; q < nq; ++q) {
    const Eigen::Vector2d& pr = predicted[q];
    if (!pr.allFinite()) continue;
    const int cx = static_cast<int>(std::floor(pr.x() / cell)), cy = static_cast<int>(std::floor(pr.y() / cell));
    const float* dq = query.descriptors.ptr<float>(q);
    std::vector<std::pair<double, int>> cands;
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        auto it = grid.find(key(cx + dx, cy + dy));
        if (it == grid.end()) continue;
        for (int j : it->second) {
          if ((train.points[j] - pr).squaredNorm() > r2) continue;
          cands.emplace_back(distance_sq(dq, train.descriptors.ptr<float>(j), dim), j);
        }
      }
    }
    if (cands.empty()) continue;
    std::sort(cands.begin(), cands.end());
    if (!DistinctRatioTest(cands, train.points, o.ratio, o.distinct_radius)) continue;
    const double d1 = cands[0].first;
    const int j1 = cands[0].second;
    if (o.max_descriptor_distance > 0 && d1 > o.max_descriptor_distance * o.max_descriptor_distance) continue;
    best_of[q] = FeatureMatch{q, j1, std::sqrt(d1)};
  }
  std::vector<FeatureMatch> matches;
  for (const auto& m : best_of)
    if (m.train >= 0) matches.push_back(m);
  return UniqueMatches(std::move(matches), query, train);
}

}  // namespace vloc
