// uav_mosaic_files: registers and mosaics a sequence of nadir photos with
// the UAV mosaicker: a geotagged survey folder (EXIF GPS, time, focal length;
// DJI XMP relative altitude) or OpenCV's aero1.jpg, aero3.jpg.
//   uav_mosaic_files [--config config/procs/uav_mosaic_files.yaml] [--calibration CAMERA.yaml]
//                    [--focal F] [--height H] [--no-gps] [--drop-gps A-B]
//                    [--geotiff OUT.tif] [--geojson OUT.geojson] [--report OUT.tsv] [--reference ORTHO.jpg]
//                    [--height-reference HEIGHTS.tsv] [--self-calibrate CAMERA_OUT.yaml]
//                    --out out/mosaic.png (FOLDER | IMAGE...)
// The survey itself runs in vloc::mosaic::SurveyRunner (survey_runner.h);
// this tool parses the arguments and calls its steps. Settings: --config,
// else the stills settings config/procs/uav_mosaic_files.yaml of the source
// tree ($VLOC_SOURCE_DIR, up from the executable, or the tree it was built
// from); the tool prints which file it read.
// Focal length (px): the calibration file, else --focal, else EXIF (focal
// length and sensor width, or the 35 mm equivalent), else the image width;
// the tool says which. First height: an ArUco marker in the first photo
// (calibration.marker_size, needs the focal), else the DJI relative altitude,
// else --height, else 100 m (heights then relative); the tool says which.
// With geotags the mosaic is tied to GPS, matching is guided by the GPS
// motion, and the route and height are compared with the GPS per frame and
// as RMS (route after a 2-D similarity fit). --drop-gps A-B drops the tags
// of frames A..B (0-based): a simulated GPS drop-out, held out of the fit.
// A photo tagged with the previous photo's fix (same GPS time) gets no GPS.
// --reference compares the route and the GPS with a reference orthomosaic
// of the same flight made by another tool (e.g. OpenDroneMap's);
// --height-reference the heights and the altitude tags with another tool's
// heights above the ground (scripts/survey_reference.py: COLMAP), read and
// checked before the run.
// --self-calibrate CAMERA_OUT.yaml: for a camera without a calibration, a
// first run finds the lens's radial distortion k1 from the height ties (the
// k1 under which they agree best, lens_search.h; no GPS used), writes the
// camera there and runs the survey with it.
//   uav_mosaic_files --split [--angle DEG] [--zoom Z] --out out/x.png IMAGE
// instead cuts one real image into two overlapping views related by a known
// similarity (rotation DEG, default 12; view 2 seen from Z times higher,
// default 1.18) and checks the registration against that truth.
// When the nadir mosaicker loses a frame of a sequence without geotags
// (views too different: oblique photos from other directions, like
// aero1/aero3), the sequence is registered pairwise with the affine-invariant
// RegisterOblique (image i -> image i-1, homographies chained to image 1) and
// mosaicked in image 1's frame instead (--no-oblique turns this off).
// Photos are untrusted: every header is read before any photo is decoded,
// and a photo over the limits (photo_limits in the config; default 20,000 px
// a side, 100 MP) or of another size than the survey's (the most common
// size) is refused in one line naming it; so is an EXIF/XMP tag outside its
// physical range (vloc::mosaic::GeotagRanges: the tag is then not used, and
// the tool says what it uses instead). The rest of the survey registers.
// Exit codes: 0 every photo registered; 2 outputs written, but a photo or a
// tag was refused or a frame not registered; 1 nothing usable, a bad
// argument or config, an output not writable, or an error (one line).
#include <glog/logging.h>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "vloc/common/command_line.h"
#include "vloc/common/logging.h"
#include "vloc/common/tool_main.h"
#include "vloc/common/options.h"
#include "vloc/mosaic/calibration.h"
#include "vloc/mosaic/geotag.h"
#include "vloc/mosaic/gis_export.h"
#include "vloc/mosaic/oblique_registration.h"
#include "vloc/mosaic/survey_eval.h"
#include "vloc/mosaic/survey_photos.h"
#include "vloc/mosaic/survey_runner.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace {

namespace vm = vloc::mosaic;

// A folder argument becomes its images, sorted by name.
std::vector<std::string> ExpandInputs(const std::vector<std::string>& args) {
  namespace fs = std::filesystem;
  std::vector<std::string> out;
  for (const auto& a : args) {
    if (!fs::is_directory(a)) {
      out.push_back(a);
      continue;
    }
    std::vector<std::string> files;
    for (const auto& e : fs::directory_iterator(a)) {
      std::string ext = e.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
      if (e.is_regular_file() && (ext == ".jpg" || ext == ".jpeg" || ext == ".png" || ext == ".tif" || ext == ".tiff"))
        files.push_back(e.path().string());
    }
    std::sort(files.begin(), files.end());
    out.insert(out.end(), files.begin(), files.end());
  }
  return out;
}

