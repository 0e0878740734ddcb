#pragma once
// A simulated site pair for the front end: terrain, two sites `distance` m
// apart along x, 7 + 7 Navcam stereo pairs each (vloc::sim panorama
// pointing), true poses, a dead-reckoning pose of the current site with a
// known error, and the rendered left depth maps for checking against truth.
// Shared by the slow whole-pipeline test and the front end benchmark.

#include <cstdio>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <optional>
#include <opencv2/imgcodecs.hpp>
#include <filesystem>
#include <sstream>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/options.h"
#include "vloc/common/stats.h"
#include "vloc/crosssite/frontend.h"
#include "vloc/sim/navcam_renderer.h"
#include "vloc/sim/rover_world.h"
#include "vloc/sim/rover_traverse.h"
#include "vloc/sim/terrain.h"

namespace vloc::testing {

struct SimSitePair {
  NavcamModel navcam;
  SiteImages previous, current;           // what the front end gets (DR poses)
  Pose3 previous_true, current_true;      // world_from_body
  std::vector<cv::Mat> previous_depth;    // left camera z (m) per pair
  std::vector<cv::Mat> current_depth;
};

struct SimSitePairOptions {
  double distance = 10.0;              // m between the sites
  double heading_change_deg = 8.0;     // deg, yaw of the current site
  Eigen::Vector3d dr_position_error = Eigen::Vector3d(0.9, -1.1, 0.05);  // m, DR minus truth (14 % of 10 m)
  double dr_yaw_error_deg = 2.0;       // deg, DR minus truth
  double dr_error_rotation_deg = 0.0;  // deg, turns the horizontal DR position error about the vertical
  double dr_sigma_fraction = 0.15;     // stated DR position sigma, fraction of the distance
  double dr_yaw_sigma_deg = 3.0;       // stated DR yaw sigma
  uint64_t terrain_seed = 3;
  bool textureless = false;            // albedo contrast and relief off: a featureless plain
  bool no_relief = false;              // relief, craters and rocks off, texture on: a textured plane
  std::string profile;                 // a sim_rover config (e.g. config/procs/sim_rover_hard.yaml): its sun, lighting
                                       // steps (site 1 = one step), render options and JPEG encoding; "" = defaults
};

// Rendered images and depths can be cached in a folder (env
// VLOC_SIM_CACHE) to iterate quickly; the cache key is the options.
inline bool LoadCachedSite(const std::string& dir, const std::string& tag, size_t n, SiteImages* site,
                           std::vector<cv::Mat>* depth) {
  for (size_t k = 0; k < n; ++k) {
    const std::string base = dir + "/" + tag + "_" + std::to_string(k);
    if (!std::filesystem::exists(base + "_d.yml.gz")) return false;  // not cached yet (OpenCV would log an error)
    cv::Mat l = cv::imread(base + "_l.png", cv::IMREAD_GRAYSCALE), r = cv::imread(base + "_r.png", cv::IMREAD_GRAYSCALE);
    cv::FileStorage fs(base + "_d.yml.gz", cv::FileStorage::READ);
    if (l.empty() || r.empty() || !fs.isOpened()) return false;
    cv::Mat d;
    fs["depth"] >> d;
    site->pairs[k].left = l;
    site->pairs[k].right = r;
    depth->push_back(d);
  }
  return true;
}

inline void SaveCachedSite(const std::string& dir, const std::string& tag, const SiteImages& site,
                           const std::vector<cv::Mat>& depth) {
  for (size_t k = 0; k < site.pairs.size(); ++k) {
    const std::string base = dir + "/" + tag + "_" + std::to_string(k);
    cv::imwrite(base + "_l.png", site.pairs[k].left);
    cv::imwrite(base + "_r.png", site.pairs[k].right);
    cv::FileStorage fs(base + "_d.yml.gz", cv::FileStorage::WRITE);
    fs << "depth" << depth[k];
  }
}

inline SimSitePair MakeSimSitePair(const SimSitePairOptions& so = SimSitePairOptions()) {
  SimSitePair out;
  out.navcam = LoadOptionsFile<NavcamModel>("config/navcam.yaml");
  const char* cache_env = std::getenv("VLOC_SIM_CACHE");
  const std::string cache = cache_env ? cache_env : "";
  std::error_code made;
  if (!cache.empty()) std::filesystem::create_directories(cache, made);  // a new folder fills on the first run
  std::ostringstream key;
  key << "t" << so.terrain_seed << "_d" << so.distance << "_h" << so.heading_change_deg << (so.textureless ? "_flat" : "") << (so.no_relief ? "_plane" : "");
  sim::NavcamRenderOptions render_options;
  sim::LightingOptions lighting;
  sim::TerrainOptions profile_terrain;
  int jpeg_quality = 0;  // 0 = PNG (lossless)
  if (!so.profile.empty()) {
    const YAML::Node root = LoadYamlFile(so.profile);
    if (root["render"]) render_options = LoadOptionsFile<sim::NavcamRenderOptions>(so.profile, "render");
    if (root["lighting"]) lighting = LoadOptionsFile<sim::LightingOptions>(so.profile, "lighting");
    if (root["terrain"]) profile_terrain = LoadOptionsFile<sim::TerrainOptions>(so.profile, "terrain");
    if (root["image_encoding"] && root["image_encoding"].as<std::string>() == "jpeg")
      jpeg_quality = root["jpeg_quality"] ? root["jpeg_quality"].as<int>() : 95;
    key << "_" << std::filesystem::path(so.profile).stem().string();
  }
  sim::TerrainOptions to;
  to.sun_azimuth_deg = profile_terrain.sun_azimuth_deg;
  to.sun_elevation_deg = profile_terrain.sun_elevation_deg;
  to.seed = so.terrain_seed;
  to.size_m = 72;
  to.origin_x_m = -24;
  to.origin_y_m = -36;
  if (so.textureless || so.no_relief) {
    if (so.textureless) to.albedo_contrast = 0.0, to.micro_slope = 0.0;
    to.relief_amplitude_m = 0.0;
    to.crater_density = 0.0;
    to.rock_density = 0.0;
  }
  std::unique_ptr<sim::Terrain> terrain_ptr;
  std::unique_ptr<sim::NavcamRenderer> renderer_ptr;
  auto renderer = [&]() -> const sim::NavcamRenderer& {
    if (!renderer_ptr) {
      terrain_ptr = std::make_unique<sim::Terrain>(to);
      renderer_ptr = std::make_unique<sim::NavcamRenderer>(*terrain_ptr, out.navcam, render_options);
    }
    return *renderer_ptr;
  };
  auto height = [&](double x, double y) {
    renderer();
    return terrain_ptr->Height(x, y);
  };
  const std::vector<MastPointing> pointing = sim::PanoramaOptions().Pointings();
  const double yaw1 = so.heading_change_deg * M_PI / 180;
  const Eigen::Vector2d c1(so.distance * std::cos(0.5 * yaw1), so.distance * std::sin(0.5 * yaw1));
  // Terrain heights at the two sites, cached with the images.
  double z0 = 0, z1 = 0;
  bool cached = false;
  if (!cache.empty() && std::filesystem::exists(cache + "/" + key.str() + "_heights.yml")) {
    cv::FileStorage fs(cache + "/" + key.str() + "_heights.yml", cv::FileStorage::READ);
    if (fs.isOpened()) {
      fs["z0"] >> z0;
      fs["z1"] >> z1;
      cached = true;
    }
  }
  if (!cached) {
    z0 = height(0, 0);
    z1 = height(c1.x(), c1.y());
  }
  out.previous_true = MakePose(0, 0, z0, 0, 0, 0);
  out.current_true = MakePose(c1.x(), c1.y(), z1, 0, 0, yaw1);
  auto render_site = [&](int site_id, const Pose3& pose, uint64_t seed, SiteImages* site, std::vector<cv::Mat>* depth) {
    site->site_id = site_id;
    for (size_t k = 0; k < pointing.size(); ++k) {
      StereoPair sp;
      sp.utime = 1000000 * (site_id * 100 + static_cast<int64_t>(k));
      sp.site_id = site_id;
      sp.pair_index = static_cast<int>(k);
      sp.num_pairs = static_cast<int>(pointing.size());
      sp.mast_pan = pointing[k].pan;
      sp.mast_tilt = pointing[k].tilt;
      site->pairs.push_back(sp);
    }
    const std::string tag = key.str() + "_s" + std::to_string(site_id);
    if (cached && LoadCachedSite(cache, tag, pointing.size(), site, depth)) return;
    depth->clear();
    renderer();
    // Site 1 sees the sun one lighting step on, with its own exposure gain.
    terrain_ptr->SetSun(to.sun_azimuth_deg + site_id * lighting.azimuth_step_deg,
                        std::clamp(to.sun_elevation_deg + site_id * lighting.elevation_step_deg, lighting.min_elevation_deg, 89.0));
    const double gain = 1.0 + site_id * lighting.exposure_jitter;
    auto encode = [&](const cv::Mat& image) {
      if (jpeg_quality <= 0) return image;
      std::vector<uchar> bytes;
      cv::imencode(".jpg", image, bytes, {cv::IMWRITE_JPEG_QUALITY, jpeg_quality});
      return cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
    };
    for (size_t k = 0; k < pointing.size(); ++k) {
      const sim::RenderedPair rp = renderer().RenderPair(pose, pointing[k].pan, pointing[k].tilt, seed + k, true, gain);
      site->pairs[k].left = encode(rp.left.image);
      site->pairs[k].right = encode(rp.right.image);
      depth->push_back(rp.left.depth);
    }
    if (!cache.empty()) SaveCachedSite(cache, tag, *site, *depth);
  };
  render_site(0, out.previous_true, 100, &out.previous, &out.previous_depth);
  render_site(1, out.current_true, 200, &out.current, &out.current_depth);
  if (!cache.empty() && !cached) {
    cv::FileStorage fs(cache + "/" + key.str() + "_heights.yml", cv::FileStorage::WRITE);
    fs << "z0" << z0 << "z1" << z1;
  }
  out.previous.world_from_body.pose = out.previous_true;
  Pose3 dr = out.current_true;
  dr.translation() += Eigen::AngleAxisd(so.dr_error_rotation_deg * M_PI / 180, Eigen::Vector3d::UnitZ()) * so.dr_position_error;
  dr.linear() = ExpSO3(Eigen::Vector3d(0, 0, so.dr_yaw_error_deg * M_PI / 180)) * dr.linear();
  out.current.world_from_body.pose = dr;
  // DR covariance: 15 % of the distance in position, 3 deg yaw, 1 deg tilt.
  Vector6d sigma;
  const double sp = so.dr_sigma_fraction * so.distance, st = M_PI / 180, sy = so.dr_yaw_sigma_deg * M_PI / 180;
  sigma << sp, sp, 0.5 * sp, st, st, sy;
  out.current.world_from_body.covariance = sigma.cwiseAbs2().asDiagonal();
  return out;
}

// Checks of tie points against the rendered truth.
struct TruthCheck {
  int num_points = 0;
  int num_wrong = 0;                   // previous-left observation > wrong_px from the truth
  int num_unchecked = 0;               // on a depth edge: no reliable truth
  std::vector<double> stereo_error_px; // |right obs - true right|, both sites
  std::vector<double> cross_error_px;  // |previous-left obs - true previous-left| of the right ones
  std::vector<double> all_cross_error_px;
  std::vector<Eigen::Vector2d> cross_error_vec;  // per tie point: true minus observed previous-left position, px (NaN: unchecked)
  // The same split (along, across) the cross-site epipolar line through the truth, px (NaN: unchecked): along
  // the image of the current camera's ray, towards its centre (a match slid along it is a depth error, which the
  // sites' stereo at 15-30 m cannot tell from the truth), and across it (what no depth explains: a wrong match
  // shows here).
  std::vector<Eigen::Vector2d> epipolar_error_vec;
};

// The largest |component| (0: along, 1: across) of the checked points' epipolar_error_vec; none when no point
// was checked.
inline std::optional<double> LargestEpipolarError(const TruthCheck& t, int component) {
  std::optional<double> out;
  for (const Eigen::Vector2d& e : t.epipolar_error_vec)
    if (std::isfinite(e(component))) out = std::max(out.value_or(0.0), std::abs(e(component)));
  return out;
}

// Bilinear depth at a sub-pixel position; 0 when a neighbour has no hit or
// the four disagree by more than 2 % (an occluding edge).
inline double DepthAt(const cv::Mat& depth, const Eigen::Vector2d& uv) {
  const int x0 = static_cast<int>(std::floor(uv.x())), y0 = static_cast<int>(std::floor(uv.y()));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= depth.cols || y0 + 1 >= depth.rows) return 0;
  const double fx = uv.x() - x0, fy = uv.y() - y0;
  const float a = depth.at<float>(y0, x0), b = depth.at<float>(y0, x0 + 1), c = depth.at<float>(y0 + 1, x0),
              d = depth.at<float>(y0 + 1, x0 + 1);
  const float lo = std::min({a, b, c, d}), hi = std::max({a, b, c, d});
  if (!(lo > 0) || hi > 1.02f * lo) return 0;
  return (1 - fy) * ((1 - fx) * a + fx * b) + fy * ((1 - fx) * c + fx * d);
}

