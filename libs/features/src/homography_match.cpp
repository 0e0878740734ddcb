#include "vloc/features/homography_match.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "vloc/common/options.h"

namespace vloc {

AsiftOptions HomographyMatchOptions::DefaultAsift() {
  AsiftOptions a;
  a.tilts = {1.0, std::sqrt(2.0), 2.0};  // both images simulated: relative tilts up to 4
  a.max_features_per_view = 800;
  return a;
}

LsmOptions HomographyMatchOptions::DefaultLsm() {
  LsmOptions l;
  l.half_window = 7;
  l.max_shift_px = 3.0;
  l.max_sigma_px = 0.2;
  l.min_correlation = 0.85;
  l.convergence_px = 0.002;
  return l;
}

void HomographyMatchOptions::Visit(OptionsReader& r) {
  r.Child("asift", [&](OptionsReader& c) { asift.Visit(c); });
  r.Optional("coarse_scale", &coarse_scale, "images reduced by this for the ASIFT stage", InLeftOpen(0.05, 1));
  r.Optional("ratio", &ratio, "Lowe ratio of the coarse matches", InLeftOpen(0, 1));
  r.Optional("coarse_ransac_px", &coarse_ransac_px, "px, RANSAC threshold of the coarse homography", Positive());
  r.Optional("refine_rounds", &refine_rounds, "LSM refinement rounds (0 = coarse only)", NonNegative());
  r.Optional("refine_points", &refine_points, "corners of the first image matched by LSM", AtLeast(4));
  r.Optional("refine_cell_px", &refine_cell_px, "px, one corner (the strongest) per cell of this size", AtLeast(1));
  r.Optional("refine_corner_quality", &refine_corner_quality, "goodFeaturesToTrack quality level", InOpen(0, 1));
  r.Optional("refine_min_distance", &refine_min_distance, "px, minimum distance between corners", AtLeast(1));
  r.Optional("refine_search_px", &refine_search_px, "px, ZNCC search radius around the prediction", AtLeast(1));
  r.Optional("refine_min_zncc", &refine_min_zncc, "minimum ZNCC of the search peak");
  r.Optional("refine_ransac_px", &refine_ransac_px, "px, RANSAC threshold on the LSM correspondences", Positive());
  r.Child("lsm", [&](OptionsReader& c) { lsm.Visit(c); });
  r.Optional("num_threads", &num_threads, "OpenMP threads", AtLeast(1));
}

bool HomographyMatchOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

std::string HomographyMatchSummary::BriefReport() const {
  std::ostringstream s;
  s << (usable ? "usable" : "not usable") << " (" << message << "): features " << features_a << " + " << features_b
    << ", coarse " << coarse_inliers << " of " << coarse_matches << " inliers, refined " << refine_inliers << " of "
    << refine_matches << " (" << refine_points << " corners), rms " << rms_px << " px, " << total_seconds
    << " s (detect " << detect_seconds << ", match " << match_seconds << ", refine " << refine_seconds << ")";
  return s.str();
}

namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

Eigen::Vector2d Apply(const cv::Matx33d& h, const Eigen::Vector2d& p) {
  const cv::Vec3d q = h * cv::Vec3d(p.x(), p.y(), 1.0);
  return {q[0] / q[2], q[1] / q[2]};
}

// d Apply(h, p) / dp.
Eigen::Matrix2d Jacobian(const cv::Matx33d& h, const Eigen::Vector2d& p) {
  const double w = h(2, 0) * p.x() + h(2, 1) * p.y() + h(2, 2);
  const double u = h(0, 0) * p.x() + h(0, 1) * p.y() + h(0, 2), v = h(1, 0) * p.x() + h(1, 1) * p.y() + h(1, 2);
  Eigen::Matrix2d j;
  j << (h(0, 0) * w - u * h(2, 0)) / (w * w), (h(0, 1) * w - u * h(2, 1)) / (w * w),
      (h(1, 0) * w - v * h(2, 0)) / (w * w), (h(1, 1) * w - v * h(2, 1)) / (w * w);
  return j;
}

// ZNCC peak of the window around integer `p` of `templ` in `target` within
// `radius` px of `p`, sub-pixel by parabolas; false when not unique enough.
bool ZnccPeak(const cv::Mat& templ, const cv::Point& p, const cv::Mat& target, int radius, int half, double min_score,
              Eigen::Vector2d* peak) {
  const cv::Rect tr(p.x - half, p.y - half, 2 * half + 1, 2 * half + 1);
  const cv::Rect sr(p.x - half - radius, p.y - half - radius, 2 * (half + radius) + 1, 2 * (half + radius) + 1);
  const cv::Rect all(0, 0, templ.cols, templ.rows);
  if ((tr & all) != tr || (sr & cv::Rect(0, 0, target.cols, target.rows)) != sr) return false;
  cv::Mat score;
  cv::matchTemplate(target(sr), templ(tr), score, cv::TM_CCOEFF_NORMED);
  double best;
  cv::Point m;
  cv::minMaxLoc(score, nullptr, &best, nullptr, &m);
  if (!(best >= min_score) || m.x == 0 || m.y == 0 || m.x == score.cols - 1 || m.y == score.rows - 1) return false;
  auto vertex = [](double a, double b, double c) {
    const double den = a - 2 * b + c;
    return std::abs(den) < 1e-12 ? 0.0 : std::clamp(0.5 * (a - c) / den, -0.5, 0.5);
  };
  const double sx = vertex(score.at<float>(m.y, m.x - 1), best, score.at<float>(m.y, m.x + 1));
  const double sy = vertex(score.at<float>(m.y - 1, m.x), best, score.at<float>(m.y + 1, m.x));
  *peak = Eigen::Vector2d(sr.x + half + m.x + sx, sr.y + half + m.y + sy);
  return true;
}

// RANSAC (threshold px) and then least squares + Levenberg-Marquardt over
// all inliers. Returns false when fewer than 8 inliers.
bool FitHomography(const std::vector<cv::Point2f>& pa, const std::vector<cv::Point2f>& pb, double threshold,
                   cv::Matx33d* h, std::vector<uchar>* inlier) {
  if (pa.size() < 8) return false;
  const cv::Mat r = cv::findHomography(pa, pb, cv::RANSAC, threshold, *inlier, 5000, 0.9999);
  if (r.empty()) return false;
  std::vector<cv::Point2f> ia, ib;
  for (size_t k = 0; k < pa.size(); ++k)
    if ((*inlier)[k]) ia.push_back(pa[k]), ib.push_back(pb[k]);
  if (ia.size() < 8) return false;
  const cv::Mat lm = cv::findHomography(ia, ib, 0);  // all inliers: DLT then LM on the transfer error
  *h = cv::Matx33d((lm.empty() ? r : lm).ptr<double>());
  return true;
}

// Corners spread evenly: the strongest in each cell of refine_cell_px. A
// real scene departs from one homography by a few tenths of a px (relief,
// lens), so the fit must weigh the whole overlap alike, not the most
// textured part of it.
std::vector<cv::Point2f> SpreadCorners(const cv::Mat& a, const HomographyMatchOptions& o) {
  std::vector<cv::Point2f> strong, corners;
  cv::goodFeaturesToTrack(a, strong, 0, o.refine_corner_quality, o.refine_min_distance, cv::noArray(), 7);
  const int cell = o.refine_cell_px, gw = (a.cols + cell - 1) / cell;
  std::vector<char> taken(static_cast<size_t>(gw) * ((a.rows + cell - 1) / cell), 0);
  for (const auto& c : strong) {  // strongest first
    char& t = taken[static_cast<int>(c.y) / cell * gw + static_cast<int>(c.x) / cell];
    if (t) continue;
    t = 1;
    corners.push_back(c);
    if (static_cast<int>(corners.size()) >= o.refine_points) break;
  }
  return corners;
}

// One refinement round's correspondences (pa in a, pb in b) at the corners
// covered by b warped through h: ZNCC within `radius` px on the warp, then
// LSM into the original b (no second resampling) from the peak mapped
// through h with h's local affine shape there.
void MatchCorners(const cv::Mat& a, const cv::Mat& b, const LsmImage& la, const LsmImage& lb,
                  const std::vector<cv::Point2f>& corners, const cv::Matx33d& h, int radius,
                  const HomographyMatchOptions& o, std::vector<cv::Point2f>* pa, std::vector<cv::Point2f>* pb) {
  const int half = o.lsm.half_window;
  const cv::Mat ones(b.size(), CV_8U, cv::Scalar(255));
  cv::Mat warped, coverage;
  cv::warpPerspective(b, warped, cv::Mat(h), a.size(), cv::INTER_CUBIC | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, 0);
  cv::warpPerspective(ones, coverage, cv::Mat(h), a.size(), cv::INTER_NEAREST | cv::WARP_INVERSE_MAP,
                      cv::BORDER_CONSTANT, 0);
  cv::erode(coverage, coverage, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * (half + radius) + 7, 2 * (half + radius) + 7)));
  const int n = static_cast<int>(corners.size());
  std::vector<Eigen::Vector2d> qa(n), qb(n);
  std::vector<char> ok(n, 0);
