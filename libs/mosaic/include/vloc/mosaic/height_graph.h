#pragma once
// Heights of the registered frames as a graph over their log scale (log of
// mosaic px per frame px, the height up to a constant: eqs. 4-5). Each
// registration to a reference frame, and each extra tie to an earlier frame
// that overlaps (the adjacent strip of a survey), measures log s_to - log
// s_from: the log height ratio of the plane-induced homography. A chain of
// registrations alone is a random walk (each link adds its error); the least-
// squares solution over the ties spreads a tie's disagreement over the links
// between, as a pose graph does with loop closures, and bounds the drift.
// Pure algorithm (Eigen): nodes keyed by a frame's unique index.
#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

namespace vloc {
class OptionsReader;
}

namespace vloc::mosaic {

struct HeightGraphOptions {
  int ties = 0;                   // earlier overlapping frames matched per registered frame for a height tie (0 = off:
                                  // the heights are the registration chain's)
  double min_overlap = 0.3;       // fraction of the frame an earlier frame must cover (mosaic poses) to be tried
  double sigma = 0.007;           // log 1-sigma of one height ratio (a registration or a tie) from 100 matches; it
                                  // scales as 1/sqrt(matches) (seneca's ties agree to this: residual RMS 1.0)
  double outlier_sigmas = 4.0;    // a tie disagreeing with the solution by more than this is dropped
  double max_disagreement = 0.15; // a tie disagreeing with the chain by more than this (log) is not added
  int window = 600;               // frames a Solve moves once the graph holds more: the newest `window`, the older
                                  // ones held at their solution (fixed-lag: a photo's cost stays that of `window`
                                  // frames; SolveAll moves them all); 0 = every frame at every Solve
  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
  double SigmaFor(int matches) const;  // a height ratio's log sigma from the matches behind it (sigma at 100)
};

class HeightGraph {
 public:
  explicit HeightGraph(const HeightGraphOptions& options = {}) : options_(options) {}

  // A frame at its chained log scale. The first frame anchors the graph; the
  // others hold to their chained value by a weak prior only (a frame no tie
  // reaches keeps it).
  void AddFrame(int64_t key, double log_scale);
  bool Has(int64_t key) const { return index_.count(key) > 0; }
  // log s_to - log s_from = log_ratio (1-sigma `sigma` in log); both frames added before. False (not added) for an
  // unknown frame, a tie of a frame to itself, a ratio that is not finite or a sigma that is not positive.
  bool AddTie(int64_t from, int64_t to, double log_ratio, double sigma);
  // Least squares over all ties; the tie farthest beyond outlier_sigmas of
  // the solution is dropped and the rest solved again, until none is (a few
  // per call). False when there is nothing to solve.
  bool Solve();
  // The same over every frame (the final heights of a survey that outgrew the window).
  bool SolveAll();
  bool Windowed() const { return windowed_; }  // a Solve has held older frames fixed
  // The solved log scale (the chained one before the first Solve).
  std::optional<double> LogScale(int64_t key) const;
  double ChainedLogScale(int64_t key) const;  // as added; NaN when unknown

  int frames() const { return static_cast<int>(chained_.size()); }
  int ties() const { return static_cast<int>(ties_.size()); }
  int dropped() const { return dropped_; }
  bool Kept(int tie) const { return ties_.at(tie).active; }  // tie `tie` (in the order added) not dropped
  // RMS of the kept ties' residuals in their sigmas (about 1 when the sigmas are right; 0 without ties).
  double ResidualRms() const;

 private:
  struct Tie {
    int from, to;
    double log_ratio, sigma;
    bool active = true;
  };
  bool SolveFrom(int first);    // frames first ... n - 1 free, the older ones fixed; drops outliers
  bool SolveActive(int first);
  bool DropWorstOutlier(int first);  // the tie (with a free frame) farthest beyond outlier_sigmas, if any

  HeightGraphOptions options_;
  std::unordered_map<int64_t, int> index_;
  std::vector<double> chained_, solved_;
  std::vector<Tie> ties_;
  int dropped_ = 0;
  bool windowed_ = false;
};

}  // namespace vloc::mosaic
