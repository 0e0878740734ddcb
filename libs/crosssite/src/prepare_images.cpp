// Step 1: the input checked and sorted, the tie point set's header, and
// every image undistorted into its matching and LSM forms, with the mask of
// the rover's body in the left images.
#include <omp.h>

#include <algorithm>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

std::optional<std::string> CheckInput(const SiteImages& previous, const SiteImages& current, const NavcamModel& navcam,
                                      SitePairState* state) {
  state->previous = previous;
  state->current = current;
  auto by_index = [](const StereoPair& a, const StereoPair& b) { return a.pair_index < b.pair_index; };
  std::sort(state->previous.pairs.begin(), state->previous.pairs.end(), by_index);
  std::sort(state->current.pairs.begin(), state->current.pairs.end(), by_index);
  if (state->previous.pairs.empty()) return std::string("no stereo pairs of the previous site");
  if (state->current.pairs.empty()) return std::string("no stereo pairs of the current site");
  const PinholeCamera& cam = navcam.rig.left;
  for (const SiteImages* s : {&state->previous, &state->current}) {
    for (const auto& p : s->pairs) {
      for (const cv::Mat* m : {&p.left, &p.right}) {
        const bool grey_or_colour = m->type() == CV_8UC1 || m->type() == CV_8UC3;
        if (m->empty() || !grey_or_colour || m->cols != cam.width || m->rows != cam.height) {
          std::ostringstream os;
          os << "site " << s->site_id << " pair " << p.pair_index << ": image is " << m->cols << "x" << m->rows
             << (m->type() == CV_8UC3 ? " colour" : m->type() == CV_8UC1 ? " grey" : " not 8-bit grey or colour")
             << ", the camera file says " << cam.width << "x" << cam.height
             << " 8-bit grey or colour (check the Navcam calibration file)";
          return os.str();
        }
      }
    }
  }
  return std::nullopt;
}

void InitTiePointSet(const SitePairState& state, TiePointSet* tps) {
  tps->previous_site_id = state.previous.site_id;
  tps->current_site_id = state.current.site_id;
  tps->previous_site_pose = state.previous.world_from_body;
  tps->current_site_pose_dr = state.current.world_from_body;
  for (const auto& p : state.previous.pairs) tps->previous_pointing.push_back({p.mast_pan, p.mast_tilt});
  for (const auto& p : state.current.pairs) {
    tps->current_pointing.push_back({p.mast_pan, p.mast_tilt});
    tps->utime = std::max(tps->utime, p.utime);
  }
}

namespace {

// A colour camera's image (BGR, as decoded) is matched on its luminance.
void Prepare(const cv::Mat& raw, const PinholeCamera& cam, bool bspline, PreparedImage* p) {
  cv::Mat grey = raw;
  if (raw.type() == CV_8UC3) cv::cvtColor(raw, grey, cv::COLOR_BGR2GRAY);
  if (cam.HasDistortion()) {
    cv::undistort(grey, p->gray, cv::Mat(cam.K()), cam.DistortionCoeffs(), cv::Mat(cam.K()));
  } else {
    p->gray = grey;
  }
  p->lsm = MakeLsmImage(p->gray, bspline);
}

}  // namespace

bool UsesBspline(const FrontendOptions& o) { return o.stereo.lsm.bspline || o.cross_site.cross_lsm.bspline; }

void PrepareImages(const NavcamModel& navcam, const VehicleOptions& vehicle, bool bspline, int num_threads,
                   SitePairState* s) {
  const int np = static_cast<int>(s->previous.pairs.size()), nc = static_cast<int>(s->current.pairs.size());
  s->previous_left.assign(np, {});
  s->previous_right.assign(np, {});
  s->current_left.assign(nc, {});
  s->current_right.assign(nc, {});
#pragma omp parallel for schedule(dynamic, 1) num_threads(num_threads)
  for (int k = 0; k < np + nc; ++k) {
    if (k < np) s->previous_left[k].vehicle = VehicleMask(navcam, {s->previous.pairs[k].mast_pan, s->previous.pairs[k].mast_tilt}, vehicle);
    else s->current_left[k - np].vehicle = VehicleMask(navcam, {s->current.pairs[k - np].mast_pan, s->current.pairs[k - np].mast_tilt}, vehicle);
  }
#pragma omp parallel for schedule(dynamic, 1) num_threads(num_threads)
  for (int k = 0; k < 2 * (np + nc); ++k) {
    if (k < np) Prepare(s->previous.pairs[k].left, navcam.rig.left, bspline, &s->previous_left[k]);
    else if (k < 2 * np) Prepare(s->previous.pairs[k - np].right, navcam.rig.right, bspline, &s->previous_right[k - np]);
    else if (k < 2 * np + nc) Prepare(s->current.pairs[k - 2 * np].left, navcam.rig.left, bspline, &s->current_left[k - 2 * np]);
    else Prepare(s->current.pairs[k - 2 * np - nc].right, navcam.rig.right, bspline, &s->current_right[k - 2 * np - nc]);
  }
}

}  // namespace vloc::frontend_internal