#pragma omp parallel for schedule(dynamic, 32) num_threads(o.num_threads)
  for (int k = 0; k < n; ++k) {
    const cv::Point p(cvRound(corners[k].x), cvRound(corners[k].y));
    if (!coverage.at<uchar>(p)) continue;
    Eigen::Vector2d q;
    if (!ZnccPeak(a, p, warped, radius, half, o.refine_min_zncc, &q)) continue;
    const Eigen::Vector2d p2(p.x, p.y);
    const LsmResult r = LeastSquaresMatch(la, p2, lb, Apply(h, q), Jacobian(h, q), o.lsm);
    if (!r.ok) continue;
    qa[k] = p2;
    qb[k] = r.target;
    ok[k] = 1;
  }
  for (int k = 0; k < n; ++k)
    if (ok[k]) {
      pa->emplace_back(static_cast<float>(qa[k].x()), static_cast<float>(qa[k].y()));
      pb->emplace_back(static_cast<float>(qb[k].x()), static_cast<float>(qb[k].y()));
    }
}

// The inliers of `refined` among the correspondences (RANSAC's, within
// refine_ransac_px of the final fit) into res, and their RMS.
void KeepInliers(const std::vector<cv::Point2f>& pa, const std::vector<cv::Point2f>& pb,
                 const std::vector<uchar>& inlier, const cv::Matx33d& refined, const HomographyMatchOptions& o,
                 HomographyMatchResult* res) {
  res->b_from_a = refined;
  res->inliers_a.clear();
  res->inliers_b.clear();
  double ss = 0;
  for (size_t k = 0; k < pa.size(); ++k) {
    if (!inlier[k]) continue;
    const Eigen::Vector2d ea(pa[k].x, pa[k].y), eb(pb[k].x, pb[k].y);
    const double e = (Apply(refined, ea) - eb).norm();
    if (e > o.refine_ransac_px) continue;
    res->inliers_a.push_back(ea);
    res->inliers_b.push_back(eb);
    ss += e * e;
  }
  HomographyMatchSummary& s = res->summary;
  s.refine_inliers = static_cast<int>(res->inliers_a.size());
  s.rms_px = s.refine_inliers ? std::sqrt(ss / s.refine_inliers) : 0;
}

