// vloc_stereo: ZNCC + least-squares matching of a rectified stereo pair
// (operators' tool).
//   vloc_stereo LEFT RIGHT [--config stereo.yaml] [--min-disp 0] [--max-disp 128 | --auto-range] [--step 4]
//               [--threads 2] [--no-pair-check] [--no-rectify] [--rectify-range 20] [--rectified PREFIX]
//               --out disp.png|disp.pfm
// LEFT, RIGHT: image files, or PDS3 products (vloc/common/pds_product.h: an
// .IMG with its label attached or beside it, a .LBL, or a browse .jpg/.png
// with its .LBL). A PDS pair whose camera models (CAHV, CAHVOR, CAHVORE) are
// not already a common CAHV pair is rectified epipolarly first, as JPL's
// marscahv does (vloc::LineariseStereoPair; CAHVORE's rays at
// --rectify-range m); --no-rectify matches the images as they are;
// --rectified PREFIX writes PREFIX_left.png and PREFIX_right.png. The
// disparities are then those of the rectified images.
// --config: a YAML of vloc::DenseStereoOptions keys (see dense_stereo.h);
// the flags override it.
// Matches the left pixels of a grid (every --step px) along their row of the
// right image within [min-disp, max-disp] by ZNCC (with a left-right check),
// filters the disparities with the median test and refines them by row LSM
// (vloc::DenseStereo; --no-lsm keeps the ZNCC parabola disparities). The map has one pixel per grid point
// (size ceil(W/step) x ceil(H/step)); PNG: 16 bit, disparity = value / 256,
// 0 = no match; PFM: float disparity, NaN = no match. Prints statistics as YAML.
// First it checks the pair from sparse feature matches
// (vloc::CheckStereoPair): a pair whose matches are not on their rows is
// refused with one line saying so (--no-pair-check skips the check);
// --auto-range searches the disparities the matches span (with a margin).
// A common row offset the matches agree on (real rectified pairs keep a few
// tenths of a pixel) is absorbed: the right image is shifted by it before
// matching (printed as row_offset_px).

#include <cmath>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>

#include "vloc/common/command_line.h"
#include "vloc/common/image_header.h"
#include "vloc/common/logging.h"
#include "vloc/common/tool_main.h"
#include "vloc/common/options.h"
#include "vloc/common/pds_product.h"
#include "vloc/features/dense_stereo.h"
#include "vloc/features/stereo_pair_check.h"

