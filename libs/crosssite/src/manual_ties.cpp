// CrossSiteFrontend::RunManual: an operator's clicks through the front end's
// own refinement steps (prepare_images, cross-site LSM, stereo_zncc,
// stereo_lsm + intersection, tie points), each timed like Run()'s steps.
#include <sstream>

#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc {

using namespace frontend_internal;

namespace {

// Index of pair_index `pair` in a site's sorted pairs; -1 when absent.
int PairSlot(const SiteImages& site, int pair) {
  for (size_t k = 0; k < site.pairs.size(); ++k)
    if (site.pairs[k].pair_index == pair) return static_cast<int>(k);
  return -1;
}

// The clicks as candidates in ideal px; clicks naming a missing pair or
// outside the image are skipped.
std::vector<Candidate> ClickCandidates(const NavcamModel& navcam, const SitePairState& s,
                                       const std::vector<ManualTie>& ties) {
  std::vector<Candidate> out;
  for (const ManualTie& t : ties) {
    Candidate c;
    c.prev_pair = PairSlot(s.previous, t.previous_pair);
    c.cur_pair = PairSlot(s.current, t.current_pair);
    if (c.prev_pair < 0 || c.cur_pair < 0) continue;
    if (!navcam.rig.left.InImage(t.previous_px) || !navcam.rig.left.InImage(t.current_px)) continue;
    c.prev_left = navcam.rig.left.HasDistortion() ? navcam.rig.left.Undistort(t.previous_px) : t.previous_px;
    c.cur_left = navcam.rig.left.HasDistortion() ? navcam.rig.left.Undistort(t.current_px) : t.current_px;
    out.push_back(c);
  }
  return out;
}

// Cross-site LSM of each current click from the previous one; returns how
// many it refined (the others keep the click at sigma_unrefined_px).
int RefineClicks(const CrossSiteLsmOptions& o, SitePairState* s) {
  int refined = 0;
  for (Candidate& c : s->candidates) {
    const LsmResult r =
        LeastSquaresMatch(s->previous_left[c.prev_pair].lsm, c.prev_left, s->current_left[c.cur_pair].lsm, c.cur_left,
                          Eigen::Matrix2d::Identity(), o.cross_lsm);
    c.sigma_cross = r.ok ? r.sigma_px : o.sigma_unrefined_px;
    if (r.ok) c.cur_left = r.target;
    refined += r.ok ? 1 : 0;
  }
  return refined;
}

}  // namespace

FrontendResult CrossSiteFrontend::RunManual(const SiteImages& previous, const SiteImages& current,
                                            const std::vector<ManualTie>& ties) const {
  FrontendResult result;
  StageLog stages(&result);
  try {
    SitePairState s;
    if (auto problem = CheckInput(previous, current, navcam_, &s))
      return stages.Finish(FrontendStatus::kMissingInput, *problem);
    InitTiePointSet(s, &result.tie_points);
    s.candidates = ClickCandidates(navcam_, s, ties);
    if (s.candidates.empty())
      return stages.Finish(FrontendStatus::kTooFewPoints, "manual: none of the " + std::to_string(ties.size()) +
                                                       " clicks names a pair of both sites inside its image");
    stages.Step("prepare_images", [&] {
      PrepareImages(navcam_, options_.vehicle, UsesBspline(options_), options_.num_threads, &s);
      return static_cast<int>(s.candidates.size());
    });
    const int refined = stages.Step("manual_cross_lsm", [&] { return RefineClicks(options_.cross_site, &s); });
    stages.Step("stereo_zncc", [&] { return CorrelateStereo(navcam_, options_.stereo, options_.num_threads, &s); });
    const int kept =
        stages.Step("stereo_lsm", [&] { return RefineStereoAndIntersect(navcam_, result.tie_points, options_.stereo, options_.num_threads, &s); });
    Verification all;
    all.keep.assign(s.candidates.size(), true);
    all.weights.assign(s.candidates.size(), 1);
    all.num_kept = kept;
    s.prediction.overlaps.assign(1, PairOverlap());  // scale 1: the click's error is shared by both images
    for (Candidate& c : s.candidates) c.overlap = 0;
    MakeTiePoints(s.candidates, all, s.prediction, options_.verification, &result.tie_points);
    std::ostringstream os;
    os << "manual: " << ties.size() << " clicks, " << refined << " refined by cross-site LSM, " << kept
       << " through stereo at both sites";
    return stages.Finish(kept > 0 ? FrontendStatus::kOk : FrontendStatus::kTooFewPoints, os.str());
  } catch (const std::exception& e) {
    return stages.Finish(FrontendStatus::kError, std::string("manual tie points: internal error: ") + e.what());
  }
}

}  // namespace vloc