// The coarse correspondences (full px) of ASIFT on the images reduced by
// coarse_scale: FLANN's 4 nearest, the distinct ratio test; counts and the
// detection's seconds into s, the matching's start into *t1.
void CoarseMatches(const cv::Mat& a, const cv::Mat& b, const HomographyMatchOptions& o, Clock::time_point t0,
                   HomographyMatchSummary* s, Clock::time_point* t1, std::vector<cv::Point2f>* pa,
                   std::vector<cv::Point2f>* pb) {
  cv::Mat sa = a, sb = b;
  if (o.coarse_scale < 1) {
    cv::resize(a, sa, cv::Size(), o.coarse_scale, o.coarse_scale, cv::INTER_AREA);
    cv::resize(b, sb, cv::Size(), o.coarse_scale, o.coarse_scale, cv::INTER_AREA);
  }
  AsiftOptions ao = o.asift;
  ao.num_threads = o.num_threads;
  const FeatureSet fa = DetectAsift(sa, cv::Mat(), ao), fb = DetectAsift(sb, cv::Mat(), ao);
  s->features_a = static_cast<int>(fa.size());
  s->features_b = static_cast<int>(fb.size());
  s->detect_seconds = Since(t0);
  *t1 = Clock::now();
  if (fa.size() < 4 || fb.size() < 4) return;
  // FLANN's randomised k-d trees draw from this thread's cv::theRNG():
  // a fixed seed (restored afterwards) makes the result repeatable.
  cv::RNG& rng = cv::theRNG();
  const uint64_t saved_state = rng.state;
  rng.state = 0x5eed1e55ULL;
  cv::FlannBasedMatcher flann;
  std::vector<std::vector<cv::DMatch>> knn;
  flann.knnMatch(fa.descriptors, fb.descriptors, knn, 4);
  rng.state = saved_state;
  // Scale factor from reduced to full px, for the pixel-centre convention of cv::resize.
  const double fx_a = static_cast<double>(a.cols) / sa.cols, fy_a = static_cast<double>(a.rows) / sa.rows;
  const double fx_b = static_cast<double>(b.cols) / sb.cols, fy_b = static_cast<double>(b.rows) / sb.rows;
  for (const auto& m : knn) {
    if (m.empty()) continue;
    // The rival is the best candidate at another place: ASIFT repeats a point once per view.
    std::vector<std::pair<double, int>> cands;
    for (const auto& c : m) cands.emplace_back(static_cast<double>(c.distance) * c.distance, c.trainIdx);
    if (!DistinctRatioTest(cands, fb.points, o.ratio, 2.0)) continue;
    const Eigen::Vector2d& p = fa.points[m[0].queryIdx];
    const Eigen::Vector2d& q = fb.points[m[0].trainIdx];
    pa->emplace_back(static_cast<float>((p.x() + 0.5) * fx_a - 0.5), static_cast<float>((p.y() + 0.5) * fy_a - 0.5));
    pb->emplace_back(static_cast<float>((q.x() + 0.5) * fx_b - 0.5), static_cast<float>((q.y() + 0.5) * fy_b - 0.5));
  }
}

}  // namespace

