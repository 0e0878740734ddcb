// vloc_match: ASIFT matching of any two images (operators' tool).
//   vloc_match IMG1 IMG2 [--homography H.yaml] [--tilts 1,1.41,2] [--gate PX] [--ratio R]
//              [--threads N] [--out overlay.png]
// Prints YAML: features, matches, RANSAC homography (IMG1 -> IMG2 px), inliers,
// seconds. With --homography (a YAML file with `homography: [9 values]`,
// row-major, IMG1 -> IMG2), candidates are gated around the predicted
// position (--gate px, default 40); otherwise brute force with the ratio test.
#include <chrono>
#include <iomanip>
#include <iostream>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "vloc/common/command_line.h"
#include "vloc/common/logging.h"
#include "vloc/features/asift.h"

namespace {

std::vector<double> ParseList(const std::string& text) {
  std::vector<double> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::stod(item));
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  vloc::CommandLine args;
  std::string error;
  const char* usage =
      "usage: vloc_match IMG1 IMG2 [--homography H.yaml] [--tilts 1,1.41,2] [--gate PX] [--ratio R] [--threads N] "
      "[--out overlay.png]";
  if (!args.Parse(argc, argv, {"homography", "tilts", "gate", "ratio", "threads", "out", "help"}, &error) ||
      args.Has("help") || args.positional().size() != 2) {
    std::cerr << (error.empty() ? usage : "vloc_match: " + error + "\n" + usage) << "\n";
    return args.Has("help") ? 0 : 1;
  }
  const cv::Mat a = cv::imread(args.positional()[0], cv::IMREAD_GRAYSCALE);
  const cv::Mat b = cv::imread(args.positional()[1], cv::IMREAD_GRAYSCALE);
  for (int k = 0; k < 2; ++k) {
    if ((k == 0 ? a : b).empty()) {
      std::cerr << "vloc_match: cannot read image " << args.positional()[k] << " (check the path and format)\n";
      return 1;
    }
  }
  vloc::AsiftOptions options;
  options.num_threads = std::max(1, args.GetInt("threads", 2));
  try {
    if (args.Has("tilts")) options.tilts = ParseList(args.Get("tilts"));
  } catch (const std::exception&) {
    std::cerr << "vloc_match: --tilts must be a comma-separated list of numbers >= 1, e.g. 1,1.41,2\n";
    return 1;
  }
  std::string check_error;
  if (!options.Check(&check_error)) {
    std::cerr << "vloc_match: " << check_error << "\n";
    return 1;
  }
  cv::Matx33d prior = cv::Matx33d::eye();
  const bool have_prior = args.Has("homography");
  if (have_prior) {
    try {
      const YAML::Node h = YAML::LoadFile(args.Get("homography"))["homography"];
      if (!h || h.size() != 9) throw std::runtime_error("needs 9 values");
      for (int k = 0; k < 9; ++k) prior(k / 3, k % 3) = h[k].as<double>();
    } catch (const std::exception& e) {
      std::cerr << "vloc_match: " << args.Get("homography") << ": expected `homography: [9 numbers]` (" << e.what()
                << ")\n";
      return 1;
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  const vloc::FeatureSet fa = vloc::DetectAsift(a, cv::Mat(), options);
  const vloc::FeatureSet fb = vloc::DetectAsift(b, cv::Mat(), options);
  std::vector<vloc::FeatureMatch> matches;
  const double ratio = args.GetDouble("ratio", 0.8);
  if (have_prior) {
    std::vector<Eigen::Vector2d> predicted;
    for (const auto& p : fa.points) {
      const cv::Vec3d q = prior * cv::Vec3d(p.x(), p.y(), 1);
      predicted.emplace_back(q[0] / q[2], q[1] / q[2]);
    }
    vloc::GatedMatchOptions g;
    g.gate_radius = args.GetDouble("gate", 40);
    g.ratio = ratio;
    g.num_threads = options.num_threads;
    matches = vloc::GatedMatch(fa, predicted, fb, g);
  } else {
    matches = vloc::BruteForceMatch(fa, fb, ratio);
  }
  std::vector<cv::Point2f> pa, pb;
  for (const auto& m : matches) {
    pa.emplace_back(static_cast<float>(fa.points[m.query].x()), static_cast<float>(fa.points[m.query].y()));
    pb.emplace_back(static_cast<float>(fb.points[m.train].x()), static_cast<float>(fb.points[m.train].y()));
  }
  cv::Mat H;
  std::vector<uchar> inliers;
  if (pa.size() >= 4) H = cv::findHomography(pa, pb, cv::RANSAC, 5.0, inliers);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  int num_inliers = 0;
  for (uchar v : inliers) num_inliers += v ? 1 : 0;
  std::cout << std::setprecision(10);
  std::cout << "features: [" << fa.size() << ", " << fb.size() << "]\n";
  std::cout << "views: " << options.Views().size() << "\n";
  std::cout << "matches: " << matches.size() << "\n";
  std::cout << "inliers: " << num_inliers << "\n";
  if (H.empty()) {
    std::cout << "homography: null\n";
  } else {
    std::cout << "homography: [";
    for (int k = 0; k < 9; ++k) std::cout << (k ? ", " : "") << H.at<double>(k / 3, k % 3);
    std::cout << "]\n";
  }
  std::cout << "seconds: " << seconds << "\n";
  if (args.Has("out")) {
    cv::Mat ca, cb, canvas;
    cv::cvtColor(a, ca, cv::COLOR_GRAY2BGR);
    cv::cvtColor(b, cb, cv::COLOR_GRAY2BGR);
    const int h = std::max(a.rows, b.rows);
    canvas = cv::Mat::zeros(h, a.cols + b.cols, CV_8UC3);
    ca.copyTo(canvas(cv::Rect(0, 0, a.cols, a.rows)));
    cb.copyTo(canvas(cv::Rect(a.cols, 0, b.cols, b.rows)));
    for (size_t k = 0; k < pa.size(); ++k) {
      const bool in = k < inliers.size() && inliers[k];
      const cv::Scalar colour = in ? cv::Scalar(0, 220, 0) : cv::Scalar(0, 0, 220);
      cv::line(canvas, pa[k], pb[k] + cv::Point2f(static_cast<float>(a.cols), 0), colour, 1, cv::LINE_AA);
    }
    if (!cv::imwrite(args.Get("out"), canvas)) {
      std::cerr << "vloc_match: cannot write " << args.Get("out") << " (check the folder and the extension)\n";
      return 1;
    }
  }
  return 0;
}
