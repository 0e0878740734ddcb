#include "vloc/mosaic/frame_matcher.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/hal/hal.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <unordered_map>

#include "vloc/common/options.h"

namespace vloc::mosaic {

void MatcherOptions::Visit(OptionsReader& r) {
  r.Optional("detector", &detector, "akaze | sift", OneOf({"akaze", "sift"}));
  r.Optional("downscale", &downscale, "the detector runs on the frame resized by this factor", InRange(0.1, 1.0));
  r.Optional("detect_width", &detect_width, "px, widest frame the detector runs on (0 = downscale alone)",
             Is(0) || InRange(64, 100000));
  r.Optional("akaze_threshold", &akaze_threshold, "A-KAZE detector response threshold", Positive());
  r.Optional("akaze_octaves", &akaze_octaves, "A-KAZE octaves", InRange(1, 8));
  r.Optional("akaze_sublevels", &akaze_sublevels, "A-KAZE sublevels per octave", InRange(1, 8));
  r.Optional("max_features", &max_features, "strongest keypoints kept per frame", AtLeast(20));
  r.Optional("min_features", &min_features, "lower the A-KAZE threshold until this many keypoints (0 = off)",
             NonNegative());
  r.Optional("sift_contrast", &sift_contrast, "SIFT contrast threshold", InOpen(0.0, 1.0));
  r.Optional("grid_cells", &grid_cells, "grid cells per side for spreading keypoints", InRange(1, 64));
  r.Optional("ratio", &ratio, "Lowe ratio test", InLeftOpen(0.0, 1.0));
  r.Optional("ransac_threshold", &ransac_threshold, "px, RANSAC reprojection threshold", Positive());
  r.Optional("foreground_rho", &foreground_rho, "px, rho of equation 2", Positive());
  r.Optional("foreground_rule", &foreground_rule, "eq2 | reprojection", OneOf({"eq2", "reprojection"}));
  r.Optional("scale_model", &scale_model, "similarity | axis_scale | affine",
             OneOf({"similarity", "axis_scale", "affine"}));
  r.Optional("min_inliers", &min_inliers, "background matches needed", AtLeast(4));
  r.Optional("max_scale_change", &max_scale_change, "largest believable scale change between frames", Above(1.0));
  r.Optional("loose_ratio", &loose_ratio, "second try: looser ratio test + MAGSAC++ (0 = off)", InRange(0.0, 1.0));
  r.Optional("guided_ratio", &guided_ratio, "ratio test inside the gate of guided matching", InLeftOpen(0.0, 1.0));
  r.Optional("num_threads", &num_threads, "OpenCV threads", AtLeast(1));
}

bool MatcherOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

namespace {
double Seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Keeps at most `budget` keypoints, the strongest of each grid cell first.
std::vector<cv::KeyPoint> SpreadKeypoints(std::vector<cv::KeyPoint> kps, cv::Size size, int cells, int budget) {
  if (static_cast<int>(kps.size()) <= budget) return kps;
  std::sort(kps.begin(), kps.end(), [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.response > b.response; });
  const int per_cell = std::max(1, budget / (cells * cells));
  std::vector<int> count(cells * cells, 0);
  std::vector<cv::KeyPoint> kept, rest;
  kept.reserve(budget);
  for (const auto& k : kps) {
    const int cx = std::clamp(static_cast<int>(k.pt.x * cells / size.width), 0, cells - 1);
    const int cy = std::clamp(static_cast<int>(k.pt.y * cells / size.height), 0, cells - 1);
    if (count[cy * cells + cx] < per_cell) {
      ++count[cy * cells + cx];
      kept.push_back(k);
    } else {
      rest.push_back(k);
    }
  }
  for (size_t i = 0; i < rest.size() && static_cast<int>(kept.size()) < budget; ++i) kept.push_back(rest[i]);
  return kept;
}
// A-KAZE (lowering its threshold until min_features) or SIFT over the whole image.
void DetectAndDescribe(const cv::Mat& gray, const MatcherOptions& options, std::vector<cv::KeyPoint>* keypoints,
                       cv::Mat* descriptors) {
  if (options.detector == "sift") {
    // Twice the budget by response; SpreadKeypoints then keeps the strongest per grid cell.
    auto sift = cv::SIFT::create(2 * options.max_features, 3, options.sift_contrast);
    sift->detectAndCompute(gray, cv::noArray(), *keypoints, *descriptors);
    // RootSIFT (Arandjelovic & Zisserman 2012): L1-normalise, square root; L2 then compares like the Hellinger kernel.
    for (int i = 0; i < descriptors->rows; ++i) {
      cv::Mat row = descriptors->row(i);
      const double l1 = cv::norm(row, cv::NORM_L1);
      if (l1 > 0) row /= l1;
      cv::sqrt(row, row);
    }
    return;
  }
  // One call: detect() and compute() separately would build the nonlinear scale space twice.
  for (double threshold = options.akaze_threshold;; threshold /= 4) {
    auto akaze = cv::AKAZE::create(cv::AKAZE::DESCRIPTOR_MLDB, 0, 3, static_cast<float>(threshold),
                                   options.akaze_octaves, options.akaze_sublevels, cv::KAZE::DIFF_PM_G2);
    keypoints->clear();
    akaze->detectAndCompute(gray, cv::noArray(), *keypoints, *descriptors);
    if (static_cast<int>(keypoints->size()) >= options.min_features || threshold < options.akaze_threshold / 60) break;
  }
}

// Matches passing the ratio test, as point pairs.
void RatioMatches(const std::vector<std::vector<cv::DMatch>>& knn, const FrameFeatures& from, const FrameFeatures& to,
                  double ratio, std::vector<cv::Point2f>* a, std::vector<cv::Point2f>* b) {
  for (const auto& pair : knn) {
    if (pair.size() < 2 || !(pair[0].distance < ratio * pair[1].distance)) continue;
    a->push_back(from.points[pair[0].queryIdx]);
    b->push_back(to.points[pair[0].trainIdx]);
  }
}

// What BFMatcher measures between row i of a and row j of b: L2 (float descriptors) or Hamming (binary).
float DescriptorDistance(const cv::Mat& a, int i, const cv::Mat& b, int j, int norm) {
  if (norm == cv::NORM_L2) return std::sqrt(cv::hal::normL2Sqr_(a.ptr<float>(i), b.ptr<float>(j), a.cols));
  return static_cast<float>(cv::hal::normHamming(a.ptr<uchar>(i), b.ptr<uchar>(j), a.cols));
}

// The two nearest `to` descriptors of each `from` feature among the `to`
// features within gate_px of its predicted place: BFMatcher::knnMatch with a
// mask of the gate, without computing the distances outside it (a grid of
// gate-sized cells holds the `to` features).
std::vector<std::vector<cv::DMatch>> GatedKnn(const FrameFeatures& from, const FrameFeatures& to,
                                              const MotionPrior& prior, int norm) {
  const double cell = std::max(1.0, prior.gate_px);
  const auto key = [](int cx, int cy) { return (static_cast<int64_t>(cx) << 32) ^ static_cast<uint32_t>(cy); };
  std::unordered_map<int64_t, std::vector<int>> grid;
  for (size_t j = 0; j < to.points.size(); ++j)
    grid[key(static_cast<int>(std::floor(to.points[j].x / cell)), static_cast<int>(std::floor(to.points[j].y / cell)))]
        .push_back(static_cast<int>(j));
  const double gate2 = prior.gate_px * prior.gate_px;
  std::vector<std::vector<cv::DMatch>> knn(from.points.size());
  for (size_t i = 0; i < from.points.size(); ++i) {
    const cv::Point2d p = prior.to_from_from.Apply(cv::Point2d(from.points[i]));
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || std::abs(p.x) > 1e6 || std::abs(p.y) > 1e6) continue;
    const int cx = static_cast<int>(std::floor(p.x / cell)), cy = static_cast<int>(std::floor(p.y / cell));
    cv::DMatch best(static_cast<int>(i), -1, FLT_MAX), second = best;
    for (int gy = cy - 1; gy <= cy + 1; ++gy) {
      for (int gx = cx - 1; gx <= cx + 1; ++gx) {
        const auto it = grid.find(key(gx, gy));
        if (it == grid.end()) continue;
        for (int j : it->second) {
          const double dx = to.points[j].x - p.x, dy = to.points[j].y - p.y;
          if (dx * dx + dy * dy > gate2) continue;
          const float d = DescriptorDistance(from.descriptors, static_cast<int>(i), to.descriptors, j, norm);
          if (d < best.distance || (d == best.distance && j < best.trainIdx)) {
            second = best;
            best = cv::DMatch(static_cast<int>(i), j, d);
          } else if (d < second.distance || (d == second.distance && j < second.trainIdx)) {
            second = cv::DMatch(static_cast<int>(i), j, d);
          }
        }
      }
    }
    if (best.trainIdx >= 0) knn[i].push_back(best);
    if (second.trainIdx >= 0) knn[i].push_back(second);
  }
  return knn;
}

// Robust homography a -> b; returns the number of inliers (0 when none was found).
int FitHomography(const std::vector<cv::Point2f>& a, const std::vector<cv::Point2f>& b, int method, double threshold,
                  cv::Matx33d* H) {
  if (a.size() < 4) return 0;
  std::vector<uchar> inlier_mask;
  const cv::Mat h = cv::findHomography(a, b, method, threshold, inlier_mask, method == cv::RANSAC ? 2000 : 5000,
                                       method == cv::RANSAC ? 0.995 : 0.999);
  if (h.empty()) return 0;
  *H = cv::Matx33d(h);
  return cv::countNonZero(inlier_mask);
}

}  // namespace