HomographyMatchResult RefineHomography(const cv::Mat& a, const cv::Mat& b, const cv::Matx33d& b_from_a,
                                       const HomographyMatchOptions& o) {
  HomographyMatchResult res;
  res.b_from_a = b_from_a;
  HomographyMatchSummary& s = res.summary;
  const auto t0 = Clock::now();
  const std::vector<cv::Point2f> corners = SpreadCorners(a, o);
  const LsmImage la = MakeLsmImage(a, o.lsm.bspline), lb = MakeLsmImage(b, o.lsm.bspline);
  for (int round = 0; round < o.refine_rounds; ++round) {
    std::vector<cv::Point2f> pa, pb;
    MatchCorners(a, b, la, lb, corners, res.b_from_a, round == 0 ? o.refine_search_px : 2, o, &pa, &pb);
    s.refine_points = static_cast<int>(corners.size());
    s.refine_matches = static_cast<int>(pa.size());
    std::vector<uchar> inlier;
    cv::Matx33d refined;
    if (!FitHomography(pa, pb, o.refine_ransac_px, &refined, &inlier)) {
      s.message = "refinement: fewer than 8 LSM correspondences agree (texture, or the coarse homography is off)";
      s.refine_seconds = Since(t0);
      return res;
    }
    KeepInliers(pa, pb, inlier, refined, o, &res);
  }
  s.refine_seconds = Since(t0);
  s.usable = true;
  s.message = "ok";
  return res;
}

HomographyMatchResult MatchHomography(const cv::Mat& a, const cv::Mat& b, const HomographyMatchOptions& o) {
  std::string error;
  if (!o.Check(&error)) throw std::invalid_argument(error);
  if (a.type() != CV_8UC1 || b.type() != CV_8UC1 || a.empty() || b.empty())
    throw std::invalid_argument("MatchHomography needs two non-empty 8-bit grey images");
  const auto t0 = Clock::now();
  HomographyMatchSummary s;
  std::vector<cv::Point2f> pa, pb;
  Clock::time_point t1;
  CoarseMatches(a, b, o, t0, &s, &t1, &pa, &pb);
  s.coarse_matches = static_cast<int>(pa.size());
  HomographyMatchResult res;
  std::vector<uchar> inlier;
  const cv::Mat h = pa.size() < 8 ? cv::Mat() : cv::findHomography(pa, pb, cv::RANSAC, o.coarse_ransac_px, inlier, 5000, 0.9999);
  if (h.empty()) {
    s.message = "coarse: too few ASIFT matches agree on a homography (not a planar overlap, or too little texture)";
    s.match_seconds = Since(t1);
    s.total_seconds = Since(t0);
    res.summary = s;
    return res;
  }
  const cv::Matx33d coarse(h.ptr<double>());
  s.coarse_inliers = static_cast<int>(std::count(inlier.begin(), inlier.end(), 1));
  s.match_seconds = Since(t1);
  res.b_from_a = coarse;
  if (o.refine_rounds > 0) {
    HomographyMatchResult r = RefineHomography(a, b, coarse, o);
    r.summary.features_a = s.features_a;
    r.summary.features_b = s.features_b;
    r.summary.coarse_matches = s.coarse_matches;
    r.summary.coarse_inliers = s.coarse_inliers;
    r.summary.detect_seconds = s.detect_seconds;
    r.summary.match_seconds = s.match_seconds;
    res = std::move(r);
  } else {
    for (size_t k = 0; k < pa.size(); ++k)
      if (inlier[k]) res.inliers_a.emplace_back(pa[k].x, pa[k].y), res.inliers_b.emplace_back(pb[k].x, pb[k].y);
    s.usable = true;
    s.message = "ok (coarse only)";
    res.summary = s;
  }
  res.summary.total_seconds = Since(t0);
  return res;
}

}  // namespace vloc
