// The rover's ground orthophoto: dense stereo per pair, 3-D points in the
// site's level frame, binned into a raster (ground_ortho.h).
#include "vloc/maploc/ground_ortho.h"

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "vloc/common/options.h"
#include "vloc/common/stopwatch.h"

namespace vloc::maploc {

GroundOrthoOptions::GroundOrthoOptions() {
  stereo.min_disparity = 6;    // reduced px: ~27 m at the default Navcam (f B = 160 px m at half size)
  stereo.max_disparity = 120;  // reduced px: ~1.3 m, nearer than the ground under a 25 deg tilt
  stereo.step = 1;
}

void GroundOrthoOptions::Visit(OptionsReader& r) {
  r.Optional("m_per_px", &m_per_px, "m, orthophoto cell size (the localizer uses the map's)", InLeftOpen(0.001, 5));
  r.Optional("max_range_m", &max_range_m, "m, horizontal range kept around the rover", AtMost(100));
  r.Optional("min_range_m", &min_range_m, "m, nearer points are dropped", NonNegative());
  r.Optional("downsample", &downsample, "image reduction before stereo (1 = full size)", InRange(1, 8));
  r.Optional("max_rectification_error", &max_rectification_error, "rig rectification tolerance", Positive());
  r.Child("stereo", [this](OptionsReader& c) { stereo.Visit(c); });
  r.Relation("max_range_m", max_range_m > min_range_m, "must exceed min_range_m");
}

bool GroundOrthoOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

std::string GroundOrthoSummary::BriefReport() const {
  std::ostringstream s;
  s << (usable ? "usable" : "not usable") << " (" << message << "): " << pairs << " pairs, " << stereo_points
    << " stereo points, " << valid_cells << " cells, " << total_seconds << " s (stereo " << stereo_seconds << ")";
  return s.str();
}

namespace {

// Accumulated samples per cell.
struct OrthoBins {
  int side = 0;
  double m_per_px = 0, half_m = 0;
  cv::Mat sum_gray, sum_height, count;  // CV_64F, CV_64F, CV_32S

