// uav_mosaic_files: registers and mosaics a sequence of nadir images (e.g.
// OpenCV's aero1.jpg, aero3.jpg) with the UAV mosaicker.
//   uav_mosaic_files [--config config/procs/uav_mosaicker.yaml] [--height H] [--focal F]
//                    --out out/mosaic.png IMAGE...
// The camera is taken as undistorted with the principal point at the image
// centre and focal F px (default: the image width); H (m, default 100) only
// scales the reported heights.
//   uav_mosaic_files --split [--angle DEG] [--zoom Z] --out out/x.png IMAGE
// instead cuts one real image into two overlapping views related by a known
// similarity (rotation DEG, default 12; view 2 seen from Z times higher,
// default 1.18) and checks the registration against that truth.
// When the nadir mosaicker loses a frame (views too different: oblique
// photos from other directions, like aero1/aero3), the sequence is
// registered pairwise with the affine-invariant RegisterOblique (image i ->
// image i-1, homographies chained to image 1) and mosaicked in image 1's
// frame instead (--no-oblique turns this off).
#include <glog/logging.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>

#include <iostream>

#include "vloc/common/command_line.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/mosaic/oblique_registration.h"
#include "vloc/mosaic/uav_mosaicker.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv, {"config", "height", "focal", "out", "help", "split", "angle", "zoom", "preview", "preview-side", "no-oblique"}, &error) || args.Has("help") ||
      args.positional().size() < (args.Has("split") ? 1u : 2u) || !args.Has("out")) {
    std::cerr << (error.empty() ? "" : "uav_mosaic_files: " + error + "\n")
              << "usage: uav_mosaic_files [--config config/procs/uav_mosaicker.yaml] [--height H] [--focal F] [--preview P.png --preview-side N] [--no-oblique] --out "
                 "OUT.png IMAGE IMAGE...\n       uav_mosaic_files --split [--angle DEG] [--zoom Z] --out OUT.png IMAGE\n";
    return 1;
  }
  std::vector<cv::Mat> images;
  for (const auto& path : args.positional()) {
    images.push_back(cv::imread(path, cv::IMREAD_COLOR));
    if (images.back().empty()) {
      std::cerr << "uav_mosaic_files: cannot read image " << path << " (missing or not an image)\n";
      return 1;
    }
  }
  // --split: two views of one image with a known similarity between them.
  double true_scale = 0;
  std::vector<std::string> names = args.positional();
  if (args.Has("split")) {
    const cv::Mat src = images[0];
    const cv::Size view(static_cast<int>(src.cols * 0.62), static_cast<int>(src.rows * 0.62));
    const double angle = args.GetDouble("angle", 12.0) * M_PI / 180.0, zoom = args.GetDouble("zoom", 1.18);
    // src px = A(v) for view 1 (a plain crop) and B(v) for view 2 (rotated, zoomed out, shifted right).
    const cv::Matx23d A(1, 0, src.cols * 0.05, 0, 1, src.rows * 0.19);
    const double c = zoom * std::cos(angle), s = zoom * std::sin(angle);
    const cv::Point2d centre(src.cols * 0.62, src.rows * 0.5);
    const cv::Point2d vc((view.width - 1) / 2.0, (view.height - 1) / 2.0);
    const cv::Matx23d B(c, -s, centre.x - (c * vc.x - s * vc.y), s, c, centre.y - (s * vc.x + c * vc.y));
    cv::Mat v1, v2;
    cv::warpAffine(src, v1, A, view, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP);
    cv::warpAffine(src, v2, B, view, cv::INTER_AREA | cv::WARP_INVERSE_MAP);
    images = {v1, v2};
    names = {args.positional()[0] + " (view 1)", args.positional()[0] + " (view 2)"};
    // View 1 px -> view 2 px is B^-1 A: scale 1/zoom (zoom out, lambda < 1), angle -angle.
    true_scale = 1.0 / zoom;
  }
  vloc::mosaic::MosaickerOptions options;
  try {
    if (args.Has("config")) options = vloc::LoadOptionsFile<vloc::mosaic::MosaickerOptions>(args.Get("config"), "mosaicker");
  } catch (const vloc::ConfigError& e) {
    std::cerr << "uav_mosaic_files: " << e.what() << "\n";
    return 1;
  }
  const cv::Size size = images[0].size();
  options.camera = vloc::PinholeCamera();
  options.camera.width = size.width;
  options.camera.height = size.height;
  options.camera.fx = options.camera.fy = args.GetDouble("focal", size.width);
  options.camera.cx = (size.width - 1) / 2.0;
  options.camera.cy = (size.height - 1) / 2.0;
  options.calibration.source = "config";
  options.calibration.height = args.GetDouble("height", 100.0);
  options.canvas.metres_per_pixel = 0;
  options.canvas.resolution_factor = 1.0;
  options.mosaic_every_n_frames = 1;
  options.matcher.downscale = size.width > 1000 ? 0.5 : 1.0;
  if (!options.Check(&error)) {
    std::cerr << "uav_mosaic_files: " << error << "\n";
    return 1;
  }
  vloc::mosaic::UavMosaicker mosaicker(options);
  int failures = 0;
  for (size_t i = 0; i < images.size(); ++i) {
    const auto s = mosaicker.ProcessFrame(images[i], static_cast<int64_t>(i) * 1000000);
    std::cout << names[i] << ": " << vloc::mosaic::ToString(s.status) << ", scale change " << s.scale
              << ", matches " << s.num_matches << ", inliers " << s.num_inliers << ", foreground " << s.num_foreground
              << ", centre at mosaic px (" << s.route_px.x << ", " << s.route_px.y << "), height "
              << s.height << " m" << (s.message.empty() ? "" : " (" + s.message + ")") << "\n";
    if (s.status == vloc::mosaic::TrackStatus::kLost) ++failures;
    if (i == 1 && true_scale > 0) {
      const double h = options.calibration.height;
      std::cout << "truth: scale change " << true_scale << " (height " << h / true_scale << " m); measured "
                << s.scale << " (height " << s.height_raw << " m), error " << 100 * (s.scale - true_scale) / true_scale
                << " %\n";
    }
  }
  const bool use_oblique = failures > 0 && !args.Has("split") && !args.Has("no-oblique");
  if (use_oblique) {
    // Fallback: pairwise affine-invariant registration, mosaic in image 1's frame.
    vloc::mosaic::ObliqueOptions oblique;
    oblique.num_threads = options.num_threads;
    std::vector<cv::Matx33d> ref_from_image{cv::Matx33d::eye()};
    failures = 0;
    for (size_t i = 1; i < images.size(); ++i) {
      const auto r = vloc::mosaic::RegisterOblique(images[i], images[i - 1], oblique);
      std::cout << names[i] << " -> " << names[i - 1] << " (affine-invariant fallback): " << r.BriefReport() << "\n";
      if (!r.ok) {
        ++failures;
        break;
      }
      ref_from_image.push_back(ref_from_image.back() * r.to_from_from);
      std::cout << "homography " << names[i] << " -> " << names[0] << ": " << cv::Mat(ref_from_image.back()).reshape(1, 1) << "\n";
    }
    std::vector<cv::Mat> placed(images.begin(), images.begin() + static_cast<long>(ref_from_image.size()));
    const cv::Mat mosaic = vloc::mosaic::MosaicByHomographies(placed, ref_from_image, images[0].size());
    if (mosaic.empty() || !cv::imwrite(args.Get("out"), mosaic)) {
      std::cerr << "uav_mosaic_files: cannot write mosaic " << args.Get("out") << "\n";
      return 1;
    }
    std::cout << "mosaic of " << placed.size() << " images (homographies, multi-band blended): " << args.Get("out")
              << " (" << mosaic.cols << " x " << mosaic.rows << " px)\n";
  } else if (!mosaicker.WriteMosaic(args.Get("out"), &error)) {
    std::cerr << "uav_mosaic_files: " << error << "\n";
    return 1;
  }
  if (args.Has("preview")) {
    // The written mosaic downscaled to a longest side of preview-side px (alpha kept).
    const cv::Mat full = cv::imread(args.Get("out"), cv::IMREAD_UNCHANGED);
    const double f = args.GetInt("preview-side", 480) / static_cast<double>(std::max(full.cols, full.rows));
    cv::Mat preview;
    if (!full.empty()) cv::resize(full, preview, cv::Size(), std::min(1.0, f), std::min(1.0, f), cv::INTER_AREA);
    if (preview.empty() || !cv::imwrite(args.Get("preview"), preview)) {
      std::cerr << "uav_mosaic_files: cannot write preview " << args.Get("preview") << "\n";
      return 1;
    }
  }
  if (!use_oblique) std::cout << "mosaic: " << args.Get("out") << " (" << mosaicker.summary().BriefReport() << ")\n";
  return failures == 0 ? 0 : 2;
}
