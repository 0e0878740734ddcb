#include "vloc/ba/accuracy.h"

#include <Eigen/Dense>
#include <cmath>
#include <iomanip>
#include <random>
#include <sstream>

#include "vloc/common/options.h"

namespace vloc {

namespace {

bool PairsOfAtLeastTwo(const std::vector<double>& xy) { return xy.size() % 2 == 0 && xy.size() >= 4; }

bool LandmarksClearOfSites(const AccuracyOptions& o) {
  for (const auto& l : o.Landmarks())
    if ((l - o.previous_site).norm() < 1e-3 || (l - o.current_site).norm() < 1e-3) return false;
  return true;
}

}  // namespace

void AccuracyOptions::Visit(OptionsReader& r) {
  r.Optional("focal_px", &focal_px, "px, Navcam focal length f", Positive());
  r.Optional("baseline_m", &baseline_m, "m, stereo baseline B", Positive());
  r.Optional("sigma_parallax_px", &sigma_parallax_px, "px, parallax 1-sigma", Positive());
  r.Optional("sigma_azimuth_px", &sigma_azimuth_px, "px, azimuth 1-sigma; sigma_theta = atan(px / f)", Positive());
  r.Optional("previous_site", &previous_site, "m, previous site centre (x, y)", Each(Finite()));
  r.Optional("current_site", &current_site, "m, current site centre (x, y)", Each(Finite()));
  r.Optional("landmarks_xy", &landmarks_xy, "m, landmark positions x0 y0 x1 y1 ...",
             Each(Finite()) && Rule<std::vector<double>>(PairsOfAtLeastTwo, "pairs x y of at least 2 landmarks"));
  r.Optional("error_model", &error_model, "which site's covariances go into M_c^p",
             OneOf({"previous", "current", "both"}));
  r.Optional("current_frame", &current_frame, "frame of the current-site coordinates", OneOf({"world", "site"}));
  r.Optional("paper_eq8_offdiagonal", &paper_eq8_offdiagonal, "use eq. 8's off-diagonal as printed");
  r.Relation("current_site", (current_site - previous_site).norm() >= 1e-6, "must differ from previous_site");
  r.Relation("landmarks_xy", LandmarksClearOfSites(*this),
             "must keep every landmark 1 mm or more away from both sites");
}

bool AccuracyOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

double AccuracyOptions::SigmaAzimuthRad() const { return std::atan(sigma_azimuth_px / focal_px); }

std::vector<Eigen::Vector2d> AccuracyOptions::Landmarks() const {
  std::vector<Eigen::Vector2d> out;
  for (size_t i = 0; i + 1 < landmarks_xy.size(); i += 2) out.emplace_back(landmarks_xy[i], landmarks_xy[i + 1]);
  return out;
}

TiePointErrorModel AccuracyOptions::ErrorModel() const {
  if (error_model == "current") return TiePointErrorModel::kCurrent;
  if (error_model == "both") return TiePointErrorModel::kBoth;
  return TiePointErrorModel::kPrevious;
}

double StereoRangeSigma(double range_m, double baseline_m, double focal_px, double sigma_parallax_px) {
  return range_m * range_m / (baseline_m * focal_px) * sigma_parallax_px;
}

Eigen::Matrix2d PolarPointCovariance(double r, double theta, double sr, double st) {
  // (x, y) = r (cos t, sin t); J = d(x, y)/d(r, t) = [c, -r s; s, r c].
  Eigen::Matrix2d J;
  const double c = std::cos(theta), s = std::sin(theta);
  J << c, -r * s, s, r * c;
  return J * Eigen::Vector2d(sr * sr, st * st).asDiagonal() * J.transpose();
}

Eigen::Matrix2d StereoPointCovariance(const Eigen::Vector2d& site, const Eigen::Vector2d& landmark,
                                      const AccuracyOptions& o) {
  const Eigen::Vector2d d = landmark - site;
  const double r = d.norm();
  const double theta = std::atan2(d.y(), d.x());
  const double sr = StereoRangeSigma(r, o.baseline_m, o.focal_px, o.sigma_parallax_px);
  const double st = o.SigmaAzimuthRad();
  Eigen::Matrix2d cov = PolarPointCovariance(r, theta, sr, st);
  if (o.paper_eq8_offdiagonal) {
    const double sc = std::sin(theta) * std::cos(theta);
    cov(0, 1) = cov(1, 0) = sc * sr * sr - r * r * sc * sc * st * st;
  }
  return cov;
}

namespace {

// Rows of eq. 9 for a point (x, y).
Eigen::Matrix<double, 2, 4> SimilarityRows(const Eigen::Vector2d& p) {
  Eigen::Matrix<double, 2, 4> A;
  A << p.x(), -p.y(), 1, 0, p.y(), p.x(), 0, 1;
  return A;
}

// The current site's coordinates of a world point (eq. 9's (x, y)).
Eigen::Vector2d CurrentCoordinates(const AccuracyOptions& o, const Eigen::Vector2d& world) {
  return o.current_frame == "site" ? Eigen::Vector2d(world - o.current_site) : world;
}

Eigen::Matrix2d ModelCovariance(const AccuracyOptions& o, const AccuracyLandmark& l) {
  switch (o.ErrorModel()) {
    case TiePointErrorModel::kPrevious: return l.cov_previous;
    case TiePointErrorModel::kCurrent: return l.cov_current;
    case TiePointErrorModel::kBoth: return l.cov_previous + l.cov_current;
  }
  return l.cov_previous;
}

}  // namespace

AccuracyResult ComputeLocalizationAccuracy(const AccuracyOptions& o) {
  AccuracyResult res;
  std::string error;
  if (!o.Check(&error)) {
    res.message = "bad accuracy options: " + error;
    return res;
  }
  const auto landmarks = o.Landmarks();
  const int n = static_cast<int>(landmarks.size());
  Eigen::MatrixXd A(2 * n, 4);
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  for (int i = 0; i < n; ++i) {
    AccuracyLandmark l;
    l.position = landmarks[i];
    l.range_previous = (l.position - o.previous_site).norm();
    l.range_current = (l.position - o.current_site).norm();
    l.sigma_range_previous = StereoRangeSigma(l.range_previous, o.baseline_m, o.focal_px, o.sigma_parallax_px);
    l.sigma_range_current = StereoRangeSigma(l.range_current, o.baseline_m, o.focal_px, o.sigma_parallax_px);
    l.cov_previous = StereoPointCovariance(o.previous_site, l.position, o);
    l.cov_current = StereoPointCovariance(o.current_site, l.position, o);
    A.block<2, 4>(2 * i, 0) = SimilarityRows(CurrentCoordinates(o, l.position));
    M.block<2, 2>(2 * i, 2 * i) = ModelCovariance(o, l);
    res.landmarks.push_back(l);
  }
  const Eigen::MatrixXd N = A.transpose() * M.inverse() * A;
  Eigen::FullPivLU<Eigen::Matrix4d> lu(N);
  if (!lu.isInvertible()) {
    res.message = "the landmarks do not determine the similarity transform (collinear with the sites?)";
    return res;
  }
  res.cov_transform = lu.inverse();
  const Eigen::Matrix<double, 2, 4> C = SimilarityRows(CurrentCoordinates(o, o.current_site));
  res.cov_site = C * res.cov_transform * C.transpose();
  res.site_distance = (o.current_site - o.previous_site).norm();
  res.sigma_x = std::sqrt(res.cov_site(0, 0));
  res.sigma_y = std::sqrt(res.cov_site(1, 1));
  res.sigma_position = std::sqrt(res.cov_site.trace());
  res.accuracy_percent = 100.0 * res.sigma_position / res.site_distance;
  res.usable = true;
  res.message = "ok";
  return res;
}

MonteCarloResult MonteCarloLocalizationAccuracy(const AccuracyOptions& o, int trials, uint64_t seed) {
  MonteCarloResult mc;
  const AccuracyResult analytic = ComputeLocalizationAccuracy(o);
  if (!analytic.usable || trials < 2) return mc;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double st = o.SigmaAzimuthRad();
  const auto model = o.ErrorModel();
  const bool noisy_previous = model != TiePointErrorModel::kCurrent;
  const bool noisy_current = model != TiePointErrorModel::kPrevious;
  // A stereo measurement of `landmark` from `site` with polar errors.
  auto measure = [&](const Eigen::Vector2d& site, const Eigen::Vector2d& landmark) {
    const Eigen::Vector2d d = landmark - site;
    const double r = d.norm();
    const double sr = StereoRangeSigma(r, o.baseline_m, o.focal_px, o.sigma_parallax_px);
    const double rn = r + sr * normal(rng);
    const double tn = std::atan2(d.y(), d.x()) + st * normal(rng);
    return Eigen::Vector2d(site + rn * Eigen::Vector2d(std::cos(tn), std::sin(tn)));
  };
  const int n = static_cast<int>(analytic.landmarks.size());
  Eigen::MatrixXd W = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  for (int i = 0; i < n; ++i) W.block<2, 2>(2 * i, 2 * i) = ModelCovariance(o, analytic.landmarks[i]).inverse();
  const Eigen::Vector2d site_current_coords = CurrentCoordinates(o, o.current_site);
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  Eigen::Matrix2d sum2 = Eigen::Matrix2d::Zero();
  for (int t = 0; t < trials; ++t) {
    Eigen::MatrixXd A(2 * n, 4);
    Eigen::VectorXd L(2 * n);
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d& p = analytic.landmarks[i].position;
      const Eigen::Vector2d X = noisy_previous ? measure(o.previous_site, p) : p;
      const Eigen::Vector2d x_world = noisy_current ? measure(o.current_site, p) : p;
      A.block<2, 4>(2 * i, 0) = SimilarityRows(CurrentCoordinates(o, x_world));
      L.segment<2>(2 * i) = X;
    }
    const Eigen::Vector4d params = (A.transpose() * W * A).ldlt().solve(A.transpose() * W * L);
    const Eigen::Vector2d site = SimilarityRows(site_current_coords) * params;
    const Eigen::Vector2d e = site - o.current_site;
    sum += e;
    sum2 += e * e.transpose();
  }
  mc.trials = trials;
  mc.mean_error = sum / trials;
  mc.cov_site = (sum2 - trials * mc.mean_error * mc.mean_error.transpose()) / (trials - 1);
  mc.sigma_position = std::sqrt(mc.cov_site.trace());
  mc.accuracy_percent = 100.0 * mc.sigma_position / analytic.site_distance;
  return mc;
}

