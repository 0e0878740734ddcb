// vloc_match: homography between two images of a planar scene (operators' tool).
//   vloc_match IMG1 IMG2 [--homography H.yaml] [--tilts 1,1.41,2] [--gate PX] [--ratio R]
//              [--coarse-scale S] [--refine-rounds N] [--truth H.yaml|H.xml] [--threads N] [--out overlay.png]
//              [--rectify [--rectify-range 20] [--rectified PREFIX]]
// IMG1, IMG2: image files, or PDS3 products (vloc/common/pds_product.h: an
// .IMG with its label attached or beside it, a .LBL, or a browse .jpg/.png
// with its .LBL). --rectify (PDS products of a stereo pair) rectifies them
// epipolarly through their CAHV / CAHVOR / CAHVORE models first (JPL's
// marscahv: vloc::LineariseStereoPair; CAHVORE's rays at --rectify-range m;
// --rectified PREFIX writes PREFIX_left.png, PREFIX_right.png), matches the
// rectified images and prints the row error of the inliers.
// Prints YAML: features, matches, inliers, homography (IMG1 -> IMG2 px),
// seconds. Without a prior: ASIFT on images reduced by --coarse-scale
// (default 0.5), FLANN + ratio test, RANSAC, then --refine-rounds (default
// 2) rounds of least-squares matching at full resolution and a
// Levenberg-Marquardt fit over all inliers (vloc::MatchHomography). With
// --homography (a YAML file with `homography: [9 values]`, row-major,
// IMG1 -> IMG2), full-size ASIFT candidates are gated around the predicted
// position (--gate px, default 40) and the RANSAC homography is refined the
// same way. --truth (same YAML, or an OpenCV XML/YAML file whose first node
// is the 3x3 matrix, e.g. H1to3p.xml) adds the corner errors.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "vloc/common/command_line.h"
#include "vloc/common/image_header.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/common/pds_product.h"
#include "vloc/common/tool_main.h"
#include "vloc/features/asift.h"
#include "vloc/features/homography_match.h"

namespace {

std::vector<double> ParseList(const std::string& text) {
  std::vector<double> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::stod(item));
  return out;
}

// Reads `homography: [9 numbers]` (YAML) or an OpenCV FileStorage whose
// first node is a 3x3 matrix; throws with the reason.
cv::Matx33d ReadHomography(const std::string& path) {
  cv::Matx33d h;
  try {
    const YAML::Node n = vloc::LoadYamlFile(path)["homography"];  // the config loader's limits
    if (n && n.size() == 9) {
      for (int k = 0; k < 9; ++k) h(k / 3, k % 3) = n[k].as<double>();
      return h;
    }
  } catch (const std::exception&) {
  }
  cv::FileStorage fs(path, cv::FileStorage::READ);
  cv::Mat m;
  if (fs.isOpened()) fs.getFirstTopLevelNode() >> m;
  if (m.rows != 3 || m.cols != 3) throw std::runtime_error("expected `homography: [9 numbers]` or an OpenCV 3x3 matrix");
  m.convertTo(m, CV_64F);
  return cv::Matx33d(m.ptr<double>());
}

// Smaller images cannot be matched (ASIFT reduces them by --coarse-scale
// and by each tilt).
constexpr int kMinImageSide = 32;

// A grayscale image from `path`, its header checked before decoding (size
// limits: vloc::ImageLimits' defaults, about 100 MP); empty with one line in
// *error when refused.
cv::Mat ReadImage(const std::string& path, std::string* error) {
  std::vector<uint8_t> bytes;
  vloc::ImageHeader header;
  if (!vloc::ReadCheckedImageFile(path, vloc::ImageLimits(), &bytes, &header, error)) return cv::Mat();
  if (header.width < kMinImageSide || header.height < kMinImageSide) {
    *error = path + ": " + header.Describe() + " is too small to match (at least " + std::to_string(kMinImageSide) +
             " x " + std::to_string(kMinImageSide) + " px)";
    return cv::Mat();
  }
  const cv::Mat image = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
  if (image.empty()) *error = path + ": " + header.Describe() + " cannot be decoded (corrupt data?)";
  return image;
}