bool ParseRange(const std::string& text, int* a, int* b) {
  return std::sscanf(text.c_str(), "%d-%d", a, b) == 2 && *a >= 0 && *b >= *a;
}

// The stills settings: --config, else config/procs/uav_mosaic_files.yaml of
// the source tree ($VLOC_SOURCE_DIR, or up from the executable, or the tree
// this tool was built from, or the working directory). "" when none is found.
std::string StillsConfig(const vloc::CommandLine& args) {
  namespace fs = std::filesystem;
  if (args.Has("config")) return args.Get("config");
  const fs::path rel = fs::path("config") / "procs" / "uav_mosaic_files.yaml";
  std::vector<fs::path> candidates;
  if (const char* src = std::getenv("VLOC_SOURCE_DIR")) candidates.push_back(fs::path(src) / rel);
  std::error_code ec;
  const fs::path exe = fs::canonical("/proc/self/exe", ec);
  if (!ec)
    for (fs::path dir = exe.parent_path(); !dir.empty() && dir != dir.root_path(); dir = dir.parent_path())
      candidates.push_back(dir / rel);
#ifdef VLOC_SOURCE_DIR
  candidates.push_back(fs::path(VLOC_SOURCE_DIR) / rel);
#endif
  candidates.push_back(rel);
  for (const auto& c : candidates)
    if (fs::is_regular_file(c, ec)) return c.string();
  return "";
}

// --split: one image cut into two overlapping views related by a known
// similarity (rotation `angle`, view 2 seen from `zoom` times higher).
// Returns the true scale change view 1 -> view 2.
double SplitViews(const cv::Mat& src, double angle_deg, double zoom, std::vector<cv::Mat>* views) {
  const cv::Size view(static_cast<int>(src.cols * 0.62), static_cast<int>(src.rows * 0.62));
  const double angle = angle_deg * M_PI / 180.0;
  // src px = A(v) for view 1 (a plain crop) and B(v) for view 2 (rotated, zoomed out, shifted right).
  const cv::Matx23d A(1, 0, src.cols * 0.05, 0, 1, src.rows * 0.19);
  const double c = zoom * std::cos(angle), s = zoom * std::sin(angle);
  const cv::Point2d centre(src.cols * 0.62, src.rows * 0.5);
  const cv::Point2d vc((view.width - 1) / 2.0, (view.height - 1) / 2.0);
  const cv::Matx23d B(c, -s, centre.x - (c * vc.x - s * vc.y), s, c, centre.y - (s * vc.x + c * vc.y));
  cv::Mat v1, v2;
  cv::warpAffine(src, v1, A, view, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP);
  cv::warpAffine(src, v2, B, view, cv::INTER_AREA | cv::WARP_INVERSE_MAP);
  *views = {v1, v2};
  // View 1 px -> view 2 px is B^-1 A: scale 1/zoom (zoom out, lambda < 1), angle -angle.
  return 1.0 / zoom;
}

// The written mosaic downscaled to a longest side of `side` px (alpha kept;
// a JPEG gets the uncovered parts white).
bool WritePreview(const std::string& mosaic_path, const std::string& preview_path, int side) {
  const cv::Mat full = cv::imread(mosaic_path, cv::IMREAD_UNCHANGED);
  const double f = side / static_cast<double>(std::max(full.cols, full.rows));
  cv::Mat preview;
  if (!full.empty()) cv::resize(full, preview, cv::Size(), std::min(1.0, f), std::min(1.0, f), cv::INTER_AREA);
  std::vector<int> params;
  const std::string& pp = preview_path;
  if (pp.size() > 4 && (pp.substr(pp.size() - 4) == ".jpg" || pp.substr(pp.size() - 5) == ".jpeg")) {
    if (!preview.empty() && preview.channels() == 4) {
      std::vector<cv::Mat> ch;
      cv::split(preview, ch);
      cv::Mat bgr;
      cv::cvtColor(preview, bgr, cv::COLOR_BGRA2BGR);
      bgr.setTo(cv::Scalar(255, 255, 255), ch[3] == 0);
      preview = bgr;
    }
    params = {cv::IMWRITE_JPEG_QUALITY, 85};
  }
  return !preview.empty() && cv::imwrite(pp, preview, params);
}

