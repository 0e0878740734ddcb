// The lens's k1 from the height ties (lens_search.h).
#include "vloc/mosaic/lens_search.h"

#include <opencv2/calib3d.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace vloc::mosaic {

std::optional<PlaneRatio> PlaneFromHomography(const cv::Matx33d& H, const cv::Matx33d& K, const cv::Vec3d& from_normal) {
  std::vector<cv::Mat> rotations, translations, normals;
  int n = 0;
  try {
    n = cv::decomposeHomographyMat(cv::Mat(H), cv::Mat(K), rotations, translations, normals);
  } catch (const cv::Exception&) {
    return std::nullopt;
  }
  // n^T X = d in the `from` frame (OpenCV returns t / d). Of the solutions facing the camera, the one whose normal
  // is nearest the `from` frame's.
  double best = 0.5;  // within 60 degrees
  std::optional<PlaneRatio> found;
  for (int i = 0; i < n; ++i) {
    const cv::Vec3d nk(normals[i]);
    if (nk[2] <= 0) continue;
    const double agree = nk.dot(from_normal) / cv::norm(nk);
    if (agree <= best) continue;
    const cv::Matx33d R(rotations[i]);
    const cv::Vec3d t(translations[i]);
    const double ratio = 1.0 + nk.dot(R.t() * t);
    if (!(ratio > 0.2 && ratio < 5)) continue;
    best = agree;
    const cv::Vec3d nc = R * nk;
    found = PlaneRatio{ratio, nc / cv::norm(nc)};
  }
  return found;
}

