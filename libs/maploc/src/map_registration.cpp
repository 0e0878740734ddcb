// Registration of the rover's ground orthophoto to the aerial map over
// (x, y, heading); the steps are listed in map_registration.h.
#include "vloc/maploc/map_registration.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <vector>

#include "masked_correlation.h"
#include "vloc/common/options.h"
#include "vloc/common/stopwatch.h"

namespace vloc::maploc {

using internal::MaskedHighPass;
using internal::MaskedStd;
using internal::MaskedZncc;
using internal::RotateAbout;

namespace {
constexpr double kDeg = M_PI / 180.0;
}

void RegistrationOptions::Visit(OptionsReader& r) {
  r.Optional("sigma_multiple", &sigma_multiple, "search window in prior sigmas", Positive());
  r.Optional("min_search_radius_m", &min_search_radius_m, "m, smallest search radius", Positive());
  r.Optional("max_search_radius_m", &max_search_radius_m, "m, largest search radius", AtMost(500));
  r.Optional("min_heading_range_deg", &min_heading_range_deg, "deg, smallest heading half range", NonNegative());
  r.Optional("max_heading_range_deg", &max_heading_range_deg, "deg, largest heading half range", AtMost(180));
  r.Optional("heading_step_deg", &heading_step_deg, "deg, coarse heading step", InLeftOpen(0.01, 10));
  r.Optional("fine_steps", &fine_steps, "fine heading steps per coarse step", InRange(1, 20));
  r.Optional("heading_fit_half_width", &heading_fit_half_width, "fine steps each side in the heading parabola",
             AtLeast(1));
  r.Optional("highpass_sigma_m", &highpass_sigma_m, "m, Gaussian removed (high pass)", Positive());
  r.Optional("lowpass_sigma_px", &lowpass_sigma_px, "px, anti-alias Gaussian", NonNegative());
  r.Optional("gray_weight", &gray_weight, "weight of the grey ZNCC", NonNegative());
  r.Optional("height_weight", &height_weight, "weight of the height ZNCC", NonNegative());
  r.Optional("min_valid_cells", &min_valid_cells, "orthophoto cells needed at map resolution", AtLeast(10));
  r.Optional("min_overlap", &min_overlap, "fraction of the orthophoto on valid map cells", InLeftOpen(0, 1));
  r.Optional("min_gray_texture", &min_gray_texture, "grey levels, high-passed std needed", NonNegative());
  r.Optional("min_height_texture_m", &min_height_texture_m, "m, high-passed height std needed", NonNegative());
  r.Optional("min_peak_score", &min_peak_score, "combined ZNCC needed at the peak", InOpen(0, 1));
  r.Optional("max_peak_ratio", &max_peak_ratio, "second / best peak above this: ambiguous", InLeftOpen(0, 1));
  r.Optional("exclusion_radius_m", &exclusion_radius_m, "m, second peak sought beyond this from the best", Positive());
  r.Optional("covariance_scale", &covariance_scale, "k in cov = k (1 - rho) H^-1 / N (calibrated)", Positive());
  r.Optional("heading_covariance_scale", &heading_covariance_scale, "k of the heading variance (calibrated)",
             Positive());
  r.Optional("min_position_sigma_m", &min_position_sigma_m, "m, floor of the position sigma", Positive());
  r.Optional("min_heading_sigma_deg", &min_heading_sigma_deg, "deg, floor of the heading sigma", Positive());
  r.Optional("map_position_sigma_m", &map_position_sigma_m, "m, the map's georeferencing error per axis (added)",
             NonNegative());
  r.Optional("map_heading_sigma_deg", &map_heading_sigma_deg, "deg, the map's orientation error (added)",
             NonNegative());
  r.Optional("tilt_sigma_rad", &tilt_sigma_rad, "rad, roll/pitch sigma of the published fix", Positive());
  r.Optional("vertical_sigma_m", &vertical_sigma_m, "m, z sigma added to the prior's (map without heights)",
             Positive());
  r.Optional("min_vertical_sigma_m", &min_vertical_sigma_m, "m, floor of the z sigma from the map's heights",
             Positive());
  r.Optional("vertical_correlation_cells", &vertical_correlation_cells, "cells per independent height difference",
             AtLeast(1));
  r.Relation("max_search_radius_m", max_search_radius_m >= min_search_radius_m, "must be >= min_search_radius_m");
  r.Relation("max_heading_range_deg", max_heading_range_deg >= min_heading_range_deg,
             "must be >= min_heading_range_deg");
  r.Relation("height_weight", gray_weight + height_weight > 0, "must be > 0 when gray_weight is 0");
}

bool RegistrationOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

SitePrior SitePriorFromPose(const PoseWithCovariance& p) {
  SitePrior prior;
  prior.xyh << p.pose.translation().x(), p.pose.translation().y(), Heading(p.pose);
  const int idx[3] = {0, 1, 5};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) prior.covariance(i, j) = p.covariance(idx[i], idx[j]);
  return prior;
}