FrameFeatures ExtractFeatures(const cv::Mat& image, const MatcherOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  FrameFeatures f;
  f.size = image.size();
  if (image.empty()) return f;
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else {
    gray = image;
  }
  cv::Mat small;
  double downscale = options.downscale;
  if (options.detect_width > 0 && gray.cols * downscale > options.detect_width)
    downscale = static_cast<double>(options.detect_width) / gray.cols;
  if (downscale < 0.999) {
    cv::resize(gray, small, cv::Size(), downscale, downscale, cv::INTER_AREA);
  } else {
    small = gray;
  }
  std::vector<cv::KeyPoint> all;
  cv::Mat all_descriptors;
  DetectAndDescribe(small, options, &all, &all_descriptors);
  for (size_t i = 0; i < all.size(); ++i) all[i].class_id = static_cast<int>(i);
  const std::vector<cv::KeyPoint> kps =
      SpreadKeypoints(std::move(all), small.size(), options.grid_cells, options.max_features);
  if (!kps.empty()) {
    f.descriptors.create(static_cast<int>(kps.size()), all_descriptors.cols, all_descriptors.type());
    for (size_t i = 0; i < kps.size(); ++i) all_descriptors.row(kps[i].class_id).copyTo(f.descriptors.row(static_cast<int>(i)));
  }
  // Keypoint coordinates of the resized image -> full resolution (pixel centres).
  const double sx = static_cast<double>(gray.cols) / small.cols;
  const double sy = static_cast<double>(gray.rows) / small.rows;
  f.points.reserve(kps.size());
  for (const auto& k : kps)
    f.points.emplace_back(static_cast<float>((k.pt.x + 0.5) * sx - 0.5), static_cast<float>((k.pt.y + 0.5) * sy - 0.5));
  f.seconds = Seconds(t0);
  return f;
}