namespace {

// The raw (distorted) pixels of points `run` undistorted.
std::vector<Eigen::Vector2d> RawPixels(const std::vector<cv::Point2f>& points, const PinholeCamera& run) {
  std::vector<Eigen::Vector2d> raw;
  raw.reserve(points.size());
  for (const cv::Point2f& p : points)
    raw.push_back(run.HasDistortion() ? run.Distort(Eigen::Vector2d(p.x, p.y)) : Eigen::Vector2d(p.x, p.y));
  return raw;
}

std::vector<cv::Point2f> UndistortedBy(const std::vector<Eigen::Vector2d>& raw, const PinholeCamera& candidate) {
  std::vector<cv::Point2f> out;
  out.reserve(raw.size());
  for (const Eigen::Vector2d& r : raw) {
    const Eigen::Vector2d ideal = candidate.Undistort(r);
    out.emplace_back(static_cast<float>(ideal.x()), static_cast<float>(ideal.y()));
  }
  return out;
}

// A pair's points as raw pixels, taken back once for every candidate.
struct RawPair {
  std::vector<Eigen::Vector2d> from, to;
};

// log(h_to / h_from) of one pair under `candidate`; NaN when its plane cannot be decomposed.
double LogRatioUnder(const HeightObservation& o, const RawPair& raw, const PinholeCamera& candidate) {
  if (o.from_px.empty()) return o.log_ratio;
  const cv::Mat H = cv::findHomography(UndistortedBy(raw.from, candidate), UndistortedBy(raw.to, candidate), 0);
  if (H.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::optional<PlaneRatio> plane = PlaneFromHomography(cv::Matx33d(H), candidate.K(), o.from_normal);
  return plane ? std::log(plane->height_ratio) : std::numeric_limits<double>::quiet_NaN();
}

struct Scored {
  double residual = 0;
  std::vector<bool> kept;  // per pair in `use`: not dropped by the solution
};

// The height graph over the pairs in `use` with the given log ratios, solved
// until no tie is dropped (graph.outlier_sigmas) or with none dropped (an
// infinite threshold).
Scored SolveWith(const HeightObservations& obs, const std::vector<double>& log_ratio, const std::vector<bool>& use,
                 const HeightGraphOptions& graph) {
  HeightGraph g(graph);
  for (const auto& [frame, chained] : obs.frames) g.AddFrame(frame, chained);
  std::vector<int> tie_of(obs.pairs.size(), -1);
  for (size_t i = 0; i < obs.pairs.size(); ++i) {
    const HeightObservation& o = obs.pairs[i];
    if (use[i] && g.AddTie(o.from, o.to, log_ratio[i], graph.SigmaFor(o.support)))
      tie_of[i] = g.ties() - 1;
  }
  for (int before = -1; g.dropped() != before;) {
    before = g.dropped();
    if (!g.Solve()) break;
  }
  Scored s{g.ResidualRms(), std::vector<bool>(obs.pairs.size(), false)};
  for (size_t i = 0; i < obs.pairs.size(); ++i) s.kept[i] = tie_of[i] >= 0 && g.Kept(tie_of[i]);
  return s;
}

}  // namespace

LensSearch SearchRadialDistortion(const HeightObservations& observations, const PinholeCamera& run_camera,
                                  const HeightGraphOptions& graph, const LensSearchOptions& options) {
  LensSearch result;
  std::vector<double> k1s = {run_camera.k1};
  const int steps = static_cast<int>(std::floor((options.k1_max - options.k1_min) / options.k1_step + 1e-6));
  for (int i = 0; i <= steps; ++i) k1s.push_back(std::round((options.k1_min + i * options.k1_step) * 1e9) / 1e9);
  // Each pair under each candidate; a pair any candidate cannot decompose is left out of all of them.
  const size_t pairs = observations.pairs.size();
  std::vector<std::vector<double>> ratios(k1s.size(), std::vector<double>(pairs));
  std::vector<bool> use(pairs, true);
  std::vector<RawPair> raw(pairs);
  for (size_t i = 0; i < pairs; ++i)
    raw[i] = {RawPixels(observations.pairs[i].from_px, run_camera), RawPixels(observations.pairs[i].to_px, run_camera)};
  for (size_t c = 0; c < k1s.size(); ++c) {
    PinholeCamera candidate = run_camera;
    candidate.k1 = k1s[c];
    for (size_t i = 0; i < pairs; ++i) {
      ratios[c][i] = LogRatioUnder(observations.pairs[i], raw[i], candidate);
      if (!std::isfinite(ratios[c][i])) use[i] = false;
    }
  }
  for (size_t i = 0; i < pairs; ++i) result.pairs += use[i] && !observations.pairs[i].from_px.empty();
  if (result.pairs < options.min_ties) {
    result.why = std::to_string(result.pairs) + " photo pairs with a plane under every candidate k1 (" +
                 std::to_string(options.min_ties) + " needed)";
    return result;
  }
  // The ties the run's own camera drops are left out of every candidate; the rest scored without dropping.
  const Scored as_run = SolveWith(observations, ratios[0], use, graph);
  for (size_t i = 0; i < pairs; ++i) {
    result.dropped += use[i] && !as_run.kept[i];
    use[i] = use[i] && as_run.kept[i];
  }
  HeightGraphOptions keep_all = graph;
  keep_all.outlier_sigmas = std::numeric_limits<double>::infinity();
  result.residual_as_run = SolveWith(observations, ratios[0], use, keep_all).residual;
  size_t best = 1;
  for (size_t c = 1; c < k1s.size(); ++c) {
    result.curve.emplace_back(k1s[c], SolveWith(observations, ratios[c], use, keep_all).residual);
    if (result.curve.back().y < result.curve[best - 1].y) best = c;
  }
  // A parabola through the best step and its neighbours (the residual is smooth in k1).
  const size_t b = best - 1;
  result.k1 = result.curve[b].x;
  result.residual = result.curve[b].y;
  if (b > 0 && b + 1 < result.curve.size()) {
    const double y0 = result.curve[b - 1].y, y1 = result.curve[b].y, y2 = result.curve[b + 1].y;
    const double curvature = y0 - 2 * y1 + y2;
    if (curvature > 0) result.k1 += 0.5 * options.k1_step * (y0 - y2) / curvature;
  }
  result.ok = true;
  return result;
}

}  // namespace vloc::mosaic