std::string MapFix::BriefReport() const {
  std::ostringstream s;
  s.precision(4);
  s << (usable ? "fix" : "no fix") << " (" << message << "): x " << xyh.x() << " y " << xyh.y() << " heading "
    << xyh.z() / kDeg << " deg, sigma " << std::sqrt(covariance(0, 0)) << " / " << std::sqrt(covariance(1, 1))
    << " m, " << std::sqrt(covariance(2, 2)) / kDeg << " deg; peak " << peak_score << " (grey " << gray_score
    << ", height " << height_score << "), z " << (has_z ? std::to_string(z) + " +- " + std::to_string(z_sigma) : "-")
    << ", second " << second_score << ", " << valid_cells << " cells, window "
    << search_radius_m << " m +-" << heading_range_deg << " deg, " << headings_tried << " headings, " << seconds
    << " s";
  return s.str();
}

namespace {

// High-passed bands and float masks of one raster.
struct Prepared {
  cv::Mat gray, height, mask;  // CV_32F; height empty when not used
  double gray_std = 0, height_std = 0;
};

Prepared Prepare(const MapRaster& raster, bool use_height, const RegistrationOptions& o) {
  Prepared p;
  raster.valid.convertTo(p.mask, CV_32F, 1.0 / 255);
  const double hp = o.highpass_sigma_m / raster.m_per_px;
  p.gray = MaskedHighPass(raster.gray, p.mask, hp, o.lowpass_sigma_px);
  p.gray_std = MaskedStd(p.gray, p.mask);
  if (use_height) {
    p.height = MaskedHighPass(raster.height, p.mask, hp, o.lowpass_sigma_px);
    p.height_std = MaskedStd(p.height, p.mask);
  }
  return p;
}

// Everything the steps share.
struct RegistrationState {
  const RegistrationOptions& o;
  const SitePrior& prior;
  MapRaster rover;          // at the map's resolution
  MapRaster crop;           // map around the prior
  Prepared rover_bands, map_bands;
  double gray_weight = 0, height_weight = 0;
  cv::Point2d origin_px;    // rover origin in the template, px
  int search_px = 0;        // window half side, px
  double radius_px = 0;     // circular window, px
  double heading_range = 0; // rad, +-
  std::string failure;      // set by the first failing step
};

// One heading's score map and its maximum.
struct HeadingScore {
  double heading = 0;
  cv::Mat score;          // combined ZNCC per placement, -1 = not scored
  cv::Mat gray_score, height_score;
  cv::Point best{-1, -1};
  double best_score = -1;
  double peak_value = -1; // best_score interpolated to the sub-pixel peak (heading parabola)
  int cells = 0;          // template cells with data at this heading
};

bool Failed(RegistrationState* s, const std::string& why) {
  s->failure = why;
  return false;
}

bool SetSearchWindow(RegistrationState* s) {
  const RegistrationOptions& o = s->o;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(s->prior.covariance.topLeftCorner<2, 2>());
  const double sigma_xy = std::sqrt(std::max(0.0, eig.eigenvalues().maxCoeff()));
  const double sigma_h = std::sqrt(std::max(0.0, s->prior.covariance(2, 2)));
  if (!s->prior.xyh.allFinite() || !std::isfinite(sigma_xy) || !std::isfinite(sigma_h))
    return Failed(s, "prior pose or covariance not finite");
  const double radius = std::clamp(o.sigma_multiple * sigma_xy, o.min_search_radius_m, o.max_search_radius_m);
  s->heading_range = std::clamp(o.sigma_multiple * sigma_h, o.min_heading_range_deg * kDeg, o.max_heading_range_deg * kDeg);
  s->radius_px = radius / s->crop.m_per_px;
  s->search_px = static_cast<int>(std::ceil(s->radius_px)) + 1;
  return true;
}

bool PrepareRover(const MapRaster& ortho, const MapRaster& map, RegistrationState* s) {
  std::string why;
  if (!ortho.Check(&why)) return Failed(s, "ground orthophoto: " + why);
  if (!map.Check(&why)) return Failed(s, "map: " + why);
  s->rover = ResampleRaster(ortho, map.m_per_px);
  if (std::abs(s->rover.m_per_px - map.m_per_px) > 0.01 * map.m_per_px)
    return Failed(s, "orthophoto cannot be resampled to the map's cell size");
  const int cells = cv::countNonZero(s->rover.valid);
  if (cells < s->o.min_valid_cells)
    return Failed(s, "featureless or unseen ground: " + std::to_string(cells) + " orthophoto cells with stereo data (< " +
                         std::to_string(s->o.min_valid_cells) + ")");
  const Eigen::Vector2d o = s->rover.PixelOfWorld(Eigen::Vector2d::Zero());
  s->origin_px = cv::Point2d(o.x(), o.y());
  return true;
}

bool PrepareMap(const MapRaster& map, RegistrationState* s) {
  s->crop.m_per_px = map.m_per_px;
  if (!SetSearchWindow(s)) return false;
  const int half_template = std::max(s->rover.gray.cols, s->rover.gray.rows) / 2 + 1;
  const int half = half_template + s->search_px;
  s->crop = CropRaster(map, s->prior.xyh.head<2>(), (half - 0.5) * map.m_per_px);
  if (cv::countNonZero(s->crop.valid) < s->o.min_overlap * s->crop.valid.total() * 0.25)
    return Failed(s, "the map does not cover the predicted position (+- search window)");
  return true;
}

bool PrepareBands(const MapRaster& map, RegistrationState* s) {
  const RegistrationOptions& o = s->o;
  const bool use_height = map.has_height() && o.height_weight > 0;
  s->rover_bands = Prepare(s->rover, use_height, o);
  s->map_bands = Prepare(s->crop, use_height, o);
  const bool gray_ok = s->rover_bands.gray_std >= o.min_gray_texture && s->map_bands.gray_std >= o.min_gray_texture;
  const bool height_ok = use_height && s->rover_bands.height_std >= o.min_height_texture_m &&
                         s->map_bands.height_std >= o.min_height_texture_m;
  s->gray_weight = gray_ok ? o.gray_weight : 0;
  s->height_weight = height_ok ? o.height_weight : 0;
  if (s->gray_weight + s->height_weight > 0) return true;
  std::ostringstream why;
  why.precision(3);
  why << "featureless: high-passed grey std rover " << s->rover_bands.gray_std << " / map " << s->map_bands.gray_std
      << " (need " << o.min_gray_texture << ")";
  if (use_height)
    why << ", height std rover " << s->rover_bands.height_std << " / map " << s->map_bands.height_std << " m";
  return Failed(s, why.str());
}

bool SubPixelPeak(const cv::Mat& score, cv::Point p, Eigen::Vector2d* offset, Eigen::Matrix2d* hessian);

void KeepWindow(const RegistrationState& s, cv::Mat* score) {
  const double c = 0.5 * (score->cols - 1), r0 = 0.5 * (score->rows - 1);
  for (int r = 0; r < score->rows; ++r)
    for (int c2 = 0; c2 < score->cols; ++c2)
      if (std::hypot(c2 - c, r - r0) > s.radius_px) score->at<float>(r, c2) = -1;
}

HeadingScore ScoreHeading(const RegistrationState& s, double heading) {
  HeadingScore h;
  h.heading = heading;
  const double angle = heading;  // the level frame's x axis turned to `heading` in the map
  cv::Mat mask = RotateAbout(s.rover_bands.mask, angle, s.origin_px, cv::INTER_LINEAR);
  cv::threshold(mask, mask, 0.999, 1.0, cv::THRESH_BINARY);
  h.cells = static_cast<int>(cv::countNonZero(mask));
  cv::Mat map_valid;
  s.crop.valid.convertTo(map_valid, CV_32F, 1.0 / 255);
  const double total_weight = s.gray_weight + s.height_weight;
  auto correlate = [&](const cv::Mat& templ, const cv::Mat& image) {
    return MaskedZncc(image, map_valid, RotateAbout(templ, angle, s.origin_px, cv::INTER_LINEAR), mask, s.o.min_overlap);
  };
  if (s.gray_weight > 0) h.gray_score = correlate(s.rover_bands.gray, s.map_bands.gray);
  if (s.height_weight > 0) h.height_score = correlate(s.rover_bands.height, s.map_bands.height);
  const cv::Mat& any = h.gray_score.empty() ? h.height_score : h.gray_score;
  h.score = cv::Mat::zeros(any.size(), CV_32F);
  if (!h.gray_score.empty()) h.score += (s.gray_weight / total_weight) * h.gray_score;
  if (!h.height_score.empty()) h.score += (s.height_weight / total_weight) * h.height_score;
  KeepWindow(s, &h.score);
  double best = -1;
  cv::minMaxLoc(h.score, nullptr, &best, nullptr, &h.best);
  h.best_score = best;
  h.peak_value = best;
  Eigen::Vector2d offset;
  Eigen::Matrix2d H;
  if (SubPixelPeak(h.score, h.best, &offset, &H)) h.peak_value = best - 0.5 * offset.dot(H * offset);
  return h;
}

std::vector<HeadingScore> SweepHeadings(const RegistrationState& s, double centre, double range, double step) {
  std::vector<HeadingScore> out;
  const int n = static_cast<int>(std::ceil(range / step - 1e-9));
  for (int k = -n; k <= n; ++k) out.push_back(ScoreHeading(s, centre + k * step));
  return out;
}

size_t BestIndex(const std::vector<HeadingScore>& sweep) {
  size_t best = 0;
  for (size_t k = 1; k < sweep.size(); ++k)
    if (sweep[k].best_score > sweep[best].best_score) best = k;
  return best;
}

// Best local maximum outside the exclusion zone, at any coarse heading:
// another place the orthophoto fits nearly as well (a rotation about the
// right place is not a second place: the heading curvature covers it).
double SecondPeak(const RegistrationState& s, const HeadingScore& best, const std::vector<HeadingScore>& coarse) {
  const double exclusion_px = s.o.exclusion_radius_m / s.crop.m_per_px;
  double second = -1;
  for (const HeadingScore& h : coarse) {
    cv::Mat dilated;
    cv::dilate(h.score, dilated, cv::Mat());
    for (int r = 0; r < h.score.rows; ++r)
      for (int c = 0; c < h.score.cols; ++c) {
        const float v = h.score.at<float>(r, c);
        if (v <= second || v < dilated.at<float>(r, c)) continue;
        if (std::hypot(c - best.best.x, r - best.best.y) > exclusion_px) second = v;
      }
  }
  return second;
}

// Quadratic fit on the 3 x 3 neighbourhood: sub-pixel offset and Hessian (per px^2).
bool SubPixelPeak(const cv::Mat& score, cv::Point p, Eigen::Vector2d* offset, Eigen::Matrix2d* hessian) {
  if (p.x < 1 || p.y < 1 || p.x + 1 >= score.cols || p.y + 1 >= score.rows) return false;
  auto f = [&](int dx, int dy) { return static_cast<double>(score.at<float>(p.y + dy, p.x + dx)); };
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx)
      if (f(dx, dy) <= -1) return false;
  const Eigen::Vector2d g(0.5 * (f(1, 0) - f(-1, 0)), 0.5 * (f(0, 1) - f(0, -1)));
  Eigen::Matrix2d H;
  H(0, 0) = f(1, 0) - 2 * f(0, 0) + f(-1, 0);
  H(1, 1) = f(0, 1) - 2 * f(0, 0) + f(0, -1);
  H(0, 1) = H(1, 0) = 0.25 * (f(1, 1) - f(1, -1) - f(-1, 1) + f(-1, -1));
  if (!(H.determinant() > 0 && H(0, 0) < 0)) return false;
  *offset = (-H.inverse() * g).cwiseMax(-1.0).cwiseMin(1.0);
  *hessian = H;
  return true;
}

