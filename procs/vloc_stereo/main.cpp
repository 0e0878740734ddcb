// vloc_stereo: ZNCC + least-squares matching of a rectified stereo pair
// (operators' tool).
//   vloc_stereo LEFT RIGHT [--min-disp 0] [--max-disp 128] [--step 4] [--threads 2] --out disp.png|disp.pfm
// Matches the left pixels of a grid (every --step px) along their row of the
// right image within [min-disp, max-disp], filters the disparities with the
// median test and refines them by LSM. The map has one pixel per grid point
// (size ceil(W/step) x ceil(H/step)); PNG: 16 bit, disparity = value / 256,
// 0 = no match; PFM: float disparity, NaN = no match. Prints statistics as YAML.
#include <omp.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>

#include "vloc/common/command_line.h"
#include "vloc/common/logging.h"
#include "vloc/features/lsm.h"
#include "vloc/features/stereo_match.h"

namespace {

bool WritePfm(const std::string& path, const cv::Mat& disp) {
  std::ofstream f(path, std::ios::binary);
  if (!f) return false;
  f << "Pf\n" << disp.cols << " " << disp.rows << "\n-1\n";  // little endian
  for (int y = disp.rows - 1; y >= 0; --y) f.write(reinterpret_cast<const char*>(disp.ptr<float>(y)), disp.cols * 4);
  return static_cast<bool>(f);
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  vloc::CommandLine args;
  std::string error;
  const char* usage =
      "usage: vloc_stereo LEFT RIGHT [--min-disp 0] [--max-disp 128] [--step 4] [--threads 2] --out disp.png|disp.pfm";
  if (!args.Parse(argc, argv, {"min-disp", "max-disp", "step", "threads", "out", "help"}, &error) ||
      args.Has("help") || args.positional().size() != 2 || !args.Has("out")) {
    std::cerr << (error.empty() ? usage : "vloc_stereo: " + error + "\n" + usage) << "\n";
    return args.Has("help") ? 0 : 1;
  }
  const cv::Mat left8 = cv::imread(args.positional()[0], cv::IMREAD_GRAYSCALE);
  const cv::Mat right8 = cv::imread(args.positional()[1], cv::IMREAD_GRAYSCALE);
  if (left8.empty() || right8.empty() || left8.size() != right8.size()) {
    std::cerr << "vloc_stereo: cannot read two images of the same size from " << args.positional()[0] << " and "
              << args.positional()[1] << "\n";
    return 1;
  }
  const double dmin = args.GetDouble("min-disp", 0), dmax = args.GetDouble("max-disp", 128);
  const int step = std::max(1, args.GetInt("step", 4)), threads = std::max(1, args.GetInt("threads", 2));
  if (!(dmax > dmin && dmin >= 0)) {
    std::cerr << "vloc_stereo: need 0 <= --min-disp < --max-disp\n";
    return 1;
  }
  const std::string out = args.Get("out");
  const bool pfm = out.size() > 4 && out.substr(out.size() - 4) == ".pfm";
  const auto t0 = std::chrono::steady_clock::now();
  const vloc::LsmImage L = vloc::MakeLsmImage(left8), R = vloc::MakeLsmImage(right8);
  const vloc::ZnccOptions zo;
  const vloc::LsmOptions lo;
  const int gw = (left8.cols + step - 1) / step, gh = (left8.rows + step - 1) / step;
  std::vector<Eigen::Vector2d> pts;
  for (int y = 0; y < gh; ++y)
    for (int x = 0; x < gw; ++x) pts.emplace_back(x * step, y * step);
  std::vector<double> zncc_d(pts.size(), NAN);
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads)
  for (int k = 0; k < static_cast<int>(pts.size()); ++k) {
    const Eigen::Vector2d& p = pts[k];
    const Eigen::Vector2d a(p.x() - dmax, p.y()), b(p.x() - dmin, p.y());
    if (a.x() < 0) continue;
    const vloc::ZnccMatch m = vloc::ZnccAlongSegment(L.gray, R.gray, p, a, b, zo);
    if (m.ok) zncc_d[k] = p.x() - m.right.x();
  }
  std::vector<Eigen::Vector2d> valid_pts;
  std::vector<double> valid_d;
  std::vector<int> valid_idx;
  for (size_t k = 0; k < pts.size(); ++k)
    if (std::isfinite(zncc_d[k])) valid_pts.push_back(pts[k]), valid_d.push_back(zncc_d[k]), valid_idx.push_back(static_cast<int>(k));
  vloc::MedianFilterOptions mo;
  mo.radius = std::max(3.0 * step, 12.0);
  const std::vector<bool> keep = vloc::MedianDisparityFilter(valid_pts, valid_d, mo);
  cv::Mat disp(gh, gw, CV_32F, cv::Scalar(NAN));
  std::vector<double> sigmas(valid_idx.size(), NAN);
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads)
  for (int q = 0; q < static_cast<int>(valid_idx.size()); ++q) {
    if (!keep[q]) continue;
    const Eigen::Vector2d& p = valid_pts[q];
    const vloc::LsmResult r =
        vloc::LeastSquaresMatch(L, p, R, p - Eigen::Vector2d(valid_d[q], 0), Eigen::Matrix2d::Identity(), lo);
    if (!r.ok) continue;
    const int k = valid_idx[q];
    disp.at<float>(k / gw, k % gw) = static_cast<float>(p.x() - r.target.x());
    sigmas[q] = r.sigma_px;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::vector<double> d, s;
  for (int y = 0; y < gh; ++y)
    for (int x = 0; x < gw; ++x)
      if (std::isfinite(disp.at<float>(y, x))) d.push_back(disp.at<float>(y, x));
  for (double v : sigmas)
    if (std::isfinite(v)) s.push_back(v);
  auto median = [](std::vector<double> v) {
    if (v.empty()) return NAN * 1.0;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  bool written;
  if (pfm) {
    written = WritePfm(out, disp);
  } else {
    cv::Mat png(gh, gw, CV_16U, cv::Scalar(0));
    for (int y = 0; y < gh; ++y)
      for (int x = 0; x < gw; ++x) {
        const float v = disp.at<float>(y, x);
        if (std::isfinite(v) && v > 0) png.at<uint16_t>(y, x) = cv::saturate_cast<uint16_t>(v * 256.0f);
      }
    written = cv::imwrite(out, png);
  }
  if (!written) {
    std::cerr << "vloc_stereo: cannot write " << out << " (check the folder; use .png or .pfm)\n";
    return 1;
  }
  std::cout << "grid: [" << gw << ", " << gh << "]  # step " << step << " px\n";
  std::cout << "points: " << pts.size() << "\n";
  std::cout << "zncc_matches: " << valid_idx.size() << "\n";
  std::cout << "after_median: " << std::count(keep.begin(), keep.end(), true) << "\n";
  std::cout << "lsm_matches: " << d.size() << "\n";
  std::cout << "disparity_median_px: " << median(d) << "\n";
  std::cout << "lsm_sigma_median_px: " << median(s) << "\n";
  std::cout << "scale: " << (pfm ? 1.0 : 1.0 / 256.0) << "  # disparity = value * scale\n";
  std::cout << "seconds: " << seconds << "\n";
  return 0;
}