// IMG1 and IMG2: image files, or PDS products (rectified with --rectify).
// False after one line on stderr.
bool ReadPair(const vloc::CommandLine& args, cv::Mat* a, cv::Mat* b) {
  const std::string& path_a = args.positional()[0];
  const std::string& path_b = args.positional()[1];
  const bool pds = vloc::IsPdsProductPath(path_a) || vloc::IsPdsProductPath(path_b);
  const bool rectify = args.Has("rectify");
  if (!rectify && (args.Has("rectify-range") || args.Has("rectified"))) {
    std::cerr << "vloc_match: --rectify-range / --rectified go with --rectify\n";
    return false;
  }
  std::string error;
  if (!pds) {
    if (rectify) {
      std::cerr << "vloc_match: --rectify needs two PDS products (their camera models)\n";
      return false;
    }
    *a = ReadImage(path_a, &error);
    *b = a->empty() ? cv::Mat() : ReadImage(path_b, &error);
    if (a->empty() || b->empty()) std::cerr << "vloc_match: " << error << "\n";
    return !a->empty() && !b->empty();
  }
  const double range = args.GetDouble("rectify-range", 20.0);
  if (!(range > 0 && range < 1e6)) {
    std::cerr << "vloc_match: --rectify-range must be in (0, 1e6) m\n";
    return false;
  }
  vloc::RectifiedPdsPair pair;
  if (!vloc::ReadPdsStereoPair(path_a, path_b, rectify, range, &pair, &error)) {
    std::cerr << "vloc_match: " << error << "\n";
    return false;
  }
  for (const cv::Mat* m : {&pair.left, &pair.right})
    if (m->cols < kMinImageSide || m->rows < kMinImageSide) {
      std::cerr << "vloc_match: " << (m == &pair.left ? path_a : path_b) << ": LINES / LINE_SAMPLES of IMAGE: "
                << m->cols << " x " << m->rows << " is too small to match (at least " << kMinImageSide << " px a side)\n";
      return false;
    }
  if (rectify) {
    std::cout << vloc::DescribeRectification(pair);
    if (args.Has("rectified")) {
      if (!vloc::WriteRectifiedPair(pair, args.Get("rectified"), &error)) {
        std::cerr << "vloc_match: " << error << "\n";
        return false;
      }
    }
  }
  *a = pair.left, *b = pair.right;
  return true;
}

// |row a - row b| of the inliers: median and 95th percentile, px.
void PrintRowError(const vloc::HomographyMatchResult& result) {
  std::vector<double> dy;
  for (size_t k = 0; k < result.inliers_a.size(); ++k) dy.push_back(std::abs(result.inliers_a[k].y() - result.inliers_b[k].y()));
  std::sort(dy.begin(), dy.end());
  const auto at = [&](double q) { return dy.empty() ? NAN : dy[std::min(dy.size() - 1, static_cast<size_t>(q * dy.size()))]; };
  std::cout << "row_error_px: {median: " << at(0.5) << ", p95: " << at(0.95) << ", points: " << dy.size()
            << "}  # |row 1 - row 2| of the refined inliers (rectified pair)\n";
}

// What the command line asks for, checked.
struct Settings {
  vloc::HomographyMatchOptions hm;
  vloc::AsiftOptions asift;  // the features' (full-size with a prior, else hm.asift)
  bool have_prior = false, have_truth = false;
  cv::Matx33d prior = cv::Matx33d::eye(), truth;
  int threads = 2;
};

// The settings from `args`: false after one line on stderr.
bool ReadSettings(const vloc::CommandLine& args, Settings* s) {
  s->threads = std::max(1, args.GetInt("threads", 2));
  vloc::HomographyMatchOptions& hm = s->hm;
  hm.num_threads = s->threads;
  hm.ratio = args.GetDouble("ratio", 0.8);
  hm.coarse_scale = args.GetDouble("coarse-scale", hm.coarse_scale);
  hm.refine_rounds = args.GetInt("refine-rounds", hm.refine_rounds);
  s->have_prior = args.Has("homography");
  s->have_truth = args.Has("truth");
  // With a prior, the full-size images are matched: ASIFT's defaults.
  s->asift = s->have_prior ? vloc::AsiftOptions() : hm.asift;
  s->asift.num_threads = s->threads;
  try {
    if (args.Has("tilts")) s->asift.tilts = ParseList(args.Get("tilts"));
  } catch (const std::exception&) {
    std::cerr << "vloc_match: --tilts must be a comma-separated list of numbers >= 1, e.g. 1,1.41,2\n";
    return false;
  }
  hm.asift = s->asift;
  std::string check_error;
  if (!hm.Check(&check_error)) {
    std::cerr << "vloc_match: " << check_error << "\n";
    return false;
  }
  for (const bool is_truth : {false, true}) {
    if (!(is_truth ? s->have_truth : s->have_prior)) continue;
    const std::string path = args.Get(is_truth ? "truth" : "homography");
    try {
      (is_truth ? s->truth : s->prior) = ReadHomography(path);
    } catch (const std::exception& e) {
      std::cerr << "vloc_match: " << path << ": " << e.what() << "\n";
      return false;
    }
  }
  return true;
}