// Least-squares parabola through the fine headings' sub-pixel peak values
// within half_width steps of the best:
// the heading offset from the best fine sample (rad, within the sweep) and
// the curvature (per rad^2, < 0 at a maximum; 0 when there is none).
void HeadingParabola(const std::vector<HeadingScore>& fine, size_t k, int half_width, double* offset,
                     double* curvature) {
  *offset = 0;
  *curvature = 0;
  const size_t first = k >= static_cast<size_t>(half_width) ? k - half_width : 0;
  const size_t last = std::min(fine.size() - 1, k + half_width);
  if (last - first < 2) return;
  const int n = static_cast<int>(last - first + 1);
  Eigen::MatrixXd A(n, 3);
  Eigen::VectorXd b(n);
  for (int i = 0; i < n; ++i) {
    const double d = fine[first + i].heading - fine[k].heading;
    A.row(i) << 1.0, d, d * d;
    b(i) = fine[first + i].peak_value;
  }
  const Eigen::Vector3d c = A.colPivHouseholderQr().solve(b);
  if (!(c(2) < 0)) return;
  const double lo = fine[first].heading - fine[k].heading, hi = fine[last].heading - fine[k].heading;
  *offset = std::clamp(-c(1) / (2 * c(2)), std::min(lo, hi), std::max(lo, hi));
  *curvature = 2 * c(2);
}