namespace {

bool WritePfm(const std::string& path, const cv::Mat& disp) {
  std::ofstream f(path, std::ios::binary);
  if (!f) return false;
  f << "Pf\n" << disp.cols << " " << disp.rows << "\n-1\n";  // little endian
  for (int y = disp.rows - 1; y >= 0; --y) f.write(reinterpret_cast<const char*>(disp.ptr<float>(y)), disp.cols * 4);
  return static_cast<bool>(f);
}

// The pair check: false (and one line on stderr) when the pair is not
// rectified, or when --auto-range needs a range the check could not give.
bool CheckPair(const cv::Mat& left, const cv::Mat& right, bool auto_range, double* dmin, double* dmax,
               double* row_offset) {
  const vloc::StereoPairCheck c = vloc::CheckStereoPair(left, right, vloc::StereoPairCheckOptions());
  if (c.usable && !c.rectified) {
    std::cerr << "vloc_stereo: the pair is " << c.message << " (--no-pair-check to match it anyway)\n";
    return false;
  }
  if (!c.usable) {
    std::cerr << "vloc_stereo: pair check: " << c.message << "\n";
    if (auto_range) std::cerr << "vloc_stereo: --auto-range needs the feature matches: give --min-disp and --max-disp\n";
    return !auto_range;
  }
  std::cout << "pair_check: \"" << c.message << "\"\n";
  std::cout << "row_error_px: {median: " << c.median_abs_dy_px << ", p90: " << c.p90_abs_dy_px << ", matches: " << c.matches
            << "}  # |left y - right y| of the check's matches, before the row offset\n";
  *row_offset = c.row_offset_px;
  if (auto_range) *dmin = c.min_disparity, *dmax = c.max_disparity;
  return true;
}

// Two images from files: the headers checked before decoding (sizes over
// vloc::ImageLimits' defaults, about 100 MP, are refused).
bool ReadImages(const std::string& left_path, const std::string& right_path, cv::Mat* left, cv::Mat* right) {
  cv::Mat images[2];
  std::string error;
  for (int k = 0; k < 2; ++k) {
    std::vector<uint8_t> bytes;
    vloc::ImageHeader header;
    if (!vloc::ReadCheckedImageFile(k ? right_path : left_path, vloc::ImageLimits(), &bytes, &header, &error)) {
      std::cerr << "vloc_stereo: cannot read two images of the same size from " << left_path << " and " << right_path
                << ": " << error << "\n";
      return false;
    }
    images[k] = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
  }
  *left = images[0], *right = images[1];
  return true;
}

// LEFT and RIGHT: image files, or PDS products rectified through their
// models (unless --no-rectify). False after one line on stderr.
bool ReadPair(const vloc::CommandLine& args, cv::Mat* left, cv::Mat* right) {
  const std::string& left_path = args.positional()[0];
  const std::string& right_path = args.positional()[1];
  const bool pds[2] = {vloc::IsPdsProductPath(left_path), vloc::IsPdsProductPath(right_path)};
  if (pds[0] != pds[1]) {
    std::cerr << "vloc_stereo: " << (pds[0] ? right_path : left_path)
              << " is not a PDS product (its partner is): give two PDS products or two images\n";
    return false;
  }
  if (!pds[0]) {
    if (args.Has("rectified") || args.Has("no-rectify") || args.Has("rectify-range")) {
      std::cerr << "vloc_stereo: --rectified / --no-rectify / --rectify-range need PDS products (camera models)\n";
      return false;
    }
    return ReadImages(left_path, right_path, left, right);
  }
  const double range = args.GetDouble("rectify-range", 20.0);
  if (!(range > 0 && range < 1e6)) {
    std::cerr << "vloc_stereo: --rectify-range must be in (0, 1e6) m\n";
    return false;
  }
  vloc::RectifiedPdsPair pair;
  std::string error;
  if (!vloc::ReadPdsStereoPair(left_path, right_path, !args.Has("no-rectify"), range, &pair, &error)) {
    std::cerr << "vloc_stereo: " << error << "\n";
    return false;
  }
  std::cout << vloc::DescribeRectification(pair);
  if (args.Has("rectified")) {
    if (!vloc::WriteRectifiedPair(pair, args.Get("rectified"), &error)) {
      std::cerr << "vloc_stereo: " << error << "\n";
      return false;
    }
  }
  *left = pair.left, *right = pair.right;
  return true;
}

// The matching options: --config, then the flags, the disparity range
// from --auto-range's pair check; the check's row offset absorbed into
// `right8`. False after one line on stderr.
bool ReadStereoOptions(const vloc::CommandLine& args, const cv::Mat& left8, cv::Mat* right8,
                       vloc::DenseStereoOptions* options) {
  vloc::DenseStereoOptions& o = *options;
  if (args.Has("config")) {
    try {
      o = vloc::LoadOptionsFile<vloc::DenseStereoOptions>(args.Get("config"));
    } catch (const std::exception& e) {
      std::cerr << "vloc_stereo: " << e.what() << "\n";
      return false;
    }
  }
  double dmin = args.GetDouble("min-disp", o.min_disparity), dmax = args.GetDouble("max-disp", o.max_disparity);
  const bool auto_range = args.Has("auto-range");
  if (auto_range && (args.Has("min-disp") || args.Has("max-disp"))) {
    std::cerr << "vloc_stereo: --auto-range chooses the disparities: drop --min-disp / --max-disp\n";
    return false;
  }
  if (auto_range && args.Has("no-pair-check")) {
    std::cerr << "vloc_stereo: --auto-range needs the pair check: drop --no-pair-check\n";
    return false;
  }
  double row_offset = 0;
  if (!args.Has("no-pair-check") && !CheckPair(left8, *right8, auto_range, &dmin, &dmax, &row_offset)) return false;
  *right8 = vloc::AlignRows(*right8, row_offset);
  std::cout << "row_offset_px: " << row_offset << "\n";
  const int step = std::max(1, args.GetInt("step", args.Has("config") ? o.step : 4));
  const int threads = std::max(1, args.GetInt("threads", o.num_threads));
  if (!(dmax > dmin && dmin >= 0)) {
    std::cerr << "vloc_stereo: need 0 <= --min-disp < --max-disp\n";
    return false;
  }
  o.min_disparity = dmin;
  o.max_disparity = dmax;
  o.step = step;
  o.num_threads = threads;
  if (args.Has("no-lsm")) o.lsm_enabled = false;
  std::string check_error;
  if (!o.Check(&check_error)) {
    std::cerr << "vloc_stereo: " << check_error << "\n";
    return false;
  }
  return true;
}

// The map as PFM (float, NaN = no match) or 16-bit PNG (value / 256, 0 =
// no match); false when it cannot be written.
bool WriteDisparities(const std::string& out, bool pfm, const cv::Mat& disp) {
  if (pfm) return WritePfm(out, disp);
  cv::Mat png(disp.rows, disp.cols, CV_16U, cv::Scalar(0));
  for (int y = 0; y < disp.rows; ++y)
    for (int x = 0; x < disp.cols; ++x) {
      const float v = disp.at<float>(y, x);
      if (std::isfinite(v) && v > 0) png.at<uint16_t>(y, x) = cv::saturate_cast<uint16_t>(v * 256.0f);
    }
  return cv::imwrite(out, png);
}

// The median of the matched disparities (NaN when none).
double MedianDisparity(const cv::Mat& disp) {
  std::vector<double> d;
  for (int y = 0; y < disp.rows; ++y)
    for (int x = 0; x < disp.cols; ++x)
      if (std::isfinite(disp.at<float>(y, x))) d.push_back(disp.at<float>(y, x));
  if (d.empty()) return NAN * 1.0;
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return d[d.size() / 2];
}

// The statistics as YAML.
void PrintSummary(const vloc::DenseStereoSummary& summary, const vloc::DenseStereoOptions& o, const cv::Mat& disp,
                  bool pfm) {
  std::cout << "grid: [" << disp.cols << ", " << disp.rows << "]  # step " << o.step << " px\n";
  std::cout << "points: " << summary.points << "\n";
  std::cout << "zncc_matches: " << summary.zncc_matches << "  # unique peaks passing the left-right check\n";
  std::cout << "after_median: " << summary.after_median << "\n";
  std::cout << "lsm_matches: " << (o.lsm_enabled ? summary.lsm_matches : 0) << "\n";
  std::cout << "disparity_median_px: " << MedianDisparity(disp) << "\n";
  std::cout << "lsm_sigma_median_px: " << summary.median_sigma_px << "\n";
  std::cout << "lsm_mean_iterations: " << summary.lsm_mean_iterations << "\n";
  if (o.lsm_lattice > 1) {
    std::cout << "lsm_from_lattice: " << summary.lsm_from_lattice << "  # from the lattice's planes, before the LSM median test\n";
    std::cout << "lsm_dropped: " << summary.lsm_dropped << "  # in a cell whose corners all failed, without LSM\n";
  }
  std::cout << "scale: " << (pfm ? 1.0 : 1.0 / 256.0) << "  # disparity = value * scale\n";
  std::cout << "seconds: " << summary.total_seconds << "  # zncc " << summary.zncc_seconds << ", median "
            << summary.median_seconds << ", lsm " << summary.lsm_seconds << "\n";
}

// The tool; main() turns any exception into one line and exit code 1.
int Run(int argc, char** argv) {
  vloc::CommandLine args;
  std::string error;
  const char* usage =
      "usage: vloc_stereo LEFT RIGHT [--config stereo.yaml] [--min-disp 0] [--max-disp 128 | --auto-range] [--step 4] "
      "[--threads 2] [--no-lsm] [--no-pair-check] [--no-rectify] [--rectify-range 20] [--rectified PREFIX] "
      "--out disp.png|disp.pfm";
  if (!args.Parse(argc, argv,
                  {"config", "min-disp", "max-disp", "auto-range", "step", "threads", "no-lsm", "no-pair-check", "no-rectify",
                   "rectify-range", "rectified", "out", "help"},
                  &error) ||
      args.Has("help") || args.positional().size() != 2 || !args.Has("out")) {
    std::cerr << (error.empty() ? usage : "vloc_stereo: " + error + "\n" + usage) << "\n";
    return args.Has("help") ? 0 : 1;
  }
  cv::Mat left8, right8;
  if (!ReadPair(args, &left8, &right8)) return 1;
  if (left8.empty() || right8.empty() || left8.size() != right8.size()) {
    std::cerr << "vloc_stereo: cannot read two images of the same size from " << args.positional()[0] << " and "
              << args.positional()[1] << "\n";
    return 1;
  }
  vloc::DenseStereoOptions o;
  if (!ReadStereoOptions(args, left8, &right8, &o)) return 1;
  const std::string out = args.Get("out");
  const bool pfm = out.size() > 4 && out.substr(out.size() - 4) == ".pfm";
  vloc::DenseStereoSummary summary;
  const cv::Mat disp = vloc::DenseStereo(left8, right8, o, &summary);
  if (!WriteDisparities(out, pfm, disp)) {
    std::cerr << "vloc_stereo: cannot write " << out << " (check the folder; use .png or .pfm)\n";
    return 1;
  }
  PrintSummary(summary, o, disp, pfm);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  return vloc::RunTool("vloc_stereo", [&] { return Run(argc, argv); });
}
