// Absolute fixes of simulated rover sites against a rendered aerial map:
// per site the Navcam panorama (512 x 512 Navcam: the shipped 1024 x 1024 Navcam at
// map_localizer's downsample 2) -> ground orthophoto ->
// registration to a 20 cm/px map under another sun, from a prior perturbed
// by sigma_xy / sigma_heading. Prints each site's error and the summary:
// median horizontal error, heading error, mean NEES (x, y: dimension 2;
// x, y, heading: 3). Used to calibrate RegistrationOptions::covariance_scale.
//   bench_maploc_sites [--sites 12] [--seed 7] [--res 0.2] [--sigma-xy 1.0] [--sigma-heading-deg 2] [--scale K] [--heading-scale K] [--height-weight W] [--max-peak-ratio R] [--max-range M] [--heading-fit N] [--downsample 1] [--sigma-multiple S] [--lsm-lattice K] [--lsm-convergence PX] [--lsm-max-iterations N] [--lsm-max-failed-corners N] [--lsm-drop-failed-cells 0|1] [--dump DIR]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "../../../libs/maploc/src/masked_correlation.h"
#include "vloc/maploc/ground_ortho.h"
#include "vloc/maploc/map_registration.h"
#include "vloc/testing/maploc_scenario.h"

namespace {

double Arg(int argc, char** argv, const char* name, double fallback) {
  for (int i = 1; i + 1 < argc; ++i)
    if (!std::strcmp(argv[i], name)) return std::atof(argv[i + 1]);
  return fallback;
}

const char* StringArg(int argc, char** argv, const char* name) {
  for (int i = 1; i + 1 < argc; ++i)
    if (!std::strcmp(argv[i], name)) return argv[i + 1];
  return nullptr;
}

// A band as 8-bit for a picture: min..max over valid cells -> 0..255, unseen cells black.
cv::Mat Picture(const cv::Mat& band, const cv::Mat& valid, int scale) {
  double lo, hi;
  cv::minMaxLoc(band, &lo, &hi, nullptr, nullptr, valid);
  cv::Mat out;
  band.convertTo(out, CV_8U, 254.0 / std::max(hi - lo, 1e-6), 1 - 254.0 * lo / std::max(hi - lo, 1e-6));
  out.setTo(0, valid == 0);
  cv::resize(out, out, cv::Size(), scale, scale, cv::INTER_NEAREST);
  return out;
}

// Side by side, north up, same extent: the rover's orthophoto grey and height turned by the fix's
// heading, the map's grey and height around the fix. Written to <dir>/maploc_site<N>.png.
void DumpPicture(const char* dir, int site, const vloc::maploc::MapRaster& ortho, const vloc::maploc::MapRaster& map,
                 const vloc::maploc::MapFix& fix) {
  using namespace vloc::maploc;
  const MapRaster rover = ResampleRaster(ortho, map.m_per_px);
  const Eigen::Vector2d o = rover.PixelOfWorld(Eigen::Vector2d::Zero());
  const cv::Point2d centre(o.x(), o.y());
  cv::Mat valid;
  rover.valid.convertTo(valid, CV_32F);
  valid = internal::RotateAbout(valid, fix.xyh.z(), centre, cv::INTER_NEAREST) > 0;
  const MapRaster crop = CropRaster(map, fix.xyh.head<2>(), (rover.gray.cols / 2 - 0.5) * map.m_per_px);
  cv::Mat crop_valid = crop.valid(cv::Rect(0, 0, valid.cols, valid.rows)).clone();
  std::vector<cv::Mat> tiles = {
      Picture(internal::RotateAbout(rover.gray, fix.xyh.z(), centre, cv::INTER_LINEAR), valid, 3),
      Picture(crop.gray(cv::Rect(0, 0, valid.cols, valid.rows)), crop_valid, 3),
      Picture(internal::RotateAbout(rover.height, fix.xyh.z(), centre, cv::INTER_LINEAR), valid, 3),
      Picture(crop.height(cv::Rect(0, 0, valid.cols, valid.rows)), crop_valid, 3)};
  cv::Mat row;
  cv::hconcat(tiles, row);
  const std::string path = std::string(dir) + "/maploc_site" + std::to_string(site) + ".png";
  cv::imwrite(path, row);
  std::printf("         wrote %s (rover grey | map grey | rover height | map height, north up, %.0f m wide)\n",
              path.c_str(), valid.cols * map.m_per_px);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace vloc;
  testing::MaplocScenarioOptions s;
  s.num_sites = static_cast<int>(Arg(argc, argv, "--sites", 12));
  s.seed = static_cast<uint64_t>(Arg(argc, argv, "--seed", 7));
  s.map_m_per_px = Arg(argc, argv, "--res", 0.2);
  s.terrain_size_m = 120;
  s.terrain_origin_x_m = -60;
  s.terrain_origin_y_m = -60;
  const double sigma_xy = Arg(argc, argv, "--sigma-xy", 1.0);
  const double sigma_h = Arg(argc, argv, "--sigma-heading-deg", 2.0) * M_PI / 180;
  maploc::RegistrationOptions reg;
  reg.covariance_scale = Arg(argc, argv, "--scale", reg.covariance_scale);
  reg.heading_covariance_scale = Arg(argc, argv, "--heading-scale", reg.heading_covariance_scale);
  reg.height_weight = Arg(argc, argv, "--height-weight", reg.height_weight);
  reg.heading_fit_half_width = static_cast<int>(Arg(argc, argv, "--heading-fit", reg.heading_fit_half_width));
  reg.sigma_multiple = Arg(argc, argv, "--sigma-multiple", reg.sigma_multiple);
  reg.max_peak_ratio = Arg(argc, argv, "--max-peak-ratio", reg.max_peak_ratio);
  const double max_range = Arg(argc, argv, "--max-range", 12.0);
  const sim::RoverWorld world(testing::MaplocWorldOptions(s));
  const maploc::MapRaster map = testing::RenderMapOf(world.options().terrain, s);
  maploc::GroundOrthoOptions ortho_options;
  ortho_options.m_per_px = s.map_m_per_px;
  ortho_options.max_range_m = max_range;
  ortho_options.downsample = static_cast<int>(Arg(argc, argv, "--downsample", 1));  // 512 px rendered = the real 1024 px / 2
  // The dense stereo's LSM lattice and stopping rule (config/procs/map_localizer.yaml sets 2, 0.004 px, 8,
  // max_failed_corners 1, drop_failed_cells true; without the flags the options' defaults: every point).
  DenseStereoOptions& st = ortho_options.stereo;
  st.lsm_lattice = static_cast<int>(Arg(argc, argv, "--lsm-lattice", st.lsm_lattice));
  st.lsm_convergence_px = Arg(argc, argv, "--lsm-convergence", st.lsm_convergence_px);
  st.lsm_max_iterations = static_cast<int>(Arg(argc, argv, "--lsm-max-iterations", st.lsm_max_iterations));
  st.lsm_lattice_max_failed_corners =
      static_cast<int>(Arg(argc, argv, "--lsm-max-failed-corners", st.lsm_lattice_max_failed_corners));
  st.lsm_lattice_drop_failed_cells = Arg(argc, argv, "--lsm-drop-failed-cells", st.lsm_lattice_drop_failed_cells) != 0;
  std::mt19937 rng(s.seed);
  std::vector<double> errors, heading_errors, nees2, nees3, z_errors, z_nees;
  int fixes = 0;
  for (const auto& site : world.traverse().sites) {
    const Pose3& truth = site.world_from_body;
    const PoseWithCovariance prior = testing::NoisyPrior(truth, sigma_xy, sigma_h, &rng);
    const Eigen::Vector3d rpy = RollPitchYawFromRotation(truth.linear());
    maploc::GroundOrthoSummary os;
    const maploc::MapRaster ortho =
        maploc::BuildGroundOrtho(world.RenderSite(site.site_id), world.options().navcam, rpy.x(), rpy.y(), ortho_options, &os);
    const maploc::MapFix fix = maploc::RegisterToMap(ortho, map, maploc::SitePriorFromPose(prior), reg);
    std::printf("site %2d: ortho %s\n         %s\n", site.site_id, os.BriefReport().c_str(), fix.BriefReport().c_str());
    if (fix.usable && StringArg(argc, argv, "--dump")) DumpPicture(StringArg(argc, argv, "--dump"), site.site_id, ortho, map, fix);
    if (!fix.usable) {
      std::printf("         prior off by %.2f m, %.2f deg; truth at %.1f, %.1f\n",
                  (prior.pose.translation() - truth.translation()).head<2>().norm(),
                  WrapAngle(Heading(prior.pose) - Heading(truth)) * 180 / M_PI, truth.translation().x(),
                  truth.translation().y());
      continue;
    }
    ++fixes;
    Eigen::Vector3d e(fix.xyh.x() - truth.translation().x(), fix.xyh.y() - truth.translation().y(),
                      WrapAngle(fix.xyh.z() - Heading(truth)));
    errors.push_back(e.head<2>().norm());
    heading_errors.push_back(std::abs(e.z()) * 180 / M_PI);
    nees2.push_back(e.head<2>().dot(fix.covariance.topLeftCorner<2, 2>().inverse() * e.head<2>()));
    nees3.push_back(e.dot(fix.covariance.inverse() * e));
    const double ez = fix.has_z ? fix.z - truth.translation().z() : std::nan("");
    if (fix.has_z) z_nees.push_back(ez * ez / (fix.z_sigma * fix.z_sigma));
    if (fix.has_z) z_errors.push_back(std::abs(ez));
    std::printf("         error %.3f m, heading %.3f deg, z %.3f m, NEES xy %.2f xyh %.2f\n", errors.back(),
                heading_errors.back(), ez, nees2.back(), nees3.back());
  }
  auto median = [](std::vector<double> v) {
    if (v.empty()) return std::nan("");
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  auto mean = [](const std::vector<double>& v) {
    double m = 0;
    for (double x : v) m += x;
    return v.empty() ? std::nan("") : m / v.size();
  };
  std::printf("summary: %d/%zu fixes, median error %.3f m (max %.3f), median heading error %.3f deg (max %.3f), "
              "mean NEES xy %.2f (dim 2), xyh %.2f (dim 3)\n",
              fixes, world.traverse().sites.size(), median(errors),
              errors.empty() ? NAN : *std::max_element(errors.begin(), errors.end()), median(heading_errors),
              heading_errors.empty() ? NAN : *std::max_element(heading_errors.begin(), heading_errors.end()),
              mean(nees2), mean(nees3));
  std::printf("height from the map: median |z error| %.3f m, mean z NEES %.2f (dim 1), %zu fixes with z\n", median(z_errors),
              mean(z_nees), z_errors.size());
  return 0;
}
