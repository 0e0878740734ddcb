// uav_mosaic_files: registers and mosaics a sequence of nadir photos with
// the UAV mosaicker: a geotagged survey folder (EXIF GPS, time, focal length;
// DJI XMP relative altitude) or OpenCV's aero1.jpg, aero3.jpg.
//   uav_mosaic_files [--config config/procs/uav_mosaic_files.yaml] [--calibration CAMERA.yaml]
//                    [--focal F] [--height H] [--no-gps] [--drop-gps A-B]
//                    [--geotiff OUT.tif] [--geojson OUT.geojson] [--report OUT.tsv] [--reference ORTHO.jpg]
//                    --out out/mosaic.png (FOLDER | IMAGE...)
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
// of the same flight made by another tool (e.g. OpenDroneMap's).
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
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>

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

struct FrameRecord {
  std::string name;
  vm::ImageGeotag tag;
  bool gps_used = false;       // tag given to the mosaicker
  bool dropped = false;        // tag withheld (--drop-gps): compared, not in the fit
  bool repeated_fix = false;   // the camera tagged it with the previous photo's fix (same GPS time): no new position
  vm::FrameState state;
  bool registered = false;
  cv::Point2d enu;             // GPS east/north of the frame (m, from the first tagged frame)
};

// A camera's GPS may tag a photo with the fix it already gave the previous
// photo (same GPSTimeStamp, same position): that is no position for this
// photo, and using it would put the photo a whole step behind.
void MarkRepeatedFixes(std::vector<FrameRecord>* frames) {
  int repeated = 0;
  for (size_t i = 1; i < frames->size(); ++i) {
    const auto& a = (*frames)[i - 1].tag;
    auto& b = (*frames)[i];
    b.repeated_fix = a.has_gps && b.tag.has_gps && a.has_gps_time && b.tag.has_gps_time &&
                     a.gps_utime == b.tag.gps_utime && a.latitude == b.tag.latitude && a.longitude == b.tag.longitude;
    if (b.repeated_fix) {
      std::cout << b.name << ": GPS tag repeats the previous photo's fix (same GPS time): not used\n";
      ++repeated;
    }
  }
  if (repeated > 0) std::cout << repeated << " repeated GPS fixes left out\n";
}

// Route and GPS against a reference orthomosaic of the same flight made by
// another tool: each registered photo located in it, then both fitted to it
// by a 2-D similarity (the reference's scale and orientation are unknown).
void CompareWithReference(const std::string& reference_path, const std::vector<FrameRecord>& frames,
                          const std::vector<std::string>& paths, const vm::RouteComparison& route_vs_gps,
                          const vloc::ImageLimits& limits) {
  std::string why;
  cv::Mat reference = vm::LoadCheckedPhoto(reference_path, limits, cv::Size(), &why);
  if (reference.empty()) {
    std::cerr << "uav_mosaic_files: the reference orthomosaic " << why << "\n";
    return;
  }
  cv::cvtColor(reference, reference, cv::COLOR_BGR2GRAY);
  const vm::ReferenceLocator locator(reference);
  std::vector<vm::ReferenceFix> fixes(frames.size());
  std::vector<cv::Point2d> route_m(frames.size()), gps_m(frames.size());
  std::vector<bool> with_gps(frames.size(), false);
  for (size_t i = 0; i < frames.size(); ++i) {
    if (!frames[i].registered) continue;
    fixes[i] = locator.Locate(vm::LoadCheckedPhoto(paths[i], limits, cv::Size(), nullptr));
    route_m[i] = route_vs_gps.enu_from_flipped.Apply({frames[i].state.route_px.x, -frames[i].state.route_px.y});
    gps_m[i] = frames[i].enu;
    with_gps[i] = frames[i].tag.has_gps && !frames[i].repeated_fix;
  }
  const vm::ReferenceComparison c = vm::CompareWithReference(fixes, route_m, gps_m, with_gps);
  std::cout << "reference orthomosaic " << reference_path << " (" << locator.reference_features() << " features): "
            << c.located << " registered photos located in it\n";
  if (!c.route.ok || !c.gps.ok) {
    std::cout << "reference comparison: " << (c.route.ok ? c.gps.why : c.route.why) << "\n";
    return;
  }
  const auto& route = c.route;
  const auto& gps = c.gps;
  const double path = route_vs_gps.path_m;  // the GPS path of the whole flight, as in the route-vs-GPS figure
  std::cout << "route vs reference (2-D similarity): RMS " << route.rms_m << " m = " << 100 * route.rms_m / path
            << " % of the " << path << " m path; GPS vs reference: RMS " << gps.rms_m << " m = " << 100 * gps.rms_m / path
            << " %\n";
}