std::string FormatAccuracyReport(const AccuracyOptions& o, const AccuracyResult& r) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(4);
  s << "camera: f = " << o.focal_px << " px, B = " << o.baseline_m << " m, sigma_p = " << o.sigma_parallax_px
    << " px, sigma_theta = " << o.SigmaAzimuthRad() << " rad (" << o.sigma_azimuth_px << " px)\n";
  s << "sites: previous (" << o.previous_site.x() << ", " << o.previous_site.y() << "), current ("
    << o.current_site.x() << ", " << o.current_site.y() << "); error model " << o.error_model
    << ", current frame " << o.current_frame << (o.paper_eq8_offdiagonal ? ", eq. 8 off-diagonal as printed" : "")
    << "\n";
  if (!r.usable) {
    s << "not computable: " << r.message << "\n";
    return s.str();
  }
  s << "landmark            r_prev  sr_prev   r_cur   sr_cur   sx_prev  sy_prev  sx_cur   sy_cur\n";
  for (const auto& l : r.landmarks) {
    s << "(" << std::setw(7) << l.position.x() << "," << std::setw(8) << l.position.y() << ") " << std::setw(7)
      << l.range_previous << " " << std::setw(7) << l.sigma_range_previous << " " << std::setw(7)
      << l.range_current << " " << std::setw(7) << l.sigma_range_current << " " << std::setw(7)
      << std::sqrt(l.cov_previous(0, 0)) << " " << std::setw(7) << std::sqrt(l.cov_previous(1, 1)) << " "
      << std::setw(7) << std::sqrt(l.cov_current(0, 0)) << " " << std::setw(7) << std::sqrt(l.cov_current(1, 1))
      << "\n";
  }
  s << "transform (a b c d) sigmas: " << std::sqrt(r.cov_transform(0, 0)) << " " << std::sqrt(r.cov_transform(1, 1))
    << " " << std::sqrt(r.cov_transform(2, 2)) << " " << std::sqrt(r.cov_transform(3, 3)) << "\n";
  s << "new site: sigma_x = " << r.sigma_x << " m, sigma_y = " << r.sigma_y
    << " m, sigma_xy = " << r.sigma_position << " m over " << r.site_distance << " m\n";
  s << "theoretical localization accuracy: " << std::setprecision(3) << r.accuracy_percent
    << " % of the site distance\n";
  return s.str();
}

}  // namespace vloc