bool Decide(RegistrationState* s, const HeadingScore& best, bool heading_at_edge, MapFix* fix) {
  const RegistrationOptions& o = s->o;
  std::ostringstream why;
  why.precision(3);
  if (fix->peak_score < o.min_peak_score) {
    why << "weak correlation: peak " << fix->peak_score << " < " << o.min_peak_score << " (wrong or changed map?)";
    return Failed(s, why.str());
  }
  if (fix->second_score > o.max_peak_ratio * fix->peak_score) {
    why << "ambiguous: second peak " << fix->second_score << " > " << o.max_peak_ratio << " x best " << fix->peak_score;
    return Failed(s, why.str());
  }
  const double c = 0.5 * (best.score.cols - 1), r = 0.5 * (best.score.rows - 1);
  if (std::hypot(best.best.x - c, best.best.y - r) > s->radius_px - 1.5)
    return Failed(s, "peak on the edge of the search window (prior too far off, or a wrong match)");
  if (heading_at_edge) return Failed(s, "peak at the edge of the heading range (prior heading too far off)");
  return true;
}

// The body's world z: median over the placed orthophoto of map height minus
// orthophoto height (heights of the level frame are relative to the body).
void MeasureHeight(const RegistrationState& s, const HeadingScore& best, MapFix* fix) {
  if (!s.crop.has_height() || !s.rover.has_height()) return;
  cv::Mat mask;
  s.rover_bands.mask.copyTo(mask);
  mask = RotateAbout(mask, best.heading, s.origin_px, cv::INTER_LINEAR);
  const cv::Mat height = RotateAbout(s.rover.height, best.heading, s.origin_px, cv::INTER_LINEAR);
  std::vector<double> dz;
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c) {
      const int mr = best.best.y + r, mc = best.best.x + c;
      if (mask.at<float>(r, c) < 0.999 || mr >= s.crop.height.rows || mc >= s.crop.height.cols ||
          !s.crop.valid.at<uint8_t>(mr, mc))
        continue;
      dz.push_back(s.crop.height.at<float>(mr, mc) - height.at<float>(r, c));
    }
  if (dz.size() < 10) return;
  std::nth_element(dz.begin(), dz.begin() + dz.size() / 2, dz.end());
  const double median = dz[dz.size() / 2];
  for (double& d : dz) d = std::abs(d - median);
  std::nth_element(dz.begin(), dz.begin() + dz.size() / 2, dz.end());
  const double spread = 1.4826 * dz[dz.size() / 2];
  fix->has_z = true;
  fix->z = median;
  fix->z_sigma = std::hypot(spread / std::sqrt(dz.size() / s.o.vertical_correlation_cells), s.o.min_vertical_sigma_m);
}

