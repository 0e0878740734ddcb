#pragma once
// Real image pairs with ground truth that Debian ships in opencv-doc
// (/usr/share/doc/opencv-doc/examples/data), and the scoring the tests and
// benchmarks share:
// - aloeL.jpg / aloeR.jpg / aloeGT.png: Middlebury 2006 "Aloe", full size
//   (1282 x 1110), rectified; GT disparity = grey value (integer px, 0 =
//   unknown). JPEG-compressed in the package. The integer truth sits about
//   0.25 px below what both vloc and SGBM measure, at every disparity and
//   across the image (mean signed error +0.23 px on |error| < 1 for both):
//   as if it were floor(D / 2) of a twice-finer integer disparity D. A
//   perfect sub-pixel matcher then has errors spread over [-0.25, 0.75) and
//   a median |error| of 0.25 px; a matcher that locks onto whole pixels (as
//   SGBM's sub-pixel step does) scores better against it than it is.
// - Middlebury 2014 "Motorcycle" as scikit-image ships it (python3-skimage,
//   /usr/lib/python3/dist-packages/skimage/data): 741 x 500, downsampled
//   4x from the perfectly rectified originals, PNG, ground truth float
//   disparity (structured light, sub-pixel; NaN = unknown) in
//   motorcycle_disp.npz. The pair for sub-pixel accuracy: Aloe's integer,
//   offset truth cannot tell a median of 0.25 px from a better one.
// - graf1.png / graf3.png / H1to3p.xml: Oxford affine-covariant "Graffiti",
//   a planar wall seen from about 40 degrees apart; H13 maps graf1 px to
//   graf3 px.
// - The peers: cv::StereoSGBM and AffineFeature(SIFT) + FLANN + RANSAC, as a
//   user of OpenCV would run them.

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "vloc/common/options.h"
#include "vloc/common/stats.h"
#include "vloc/features/dense_stereo.h"
#include "vloc/features/stereo_pair_check.h"
#include "vloc/testing/npz.h"