const char* kUsage =
    "usage: uav_mosaic_files [--config config/procs/uav_mosaic_files.yaml] [--calibration CAMERA.yaml] "
    "[--focal F] [--height H] [--no-gps] [--drop-gps A-B] [--gps-sigma M] [--geotiff OUT.tif] "
    "[--geojson OUT.geojson] [--report OUT.tsv] [--reference ORTHO.jpg] [--height-reference HEIGHTS.tsv] "
    "[--preview P.png --preview-side N] "
    "[--no-oblique] [--self-calibrate CAMERA_OUT.yaml] --out OUT.png (FOLDER | IMAGE IMAGE...)\n"
    "       uav_mosaic_files --split [--angle DEG] [--zoom Z] --out OUT.png IMAGE\n";

// The survey options from the arguments; false with one line on stderr.
bool SurveyOptionsFrom(const vloc::CommandLine& args, vm::SurveyOptions* o) {
  const std::string config = StillsConfig(args);
  if (config.empty()) {
    std::cerr << "uav_mosaic_files: the stills settings config/procs/uav_mosaic_files.yaml were not found "
                 "(set VLOC_SOURCE_DIR or give --config FILE)\n";
    return false;
  }
  try {
    *o = vm::LoadSurveyOptions(config);
  } catch (const vloc::ConfigError& e) {
    std::cerr << "uav_mosaic_files: " << e.what() << "\n";
    return false;
  }
  std::cout << "settings: " << config << "\n";
  if (args.Has("drop-gps") && !ParseRange(args.Get("drop-gps"), &o->drop_gps_first, &o->drop_gps_last)) {
    std::cerr << "uav_mosaic_files: --drop-gps wants a frame range A-B (0-based, A <= B), got '" << args.Get("drop-gps")
              << "'\n";
    return false;
  }
  if (args.Has("calibration")) o->calibration_file = args.Get("calibration");
  if (args.Has("focal")) o->focal_px = args.GetDouble("focal", 0.0);
  if (args.Has("height")) o->height_m = args.GetDouble("height", 0.0);
  o->use_gps = !args.Has("no-gps");
  o->gps_sigma = args.GetDouble("gps-sigma", 3.0);
  o->oblique_fallback = !args.Has("no-oblique");
  return true;
}

// --self-calibrate CAMERA.yaml: a first run over the photos finds the lens's k1 from the height ties
// (lens_search.h); the camera is written to CAMERA.yaml and the survey runs with it. False with one line on stderr.
// Whether `path` can be written without writing it: its folder exists and
// is writable, and so is the file if it exists (`why` says which not).
bool CanWrite(const std::string& path, std::string* why) {
  namespace fs = std::filesystem;
  const fs::path file(path), folder = file.has_parent_path() ? file.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    *why = "no folder " + folder.string();
    return false;
  }
  const bool writable = fs::exists(file, ec) ? ::access(path.c_str(), W_OK) == 0 : ::access(folder.c_str(), W_OK) == 0;
  if (!writable) *why = "not writable";
  return writable;
}

bool SelfCalibrate(const std::string& camera_path, const std::vector<std::string>& photos, vm::SurveyOptions* o) {
  std::string why;
  if (!CanWrite(camera_path, &why)) {  // before the first run, not after it
    std::cerr << "uav_mosaic_files: --self-calibrate: cannot write " << camera_path << " (" << why << ")\n";
    return false;
  }
  std::cout << "lens self-calibration: a first run over the " << photos.size() << " photos\n";
  vloc::PinholeCamera camera;
  vm::LensSearch search;
  if (!vm::SelfCalibrateLens(*o, photos, &std::cout, &std::cerr, &camera, &search)) return false;
  std::ostringstream comment;
  comment << "Self-calibrated by uav_mosaic_files --self-calibrate: of k1 = " << search.curve.front().x << " ... "
          << search.curve.back().x << ", the one whose height ties agree best\n(" << search.pairs
          << " links and ties; residual " << search.residual << " sigmas, " << search.residual_as_run
          << " without). No GPS used.";
  std::string error;
  if (!vm::WriteCameraFile(camera_path, camera, comment.str(), &error)) {
    std::cerr << "uav_mosaic_files: --self-calibrate: " << error << "\n";
    return false;
  }
  std::cout << "lens self-calibration: camera written to " << camera_path << "; the survey runs with it\n";
  o->calibration_file = camera_path;
  return true;
}

// The references --reference and --height-reference name; the heights are
// read and checked now, before the survey runs. False with one line on stderr.
bool ReferencesFrom(const vloc::CommandLine& args, bool split, vm::SurveyReferences* references) {
  references->orthomosaic = args.Has("reference") ? args.Get("reference") : "";
  if (!args.Has("height-reference")) return true;
  if (split || args.Has("no-gps")) {
    std::cerr << "uav_mosaic_files: --height-reference needs a geotagged survey (its heights' metric scale), not "
              << (split ? "--split's two views" : "--no-gps") << "\n";
    return false;
  }
  references->heights_path = args.Get("height-reference");
  std::string error;
  if (!vm::ReadReferenceHeights(references->heights_path, &references->heights, &error)) {
    std::cerr << "uav_mosaic_files: " << error << "\n";
    return false;
  }
  return true;
}

