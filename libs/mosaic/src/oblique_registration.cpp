#include "vloc/mosaic/oblique_registration.h"

#include "vloc/mosaic/geometry.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/flann.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/stitching/detail/blenders.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <sstream>

#include "vloc/common/options.h"
#include "vloc/mosaic/geometry.h"

namespace vloc::mosaic {

void ObliqueOptions::Visit(OptionsReader& r) {
  r.Optional("max_tilt", &max_tilt, "largest simulated ASIFT tilt", InRange(1.0, 8.0));
  r.Optional("sift_features", &sift_features, "SIFT keypoints per simulated view (0 = all)", NonNegative());
  r.Optional("max_side", &max_side, "px, longer images are downscaled for matching", AtLeast(100));
  r.Optional("ratio", &ratio, "ratio test against the best candidate at another place", InLeftOpen(0.0, 1.0));
  r.Optional("distinct_radius", &distinct_radius, "px, candidates this close are the same point", NonNegative());
  r.Optional("ransac_threshold", &ransac_threshold, "px, MAGSAC++ threshold", Positive());
  r.Optional("min_inliers", &min_inliers, "distinct inliers needed", AtLeast(4));
  r.Optional("min_ncc_gain", &min_ncc_gain, "NCC gain of the registered overlap over the unregistered images",
             InRange(0.0, 2.0));
  r.Optional("num_threads", &num_threads, "OpenCV threads", AtLeast(1));
}

bool ObliqueOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

std::string PairRegistration::BriefReport() const {
  std::ostringstream s;
  s << (ok ? "registered" : "not registered: " + why) << "; keypoints " << keypoints_from << " / " << keypoints_to
    << ", matches " << num_matches << ", distinct inliers " << num_inliers << ", median residual " << median_residual
    << " px, overlap NCC " << ncc_registered << " (unregistered " << ncc_identity << "), overlap " << 100 * overlap
    << " %, " << seconds << " s";
  return s.str();
}

namespace {

// Ratio test where the rival is the best candidate at least `radius` px away
// from the best one (ASIFT repeats a point once per simulated view).
void MatchDistinct(const cv::Mat& d_from, const cv::Mat& d_to, const std::vector<cv::KeyPoint>& k_from,
                   const std::vector<cv::KeyPoint>& k_to, double ratio, double radius, std::vector<cv::Point2f>* from,
                   std::vector<cv::Point2f>* to) {
  cv::FlannBasedMatcher matcher(cv::makePtr<cv::flann::KDTreeIndexParams>(4), cv::makePtr<cv::flann::SearchParams>(64));
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(d_from, d_to, knn, 8);
  const float r2 = static_cast<float>(radius * radius);
  for (const auto& k : knn) {
    if (k.empty()) continue;
    const cv::Point2f best = k_to[k[0].trainIdx].pt;
    float rival = std::numeric_limits<float>::infinity();
    for (size_t j = 1; j < k.size(); ++j) {
      const cv::Point2f d = k_to[k[j].trainIdx].pt - best;
      if (d.dot(d) > r2) {
        rival = k[j].distance;
        break;
      }
    }
    if (k[0].distance < ratio * rival) {
      from->push_back(k_from[k[0].queryIdx].pt);
      to->push_back(best);
    }
  }
}

double Ncc(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  cv::Mat fa, fb;
  a.convertTo(fa, CV_32F);
  b.convertTo(fb, CV_32F);
  cv::Scalar ma, sa, mb, sb;
  cv::meanStdDev(fa, ma, sa, mask);
  cv::meanStdDev(fb, mb, sb, mask);
  if (sa[0] < 1e-6 || sb[0] < 1e-6) return 0;
  cv::Mat p = (fa - ma[0]).mul(fb - mb[0]);
  return cv::mean(p, mask)[0] / (sa[0] * sb[0]);
}

// Detail of an image: itself minus a Gaussian blur (sigma 3 px), float.
// Correlating detail rather than brightness ignores the large bright and dark
// areas (sky, water, forest) that correlate in any two such photos.
cv::Mat Detail(const cv::Mat& gray) {
  cv::Mat f, blurred;
  gray.convertTo(f, CV_32F);
  cv::GaussianBlur(f, blurred, cv::Size(0, 0), 3.0);
  return f - blurred;
}

}  // namespace

double RegisteredNcc(const cv::Mat& from, const cv::Mat& to, const cv::Matx33d& to_from_from, double* overlap) {
  const cv::Mat g_from = ToGray(from), g_to = ToGray(to);
  cv::Mat warped, mask;
  cv::warpPerspective(g_from, warped, cv::Mat(to_from_from), g_to.size(), cv::INTER_LINEAR);
  cv::warpPerspective(cv::Mat(g_from.size(), CV_8UC1, cv::Scalar(255)), mask, cv::Mat(to_from_from), g_to.size(),
                      cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::erode(mask, mask, cv::Mat(), cv::Point(-1, -1), 3);
  const double covered = cv::countNonZero(mask) / static_cast<double>(mask.total());
  if (overlap) *overlap = covered;
  if (covered < 0.01) return 0;
  return Ncc(Detail(warped), Detail(g_to), mask);
}

namespace {

// ASIFT on both grey images reduced to at most options.max_side px, the
// distinct ratio-test matches scaled back to full px (p_from -> p_to);
// counts into `result`, "" or why too few.
std::string MatchAffineInvariant(const cv::Mat& g_from, const cv::Mat& g_to, const ObliqueOptions& options,
                                 std::vector<cv::Point2f>* p_from, std::vector<cv::Point2f>* p_to,
                                 PairRegistration* result) {
  const double f_from = std::min(1.0, options.max_side / std::max(g_from.cols, g_from.rows));
  const double f_to = std::min(1.0, options.max_side / std::max(g_to.cols, g_to.rows));
  cv::Mat s_from = g_from, s_to = g_to;
  if (f_from < 1) cv::resize(g_from, s_from, cv::Size(), f_from, f_from, cv::INTER_AREA);
  if (f_to < 1) cv::resize(g_to, s_to, cv::Size(), f_to, f_to, cv::INTER_AREA);
  auto asift = cv::AffineFeature::create(cv::SIFT::create(options.sift_features), static_cast<int>(options.max_tilt), 0,
                                         std::sqrt(2.0), 72);
  std::vector<cv::KeyPoint> k_from, k_to;
  cv::Mat d_from, d_to;
  asift->detectAndCompute(s_from, cv::noArray(), k_from, d_from);
  asift->detectAndCompute(s_to, cv::noArray(), k_to, d_to);
  result->keypoints_from = static_cast<int>(k_from.size());
  result->keypoints_to = static_cast<int>(k_to.size());
  if (k_from.size() < 8 || k_to.size() < 8) return "too few keypoints (featureless image?)";
  MatchDistinct(d_from, d_to, k_from, k_to, options.ratio, options.distinct_radius, p_from, p_to);
  result->num_matches = static_cast<int>(p_from->size());
  if (p_from->size() < 8) return "only " + std::to_string(p_from->size()) + " matches pass the ratio test";
  for (auto& p : *p_from) p *= 1.0 / f_from;
  for (auto& p : *p_to) p *= 1.0 / f_to;
  return "";
}

// The homography's inliers, one per 2-px cell pair (the same point seen in
// several simulated views counts once), and their median residual.
void DistinctInliers(const std::vector<cv::Point2f>& p_from, const std::vector<cv::Point2f>& p_to,
                     const cv::Mat& inlier_mask, PairRegistration* result) {
  std::set<std::array<int, 4>> seen;
  std::vector<double> residuals;
  for (size_t i = 0; i < p_from.size(); ++i) {
    if (!inlier_mask.at<uchar>(static_cast<int>(i))) continue;
    const std::array<int, 4> key{cvRound(p_from[i].x / 2), cvRound(p_from[i].y / 2), cvRound(p_to[i].x / 2),
                                 cvRound(p_to[i].y / 2)};
    if (!seen.insert(key).second) continue;
    result->inliers_from.push_back(p_from[i]);
    result->inliers_to.push_back(p_to[i]);
    const cv::Vec3d q = result->to_from_from * cv::Vec3d(p_from[i].x, p_from[i].y, 1);
    residuals.push_back(std::hypot(q[0] / q[2] - p_to[i].x, q[1] / q[2] - p_to[i].y));
  }
  result->num_inliers = static_cast<int>(result->inliers_from.size());
  if (!residuals.empty()) {
    std::nth_element(residuals.begin(), residuals.begin() + residuals.size() / 2, residuals.end());
    result->median_residual = residuals[residuals.size() / 2];
  }
}

}  // namespace

PairRegistration RegisterOblique(const cv::Mat& from_in, const cv::Mat& to_in, const ObliqueOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  PairRegistration result;
  auto finish = [&](const std::string& why) {
    result.why = why;
    result.ok = why.empty();
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return result;
  };
  std::string error;
  if (!options.Check(&error)) return finish(error);
  if (from_in.empty() || to_in.empty()) return finish("an image is empty");
  cv::setNumThreads(options.num_threads);
  const cv::Mat g_from = ToGray(from_in), g_to = ToGray(to_in);
  std::vector<cv::Point2f> p_from, p_to;
  const std::string unmatched = MatchAffineInvariant(g_from, g_to, options, &p_from, &p_to, &result);
  if (!unmatched.empty()) return finish(unmatched);
  cv::setRNGSeed(7);
  cv::Mat inlier_mask;
  const cv::Mat H = cv::findHomography(p_from, p_to, cv::USAC_MAGSAC, options.ransac_threshold, inlier_mask, 20000, 0.9999);
  if (H.empty()) return finish("no homography fits the " + std::to_string(p_from.size()) + " matches");
  result.to_from_from = cv::Matx33d(H);
  DistinctInliers(p_from, p_to, inlier_mask, &result);
  result.ncc_registered = RegisteredNcc(from_in, to_in, result.to_from_from, &result.overlap);
  cv::Mat same_size = g_from;
  if (g_from.size() != g_to.size()) cv::resize(g_from, same_size, g_to.size(), 0, 0, cv::INTER_AREA);
  result.ncc_identity = Ncc(Detail(same_size), Detail(g_to), cv::Mat());
  if (result.num_inliers < options.min_inliers)
    return finish("only " + std::to_string(result.num_inliers) + " distinct inliers (need " +
                  std::to_string(options.min_inliers) + ")");
  if (result.ncc_registered < result.ncc_identity + options.min_ncc_gain)
    return finish("the registered overlap does not correlate (NCC " + std::to_string(result.ncc_registered) +
                  " vs " + std::to_string(result.ncc_identity) + " unregistered)");
  return finish("");
}

namespace {

// The canvas in the reference's pixels that holds every image's extent
// inside the allowed box (max_extent reference sizes around it; sampled on
// a grid, only points in front of the horizon, w > 0): false when none is.
bool CanvasOf(const std::vector<cv::Mat>& images, const std::vector<cv::Matx33d>& ref_from_image,
              cv::Size reference_size, double max_extent, cv::Point* origin, cv::Size* canvas) {
  const cv::Rect2d box(-max_extent * reference_size.width, -max_extent * reference_size.height,
                       (1 + 2 * max_extent) * reference_size.width, (1 + 2 * max_extent) * reference_size.height);
  double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30;
  for (size_t i = 0; i < images.size(); ++i) {
    const cv::Size s = images[i].size();
    for (int gy = 0; gy <= 32; ++gy) {
      for (int gx = 0; gx <= 32; ++gx) {
        const cv::Vec3d q = ref_from_image[i] * cv::Vec3d(gx * (s.width - 1) / 32.0, gy * (s.height - 1) / 32.0, 1);
        if (q[2] <= 1e-12) continue;
        const cv::Point2d p(q[0] / q[2], q[1] / q[2]);
        if (!box.contains(p)) continue;
        x0 = std::min(x0, p.x), y0 = std::min(y0, p.y), x1 = std::max(x1, p.x), y1 = std::max(y1, p.y);
      }
    }
  }
  if (x1 < x0) return false;
  *origin = cv::Point(static_cast<int>(std::floor(x0)), static_cast<int>(std::floor(y0)));
  *canvas = cv::Size(static_cast<int>(std::ceil(x1)) - origin->x + 1, static_cast<int>(std::ceil(y1)) - origin->y + 1);
  return true;
}

// One image warped onto the canvas with its own inverse map (canvas pixels
// whose preimage lies behind the horizon, w <= 0, or outside the image are
// not covered), its coverage mask and each pixel's depth inside it.
struct WarpedImage {
  cv::Mat bgr, mask, depth;
};
WarpedImage WarpOntoCanvas(const cv::Mat& image, const cv::Matx33d& ref_from_image, cv::Point origin, cv::Size canvas) {
  WarpedImage w;
  const cv::Matx33d image_from_ref = ref_from_image.inv();
  cv::Mat mapx(canvas, CV_32FC1), mapy(canvas, CV_32FC1);
  w.mask = cv::Mat(canvas, CV_8UC1, cv::Scalar(0));
  const cv::Size s = image.size();
  for (int y = 0; y < canvas.height; ++y) {
    float* mx = mapx.ptr<float>(y);
    float* my = mapy.ptr<float>(y);
    uchar* m = w.mask.ptr<uchar>(y);
    for (int x = 0; x < canvas.width; ++x) {
      const cv::Vec3d q = image_from_ref * cv::Vec3d(x + origin.x, y + origin.y, 1);
      mx[x] = my[x] = -1;
      if (q[2] <= 1e-12) continue;
      const double u = q[0] / q[2], v = q[1] / q[2];
      if (u < 0 || v < 0 || u > s.width - 1 || v > s.height - 1) continue;
      mx[x] = static_cast<float>(u);
      my[x] = static_cast<float>(v);
      m[x] = 255;
    }
  }
  cv::Mat bgr = image;
  if (bgr.channels() == 1) cv::cvtColor(bgr, bgr, cv::COLOR_GRAY2BGR);
  if (bgr.channels() == 4) cv::cvtColor(bgr, bgr, cv::COLOR_BGRA2BGR);
  cv::remap(bgr, w.bgr, mapx, mapy, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  cv::erode(w.mask, w.mask, cv::Mat(), cv::Point(-1, -1), 1);
  cv::distanceTransform(w.mask, w.depth, cv::DIST_L2, 3);
  return w;
}

// Seams: each canvas pixel's owner is the image it lies deepest inside (-1: none).
cv::Mat SeamOwners(const std::vector<WarpedImage>& warped, cv::Size canvas) {
  cv::Mat owner(canvas, CV_32SC1, cv::Scalar(-1));
  cv::Mat best(canvas, CV_32FC1, cv::Scalar(0));
  for (size_t i = 0; i < warped.size(); ++i) {
    for (int y = 0; y < canvas.height; ++y) {
      const float* d = warped[i].depth.ptr<float>(y);
      float* b = best.ptr<float>(y);
      int* o = owner.ptr<int>(y);
      for (int x = 0; x < canvas.width; ++x) {
        if (d[x] > b[x]) b[x] = d[x], o[x] = static_cast<int>(i);
      }
    }
  }
  return owner;
}

// The images multi-band blended across the seams, BGRA (alpha: covered).
cv::Mat BlendAcrossSeams(const std::vector<WarpedImage>& warped, const cv::Mat& owner, int bands) {
  cv::detail::MultiBandBlender blender(false, bands);
  blender.prepare(cv::Rect(0, 0, owner.cols, owner.rows));
  for (size_t i = 0; i < warped.size(); ++i) {
    cv::Mat seam_mask = (owner == static_cast<int>(i));
    if (cv::countNonZero(seam_mask) == 0) continue;
    cv::Mat w16;
    warped[i].bgr.convertTo(w16, CV_16SC3);
    blender.feed(w16, seam_mask, cv::Point(0, 0));
  }
  cv::Mat blended, blended_mask;
  blender.blend(blended, blended_mask);
  cv::Mat bgr8;
  blended.convertTo(bgr8, CV_8U);
  cv::Mat covered = (owner >= 0);
  std::vector<cv::Mat> channels;
  cv::split(bgr8, channels);
  channels.push_back(covered);
  cv::Mat bgra;
  cv::merge(channels, bgra);
  bgra.setTo(cv::Scalar(0, 0, 0, 0), ~covered);
  return bgra;
}

}  // namespace

cv::Mat MosaicByHomographies(const std::vector<cv::Mat>& images, const std::vector<cv::Matx33d>& ref_from_image,
                             cv::Size reference_size, double max_extent, int bands) {
  if (images.empty() || images.size() != ref_from_image.size()) return {};
  cv::Point origin;
  cv::Size canvas;
  if (!CanvasOf(images, ref_from_image, reference_size, max_extent, &origin, &canvas)) return {};
  std::vector<WarpedImage> warped;
  for (size_t i = 0; i < images.size(); ++i) warped.push_back(WarpOntoCanvas(images[i], ref_from_image[i], origin, canvas));
  return BlendAcrossSeams(warped, SeamOwners(warped, canvas), bands);
}

}  // namespace vloc::mosaic
