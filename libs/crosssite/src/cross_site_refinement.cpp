// Step 10: the cross-site positions the grid LSM did not refine. With the
// grid LSM (warp_current, the default) they are dropped; otherwise (and for
// backward overlaps) the previous-left window is matched into the
// full-resolution current-left image from the predicted affine, and a match
// it cannot refine is dropped.
// Then duplicates (one current pixel matched through two overlaps) merge.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>

#include <glog/logging.h>

#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

int RefineCrossSite(const CrossSiteLsmOptions& o, bool grid_refined_only, int num_threads, SitePairState* s) {
  std::vector<Candidate>& cands = s->candidates;
  const auto& overlaps = s->prediction.overlaps;
  const int n0 = static_cast<int>(cands.size());
#pragma omp parallel for schedule(dynamic, 16) num_threads(num_threads)
  for (int k = 0; k < n0; ++k) {
    Candidate& c = cands[k];
    if (c.grid_refined) continue;
    const PairOverlap& ov = overlaps[c.overlap];
    if (grid_refined_only && !ov.backward) {
      c.ok = false;
      c.why = "grid LSM failed";
      continue;
    }
    const LsmResult r = LeastSquaresMatch(s->previous_left[c.prev_pair].lsm, c.prev_left,
                                          s->current_left[c.cur_pair].lsm, c.cur_left, c.initial_affine, o.cross_lsm);
    c.ok = r.ok;
    c.why = r.why;
    if (r.ok) {
      c.cur_left = r.target;
      c.sigma_cross = r.sigma_px;
    }
  }
  if (VLOG_IS_ON(1)) {
    std::map<std::string, int> reasons;
    for (const auto& c : cands)
      if (c.why && *c.why) ++reasons[c.why];
    for (const auto& [why, n] : reasons) VLOG(1) << "cross-site LSM rejected " << n << ": " << why;
    int num_refined = 0;
    for (const auto& c : cands) num_refined += c.ok ? 1 : 0;
    VLOG(1) << "cross-site LSM refined " << num_refined << " of " << cands.size();
  }
  cands.erase(std::remove_if(cands.begin(), cands.end(), [](const Candidate& c) { return !c.ok; }), cands.end());
  MergeDuplicates(o.duplicate_radius, &cands);
  return static_cast<int>(cands.size());
}

void MergeDuplicates(double radius, std::vector<Candidate>* candidates) {
  std::vector<Candidate>& cands = *candidates;
  std::sort(cands.begin(), cands.end(), [](const Candidate& a, const Candidate& b) { return a.sigma_cross < b.sigma_cross; });
  std::unordered_map<long long, std::vector<int>> grid;
  const double cell = std::max(radius, 0.5);
  auto key = [](int pair, int gx, int gy) {
    return (static_cast<long long>(pair) << 48) ^ (static_cast<long long>(gx) << 24) ^ gy;
  };
  std::vector<Candidate> kept;
  for (const auto& c : cands) {
    const int gx = static_cast<int>(std::floor(c.cur_left.x() / cell)), gy = static_cast<int>(std::floor(c.cur_left.y() / cell));
    bool dup = false;
    for (int dx = -1; dx <= 1 && !dup; ++dx)
      for (int dy = -1; dy <= 1 && !dup; ++dy) {
        auto it = grid.find(key(c.cur_pair, gx + dx, gy + dy));
        if (it == grid.end()) continue;
        for (int q : it->second)
          if ((kept[q].cur_left - c.cur_left).norm() < radius) dup = true;
      }
    if (dup) continue;
    grid[key(c.cur_pair, gx, gy)].push_back(static_cast<int>(kept.size()));
    kept.push_back(c);
  }
  cands.swap(kept);
}

}  // namespace vloc::frontend_internal
