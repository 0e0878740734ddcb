// The rover's own body in the images (vehicle_boxes_m): pixels whose ray
// meets one of the body's boxes before anything else are masked, and no
// feature or tie point may lie on them. The deck and the wheels are at the
// same pixels at every site; matched, they say the rover did not move.
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "vloc/common/homography.h"
#include "vloc/crosssite/internal/frontend_steps.h"

namespace vloc::frontend_internal {

namespace {

constexpr int kMaskStep = 4;  // px: rays are cast on this grid, then the mask is scaled up and dilated

// Slab test: does the ray origin + t dir, t > 0, meet the axis-aligned box [lo, hi]?
bool RayMeetsBox(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, const Eigen::Vector3d& lo,
                 const Eigen::Vector3d& hi) {
  double t0 = 0, t1 = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    if (std::abs(dir[i]) < 1e-12) {
      if (origin[i] < lo[i] || origin[i] > hi[i]) return false;
      continue;
    }
    double a = (lo[i] - origin[i]) / dir[i], b = (hi[i] - origin[i]) / dir[i];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    if (t0 > t1) return false;
  }
  return true;
}

}  // namespace

cv::Mat VehicleMask(const NavcamModel& navcam, const MastPointing& pointing, const VehicleOptions& o) {
  if (o.vehicle_boxes_m.empty()) return cv::Mat();
  const PinholeCamera& cam = navcam.rig.left;
  const Pose3 body_from_left = navcam.mast.BodyFromLeft(pointing.pan, pointing.tilt, navcam.rig);
  const Eigen::Vector3d origin = body_from_left.translation();
  const int w = (cam.width + kMaskStep - 1) / kMaskStep, h = (cam.height + kMaskStep - 1) / kMaskStep;
  cv::Mat coarse = cv::Mat::zeros(h, w, CV_8UC1);
  bool any = false;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double u = x * kMaskStep + 0.5 * (kMaskStep - 1), v = y * kMaskStep + 0.5 * (kMaskStep - 1);
      const Eigen::Vector3d dir = body_from_left.linear() * cam.Ray(Eigen::Vector2d(u, v));
      for (size_t b = 0; b + 6 <= o.vehicle_boxes_m.size(); b += 6) {
        const double* q = &o.vehicle_boxes_m[b];
        if (RayMeetsBox(origin, dir, {q[0], q[2], q[4]}, {q[1], q[3], q[5]})) {
          coarse.at<uchar>(y, x) = 255;
          any = true;
          break;
        }
      }
    }
  }
  if (!any) return cv::Mat();
  cv::Mat mask;
  cv::resize(coarse, mask, cv::Size(cam.width, cam.height), 0, 0, cv::INTER_NEAREST);
  const int r = static_cast<int>(std::ceil(o.vehicle_margin_px)) + kMaskStep / 2;
  cv::dilate(mask, mask, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1)));
  return mask;
}

bool OnVehicle(const cv::Mat& mask, const Eigen::Vector2d& px) {
  if (mask.empty()) return false;
  const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
  if (x < 0 || y < 0 || x >= mask.cols || y >= mask.rows) return false;
  return mask.at<uchar>(y, x) != 0;
}

void DropVehicleFeatures(const cv::Mat& mask, const cv::Matx33d& image_from_feature, FeatureSet* f) {
  if (mask.empty() || f->size() == 0) return;
  FeatureSet kept;
  kept.views = f->views;
  std::vector<int> rows;
  for (size_t q = 0; q < f->size(); ++q) {
    if (OnVehicle(mask, ApplyHomography(image_from_feature, f->points[q]))) continue;
    kept.keypoints.push_back(f->keypoints[q]);
    kept.points.push_back(f->points[q]);
    if (q < f->view.size()) kept.view.push_back(f->view[q]);
    rows.push_back(static_cast<int>(q));
  }
  if (!f->descriptors.empty()) {
    kept.descriptors = cv::Mat(static_cast<int>(rows.size()), f->descriptors.cols, f->descriptors.type());
    for (size_t k = 0; k < rows.size(); ++k) f->descriptors.row(rows[k]).copyTo(kept.descriptors.row(static_cast<int>(k)));
  }
  *f = std::move(kept);
}

int DropVehicleCandidates(SitePairState* s) {
  std::vector<Candidate>& c = s->candidates;
  const size_t before = c.size();
  c.erase(std::remove_if(c.begin(), c.end(),
                         [&](const Candidate& k) {
                           return OnVehicle(s->previous_left[k.prev_pair].vehicle, k.prev_left) ||
                                  OnVehicle(s->current_left[k.cur_pair].vehicle, k.cur_left);
                         }),
          c.end());
  return static_cast<int>(before - c.size());
}

}  // namespace vloc::frontend_internal