void FillCovariance(const RegistrationState& s, const Eigen::Matrix2d& H, double heading_curvature, MapFix* fix) {
  const RegistrationOptions& o = s.o;
  const double rho = std::clamp(fix->peak_score, 0.0, 0.999);
  const double n = std::max(1, fix->valid_cells);
  const double res = s.crop.m_per_px;
  // Pixel rows grow southward: flip the y axis of the pixel Hessian.
  Eigen::Matrix2d flip = Eigen::Vector2d(1, -1).asDiagonal();
  Eigen::Matrix2d cov_xy = o.covariance_scale * (1 - rho) / n * (flip * (-H).inverse() * flip) * res * res;
  cov_xy += Eigen::Matrix2d::Identity() * (o.min_position_sigma_m * o.min_position_sigma_m +
                                           o.map_position_sigma_m * o.map_position_sigma_m);
  double var_h = heading_curvature < 0 ? o.heading_covariance_scale * (1 - rho) / (n * -heading_curvature)
                                       : std::pow(s.o.heading_step_deg * kDeg, 2);
  var_h += std::pow(o.min_heading_sigma_deg * kDeg, 2) + std::pow(o.map_heading_sigma_deg * kDeg, 2);
  fix->covariance.setZero();
  fix->covariance.topLeftCorner<2, 2>() = cov_xy;
  fix->covariance(2, 2) = var_h;
}

