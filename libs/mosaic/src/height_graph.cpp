// HeightGraph (height_graph.h): linear least squares over log scales.
#include "vloc/mosaic/height_graph.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cmath>
#include <limits>

#include "vloc/common/options.h"

namespace vloc::mosaic {

namespace {
constexpr double kAnchorSigma = 1e-6;  // the first frame: fixed
constexpr double kPriorSigma = 1.0;    // the others: their chained value, as good as unknown (100 % in height)
constexpr int kMaxDropsPerSolve = 8;   // a frame brings at most a few ties: a few outliers at a time
}  // namespace

void HeightGraphOptions::Visit(OptionsReader& r) {
  r.Optional("ties", &ties, "earlier overlapping frames matched per frame for a height tie (0 = off)", InRange(0, 16));
  r.Optional("min_overlap", &min_overlap, "fraction of the frame an earlier frame must cover", InOpen(0.0, 1.0));
  r.Optional("sigma", &sigma, "log 1-sigma of one height ratio", Positive());
  r.Optional("outlier_sigmas", &outlier_sigmas, "ties beyond this many sigmas of the solution dropped", Above(1.0));
  r.Optional("max_disagreement", &max_disagreement, "log: ties farther than this from the chain not added", Positive());
  r.Optional("window", &window, "frames a solve moves (the newest; older ones held; 0 = all)", InRange(0, 1000000));
}

bool HeightGraphOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

// As 1/sqrt(matches) (seneca's links against the GPS altitude: 3.1 % below 60 matches, 2.0 % at 150-300, 1.7 % above
// 300, most of it the GPS altitude's own noise).
double HeightGraphOptions::SigmaFor(int matches) const { return sigma * std::sqrt(100.0 / std::max(matches, 1)); }

void HeightGraph::AddFrame(int64_t key, double log_scale) {
  if (!std::isfinite(log_scale) || Has(key)) return;
  index_[key] = static_cast<int>(chained_.size());
  chained_.push_back(log_scale);
  solved_.push_back(log_scale);
}

bool HeightGraph::AddTie(int64_t from, int64_t to, double log_ratio, double sigma) {
  const auto f = index_.find(from), t = index_.find(to);
  if (f == index_.end() || t == index_.end() || f->second == t->second) return false;
  if (!std::isfinite(log_ratio) || !(sigma > 0)) return false;
  ties_.push_back(Tie{f->second, t->second, log_ratio, sigma});
  return true;
}

bool HeightGraph::Solve() {
  const int n = static_cast<int>(chained_.size());
  const int first = options_.window > 0 && n > options_.window ? n - options_.window : 0;
  windowed_ = windowed_ || first > 0;
  return SolveFrom(first);
}

bool HeightGraph::SolveAll() { return SolveFrom(0); }

bool HeightGraph::SolveFrom(int first) {
  if (chained_.empty() || !SolveActive(first)) return false;
  // The worst tie at a time: a gross one pulls its neighbours' residuals up with it.
  for (int round = 0; round < kMaxDropsPerSolve && DropWorstOutlier(first); ++round)
    if (!SolveActive(first)) return false;
  return true;
}

// Least squares over frames first ... n - 1; a tie to an older (fixed) frame pulls its free frame towards the fixed
// frame's solution plus the ratio.
bool HeightGraph::SolveActive(int first) {
  const int n = static_cast<int>(chained_.size()) - first;
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
  for (int i = 0; i < n; ++i) {
    const double w = 1.0 / std::pow(first + i == 0 ? kAnchorSigma : kPriorSigma, 2);
    entries.emplace_back(i, i, w);
    b[i] += w * chained_[first + i];
  }
  for (const Tie& t : ties_) {
    if (!t.active || (t.from < first && t.to < first)) continue;
    const double w = 1.0 / (t.sigma * t.sigma);
    const int to = t.to - first, from = t.from - first;
    if (from < 0) {
      entries.emplace_back(to, to, w);
      b[to] += w * (t.log_ratio + solved_[t.from]);
    } else if (to < 0) {
      entries.emplace_back(from, from, w);
      b[from] += w * (solved_[t.to] - t.log_ratio);
    } else {
      entries.emplace_back(to, to, w);
      entries.emplace_back(from, from, w);
      entries.emplace_back(to, from, -w);
      entries.emplace_back(from, to, -w);
      b[to] += w * t.log_ratio;
      b[from] -= w * t.log_ratio;
    }
  }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(entries.begin(), entries.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
  if (solver.info() != Eigen::Success) return false;
  const Eigen::VectorXd x = solver.solve(b);
  if (solver.info() != Eigen::Success || !x.allFinite()) return false;
  for (int i = 0; i < n; ++i) solved_[first + i] = x[i];
  return true;
}

bool HeightGraph::DropWorstOutlier(int first) {
  Tie* worst = nullptr;
  double worst_r = options_.outlier_sigmas;
  for (Tie& t : ties_) {
    if (!t.active || (t.from < first && t.to < first)) continue;
    const double r = std::abs(solved_[t.to] - solved_[t.from] - t.log_ratio) / t.sigma;
    if (r > worst_r) {
      worst_r = r;
      worst = &t;
    }
  }
  if (!worst) return false;
  worst->active = false;
  ++dropped_;
  return true;
}

double HeightGraph::ResidualRms() const {
  double sum = 0;
  int n = 0;
  for (const Tie& t : ties_) {
    if (!t.active) continue;
    const double r = (solved_[t.to] - solved_[t.from] - t.log_ratio) / t.sigma;
    sum += r * r;
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) : 0.0;
}

std::optional<double> HeightGraph::LogScale(int64_t key) const {
  const auto it = index_.find(key);
  if (it == index_.end()) return std::nullopt;
  return solved_[it->second];
}

double HeightGraph::ChainedLogScale(int64_t key) const {
  const auto it = index_.find(key);
  return it == index_.end() ? std::numeric_limits<double>::quiet_NaN() : chained_[it->second];
}

}  // namespace vloc::mosaic