  explicit OrthoBins(const GroundOrthoOptions& o) : m_per_px(o.m_per_px) {
    side = 2 * static_cast<int>(std::ceil(o.max_range_m / o.m_per_px)) + 1;  // odd: the origin is a cell centre
    half_m = 0.5 * side * m_per_px;
    sum_gray = cv::Mat::zeros(side, side, CV_64F);
    sum_height = cv::Mat::zeros(side, side, CV_64F);
    count = cv::Mat::zeros(side, side, CV_32S);
  }
  void Add(const Eigen::Vector3d& p, double gray) {
    const int c = static_cast<int>(std::floor((p.x() + half_m) / m_per_px));
    const int r = static_cast<int>(std::floor((half_m - p.y()) / m_per_px));
    if (c < 0 || r < 0 || c >= side || r >= side) return;
    sum_gray.at<double>(r, c) += gray;
    sum_height.at<double>(r, c) += p.z();
    ++count.at<int>(r, c);
  }
};

bool RigIsRectified(const StereoRig& rig, double tol, std::string* why) {
  const Eigen::Matrix3d R = rig.left_from_right.linear();
  const Eigen::Vector3d t = rig.left_from_right.translation();
  const PinholeCamera &a = rig.left, &b = rig.right;
  const bool same = std::abs(a.fx - b.fx) < tol && std::abs(a.fy - b.fy) < tol && std::abs(a.cx - b.cx) < tol &&
                    std::abs(a.cy - b.cy) < tol && a.width == b.width && a.height == b.height;
  if ((R - Eigen::Matrix3d::Identity()).norm() > tol || std::abs(t.y()) > tol || std::abs(t.z()) > tol || !(t.x() > 0) ||
      !same)
    return Fail(why, "the Navcam rig is not rectified (rotation, vertical offset or intrinsics differ); rectify first");
  return true;
}

// The camera of an image reduced by `factor` (pixel centres kept).
PinholeCamera Reduced(const PinholeCamera& c, int factor) {
  PinholeCamera r = c;
  r.width = c.width / factor;
  r.height = c.height / factor;
  r.fx = c.fx / factor;
  r.fy = c.fy / factor;
  r.cx = (c.cx + 0.5) / factor - 0.5;
  r.cy = (c.cy + 0.5) / factor - 0.5;
  r.k1 = r.k2 = r.p1 = r.p2 = r.k3 = 0;
  return r;
}

cv::Mat PrepareImage(const cv::Mat& raw, const PinholeCamera& camera, int factor) {
  cv::Mat ideal = raw;
  if (camera.HasDistortion()) cv::undistort(raw, ideal, camera.K(), camera.DistortionCoeffs(), camera.K());
  if (factor == 1) return ideal;
  cv::Mat small;
  cv::resize(ideal, small, cv::Size(raw.cols / factor, raw.rows / factor), 0, 0, cv::INTER_AREA);
  return small;
}

// Every matched grid point of one pair, levelled, into the bins; returns the count in range.
long BinPair(const StereoPair& pair, const NavcamModel& navcam, const Eigen::Matrix3d& level_from_body,
             const GroundOrthoOptions& o, OrthoBins* bins, double* stereo_seconds) {
  const int f = o.downsample;
  const cv::Mat left = PrepareImage(pair.left, navcam.rig.left, f);
  const cv::Mat right = PrepareImage(pair.right, navcam.rig.right, f);
  Stopwatch stereo_time;
  const cv::Mat disparity = DenseStereo(left, right, o.stereo);
  *stereo_seconds += stereo_time.Seconds();
  const PinholeCamera camera = Reduced(navcam.rig.left, f);
  const double focal_baseline = camera.fx * navcam.rig.Baseline();
  const Pose3 body_from_left = navcam.mast.BodyFromLeft(pair.mast_pan, pair.mast_tilt, navcam.rig);
  const Eigen::Matrix3d R = level_from_body * body_from_left.linear();
  const Eigen::Vector3d t = level_from_body * body_from_left.translation();
  long kept = 0;
  for (int i = 0; i < disparity.rows; ++i)
    for (int j = 0; j < disparity.cols; ++j) {
      const float d = disparity.at<float>(i, j);
      if (!(d > 0)) continue;
      const int u = j * o.stereo.step, v = i * o.stereo.step;
      const Eigen::Vector3d p = R * (focal_baseline / d * camera.Ray(Eigen::Vector2d(u, v))) + t;
      const double range = std::hypot(p.x(), p.y());
      if (range < o.min_range_m || range > o.max_range_m) continue;
      bins->Add(p, left.at<uint8_t>(v, u));
      ++kept;
    }
  return kept;
}

MapRaster RasterOfBins(const OrthoBins& bins) {
  MapRaster out;
  out.m_per_px = bins.m_per_px;
  out.x_min = -bins.half_m;
  out.y_max = bins.half_m;
  cv::Mat count;
  bins.count.convertTo(count, CV_64F);
  cv::Mat gray = bins.sum_gray / cv::max(count, 1.0), height = bins.sum_height / cv::max(count, 1.0);
  gray.convertTo(out.gray, CV_32F);
  height.convertTo(out.height, CV_32F);
  out.valid = bins.count > 0;
  return out;
}

}  // namespace

MapRaster BuildGroundOrtho(const std::vector<StereoPair>& pairs, const NavcamModel& navcam, double roll, double pitch,
                           const GroundOrthoOptions& options, GroundOrthoSummary* summary) {
  std::string error;
  if (!options.Check(&error)) throw std::invalid_argument("GroundOrthoOptions: " + error);
  GroundOrthoSummary local;
  GroundOrthoSummary& s = summary ? *summary : local;
  s = GroundOrthoSummary();
  Stopwatch total;
  if (!RigIsRectified(navcam.rig, options.max_rectification_error, &s.message)) return {};
  if (!std::isfinite(roll) || !std::isfinite(pitch)) {
    s.message = "roll or pitch not finite";
    return {};
  }
  const Eigen::Matrix3d level_from_body = RotationFromRollPitchYaw(roll, pitch, 0.0);
  OrthoBins bins(options);
  for (const StereoPair& pair : pairs) {
    const cv::Size size(navcam.rig.left.width, navcam.rig.left.height);
    if (pair.left.type() != CV_8UC1 || pair.right.type() != CV_8UC1 || pair.left.size() != size ||
        pair.right.size() != size)
      continue;  // not this Navcam's images: skipped, counted by `pairs`
    s.stereo_points += BinPair(pair, navcam, level_from_body, options, &bins, &s.stereo_seconds);
    ++s.pairs;
  }
  MapRaster ortho = RasterOfBins(bins);
  s.valid_cells = cv::countNonZero(ortho.valid);
  s.total_seconds = total.Seconds();
  s.usable = s.valid_cells > 0;
  s.message = s.pairs == 0 ? "no stereo pair of the Navcam's size and type"
              : s.usable  ? "ok"
                          : "stereo matched nothing within range (featureless ground?)";
  return ortho;
}

}  // namespace vloc::maploc