// Sub-pixel position (quadratic fit at the best heading), heading (parabola
// over the fine sweep), and the covariance from their curvatures.
bool RefinePeak(RegistrationState* s, const std::vector<HeadingScore>& fine, size_t kf, MapFix* fix) {
  const HeadingScore& best = fine[kf];
  Eigen::Vector2d offset;
  Eigen::Matrix2d H;
  if (!SubPixelPeak(best.score, best.best, &offset, &H)) return Failed(s, "correlation peak is not a clean maximum");
  double dh = 0, curvature = 0;
  HeadingParabola(fine, kf, s->o.heading_fit_half_width, &dh, &curvature);
  const Eigen::Vector2d xy = s->crop.WorldOfPixel(best.best.x + s->origin_px.x + offset.x(),
                                                  best.best.y + s->origin_px.y + offset.y());
  fix->xyh << xy.x(), xy.y(), WrapAngle(best.heading + dh);
  FillCovariance(*s, H, curvature, fix);
  return true;
}

}  // namespace

MapFix RegisterToMap(const MapRaster& ground_ortho, const MapRaster& map, const SitePrior& prior,
                     const RegistrationOptions& options) {
  std::string error;
  if (!options.Check(&error)) throw std::invalid_argument("RegistrationOptions: " + error);
  Stopwatch timer;
  MapFix fix;
  RegistrationState s{options, prior};
  auto finish = [&](bool ok) {
    fix.usable = ok;
    fix.message = ok ? "ok" : s.failure;
    fix.seconds = timer.Seconds();
    return fix;
  };
  if (!PrepareRover(ground_ortho, map, &s) || !PrepareMap(map, &s) || !PrepareBands(map, &s)) return finish(false);
  fix.search_radius_m = s.radius_px * s.crop.m_per_px;
  fix.heading_range_deg = s.heading_range / kDeg;
  const double step = options.heading_step_deg * kDeg;
  const std::vector<HeadingScore> coarse = SweepHeadings(s, prior.xyh.z(), s.heading_range, step);
  const size_t kc = BestIndex(coarse);
  const std::vector<HeadingScore> fine = SweepHeadings(s, coarse[kc].heading, step, step / options.fine_steps);
  const size_t kf = BestIndex(fine);
  fix.headings_tried = static_cast<int>(coarse.size() + fine.size());
  const HeadingScore& best = fine[kf];
  fix.peak_score = best.best_score;
  fix.gray_score = best.gray_score.empty() ? 0 : best.gray_score.at<float>(best.best);
  fix.height_score = best.height_score.empty() ? 0 : best.height_score.at<float>(best.best);
  fix.second_score = SecondPeak(s, best, coarse);
  fix.valid_cells = best.cells;
  const bool heading_at_edge = coarse.size() > 1 && (kc == 0 || kc + 1 == coarse.size());
  if (!Decide(&s, best, heading_at_edge, &fix)) return finish(false);
  if (!RefinePeak(&s, fine, kf, &fix)) return finish(false);
  MeasureHeight(s, best, &fix);
  return finish(true);
}

PoseWithCovariance FixToPose(const MapFix& fix, const PoseWithCovariance& predicted, const RegistrationOptions& o) {
  const Eigen::Vector3d rpy = RollPitchYawFromRotation(predicted.pose.linear());
  PoseWithCovariance out;
  out.utime = predicted.utime;
  const double z = fix.has_z ? fix.z : predicted.pose.translation().z();
  out.pose = MakePose(fix.xyh.x(), fix.xyh.y(), z, rpy.x(), rpy.y(), fix.xyh.z());
  out.covariance.setZero();
  const int idx[3] = {0, 1, 5};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out.covariance(idx[i], idx[j]) = fix.covariance(i, j);
  out.covariance(2, 2) = fix.has_z ? fix.z_sigma * fix.z_sigma
                                   : std::max(0.0, predicted.covariance(2, 2)) + o.vertical_sigma_m * o.vertical_sigma_m;
  out.covariance(3, 3) = out.covariance(4, 4) = o.tilt_sigma_rad * o.tilt_sigma_rad;
  return out;
}

}  // namespace vloc::maploc
