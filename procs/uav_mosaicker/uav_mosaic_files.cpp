// uav_mosaic_files: registers and mosaics a sequence of nadir images (e.g.
// OpenCV's aero1.jpg, aero3.jpg) with the UAV mosaicker.
//   uav_mosaic_files [--config config/procs/uav_mosaicker.yaml] [--height H] [--focal F]
//                    --out out/mosaic.png IMAGE...
// The camera is taken as undistorted with the principal point at the image
// centre and focal F px (default: the image width); H (m, default 100) only
// scales the reported heights.
#include <glog/logging.h>
#include <opencv2/imgcodecs.hpp>

#include <iostream>

#include "vloc/common/command_line.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/mosaic/uav_mosaicker.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv, {"config", "height", "focal", "out", "help"}, &error) || args.Has("help") ||
      args.positional().size() < 2 || !args.Has("out")) {
    std::cerr << (error.empty() ? "" : "uav_mosaic_files: " + error + "\n")
              << "usage: uav_mosaic_files [--config config/procs/uav_mosaicker.yaml] [--height H] [--focal F] --out "
                 "OUT.png IMAGE IMAGE...\n";
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
    std::cout << args.positional()[i] << ": " << vloc::mosaic::ToString(s.status) << ", scale change " << s.scale
              << ", matches " << s.num_matches << ", inliers " << s.num_inliers << ", foreground " << s.num_foreground
              << ", centre at mosaic px (" << s.route_px.x << ", " << s.route_px.y << "), height "
              << s.height << " m" << (s.message.empty() ? "" : " (" + s.message + ")") << "\n";
    if (s.status == vloc::mosaic::TrackStatus::kLost) ++failures;
  }
  if (!mosaicker.WriteMosaic(args.Get("out"), &error)) {
    std::cerr << "uav_mosaic_files: " << error << "\n";
    return 1;
  }
  std::cout << "mosaic: " << args.Get("out") << " (" << mosaicker.summary().BriefReport() << ")\n";
  return failures == 0 ? 0 : 2;
}