bool ParseRange(const std::string& text, int* a, int* b) {
  return std::sscanf(text.c_str(), "%d-%d", a, b) == 2 && *a >= 0 && *b >= *a;
}


// The tool; main() turns any exception into one line and exit code 1.
int Run(int argc, char** argv) {
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv,
                  {"config", "calibration", "height", "focal", "out", "help", "split", "angle", "zoom", "preview",
                   "preview-side", "no-oblique", "no-gps", "drop-gps", "geotiff", "geojson", "report", "gps-sigma",
                   "reference"},
                  &error) ||
      args.Has("help") || args.positional().empty() || !args.Has("out")) {
    std::cerr << (error.empty() ? "" : "uav_mosaic_files: " + error + "\n")
              << "usage: uav_mosaic_files [--config config/procs/uav_mosaic_files.yaml] [--calibration CAMERA.yaml] "
                 "[--focal F] [--height H] [--no-gps] [--drop-gps A-B] [--gps-sigma M] [--geotiff OUT.tif] "
                 "[--geojson OUT.geojson] [--report OUT.tsv] [--reference ORTHO.jpg] [--preview P.png --preview-side N] "
                 "[--no-oblique] "
                 "--out OUT.png (FOLDER | IMAGE IMAGE...)\n"
                 "       uav_mosaic_files --split [--angle DEG] [--zoom Z] --out OUT.png IMAGE\n";
    return 1;
  }
  std::vector<std::string> paths = args.Has("split") ? args.positional() : ExpandInputs(args.positional());
  for (const auto& p : args.positional()) {
    if (!std::filesystem::exists(p)) {
      std::cerr << "uav_mosaic_files: " << p << ": no such image or folder\n";
      return 1;
    }
  }
  if (paths.size() < (args.Has("split") ? 1u : 2u)) {
    std::cerr << "uav_mosaic_files: give at least two images (or a folder holding them)\n";
    return 1;
  }
  int drop_a = -1, drop_b = -2;
  if (args.Has("drop-gps") && !ParseRange(args.Get("drop-gps"), &drop_a, &drop_b)) {
    std::cerr << "uav_mosaic_files: --drop-gps wants a frame range A-B (0-based, A <= B), got '" << args.Get("drop-gps")
              << "'\n";
    return 1;
  }
  // Every header before any photo is decoded: limits, and one size for the survey.
  vloc::ImageLimits limits;
  try {
    const std::string config = args.Has("config") ? args.Get("config") : "";
    if (!config.empty() && vloc::LoadYamlFile(config)["photo_limits"])
      limits = vloc::LoadOptionsFile<vloc::ImageLimits>(config, "photo_limits");
  } catch (const vloc::ConfigError& e) {
    std::cerr << "uav_mosaic_files: " << e.what() << "\n";
    return 1;
  }
  int refusals = 0;  // photos and tags refused: the outputs hold the rest, the exit code is 2
  cv::Size survey_size;
  if (!args.Has("split")) {
    const vm::SurveyPhotos checked = vm::CheckSurveyPhotos(paths, limits);
    for (const auto& line : checked.refused) std::cerr << "uav_mosaic_files: " << line << "\n";
    refusals += static_cast<int>(checked.refused.size());
    if (checked.accepted.size() < 2) {
      std::cerr << "uav_mosaic_files: " << checked.accepted.size() << " of " << paths.size()
                << " photos usable: at least two are needed\n";
      return 1;
    }
    paths = checked.accepted;
    survey_size = checked.size;
  }
  // Images are read one at a time (a survey can hold thousands); --split needs its one image.
  std::string load_error;
  cv::Mat first = vm::LoadCheckedPhoto(paths[0], limits, survey_size, &load_error);
  if (first.empty()) {
    std::cerr << "uav_mosaic_files: " << load_error << "\n";
    return 1;
  }
  std::vector<cv::Mat> split_views;
  double true_scale = 0;
  std::vector<std::string> names = paths;
  if (args.Has("split")) {
    const cv::Mat src = first;
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
    split_views = {v1, v2};
    names = {paths[0] + " (view 1)", paths[0] + " (view 2)"};
    // View 1 px -> view 2 px is B^-1 A: scale 1/zoom (zoom out, lambda < 1), angle -angle.
    true_scale = 1.0 / zoom;
  }
  auto load = [&](size_t i) -> cv::Mat {
    if (!split_views.empty()) return split_views[i];
    return i == 0 ? first : vm::LoadCheckedPhoto(paths[i], limits, survey_size, &load_error);
  };
  const size_t count = split_views.empty() ? paths.size() : split_views.size();

  vm::MosaickerOptions options;
  try {
    if (args.Has("config")) options = vloc::LoadOptionsFile<vm::MosaickerOptions>(args.Get("config"), "mosaicker");
  } catch (const vloc::ConfigError& e) {
    std::cerr << "uav_mosaic_files: " << e.what() << "\n";
    return 1;
  }
  // Geotags.
  std::vector<FrameRecord> frames(count);
  int tagged = 0;
  for (size_t i = 0; i < count; ++i) {
    frames[i].name = names[i];
    if (!split_views.empty()) continue;
    std::string tag_error;
    if (!vm::ReadGeotag(paths[i], &frames[i].tag, &tag_error)) {
      std::cerr << "uav_mosaic_files: " << tag_error << " (geotags of this photo ignored)\n";
      frames[i].tag = vm::ImageGeotag();
    }
    for (const auto& line : frames[i].tag.refused)
      std::cerr << "uav_mosaic_files: " << paths[i] << ": " << line << " (this tag is not used)\n";
    refusals += static_cast<int>(frames[i].tag.refused.size());
    if (frames[i].tag.has_gps) ++tagged;
  }
  const bool use_gps = tagged >= 2 && !args.Has("no-gps");
  if (use_gps) MarkRepeatedFixes(&frames);
  const vm::ImageGeotag& tag0 = frames[0].tag;

  // Focal length: calibration file, --focal, EXIF, image width.
  const cv::Size size = split_views.empty() ? first.size() : split_views[0].size();
  std::string focal_source;
  if (args.Has("calibration")) {
    try {
      options.camera = vloc::LoadOptionsFile<vloc::PinholeCamera>(args.Get("calibration"));
    } catch (const vloc::ConfigError& e) {
      std::cerr << "uav_mosaic_files: " << e.what() << "\n";
      return 1;
    }
    if (options.camera.width != size.width || options.camera.height != size.height) {
      const double k = static_cast<double>(size.width) / options.camera.width;
      std::cout << "calibration " << options.camera.width << " x " << options.camera.height << " scaled by " << k
                << " to the photos' " << size.width << " x " << size.height << "\n";
      options.camera.fx *= k, options.camera.fy *= k, options.camera.cx = (options.camera.cx + 0.5) * k - 0.5;
      options.camera.cy = (options.camera.cy + 0.5) * k - 0.5;
      options.camera.width = size.width, options.camera.height = size.height;
    }
    focal_source = "the calibration file " + args.Get("calibration");
  } else {
    options.camera = vloc::PinholeCamera();
    options.camera.width = size.width;
    options.camera.height = size.height;
    options.camera.cx = (size.width - 1) / 2.0;
    options.camera.cy = (size.height - 1) / 2.0;
    std::string how;
    const double exif_focal = vm::FocalPixelsFromExif(tag0, size.width, &how);
    double f = size.width;
    if (args.Has("focal")) {
      f = args.GetDouble("focal", size.width);
      if (!(f > 0 && f < 1e6)) {
        std::cerr << "uav_mosaic_files: --focal " << args.Get("focal") << " is not a focal length in px (0, 1e6)\n";
        return 1;
      }
      focal_source = "--focal";
    } else if (std::isfinite(exif_focal)) {
      f = exif_focal;
      focal_source = how;
    } else {
      focal_source = "the image width (no calibration file, no --focal, EXIF has no focal length and sensor size: "
                     "heights are then only relative)";
    }
    options.camera.fx = options.camera.fy = f;
  }
  std::cout << "focal length " << options.camera.fx << " px from " << focal_source << "\n";

  // First height: marker, relative altitude, --height, 100 m.
  std::string height_source;
  double height = 100.0;
  options.calibration.source = "config";
  const vm::MarkerObservation marker = vm::DetectMarker(first, options.calibration);
  if (marker.found && split_views.empty()) {
    height = options.camera.fx * options.calibration.marker_size / marker.side_px;
    height_source = "the marker (id " + std::to_string(marker.id) + ", " + std::to_string(marker.side_px) +
                    " px for " + std::to_string(options.calibration.marker_size) + " m)";
  } else if (std::isfinite(tag0.relative_altitude) && tag0.relative_altitude > 0 && !args.Has("no-gps")) {
    height = tag0.relative_altitude;
    height_source = "the DJI relative altitude (XMP) of the first photo";
  } else if (args.Has("height")) {
    height = args.GetDouble("height", 100.0);
    if (!(height > 0 && height <= vm::GeotagRanges::kMaxAltitude)) {
      std::cerr << "uav_mosaic_files: --height " << args.Get("height") << " is not a height in (0, "
                << vm::GeotagRanges::kMaxAltitude << "] m\n";
      return 1;
    }
    height_source = "--height";
  } else {
    height_source = "the default (no marker, no relative altitude, no --height: heights are only relative)";
  }
  options.calibration.height = height;
  std::cout << "first height " << height << " m from " << height_source << "\n";
  options.canvas.metres_per_pixel = 0;
  if (!args.Has("config")) {
    options.canvas.resolution_factor = 1.0;
    options.mosaic_every_n_frames = 1;
    options.matcher.downscale = size.width > 1400 ? 1000.0 / size.width : 1.0;
  }
  if (!options.Check(&error)) {
    std::cerr << "uav_mosaic_files: " << error << "\n";
    return 1;
  }

  // Times: EXIF capture times when they increase, else one second apart.
  bool times_ok = split_views.empty();
  for (size_t i = 0; i < count && times_ok; ++i)
    times_ok = frames[i].tag.has_time && (i == 0 || frames[i].tag.utime > frames[i - 1].tag.utime);
  auto utime_of = [&](size_t i) -> int64_t {
    return times_ok ? frames[i].tag.utime - frames[0].tag.utime : static_cast<int64_t>(i) * 1000000;
  };
  const double gps_sigma = args.GetDouble("gps-sigma", 3.0);
  const vm::ImageGeotag* origin = nullptr;
  for (const auto& f : frames)
    if (f.tag.has_gps) {
      origin = &f.tag;
      break;
    }
  if (use_gps) {
    std::cout << tagged << " of " << count << " photos geotagged; " << (times_ok ? "EXIF capture times" : "one second per photo (EXIF times missing or not increasing)")
              << (drop_a >= 0 ? "; GPS dropped for frames " + std::to_string(drop_a) + "-" + std::to_string(drop_b) : "")
              << "\n";
  }

  vm::UavMosaicker mosaicker(options);
  int failures = 0;
  double processing_seconds = 0, decode_seconds = 0, tracking_seconds = 0, blending_seconds = 0;
  for (size_t i = 0; i < count; ++i) {
    FrameRecord& rec = frames[i];
    const auto t_decode = std::chrono::steady_clock::now();
    const cv::Mat image = load(i);
    decode_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t_decode).count();
    if (image.empty()) {
      std::cerr << "uav_mosaic_files: " << load_error << "; skipped\n";
      ++failures;
      continue;
    }
    const int64_t utime = utime_of(i);
    if (origin && rec.tag.has_gps)
      rec.enu = vm::LatLonToEnu(rec.tag.latitude, rec.tag.longitude, origin->latitude, origin->longitude);
    const auto t0 = std::chrono::steady_clock::now();
    const bool dropped = static_cast<int>(i) >= drop_a && static_cast<int>(i) <= drop_b;
    rec.dropped = dropped;
    if (use_gps && rec.tag.has_gps && !dropped && !rec.repeated_fix) {
      vm::GpsFix fix;
      fix.utime = utime;
      fix.valid = true;
      fix.latitude = rec.tag.latitude;
      fix.longitude = rec.tag.longitude;
      fix.altitude = std::isfinite(rec.tag.altitude) ? rec.tag.altitude : 0.0;
      fix.height_above_ground = rec.tag.relative_altitude;
      fix.horizontal_sigma = gps_sigma;
      mosaicker.AddGps(fix);
      rec.gps_used = true;
    }
    rec.state = mosaicker.ProcessFrame(image, utime);
    processing_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    tracking_seconds += rec.state.tracking_seconds;
    blending_seconds += rec.state.mosaic_seconds;
    const auto& s = rec.state;
    rec.registered = s.status == vm::TrackStatus::kTracking || s.status == vm::TrackStatus::kRecovered;
    std::cout << names[i] << ": " << vm::ToString(s.status) << (s.guided ? " (guided)" : "") << ", scale change "
              << s.scale << ", matches " << s.num_matches << ", inliers " << s.num_inliers << ", foreground "
              << s.num_foreground << ", centre at mosaic px (" << s.route_px.x << ", " << s.route_px.y << "), height "
              << s.height << " m" << (s.message.empty() ? "" : " (" + s.message + ")") << "\n";
    if (s.status == vm::TrackStatus::kLost) ++failures;
    if (i == 1 && true_scale > 0) {
      const double h = options.calibration.height;
      std::cout << "truth: scale change " << true_scale << " (height " << h / true_scale << " m); measured "
                << s.scale << " (height " << s.height_raw << " m), error " << 100 * (s.scale - true_scale) / true_scale
                << " %\n";
    }
  }
  int registered = 0;
  for (const auto& f : frames) registered += f.registered ? 1 : 0;

  const bool use_oblique = failures > 0 && !use_gps && !args.Has("split") && !args.Has("no-oblique");
  if (use_oblique) {
    // Fallback: pairwise affine-invariant registration, mosaic in image 1's frame.
    vm::ObliqueOptions oblique;
    oblique.num_threads = options.num_threads;
    std::vector<cv::Mat> images;
    for (size_t i = 0; i < count; ++i) images.push_back(load(i));
    std::vector<cv::Matx33d> ref_from_image{cv::Matx33d::eye()};
    failures = 0;
    for (size_t i = 1; i < images.size(); ++i) {
      const auto r = vm::RegisterOblique(images[i], images[i - 1], oblique);
      std::cout << names[i] << " -> " << names[i - 1] << " (affine-invariant fallback): " << r.BriefReport() << "\n";
      if (!r.ok) {
        ++failures;
        break;
      }
      ref_from_image.push_back(ref_from_image.back() * r.to_from_from);
      std::cout << "homography " << names[i] << " -> " << names[0] << ": " << cv::Mat(ref_from_image.back()).reshape(1, 1) << "\n";
    }
    std::vector<cv::Mat> placed(images.begin(), images.begin() + static_cast<long>(ref_from_image.size()));
    const cv::Mat mosaic = vm::MosaicByHomographies(placed, ref_from_image, images[0].size());
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
    std::vector<int> params;
    const std::string pp = args.Get("preview");
    if (pp.size() > 4 && (pp.substr(pp.size() - 4) == ".jpg" || pp.substr(pp.size() - 5) == ".jpeg")) {
      // JPEG: no alpha; uncovered parts white.
      if (!preview.empty() && preview.channels() == 4) {
        cv::Mat bgr(preview.size(), CV_8UC3, cv::Scalar(255, 255, 255));
        std::vector<cv::Mat> ch;
        cv::split(preview, ch);
        preview.copyTo(bgr);
        cv::cvtColor(preview, bgr, cv::COLOR_BGRA2BGR);
        bgr.setTo(cv::Scalar(255, 255, 255), ch[3] == 0);
        preview = bgr;
      }
      params = {cv::IMWRITE_JPEG_QUALITY, 85};
    }
    if (preview.empty() || !cv::imwrite(pp, preview, params)) {
      std::cerr << "uav_mosaic_files: cannot write preview " << pp << "\n";
      return 1;
    }
  }
  if (!use_oblique) std::cout << "mosaic: " << args.Get("out") << " (" << mosaicker.summary().BriefReport() << ")\n";
  if (!use_oblique)
    std::cout << "registered " << registered << " of " << count << " frames; " << count / std::max(1e-9, processing_seconds)
            << " frames/s registering and mosaicking (" << processing_seconds << " s; decoding "
            << decode_seconds << " s more; features + matching " << tracking_seconds << " s, blending " << blending_seconds
            << " s)\n";

  // Route and height against the GPS.
  if (origin && split_views.empty()) {
    std::vector<cv::Point2d> route, enu;
    std::vector<bool> usable, in_fit;
    std::vector<double> heights, gps_heights;
    const bool relative = std::isfinite(tag0.relative_altitude);
    for (const auto& f : frames) {
      route.push_back(f.state.route_px);
      enu.push_back(f.enu);
      usable.push_back(f.registered && f.tag.has_gps && !f.repeated_fix);
      in_fit.push_back(!f.dropped);
      heights.push_back(f.registered ? f.state.height : std::nan(""));
      gps_heights.push_back(relative ? f.tag.relative_altitude : f.tag.altitude);
    }
    vm::RouteFitOptions least_squares;
    least_squares.robust = false;
    const vm::RouteComparison ls = vm::CompareRouteToGps(route, enu, usable, in_fit, least_squares);
    const vm::RouteComparison rc = vm::CompareRouteToGps(route, enu, usable, in_fit);
    if (rc.ok) {
      std::cout << "route vs GPS (2-D similarity fit over " << ls.pairs << " frames): RMS " << ls.rms_m << " m = "
                << ls.rms_percent() << " % of the " << ls.path_m << " m path";
      if (ls.held_out > 0) std::cout << "; during the GPS drop-out (" << ls.held_out << " frames, not in the fit): RMS " << ls.held_out_rms_m << " m";
      std::cout << "\nroute vs GPS, robust fit: " << rc.gps_outliers << " GPS fixes off the route by more than 3 robust sigmas"
                << " (frames";
      for (int i : rc.outlier_frames) std::cout << " " << i;
      std::cout << "), RMS over the other " << rc.pairs - rc.gps_outliers << " " << rc.inlier_rms_m << " m = "
                << rc.inlier_rms_percent() << " %, over all " << rc.rms_m << " m = " << rc.rms_percent() << " %";
      if (rc.held_out > 0) std::cout << "; drop-out RMS " << rc.held_out_rms_m << " m";
      std::cout << "\n";
    } else {
      std::cout << "route vs GPS: " << rc.why << "\n";
    }
    // Without a relative altitude the GPS altitude is above sea level over
    // unknown ground, and the first height may be a guess: the heights are
    // put on the GPS track's scale (the tie's metres per mosaic px, h = s r f)
    // and compared with the altitude minus a fitted ground level.
    if (!relative && rc.ok && mosaicker.metres_per_pixel() > 0) {
      const double k = rc.enu_from_flipped.Scale() / mosaicker.metres_per_pixel();
      for (auto& h : heights) h *= k;
      std::cout << "heights on the GPS track's scale: first height " << options.calibration.height * k << " m (x " << k
                << ")\n";
    }
    if (rc.ok && args.Has("reference")) CompareWithReference(args.Get("reference"), frames, paths, ls, limits);
    const vm::HeightComparison hc = vm::CompareHeights(heights, gps_heights, !relative);
    if (hc.ok) {
      std::cout << "height vs GPS " << (relative ? "relative altitude" : "altitude minus a fitted ground level (" + std::to_string(hc.offset_m) + " m)")
                << " over " << hc.pairs << " frames: RMS " << hc.rms_m << " m = " << hc.rms_percent << " %\n";
    }
    if (args.Has("report")) {
      std::ofstream out(args.Get("report"));
      out << "frame\tname\tstatus\tguided\tgps_used\troute_east_m\troute_north_m\tgps_east_m\tgps_north_m\tresidual_m\theight_m\tgps_height_m\tmatches\tinliers\tmessage\n";
      out << std::setprecision(8);
      for (size_t i = 0; i < frames.size(); ++i) {
        const auto& f = frames[i];
        const cv::Point2d e = rc.ok ? rc.enu_from_flipped.Apply({f.state.route_px.x, -f.state.route_px.y}) : cv::Point2d();
        out << i << "\t" << std::filesystem::path(f.name).filename().string() << "\t" << vm::ToString(f.state.status) << "\t"
            << f.state.guided << "\t" << f.gps_used << "\t" << e.x << "\t" << e.y << "\t" << f.enu.x << "\t" << f.enu.y
            << "\t" << (rc.ok && i < rc.residual_m.size() ? rc.residual_m[i] : std::nan("")) << "\t" << heights[i]
            << "\t" << (hc.ok ? gps_heights[i] - hc.offset_m : std::nan("")) << "\t" << f.state.num_matches << "\t"
            << f.state.num_inliers << "\t" << f.state.message << "\n";
      }
      if (!out) {
        std::cerr << "uav_mosaic_files: cannot write report " << args.Get("report") << "\n";
        return 1;
      }
    }
  }
  if (args.Has("geotiff")) {
    if (!mosaicker.WriteGeoTiff(args.Get("geotiff"), &error)) {
      std::cerr << "uav_mosaic_files: " << error << "\n";
      return 1;
    }
    std::cout << "GeoTIFF: " << args.Get("geotiff") << "\n";
  }
  if (args.Has("geojson")) {
    std::vector<vm::GeoFrame> geo;
    for (size_t i = 0; i < frames.size(); ++i) {
      const auto& f = frames[i];
      vm::GeoFrame g;
      g.name = std::filesystem::path(f.name).filename().string();
      g.index = static_cast<int>(i);
      g.status = vm::ToString(f.state.status);
      g.height = f.state.height;
      g.registered = f.registered;
      cv::Point2d ll;
      if (f.registered && mosaicker.MosaicToLatLon(f.state.route_px, &ll)) {
        g.latitude = ll.x, g.longitude = ll.y;
      } else if (f.tag.has_gps) {
        g.latitude = f.tag.latitude, g.longitude = f.tag.longitude;
      } else {
        continue;
      }
      geo.push_back(g);
    }
    if (geo.empty() || !vm::WriteRouteGeoJson(geo, args.Get("geojson"), &error)) {
      std::cerr << "uav_mosaic_files: " << (geo.empty() ? "no GeoJSON: the flight is not tied to GPS" : error) << "\n";
      return 1;
    }
    std::cout << "GeoJSON: " << args.Get("geojson") << "\n";
  }
  return failures == 0 && refusals == 0 ? 0 : 2;
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  return vloc::RunTool("uav_mosaic_files", [&] { return Run(argc, argv); });
}