// The match and the counts it printed before refinement.
struct Match {
  vloc::HomographyMatchResult result;
  int features[2] = {0, 0}, matches = 0, inliers = 0;
};

// With --homography: full-size ASIFT gated around the prior's prediction
// (--gate px), RANSAC, then the refinement rounds (none: the RANSAC
// homography and its inliers).
Match MatchWithPrior(const cv::Mat& a, const cv::Mat& b, const Settings& s, double gate_px) {
  Match m;
  const vloc::FeatureSet fa = vloc::DetectAsift(a, cv::Mat(), s.asift);
  const vloc::FeatureSet fb = vloc::DetectAsift(b, cv::Mat(), s.asift);
  m.features[0] = static_cast<int>(fa.size());
  m.features[1] = static_cast<int>(fb.size());
  std::vector<Eigen::Vector2d> predicted;
  for (const auto& p : fa.points) {
    const cv::Vec3d q = s.prior * cv::Vec3d(p.x(), p.y(), 1);
    predicted.emplace_back(q[0] / q[2], q[1] / q[2]);
  }
  vloc::GatedMatchOptions g;
  g.gate_radius = gate_px;
  g.ratio = s.hm.ratio;
  g.num_threads = s.threads;
  const std::vector<vloc::FeatureMatch> matches = vloc::GatedMatch(fa, predicted, fb, g);
  m.matches = static_cast<int>(matches.size());
  std::vector<cv::Point2f> pa, pb;
  for (const auto& fm : matches) {
    pa.emplace_back(static_cast<float>(fa.points[fm.query].x()), static_cast<float>(fa.points[fm.query].y()));
    pb.emplace_back(static_cast<float>(fb.points[fm.train].x()), static_cast<float>(fb.points[fm.train].y()));
  }
  std::vector<uchar> inliers;
  cv::Mat H;
  if (pa.size() >= 4) H = cv::findHomography(pa, pb, cv::RANSAC, 5.0, inliers);
  m.inliers = static_cast<int>(std::count(inliers.begin(), inliers.end(), 1));
  if (H.empty()) {
    m.result.summary.message = "too few gated matches agree on a homography";
    return m;
  }
  if (s.hm.refine_rounds > 0) {
    m.result = vloc::RefineHomography(a, b, cv::Matx33d(H.ptr<double>()), s.hm);
    return m;
  }
  m.result.b_from_a = cv::Matx33d(H.ptr<double>());
  m.result.summary.usable = true;
  for (size_t k = 0; k < pa.size(); ++k)
    if (inliers[k]) m.result.inliers_a.emplace_back(pa[k].x, pa[k].y), m.result.inliers_b.emplace_back(pb[k].x, pb[k].y);
  return m;
}

// Without a prior: vloc::MatchHomography (coarse ASIFT, RANSAC, refinement).
Match MatchWithoutPrior(const cv::Mat& a, const cv::Mat& b, const Settings& s) {
  Match m;
  m.result = vloc::MatchHomography(a, b, s.hm);
  m.features[0] = m.result.summary.features_a;
  m.features[1] = m.result.summary.features_b;
  m.matches = m.result.summary.coarse_matches;
  m.inliers = m.result.summary.coarse_inliers;
  return m;
}