namespace vloc::testing {

inline std::string OpencvSampleDir() {
  const char* env = std::getenv("VLOC_OPENCV_SAMPLES");
  return env ? env : "/usr/share/doc/opencv-doc/examples/data";
}

inline bool FileExists(const std::string& p) { return static_cast<bool>(std::ifstream(p)); }

// The first of `files` missing in `dir`, named with its package ("" = all there).
inline std::string FirstMissing(const std::string& dir, std::initializer_list<const char*> files, const char* package) {
  for (const char* f : files)
    if (!FileExists(dir + f)) return dir + f + " (Debian package " + package + ")";
  return "";
}

struct StereoPair {
  cv::Mat left, right;  // CV_8UC1
  cv::Mat gt;           // CV_32F, px (left x - right x), NaN = unknown
  int min_disparity = 0, num_disparities = 0;  // the search range that covers the truth
  bool ok = false;
  std::string missing;  // what was not found
};

inline StereoPair LoadAloe() {
  StereoPair p;
  const std::string d = OpencvSampleDir() + "/";
  p.missing = FirstMissing(d, {"aloeL.jpg", "aloeR.jpg", "aloeGT.png"}, "opencv-doc");
  if (!p.missing.empty()) return p;
  p.left = cv::imread(d + "aloeL.jpg", cv::IMREAD_GRAYSCALE);
  p.right = cv::imread(d + "aloeR.jpg", cv::IMREAD_GRAYSCALE);
  const cv::Mat g = cv::imread(d + "aloeGT.png", cv::IMREAD_GRAYSCALE);
  g.convertTo(p.gt, CV_32F);
  p.gt.setTo(std::numeric_limits<float>::quiet_NaN(), g == 0);
  p.min_disparity = 16;
  p.num_disparities = 224;  // truth spans 40-215 px
  p.ok = !p.left.empty() && !p.right.empty() && !g.empty();
  return p;
}

inline std::string SkimageDataDir() {
  const char* env = std::getenv("VLOC_SKIMAGE_DATA");
  return env ? env : "/usr/lib/python3/dist-packages/skimage/data";
}

inline StereoPair LoadMotorcycle() {
  StereoPair p;
  const std::string d = SkimageDataDir() + "/";
  p.missing = FirstMissing(d, {"motorcycle_left.png", "motorcycle_right.png", "motorcycle_disp.npz"}, "python3-skimage");
  if (!p.missing.empty()) return p;
  p.left = cv::imread(d + "motorcycle_left.png", cv::IMREAD_GRAYSCALE);
  p.right = cv::imread(d + "motorcycle_right.png", cv::IMREAD_GRAYSCALE);
  p.gt = ReadNpzFloat2d(d + "motorcycle_disp.npz", "arr_0.npy", &p.missing);
  p.min_disparity = 0;
  p.num_disparities = 64;  // truth spans 7.2-59.9 px
  p.ok = !p.left.empty() && !p.right.empty() && p.gt.size() == p.left.size();
  return p;
}

// A real Curiosity Navcam stereo pair (../shared/data/real/mars_navcam,
// sol 1431, JPEG, no labels: see its README), rectified from its own SIFT
// matches (fundamental matrix by RANSAC, cv::stereoRectifyUncalibrated),
// the right image shifted so every disparity is positive. No dense truth:
// the check points are the SIFT matches on the epipolar lines after
// rectification (|dy| < 0.3 px), whose own localisation noise is ~0.1 px;
// `terrain` is below the skyline (per column, the first row whose 9 x 9
// grey std exceeds 12, inside the warped image: the sky's noise stays
// under that).
struct SparseStereoPair {
  cv::Mat left, right;                // CV_8UC1, rectified
  cv::Mat valid, terrain;             // CV_8U masks: inside both warps; below the skyline
  std::vector<cv::Point2f> points;    // left px of the check points
  std::vector<float> disparity;       // their disparity (left x - right x), px
  int min_disparity = 0, num_disparities = 32;
  bool ok = false;
  std::string missing;
};

// Terrain below the skyline: per column, from the first row whose 9 x 9
// grey std exceeds 12 (inside `valid`, eroded by 10 px) down.
inline cv::Mat TerrainBelowSkyline(const cv::Mat& left, const cv::Mat& valid) {
  cv::Mat g, mean, sq, std_dev, inner;
  left.convertTo(g, CV_32F);
  cv::blur(g, mean, cv::Size(9, 9));
  cv::blur(g.mul(g), sq, cv::Size(9, 9));
  cv::sqrt(cv::max(sq - mean.mul(mean), 0), std_dev);
  cv::erode(valid, inner, cv::Mat::ones(21, 21, CV_8U));
  cv::Mat terrain(left.size(), CV_8U, cv::Scalar(0));
  for (int x = 0; x < left.cols; ++x)
    for (int y = 0; y < left.rows; ++y)
      if (inner.at<uchar>(y, x) && std_dev.at<float>(y, x) > 12) {
        for (int yy = y; yy < left.rows; ++yy) terrain.at<uchar>(yy, x) = valid.at<uchar>(yy, x);
        break;
      }
  return terrain;
}

inline SparseStereoPair LoadNavcamPair() {
  SparseStereoPair p;
  const std::string d = std::string(VLOC_SOURCE_DIR) + "/../shared/data/real/mars_navcam/";
  const char* kLeft = "NLB_524534514EDR_F0562034NCAM00280M_.jpeg";
  const char* kRight = "NRB_524534514EDR_F0562034NCAM00280M_.jpeg";
  p.missing = FirstMissing(d, {kLeft, kRight}, "none: real data beside the repo, see ../shared/data/README.md");
  if (!p.missing.empty()) return p;
  const cv::Mat l = cv::imread(d + kLeft, cv::IMREAD_GRAYSCALE), r = cv::imread(d + kRight, cv::IMREAD_GRAYSCALE);
  if (l.empty() || r.empty() || l.size() != r.size()) return p;
  StereoPairCheckOptions match;
  match.max_features = 8000;
  match.ransac_px = 0.5;
  match.min_matches = 100;
  const StereoMatches m = MatchStereoPair(l, r, match);
  const std::vector<cv::Point2f>&il = m.left, &ir = m.right;
  cv::Mat h1, h2;
  if (m.fundamental.rows != 3 || !cv::stereoRectifyUncalibrated(il, ir, m.fundamental, l.size(), h1, h2)) return p;
  const double kShift = 12;  // px added to every disparity (the rectified ones span about -6..8)
  h2 = (cv::Mat_<double>(3, 3) << 1, 0, -kShift, 0, 1, 0, 0, 0, 1) * h2;
  cv::warpPerspective(l, p.left, h1, l.size(), cv::INTER_CUBIC);
  cv::warpPerspective(r, p.right, h2, r.size(), cv::INTER_CUBIC);
  cv::Mat ones(l.size(), CV_8U, cv::Scalar(255)), vl, vr;
  cv::warpPerspective(ones, vl, h1, l.size(), cv::INTER_NEAREST);
  cv::warpPerspective(ones, vr, h2, r.size(), cv::INTER_NEAREST);
  p.valid = vl & vr;
  std::vector<cv::Point2f> ql, qr;
  cv::perspectiveTransform(il, ql, h1);
  cv::perspectiveTransform(ir, qr, h2);
  for (size_t k = 0; k < ql.size(); ++k)
    if (std::abs(ql[k].y - qr[k].y) < 0.3f) p.points.push_back(ql[k]), p.disparity.push_back(ql[k].x - qr[k].x);
  p.terrain = TerrainBelowSkyline(p.left, p.valid);
  p.ok = p.points.size() >= 100;
  return p;
}

// A UTIAS Devon Island pair (../shared/data/real/rover_devon; Furgale et
// al., IJRR 2012): the dataset's rectified XB3 images, the right one
// shifted by the row offset vloc::CheckStereoPair measures (AlignRows);
// check points: the check's SIFT matches within 0.3 px of their row after
// the shift. *check gets the check.
inline SparseStereoPair LoadDevonPair(int n, StereoPairCheck* check) {
  SparseStereoPair p;
  const std::string d = std::string(VLOC_SOURCE_DIR) + "/../shared/data/real/rover_devon/";
  const std::string kLeft = "devon" + std::to_string(n) + "-left.png", kRight = "devon" + std::to_string(n) + "-right.png";
  p.missing = FirstMissing(d, {kLeft.c_str(), kRight.c_str()}, "none: real data beside the repo, see ../shared/data/README.md");
  if (!p.missing.empty()) return p;
  p.left = cv::imread(d + kLeft, cv::IMREAD_GRAYSCALE);
  const cv::Mat r = cv::imread(d + kRight, cv::IMREAD_GRAYSCALE);
  if (p.left.empty() || r.empty() || p.left.size() != r.size()) return p;
  const StereoPairCheckOptions o;
  *check = CheckStereoPair(p.left, r, o);
  p.right = AlignRows(r, check->row_offset_px);
  const StereoMatches m = MatchStereoPair(p.left, r, o);
  for (size_t k = 0; k < m.left.size(); ++k)
    if (std::abs(m.right[k].y - check->row_offset_px - m.left[k].y) < 0.3f)
      p.points.push_back(m.left[k]), p.disparity.push_back(m.left[k].x - m.right[k].x);
  p.valid = cv::Mat(p.left.size(), CV_8U, cv::Scalar(255));
  p.terrain = TerrainBelowSkyline(p.left, p.valid);
  p.min_disparity = static_cast<int>(check->min_disparity);
  p.num_disparities = (static_cast<int>(check->max_disparity - check->min_disparity) + 16) / 16 * 16;
  p.ok = check->usable && p.points.size() >= 100;
  return p;
}

struct SparseScore {
  double terrain_coverage = 0;  // fraction of the terrain pixels with a disparity
  double sky_matched = 0;       // fraction of the valid pixels above the skyline with one (all wrong: no texture)
  long checked = 0;             // check points with a disparity (and, with `other`, the other map's too)
  double bad1 = 0;              // fraction of checked more than 1 px from the check point's disparity
  double median_abs = 0;        // px
};

// Scores a full-resolution disparity map against the pair's check points
// (nearest pixel), counting only those where `other` (optional) has a
// disparity too.
inline SparseScore ScoreSparse(const cv::Mat& disp, const SparseStereoPair& p, const cv::Mat& other = cv::Mat()) {
  SparseScore s;
  long terrain = 0, terrain_hit = 0, sky = 0, sky_hit = 0;
  for (int y = 0; y < disp.rows; ++y)
    for (int x = 0; x < disp.cols; ++x) {
      if (!p.valid.at<uchar>(y, x)) continue;
      const bool hit = std::isfinite(disp.at<float>(y, x));
      if (p.terrain.at<uchar>(y, x)) {
        ++terrain, terrain_hit += hit;
      } else {
        ++sky, sky_hit += hit;
      }
    }
  s.terrain_coverage = terrain ? static_cast<double>(terrain_hit) / terrain : 0;
  s.sky_matched = sky ? static_cast<double>(sky_hit) / sky : 0;
  std::vector<float> err;
  for (size_t k = 0; k < p.points.size(); ++k) {
    const int x = std::clamp(static_cast<int>(std::lround(p.points[k].x)), 0, disp.cols - 1);
    const int y = std::clamp(static_cast<int>(std::lround(p.points[k].y)), 0, disp.rows - 1);
    const float v = disp.at<float>(y, x);
    if (!std::isfinite(v) || (!other.empty() && !std::isfinite(other.at<float>(y, x)))) continue;
    err.push_back(std::abs(v - p.disparity[k]));
  }
  s.checked = static_cast<long>(err.size());
  if (!err.empty()) {
    s.bad1 = static_cast<double>(std::count_if(err.begin(), err.end(), [](float e) { return e > 1.f; })) / err.size();
    s.median_abs = Median(err);
  }
  return s;
}

// vloc::DenseStereo's options for a pair (StereoPair, SparseStereoPair):
// `config_file` (relative to the source tree; nullptr = the defaults) over
// the pair's search range, on a grid of `step` px.
template <typename Pair>
DenseStereoOptions StereoOptionsFor(const Pair& pair, const char* config_file, int step) {
  DenseStereoOptions o;
  if (config_file) o = LoadOptionsFile<DenseStereoOptions>(std::string(VLOC_SOURCE_DIR "/") + config_file);
  o.min_disparity = pair.min_disparity;
  o.max_disparity = pair.min_disparity + pair.num_disparities - 1;
  o.step = step;
  return o;
}

struct GrafPair {
  cv::Mat a, b;         // CV_8UC1
  cv::Matx33d b_from_a; // ground truth homography
  bool ok = false;
  std::string missing;
};

inline GrafPair LoadGraf() {
  GrafPair p;
  const std::string d = OpencvSampleDir() + "/";
  p.missing = FirstMissing(d, {"graf1.png", "graf3.png", "H1to3p.xml"}, "opencv-doc");
  if (!p.missing.empty()) return p;
  p.a = cv::imread(d + "graf1.png", cv::IMREAD_GRAYSCALE);
  p.b = cv::imread(d + "graf3.png", cv::IMREAD_GRAYSCALE);
  cv::FileStorage fs(d + "H1to3p.xml", cv::FileStorage::READ);
  cv::Mat h;
  fs["H13"] >> h;
  if (h.rows == 3 && h.cols == 3) {
    h.convertTo(h, CV_64F);
    p.b_from_a = cv::Matx33d(h.ptr<double>());
  }
  p.ok = !p.a.empty() && !p.b.empty() && h.rows == 3;
  return p;
}

// Mean and largest distance between the two homographies' images of the
// corners of an image of `size`, px.
inline void CornerErrors(const cv::Matx33d& h, const cv::Matx33d& truth, const cv::Size& size, double* mean_px,
                         double* max_px) {
  double sum = 0, worst = 0;
  for (const cv::Vec3d& c : {cv::Vec3d(0, 0, 1), cv::Vec3d(size.width - 1, 0, 1),
                            cv::Vec3d(size.width - 1, size.height - 1, 1), cv::Vec3d(0, size.height - 1, 1)}) {
    const cv::Vec3d p = h * c, q = truth * c;
    const double e = std::hypot(p[0] / p[2] - q[0] / q[2], p[1] / p[2] - q[1] / q[2]);
    sum += e;
    worst = std::max(worst, e);
  }
  *mean_px = sum / 4;
  *max_px = worst;
}

struct DisparityScore {
  long gt_pixels = 0;      // pixels with ground truth
  long scored = 0;         // ... where the map has a disparity
  double coverage = 0;     // scored / gt_pixels
  double bad1 = 0;         // fraction of scored with |error| > 1 px
  double median_abs = 0;   // px
  double mean_signed = 0;  // px, estimate - truth
};

// Scores a disparity map on a grid of `step` px (cell (i, j) = pixel
// (j step, i step)) against the full-size truth; `mask` (grid size, CV_8U,
// optional) restricts the scored cells (e.g. to those both methods matched).
// `truth_offset` is added to the truth (Aloe: +0.25 centres its integer
// steps, see the notes at the top).
inline DisparityScore ScoreDisparity(const cv::Mat& disp, const cv::Mat& gt, int step, const cv::Mat& mask = cv::Mat(),
                                     double truth_offset = 0) {
  DisparityScore s;
  std::vector<float> err;
  double signed_sum = 0;
  long bad = 0;
  for (int i = 0; i < disp.rows; ++i)
    for (int j = 0; j < disp.cols; ++j) {
      const float t = static_cast<float>(gt.at<float>(i * step, j * step) + truth_offset);
      if (!std::isfinite(t)) continue;
      if (!mask.empty() && !mask.at<uchar>(i, j)) continue;
      ++s.gt_pixels;
      const float d = disp.at<float>(i, j);
      if (!std::isfinite(d)) continue;
      const float e = d - t;
      err.push_back(std::abs(e));
      signed_sum += e;
      bad += std::abs(e) > 1.f ? 1 : 0;
    }
  s.scored = static_cast<long>(err.size());
  if (s.gt_pixels) s.coverage = static_cast<double>(s.scored) / s.gt_pixels;
  if (!err.empty()) {
    s.bad1 = static_cast<double>(bad) / err.size();
    s.mean_signed = signed_sum / err.size();
    s.median_abs = Median(err);
  }
  return s;
}

// Cells where both maps have a disparity (and the truth is known).
inline cv::Mat BothMatched(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat m(a.size(), CV_8U, cv::Scalar(0));
  for (int i = 0; i < a.rows; ++i)
    for (int j = 0; j < a.cols; ++j)
      m.at<uchar>(i, j) = std::isfinite(a.at<float>(i, j)) && std::isfinite(b.at<float>(i, j)) ? 255 : 0;
  return m;
}

// The peer: cv::StereoSGBM with the settings of OpenCV's stereo_match
// sample (block 5, P1 = 8 b^2, P2 = 32 b^2, uniqueness 10, speckle 100/32,
// left-right check 1 px), over [min_disp, min_disp + num_disp). Float
// disparity (1/16 px), NaN = no match.
inline cv::Mat SgbmDisparity(const cv::Mat& left, const cv::Mat& right, int min_disp, int num_disp) {
  const int block = 5;
  auto sgbm = cv::StereoSGBM::create(min_disp, num_disp, block, 8 * block * block, 32 * block * block, 1, 63, 10, 100, 32,
                                     cv::StereoSGBM::MODE_SGBM);
  cv::Mat d16, out;
  sgbm->compute(left, right, d16);
  d16.convertTo(out, CV_32F, 1.0 / 16);
  out.setTo(std::numeric_limits<float>::quiet_NaN(), d16 < min_disp * 16);
  return out;
}

// The peer: AffineFeature(SIFT) with OpenCV's defaults, FLANN (KD-trees)
// with Lowe's 0.8 ratio, RANSAC homography (3 px).
struct PlainAsiftResult {
  cv::Matx33d b_from_a = cv::Matx33d::eye();
  bool ok = false;
  int keypoints_a = 0, keypoints_b = 0, matches = 0, inliers = 0;
};
inline PlainAsiftResult PlainAsiftHomography(const cv::Mat& a, const cv::Mat& b) {
  PlainAsiftResult r;
  auto asift = cv::AffineFeature::create(cv::SIFT::create());
  std::vector<cv::KeyPoint> ka, kb;
  cv::Mat da, db;
  asift->detectAndCompute(a, cv::noArray(), ka, da);
  asift->detectAndCompute(b, cv::noArray(), kb, db);
  r.keypoints_a = static_cast<int>(ka.size());
  r.keypoints_b = static_cast<int>(kb.size());
  if (ka.size() < 4 || kb.size() < 4) return r;
  cv::FlannBasedMatcher flann;
  std::vector<std::vector<cv::DMatch>> knn;
  flann.knnMatch(da, db, knn, 2);
  std::vector<cv::Point2f> pa, pb;
  for (const auto& m : knn)
    if (m.size() == 2 && m[0].distance < 0.8f * m[1].distance) {
      pa.push_back(ka[m[0].queryIdx].pt);
      pb.push_back(kb[m[0].trainIdx].pt);
    }
  r.matches = static_cast<int>(pa.size());
  if (pa.size() < 4) return r;
  std::vector<uchar> inl;
  cv::Mat h = cv::findHomography(pa, pb, cv::RANSAC, 3.0, inl);
  if (h.empty()) return r;
  r.b_from_a = cv::Matx33d(h.ptr<double>());
  r.inliers = static_cast<int>(std::count(inl.begin(), inl.end(), 1));
  r.ok = true;
  return r;
}

}  // namespace vloc::testing