std::vector<bool> ForegroundFilter(const std::vector<cv::Point2f>& from, const std::vector<cv::Point2f>& to,
                                   const cv::Matx33d& H, double rho, const std::string& rule) {
  std::vector<bool> fg(from.size(), true);
  for (size_t i = 0; i < from.size(); ++i) {
    const cv::Vec3d h = H * cv::Vec3d(from[i].x, from[i].y, 1.0);
    if (std::abs(h[2]) < 1e-12) continue;
    const cv::Point2d hk(h[0] / h[2], h[1] / h[2]);
    const cv::Point2d k(from[i]), khat(to[i]);
    if (rule == "eq2") {
      // Equation 2: distance moved by the match minus distance moved under H.
      const double d_match = cv::norm(k - khat);
      const double d_h = cv::norm(k - hk);
      fg[i] = std::abs(d_match - d_h) >= rho;
    } else {
      fg[i] = cv::norm(khat - hk) >= rho;
    }
  }
  return fg;
}

namespace {

// The two nearest descriptors of each `from` feature in `to` (gated around
// the prior's prediction when there is one) and the ratio to test them by.
std::vector<std::vector<cv::DMatch>> NearestDescriptors(const FrameFeatures& from, const FrameFeatures& to,
                                                        const MatcherOptions& options, const MotionPrior* prior,
                                                        double* ratio) {
  const int norm = from.descriptors.depth() == CV_32F ? cv::NORM_L2 : cv::NORM_HAMMING;
  std::vector<std::vector<cv::DMatch>> knn;
  *ratio = options.ratio;
  if (prior) {
    knn = GatedKnn(from, to, *prior, norm);
    *ratio = options.guided_ratio;
  } else {
    cv::BFMatcher(norm).knnMatch(from.descriptors, to.descriptors, knn, 2);
  }
  return knn;
}

// The plane's homography from the matches (a -> b) that pass the ratio
// test: RANSAC, then Levenberg-Marquardt over its inliers (OpenCV does
// both); where that finds too few, a looser ratio with MAGSAC++. Fills
// m's matches, inliers, homography and `loose`; "" or why it fails.
std::string FitPlane(const std::vector<std::vector<cv::DMatch>>& knn, const FrameFeatures& from,
                     const FrameFeatures& to, double ratio, const MatcherOptions& options, std::vector<cv::Point2f>* a,
                     std::vector<cv::Point2f>* b, MotionEstimate* m) {
  RatioMatches(knn, from, to, ratio, a, b);
  m->num_matches = static_cast<int>(a->size());
  const bool loose_allowed = options.loose_ratio > ratio;
  if (m->num_matches < options.min_inliers && !loose_allowed)
    return "too few matches (" + std::to_string(m->num_matches) + ")";
  if (m->num_matches >= options.min_inliers)
    m->num_inliers = FitHomography(*a, *b, cv::RANSAC, options.ransac_threshold, &m->homography);
  if (m->num_inliers < options.min_inliers && loose_allowed) {
    // Low texture: few distinctive matches. A looser ratio test keeps more candidates, and MAGSAC++ (which
    // scores by likelihood, not by a count inside one threshold) still finds the plane among them.
    std::vector<cv::Point2f> a2, b2;
    RatioMatches(knn, from, to, options.loose_ratio, &a2, &b2);
    cv::Matx33d H2;
    const int n2 = FitHomography(a2, b2, cv::USAC_MAGSAC, options.ransac_threshold, &H2);
    if (n2 > m->num_inliers) {
      a->swap(a2);
      b->swap(b2);
      m->num_matches = static_cast<int>(a->size());
      m->num_inliers = n2;
      m->homography = H2;
      m->loose = true;
    }
  }
  if (m->num_matches < options.min_inliers) return "too few matches (" + std::to_string(m->num_matches) + ")";
  if (m->num_inliers == 0) return "no homography (matches inconsistent)";
  if (m->num_inliers < options.min_inliers)
    return "too few RANSAC inliers (" + std::to_string(m->num_inliers) + " of " + std::to_string(m->num_matches) + ")";
  return "";
}

// The foreground filter (equation 2): the matches that move with the
// plane are the background, kept in m; "" or why too few are left.
std::string SplitBackground(const std::vector<cv::Point2f>& a, const std::vector<cv::Point2f>& b,
                            const MatcherOptions& options, MotionEstimate* m) {
  const std::vector<bool> fg = ForegroundFilter(a, b, m->homography, options.foreground_rho, options.foreground_rule);
  for (size_t i = 0; i < a.size(); ++i) {
    if (fg[i]) {
      ++m->num_foreground;
    } else {
      m->from_background.push_back(a[i]);
      m->to_background.push_back(b[i]);
    }
  }
  m->num_background = static_cast<int>(m->from_background.size());
  if (m->num_background < options.min_inliers)
    return "too few background matches (" + std::to_string(m->num_background) + ")";
  return "";
}

// Equation 3 by least squares over all background matches: the scale
// change lambda by options.scale_model; "" or why it fails.
std::string FitScaleChange(const MatcherOptions& options, MotionEstimate* m) {
  double rms = 0;
  if (!FitSimilarity(m->from_background, m->to_background, &m->similarity, &rms)) return "degenerate scale fit";
  const AxisScaleFit axis = FitAxisScale(m->from_background, m->to_background);
  if (axis.ok) {
    m->lambda_x = axis.lambda_x;
    m->lambda_y = axis.lambda_y;
  }
  if (options.scale_model == "similarity") {
    m->lambda = m->similarity.Scale();
    m->fit_rms = rms;
  } else if (options.scale_model == "axis_scale") {
    if (!axis.ok) return "degenerate axis-scale fit";
    m->lambda = 0.5 * (axis.lambda_x + axis.lambda_y);
    m->fit_rms = axis.rms;
  } else {
    cv::Matx23d A;
    if (!FitAffine(m->from_background, m->to_background, &A, &m->fit_rms)) return "degenerate affine fit";
    m->lambda = std::sqrt(std::abs(A(0, 0) * A(1, 1) - A(0, 1) * A(1, 0)));
  }
  if (!(m->lambda > 1.0 / options.max_scale_change && m->lambda < options.max_scale_change))
    return "implausible scale change " + std::to_string(m->lambda);
  return "";
}

}  // namespace