using vloc::Median;
inline double Rms(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return v.empty() ? NAN : std::sqrt(s / v.size());
}

// Depth-based truth: the current-left observation's pixel and the rendered
// depth give the true 3D point, projected with the true poses into the
// other images.
inline TruthCheck CheckAgainstTruth(const SimSitePair& s, const TiePointSet& tps, double wrong_px = 2.0) {
  TruthCheck out;
  const auto& cam = s.navcam.rig.left;
  for (const auto& tp : tps.points) {
    const TieObservation *pl = nullptr, *pr = nullptr, *cl = nullptr, *cr = nullptr;
    for (const auto& o : tp.observations) {
      const bool prev = o.site == SiteRole::kPrevious, left = o.camera == CameraSide::kLeft;
      (prev ? (left ? pl : pr) : (left ? cl : cr)) = &o;
    }
    if (!pl || !cl) {
      out.cross_error_vec.push_back(Eigen::Vector2d::Constant(NAN));
      out.epipolar_error_vec.push_back(Eigen::Vector2d::Constant(NAN));
      continue;
    }
    ++out.num_points;
    const double z = DepthAt(s.current_depth[cl->pair_index], cl->uv);
    if (!(z > 0)) {
      ++out.num_unchecked;
      out.cross_error_vec.push_back(Eigen::Vector2d::Constant(NAN));
      out.epipolar_error_vec.push_back(Eigen::Vector2d::Constant(NAN));
      continue;
    }
    const Eigen::Vector3d p_cam = cam.Ray(cl->uv) * z;
    const MastPointing& mc = tps.current_pointing[cl->pair_index];
    const Pose3 body_from_cl = s.navcam.mast.BodyFromLeft(mc.pan, mc.tilt, s.navcam.rig);
    const Eigen::Vector3d p_world = s.current_true * (body_from_cl * p_cam);
    if (cr) {
      const auto q = s.navcam.rig.right.ProjectIdeal((body_from_cl * s.navcam.rig.left_from_right).inverse() *
                                                     (body_from_cl * p_cam));
      if (q) out.stereo_error_px.push_back((*q - cr->uv).norm());
    }
    const MastPointing& mp = tps.previous_pointing[pl->pair_index];
    const Pose3 body_from_pl = s.navcam.mast.BodyFromLeft(mp.pan, mp.tilt, s.navcam.rig);
    const Pose3 pl_from_world = (s.previous_true * body_from_pl).inverse();
    const auto q = cam.ProjectIdeal(pl_from_world * p_world);
    const double err = q ? (*q - pl->uv).norm() : 1e9;
    out.all_cross_error_px.push_back(err);
    out.cross_error_vec.push_back(q ? Eigen::Vector2d(*q - pl->uv) : Eigen::Vector2d::Constant(NAN));
    const Eigen::Vector3d current_centre = (s.current_true * body_from_cl).translation();
    const auto q_nearer = cam.ProjectIdeal(pl_from_world * (p_world + 0.01 * (current_centre - p_world)));
    Eigen::Vector2d split = Eigen::Vector2d::Constant(NAN);
    if (q && q_nearer && (*q_nearer - *q).norm() > 1e-9) {
      const Eigen::Vector2d along = (*q_nearer - *q).normalized(), e = *q - pl->uv;
      split = Eigen::Vector2d(e.dot(along), e.x() * along.y() - e.y() * along.x());
    }
    out.epipolar_error_vec.push_back(split);
    if (err > wrong_px) {
      ++out.num_wrong;
      std::printf("wrong tie point: previous pair %d at (%.1f, %.1f), current pair %d at (%.1f, %.1f), depth %.2f m, "
                  "%.1f px from the truth\n", pl->pair_index, pl->uv.x(), pl->uv.y(), cl->pair_index, cl->uv.x(),
                  cl->uv.y(), z, err);
    }
    else out.cross_error_px.push_back(err);
    if (pr) {
      // Previous right: true point seen from the previous right camera, via
      // the previous-left depth.
      const double zp = DepthAt(s.previous_depth[pl->pair_index], pl->uv);
      if (zp > 0) {
        const Eigen::Vector3d pc = cam.Ray(pl->uv) * zp;
        const auto qr = s.navcam.rig.right.ProjectIdeal(s.navcam.rig.left_from_right.inverse() * pc);
        if (qr) out.stereo_error_px.push_back((*qr - pr->uv).norm());
      }
    }
  }
  return out;
}

}  // namespace vloc::testing