// The YAML on stdout (without the seconds); the corner errors against --truth.
void PrintMatch(const Match& m, const Settings& s, const cv::Size& size_a) {
  const vloc::HomographyMatchSummary& sum = m.result.summary;
  std::cout << std::setprecision(10);
  std::cout << "features: [" << m.features[0] << ", " << m.features[1] << "]\n";
  std::cout << "views: " << s.asift.Views().size() << "\n";
  std::cout << "matches: " << m.matches << "\n";
  std::cout << "inliers: " << m.inliers << "  # ASIFT matches on the RANSAC homography\n";
  std::cout << "refined_inliers: " << sum.refine_inliers << "  # LSM correspondences on the final homography\n";
  std::cout << "refined_rms_px: " << sum.rms_px << "\n";
  if (!sum.usable) {
    std::cout << "homography: null\n";
    std::cout << "message: \"" << sum.message << "\"\n";
    return;
  }
  std::cout << "homography: [";
  for (int k = 0; k < 9; ++k) std::cout << (k ? ", " : "") << m.result.b_from_a(k / 3, k % 3);
  std::cout << "]\n";
  if (!s.have_truth) return;
  double worst = 0, total = 0;
  const double w = size_a.width - 1, h = size_a.height - 1;
  for (const cv::Vec3d& c : {cv::Vec3d(0, 0, 1), cv::Vec3d(w, 0, 1), cv::Vec3d(w, h, 1), cv::Vec3d(0, h, 1)}) {
    const cv::Vec3d p = m.result.b_from_a * c, q = s.truth * c;
    const double e = std::hypot(p[0] / p[2] - q[0] / q[2], p[1] / p[2] - q[1] / q[2]);
    worst = std::max(worst, e);
    total += e;
  }
  std::cout << "corner_error_px: {mean: " << total / 4 << ", max: " << worst << "}  # against --truth\n";
}

// The two images side by side, each inlier joined by a green line.
bool WriteOverlay(const cv::Mat& a, const cv::Mat& b, const vloc::HomographyMatchResult& result,
                  const std::string& path) {
  cv::Mat ca, cb;
  cv::cvtColor(a, ca, cv::COLOR_GRAY2BGR);
  cv::cvtColor(b, cb, cv::COLOR_GRAY2BGR);
  cv::Mat canvas = cv::Mat::zeros(std::max(a.rows, b.rows), a.cols + b.cols, CV_8UC3);
  ca.copyTo(canvas(cv::Rect(0, 0, a.cols, a.rows)));
  cb.copyTo(canvas(cv::Rect(a.cols, 0, b.cols, b.rows)));
  for (size_t k = 0; k < result.inliers_a.size(); ++k) {
    const cv::Point2f pa(static_cast<float>(result.inliers_a[k].x()), static_cast<float>(result.inliers_a[k].y()));
    const cv::Point2f pb(static_cast<float>(result.inliers_b[k].x()), static_cast<float>(result.inliers_b[k].y()));
    cv::line(canvas, pa, pb + cv::Point2f(static_cast<float>(a.cols), 0), cv::Scalar(0, 220, 0), 1, cv::LINE_AA);
  }
  return cv::imwrite(path, canvas);
}

// The tool; main() turns any exception into one line and exit code 1.
int Run(int argc, char** argv) {
  vloc::CommandLine args;
  std::string error;
  const char* usage =
      "usage: vloc_match IMG1 IMG2 [--homography H.yaml] [--tilts 1,1.41,2] [--gate PX] [--ratio R] [--coarse-scale S] "
      "[--refine-rounds N] [--truth H.yaml|H.xml] [--threads N] [--out overlay.png] "
      "[--rectify [--rectify-range 20] [--rectified PREFIX]]";
  if (!args.Parse(argc, argv,
                  {"homography", "tilts", "gate", "ratio", "coarse-scale", "refine-rounds", "truth", "threads", "out", "rectify",
                   "rectify-range", "rectified", "help"},
                  &error) ||
      args.Has("help") || args.positional().size() != 2) {
    std::cerr << (error.empty() ? usage : "vloc_match: " + error + "\n" + usage) << "\n";
    return args.Has("help") ? 0 : 1;
  }
  cv::Mat a, b;
  if (!ReadPair(args, &a, &b)) return 1;
  Settings settings;
  if (!ReadSettings(args, &settings)) return 1;
  const auto t0 = std::chrono::steady_clock::now();
  const Match match = settings.have_prior ? MatchWithPrior(a, b, settings, args.GetDouble("gate", 40))
                                          : MatchWithoutPrior(a, b, settings);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  PrintMatch(match, settings, a.size());
  if (args.Has("rectify")) PrintRowError(match.result);
  std::cout << "seconds: " << seconds << "\n";
  if (args.Has("out") && !WriteOverlay(a, b, match.result, args.Get("out"))) {
    std::cerr << "vloc_match: cannot write " << args.Get("out") << " (check the folder and the extension)\n";
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  return vloc::RunTool("vloc_match", [&] { return Run(argc, argv); });
}