MotionEstimate EstimateMotion(const FrameFeatures& from, const FrameFeatures& to, const MatcherOptions& options,
                              const MotionPrior* prior) {
  const auto t0 = std::chrono::steady_clock::now();
  MotionEstimate m;
  auto fail = [&](const std::string& why) {
    m.ok = false;
    m.why = why;
    m.seconds = Seconds(t0);
    return m;
  };
  if (from.points.size() < 8 || to.points.size() < 8)
    return fail("too few features (" + std::to_string(std::min(from.points.size(), to.points.size())) +
                "): blank, blurred or featureless frame");
  if (from.descriptors.type() != to.descriptors.type())
    return fail("descriptors of different kinds (detector changed between frames)");
  double ratio = 0;
  const std::vector<std::vector<cv::DMatch>> knn = NearestDescriptors(from, to, options, prior, &ratio);
  m.guided = prior != nullptr;
  std::vector<cv::Point2f> a, b;
  std::string why = FitPlane(knn, from, to, ratio, options, &a, &b, &m);
  if (why.empty()) why = SplitBackground(a, b, options, &m);
  if (why.empty()) why = FitScaleChange(options, &m);
  if (!why.empty()) return fail(why);
  std::vector<cv::Point2f> hull;
  cv::convexHull(m.to_background, hull);
  m.spread = cv::contourArea(hull) / std::max(1.0, static_cast<double>(to.size.area()));
  m.ok = true;
  m.seconds = Seconds(t0);
  return m;
}

}  // namespace vloc::mosaic