// The images to register: --split's one photo, or the photos given and those in the folders given; false after
// one error line.
bool InputPaths(const vloc::CommandLine& args, bool split, std::vector<std::string>* paths) {
  for (const auto& p : args.positional()) {
    if (!std::filesystem::exists(p)) {
      std::cerr << "uav_mosaic_files: " << p << ": no such image or folder\n";
      return false;
    }
  }
  *paths = split ? args.positional() : ExpandInputs(args.positional());
  if (paths->size() < (split ? 1u : 2u)) {
    std::cerr << "uav_mosaic_files: give at least two images (or a folder holding them)\n";
    return false;
  }
  return true;
}

// --split: two views cut from one photo loaded into `runner`, *true_scale the scale change between them; false
// after one error line.
bool LoadSplitViews(const vloc::CommandLine& args, const std::string& path, const vm::SurveyOptions& options,
                    vm::SurveyRunner* runner, double* true_scale) {
  std::string error;
  const cv::Mat src = vm::LoadCheckedPhoto(path, options.limits, cv::Size(), &error);
  if (src.empty()) {
    std::cerr << "uav_mosaic_files: " << error << "\n";
    return false;
  }
  std::vector<cv::Mat> views;
  *true_scale = SplitViews(src, args.GetDouble("angle", 12.0), args.GetDouble("zoom", 1.18), &views);
  runner->LoadViews({path + " (view 1)", path + " (view 2)"}, views);
  return true;
}

// The mosaic and the products asked for (--preview, --report, --geotiff, --geojson), the summary and the
// comparison with the references; the exit code.
int WriteOutputs(const vloc::CommandLine& args, const vm::SurveyReferences& references, vm::SurveyRunner* runner) {
  const std::string out = args.Get("out");
  if (!runner->WriteMosaic(out)) return 1;
  if (args.Has("preview") && !WritePreview(out, args.Get("preview"), args.GetInt("preview-side", 480))) {
    std::cerr << "uav_mosaic_files: cannot write preview " << args.Get("preview") << "\n";
    return 1;
  }
  runner->PrintSummary(out);
  runner->Evaluate(references);
  if (args.Has("report") && !runner->WriteReport(args.Get("report"))) return 1;
  if (args.Has("geotiff") && !runner->WriteGeoTiff(args.Get("geotiff"))) return 1;
  if (args.Has("geojson") && !runner->WriteGeoJson(args.Get("geojson"))) return 1;
  return runner->ExitCode();
}

// The tool; main() turns any exception into one line and exit code 1.
int Run(int argc, char** argv) {
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv,
                  {"config", "calibration", "height", "focal", "out", "help", "split", "angle", "zoom", "preview",
                   "preview-side", "no-oblique", "no-gps", "drop-gps", "geotiff", "geojson", "report", "gps-sigma",
                   "reference", "height-reference", "self-calibrate"},
                  &error) ||
      args.Has("help") || args.positional().empty() || !args.Has("out")) {
    std::cerr << (error.empty() ? "" : "uav_mosaic_files: " + error + "\n") << kUsage;
    return 1;
  }
  const bool split = args.Has("split");
  std::vector<std::string> paths;
  if (!InputPaths(args, split, &paths)) return 1;
  vm::SurveyOptions options;
  if (!SurveyOptionsFrom(args, &options)) return 1;
  vm::SurveyReferences references;
  if (!ReferencesFrom(args, split, &references)) return 1;
  if (split && args.Has("self-calibrate")) {
    std::cerr << "uav_mosaic_files: --self-calibrate needs a survey (its height ties), not --split's two views\n";
    return 1;
  }
  if (!split && args.Has("self-calibrate") && !SelfCalibrate(args.Get("self-calibrate"), paths, &options)) return 1;
  vm::SurveyRunner runner(options, &std::cout, &std::cerr);
  double true_scale = 0;
  if (split ? !LoadSplitViews(args, paths[0], options, &runner, &true_scale) : !runner.LoadPhotos(paths)) return 1;
  if (!runner.ChooseCamera() || !runner.ChooseFirstHeight()) return 1;
  runner.RegisterAll();
  if (true_scale > 0) {
    const vm::FrameState& s = runner.frames()[1].state;
    const double h = runner.mosaicker_options().calibration.height;
    std::cout << "truth: scale change " << true_scale << " (height " << h / true_scale << " m); measured " << s.scale
              << " (height " << s.height_raw << " m), error " << 100 * (s.scale - true_scale) / true_scale << " %\n";
  }
  return WriteOutputs(args, references, &runner);
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  return vloc::RunTool("uav_mosaic_files", [&] { return Run(argc, argv); });
}
