// SurveyRunner: uav_mosaic_files' survey, step by step (survey_runner.h).
#include "vloc/mosaic/survey_runner.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>

#include "vloc/common/options.h"
#include "vloc/mosaic/calibration.h"
#include "vloc/mosaic/gis_export.h"
#include "vloc/mosaic/oblique_registration.h"
#include "vloc/mosaic/survey_photos.h"

namespace vloc::mosaic {

namespace {
std::ostream& NullStream() {
  static std::ostream null(nullptr);
  return null;
}
double SecondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

SurveyOptions LoadSurveyOptions(const std::string& config_path) {
  SurveyOptions o;
  o.mosaicker = LoadOptionsFile<MosaickerOptions>(config_path, "mosaicker");
  const YAML::Node root = LoadYamlFile(config_path);
  if (root["photo_limits"]) o.limits = LoadOptionsFile<ImageLimits>(config_path, "photo_limits");
  if (root["altitude_fusion"]) o.altitude_fusion = LoadOptionsFile<AltitudeFusionOptions>(config_path, "altitude_fusion");
  return o;
}

SurveyRunner::SurveyRunner(const SurveyOptions& options, std::ostream* out, std::ostream* err)
    : options_(options), out_(out), err_(err) {}

SurveyRunner::~SurveyRunner() = default;

std::ostream& SurveyRunner::Out() const { return out_ ? *out_ : NullStream(); }
std::ostream& SurveyRunner::Err() const { return err_ ? *err_ : NullStream(); }

int SurveyRunner::registered() const {
  int n = 0;
  for (const auto& f : frames_) n += f.registered ? 1 : 0;
  return n;
}

bool SurveyRunner::LoadPhotos(const std::vector<std::string>& paths) {
  // Every header before any photo is decoded: limits, and one size for the survey.
  const SurveyPhotos checked = CheckSurveyPhotos(paths, options_.limits, /*one_size=*/false);
  for (const auto& line : checked.refused) Err() << "uav_mosaic_files: " << line << "\n";
  refusals_ += static_cast<int>(checked.refused.size());
  if (checked.accepted.size() < 2) {
    Err() << "uav_mosaic_files: " << checked.accepted.size() << " of " << paths.size()
          << " photos usable: at least two are needed\n";
    return false;
  }
  paths_ = checked.accepted;
  sizes_ = checked.sizes;
  size_ = checked.size;
  frames_.assign(paths_.size(), SurveyFrame());
  for (size_t i = 0; i < paths_.size(); ++i) frames_[i].name = paths_[i];
  ReadGeotags();
  return true;
}

void SurveyRunner::LoadViews(const std::vector<std::string>& names, const std::vector<cv::Mat>& views) {
  views_ = views;
  first_ = views.at(0);
  size_ = first_.size();
  frames_.assign(views.size(), SurveyFrame());
  for (size_t i = 0; i < views.size(); ++i) frames_[i].name = names.at(i);
  tagged_ = 0;  // views carry no geotags: no GPS
}

// Images are read one at a time (a survey can hold thousands), each brought to the survey's camera.
cv::Mat SurveyRunner::Load(size_t i, std::string* error) const {
  if (!views_.empty()) return views_[i];
  if (i == 0 && !first_.empty()) return first_;
  const cv::Mat photo = LoadCheckedPhoto(paths_[i], options_.limits, sizes_[i], error);
  return i < fits_.size() ? ApplyCameraFit(photo, fits_[i], size_) : photo;
}

void SurveyRunner::ReadGeotags() {
  for (size_t i = 0; i < frames_.size(); ++i) {
    std::string tag_error;
    if (!ReadGeotag(paths_[i], &frames_[i].tag, &tag_error)) {
      Err() << "uav_mosaic_files: " << tag_error << " (geotags of this photo ignored)\n";
      frames_[i].tag = ImageGeotag();
    }
    for (const auto& line : frames_[i].tag.refused)
      Err() << "uav_mosaic_files: " << paths_[i] << ": " << line << " (this tag is not used)\n";
    refusals_ += static_cast<int>(frames_[i].tag.refused.size());
    if (frames_[i].tag.has_gps) ++tagged_;
  }
  if (UseGps()) MarkRepeatedFixes();
}

// A camera's GPS may tag a photo with the fix it already gave the previous
// photo (same GPSTimeStamp, same position): that is no position for this
// photo, and using it would put the photo a whole step behind.
void SurveyRunner::MarkRepeatedFixes() {
  int repeated = 0;
  for (size_t i = 1; i < frames_.size(); ++i) {
    const auto& a = frames_[i - 1].tag;
    auto& b = frames_[i];
    b.repeated_fix = a.has_gps && b.tag.has_gps && a.has_gps_time && b.tag.has_gps_time &&
                     a.gps_utime == b.tag.gps_utime && a.latitude == b.tag.latitude && a.longitude == b.tag.longitude;
    if (b.repeated_fix) {
      Out() << b.name << ": GPS tag repeats the previous photo's fix (same GPS time): not used\n";
      ++repeated;
    }
  }
  if (repeated > 0) Out() << repeated << " repeated GPS fixes left out\n";
}

// Focal length: calibration file, focal_px, EXIF, image width.
bool SurveyRunner::ChooseCamera() {
  PinholeCamera& camera = options_.mosaicker.camera;
  const cv::Size size = size_;
  std::string focal_source;
  if (!options_.calibration_file.empty()) {
    try {
      camera = LoadOptionsFile<PinholeCamera>(options_.calibration_file);
    } catch (const ConfigError& e) {
      Err() << "uav_mosaic_files: " << e.what() << "\n";
      return false;
    }
    if (camera.width != size.width || camera.height != size.height) {
      const double k = static_cast<double>(size.width) / camera.width;
      Out() << "calibration " << camera.width << " x " << camera.height << " scaled by " << k << " to the photos' "
            << size.width << " x " << size.height << "\n";
      camera.fx *= k, camera.fy *= k, camera.cx = (camera.cx + 0.5) * k - 0.5;
      camera.cy = (camera.cy + 0.5) * k - 0.5;
      camera.width = size.width, camera.height = size.height;
    }
    focal_source = "the calibration file " + options_.calibration_file;
  } else {
    camera = PinholeCamera();
    camera.width = size.width;
    camera.height = size.height;
    camera.cx = (size.width - 1) / 2.0;
    camera.cy = (size.height - 1) / 2.0;
    std::string how;
    const size_t ref = ReferencePhoto();
    const double exif_focal = ref < frames_.size() ? FocalPixelsFromExif(frames_[ref].tag, size.width, &how) : std::nan("");
    double f = size.width;
    if (options_.focal_px) {
      f = *options_.focal_px;
      if (!(f > 0 && f < 1e6)) {
        Err() << "uav_mosaic_files: --focal " << f << " is not a focal length in px (0, 1e6)\n";
        return false;
      }
      focal_source = "--focal";
    } else if (std::isfinite(exif_focal)) {
      f = exif_focal;
      focal_source = how;
    } else {
      focal_source = "the image width (no calibration file, no --focal, EXIF has no focal length and sensor size: "
                     "heights are then only relative)";
    }
    camera.fx = camera.fy = f;
  }
  Out() << "focal length " << camera.fx << " px from " << focal_source << "\n";
  return FitCameras();
}

size_t SurveyRunner::ReferencePhoto() const {
  for (size_t i = 0; i < sizes_.size(); ++i)
    if (sizes_[i] == size_) return i;
  return 0;
}

// Photos of another camera (size, focal length: a second flight) are
// resampled to the survey camera's focal and cropped to its size; those
// that would not cover its frame are refused by name.
bool SurveyRunner::FitCameras() {
  if (!views_.empty()) return true;
  const double f = options_.mosaicker.camera.fx;
  const size_t ref = ReferencePhoto();
  const double ref_exif = ref < frames_.size() ? FocalPixelsFromExif(frames_[ref].tag, size_.width, nullptr) : std::nan("");
  std::vector<SurveyFrame> frames;
  std::vector<std::string> paths;
  std::vector<cv::Size> sizes;
  int refitted = 0;
  for (size_t i = 0; i < sizes_.size(); ++i) {
    const double exif = FocalPixelsFromExif(frames_[i].tag, sizes_[i].width, nullptr);
    const double focal = std::isfinite(exif) && std::isfinite(ref_exif) ? f * exif / ref_exif
                                                                        : f * sizes_[i].width / size_.width;
    CameraFit fit;
    std::string why;
    if (!FitCamera(sizes_[i], focal, size_, f, &fit, &why)) {
      Err() << "uav_mosaic_files: " << paths_[i] << ": " << why << "; skipped\n";
      ++refusals_;
      tagged_ -= frames_[i].tag.has_gps ? 1 : 0;
      continue;
    }
    if (!fit.identity()) ++refitted;
    frames.push_back(frames_[i]), paths.push_back(paths_[i]), sizes.push_back(sizes_[i]), fits_.push_back(fit);
  }
  frames_.swap(frames), paths_.swap(paths), sizes_.swap(sizes);
  if (refitted > 0)
    Out() << refitted << " photos of another camera resampled to the survey's " << size_.width << " x " << size_.height
          << " px at " << f << " px focal length\n";
  if (frames_.size() < 2) {
    Err() << "uav_mosaic_files: " << frames_.size() << " photos usable: at least two are needed\n";
    return false;
  }
  std::string error;
  first_ = Load(0, &error);
  if (first_.empty()) {
    Err() << "uav_mosaic_files: " << error << "\n";
    return false;
  }
  return true;
}

// First height: marker, relative altitude, height_m, 100 m.
bool SurveyRunner::ChooseFirstHeight() {
  MosaickerOptions& o = options_.mosaicker;
  const ImageGeotag& tag0 = frames_.at(0).tag;
  std::string height_source;
  double height = 100.0;
  o.calibration.source = "config";
  const MarkerObservation marker = DetectMarker(first_, o.calibration);
  if (marker.found && views_.empty()) {
    height = o.camera.fx * o.calibration.marker_size / marker.side_px;
    height_source = "the marker (id " + std::to_string(marker.id) + ", " + std::to_string(marker.side_px) +
                    " px for " + std::to_string(o.calibration.marker_size) + " m)";
  } else if (std::isfinite(tag0.relative_altitude) && tag0.relative_altitude > 0 && options_.use_gps) {
    height = tag0.relative_altitude;
    height_source = "the DJI relative altitude (XMP) of the first photo";
  } else if (options_.height_m) {
    height = *options_.height_m;
    if (!(height > 0 && height <= GeotagRanges::kMaxAltitude)) {
      Err() << "uav_mosaic_files: --height " << height << " is not a height in (0, " << GeotagRanges::kMaxAltitude
            << "] m\n";
      return false;
    }
    height_source = "--height";
  } else {
    height_source = "the default (no marker, no relative altitude, no --height: heights are only relative)";
  }
  o.calibration.height = height;
  Out() << "first height " << height << " m from " << height_source << "\n";
  o.canvas.metres_per_pixel = 0;
  std::string error;
  if (!o.Check(&error)) {
    Err() << "uav_mosaic_files: " << error << "\n";
    return false;
  }
  return true;
}

// Times: EXIF capture times when they increase, else one second apart.
void SurveyRunner::ChooseTimes() {
  times_ok_ = views_.empty();
  for (size_t i = 0; i < frames_.size() && times_ok_; ++i)
    times_ok_ = frames_[i].tag.has_time && (i == 0 || frames_[i].tag.utime > frames_[i - 1].tag.utime);
  origin_ = nullptr;
  for (const auto& f : frames_)
    if (f.tag.has_gps) {
      origin_ = &f.tag;
      break;
    }
  const double gap = options_.mosaicker.reseat_after_gap_s;
  for (size_t i = 1; i < frames_.size() && times_ok_ && gap > 0; ++i) {
    const double seconds = (frames_[i].tag.utime - frames_[i - 1].tag.utime) * 1e-6;
    if (seconds >= gap)
      Out() << frames_[i].name << ": taken " << seconds << " s after the previous photo: a new flight (a photo that "
            << "matches nothing is placed by its GPS)\n";
  }
  if (UseGps()) {
    const int a = options_.drop_gps_first, b = options_.drop_gps_last;
    Out() << tagged_ << " of " << frames_.size() << " photos geotagged; "
          << (times_ok_ ? "EXIF capture times" : "one second per photo (EXIF times missing or not increasing)")
          << (a >= 0 ? "; GPS dropped for frames " + std::to_string(a) + "-" + std::to_string(b) : "") << "\n";
  }
}

struct SurveyRunner::Loaded {
  PreparedFrame frame;
  std::string error;       // when the photo could not be read
  double decode_seconds = 0;
};

SurveyRunner::Loaded SurveyRunner::Prepare(size_t i, FramePreparer* preparer) const {
  Loaded loaded;
  const auto t0 = std::chrono::steady_clock::now();
  const cv::Mat image = Load(i, &loaded.error);
  loaded.decode_seconds = SecondsSince(t0);
  if (!image.empty()) loaded.frame = preparer->Prepare(image);
  return loaded;
}

// Photo i registers while photo i + 1 is decoded and its features found (prefetch).
void SurveyRunner::RegisterAll() {
  ChooseTimes();
  mosaicker_ = std::make_unique<UavMosaicker>(options_.mosaicker);
  if (options_.keep_height_observations) mosaicker_->KeepHeightObservations();
  FramePreparer preparer(options_.mosaicker);
  const auto t0 = std::chrono::steady_clock::now();
  auto prepare = [this, &preparer](size_t i) { return Prepare(i, &preparer); };
  std::future<Loaded> next;
  if (options_.prefetch && !frames_.empty()) next = std::async(std::launch::async, prepare, 0);
  for (size_t i = 0; i < frames_.size(); ++i) {
    Loaded loaded = options_.prefetch ? next.get() : prepare(i);
    if (options_.prefetch && i + 1 < frames_.size()) next = std::async(std::launch::async, prepare, i + 1);
    RegisterOne(i, std::move(loaded));
  }
  mosaicker_->FlushMosaic();
  mosaicker_->FinishHeights();
  times_.wall = SecondsSince(t0);
  times_.blending = mosaicker_->summary().blend_seconds;
}

void SurveyRunner::RegisterOne(size_t i, Loaded loaded) {
  SurveyFrame& rec = frames_[i];
  times_.decoding += loaded.decode_seconds;
  times_.features += loaded.frame.seconds;
  if (!loaded.error.empty()) {
    Err() << "uav_mosaic_files: " << loaded.error << "; skipped\n";
    ++failures_;
    return;
  }
  const int64_t utime = rec.utime =
      times_ok_ ? rec.tag.utime - frames_[0].tag.utime : static_cast<int64_t>(i) * 1000000;
  if (origin_ && rec.tag.has_gps)
    rec.enu = LatLonToEnu(rec.tag.latitude, rec.tag.longitude, origin_->latitude, origin_->longitude);
  rec.dropped = static_cast<int>(i) >= options_.drop_gps_first && static_cast<int>(i) <= options_.drop_gps_last;
  if (UseGps() && rec.tag.has_gps && !rec.dropped && !rec.repeated_fix) {
    GpsFix fix;
    fix.utime = utime;
    fix.valid = true;
    fix.latitude = rec.tag.latitude;
    fix.longitude = rec.tag.longitude;
    fix.altitude = std::isfinite(rec.tag.altitude) ? rec.tag.altitude : 0.0;
    fix.height_above_ground = rec.tag.relative_altitude;
    fix.horizontal_sigma = options_.gps_sigma;
    mosaicker_->AddGps(fix);
    rec.gps_used = true;
  }
  rec.state = mosaicker_->ProcessFrame(std::move(loaded.frame), utime);
  times_.registration += rec.state.tracking_seconds - rec.state.features_seconds;
  const auto& s = rec.state;
  rec.registered = s.status == TrackStatus::kTracking || s.status == TrackStatus::kRecovered;
  Out() << rec.name << ": " << ToString(s.status) << (s.guided ? " (guided)" : "") << ", scale change " << s.scale
        << ", matches " << s.num_matches << ", inliers " << s.num_inliers << ", foreground " << s.num_foreground
        << ", centre at mosaic px (" << s.route_px.x << ", " << s.route_px.y << "), height " << s.height << " m"
        << (s.message.empty() ? "" : " (" + s.message + ")") << "\n";
  if (s.status == TrackStatus::kLost) ++failures_;
}

bool SurveyRunner::WriteMosaic(const std::string& png_path) {
  used_oblique_ = failures_ > 0 && !UseGps() && views_.empty() && options_.oblique_fallback;
  if (used_oblique_) return WriteObliqueMosaic(png_path);
  std::string error;
  if (!mosaicker_->WriteMosaic(png_path, &error)) {
    Err() << "uav_mosaic_files: " << error << "\n";
    return false;
  }
  return true;
}

// Fallback: pairwise affine-invariant registration, mosaic in image 1's frame.
bool SurveyRunner::WriteObliqueMosaic(const std::string& png_path) {
  ObliqueOptions oblique;
  oblique.num_threads = options_.mosaicker.num_threads;
  std::vector<cv::Mat> images;
  for (size_t i = 0; i < frames_.size(); ++i) images.push_back(Load(i, nullptr));
  std::vector<cv::Matx33d> ref_from_image{cv::Matx33d::eye()};
  failures_ = 0;
  for (size_t i = 1; i < images.size(); ++i) {
    const auto r = RegisterOblique(images[i], images[i - 1], oblique);
    Out() << frames_[i].name << " -> " << frames_[i - 1].name << " (affine-invariant fallback): " << r.BriefReport()
          << "\n";
    if (!r.ok) {
      ++failures_;
      break;
    }
    ref_from_image.push_back(ref_from_image.back() * r.to_from_from);
    Out() << "homography " << frames_[i].name << " -> " << frames_[0].name << ": "
          << cv::Mat(ref_from_image.back()).reshape(1, 1) << "\n";
  }
  std::vector<cv::Mat> placed(images.begin(), images.begin() + static_cast<long>(ref_from_image.size()));
  const cv::Mat mosaic = MosaicByHomographies(placed, ref_from_image, images[0].size());
  if (mosaic.empty() || !cv::imwrite(png_path, mosaic)) {
    Err() << "uav_mosaic_files: cannot write mosaic " << png_path << "\n";
    return false;
  }
  Out() << "mosaic of " << placed.size() << " images (homographies, multi-band blended): " << png_path << " ("
        << mosaic.cols << " x " << mosaic.rows << " px)\n";
  return true;
}

void SurveyRunner::PrintSummary(const std::string& png_path) const {
  if (used_oblique_) return;
  const size_t count = frames_.size();
  Out() << "mosaic: " << png_path << " (" << mosaicker_->summary().BriefReport() << ")\n";
  Out() << "registered " << registered() << " of " << count << " frames; " << count / std::max(1e-9, times_.wall)
        << " frames/s decoding, registering and mosaicking (" << times_.wall << " s wall"
        << (options_.prefetch ? ", the next photo decoded and its features found meanwhile" : "") << "; decoding "
        << times_.decoding << " s, features " << times_.features << " s, registration " << times_.registration
        << " s, blending " << times_.blending << " s)\n";
}

void SurveyRunner::Evaluate(const SurveyReferences& references) {
  if (!origin_ || !views_.empty()) {
    if (!references.heights.empty())
      Err() << "uav_mosaic_files: the height reference is not compared: no photo carries GPS (the heights have no "
               "metric scale)\n";
    return;
  }
  SurveyFigures& fig = figures_;
  fig.evaluated = true;
  std::vector<cv::Point2d> route, enu;
  std::vector<bool> usable, in_fit;
  fig.relative_altitude = std::isfinite(frames_.at(0).tag.relative_altitude);
  for (const auto& f : frames_) {
    route.push_back(f.state.route_px);
    enu.push_back(f.enu);
    usable.push_back(f.registered && f.tag.has_gps && !f.repeated_fix);
    in_fit.push_back(!f.dropped);
    // With height ties, every height from the graph as solved at the end (later ties correct earlier frames).
    fig.heights.push_back(f.registered ? mosaicker_->AdjustedHeight(f.state.frame_index).value_or(f.state.height)
                                       : std::nan(""));
    fig.gps_heights.push_back(fig.relative_altitude ? f.tag.relative_altitude : f.tag.altitude);
  }
  RouteFitOptions least_squares;
  least_squares.robust = false;
  const RouteComparison& ls = fig.route_least_squares = CompareRouteToGps(route, enu, usable, in_fit, least_squares);
  const RouteComparison& rc = fig.route = CompareRouteToGps(route, enu, usable, in_fit);
  if (rc.ok) {
    Out() << "route vs GPS (2-D similarity fit over " << ls.pairs << " frames): RMS " << ls.rms_m << " m = "
          << ls.rms_percent() << " % of the " << ls.path_m << " m path";
    if (ls.held_out > 0)
      Out() << "; during the GPS drop-out (" << ls.held_out << " frames, not in the fit): RMS " << ls.held_out_rms_m << " m";
    Out() << "\nroute vs GPS, robust fit: " << rc.gps_outliers << " GPS fixes off the route by more than 3 robust sigmas"
          << " (frames";
    for (int i : rc.outlier_frames) Out() << " " << i;
    Out() << "), RMS over the other " << rc.pairs - rc.gps_outliers << " " << rc.inlier_rms_m << " m = "
          << rc.inlier_rms_percent() << " %, over all " << rc.rms_m << " m = " << rc.rms_percent() << " %";
    if (rc.held_out > 0) Out() << "; drop-out RMS " << rc.held_out_rms_m << " m";
    Out() << "\n";
  } else {
    Out() << "route vs GPS: " << rc.why << "\n";
  }
  // Without a relative altitude the GPS altitude is above sea level over
  // unknown ground, and the first height may be a guess: the heights are
  // put on the GPS track's scale (the tie's metres per mosaic px, h = s r f)
  // and compared with the altitude minus a fitted ground level.
  if (!fig.relative_altitude && rc.ok && mosaicker_->metres_per_pixel() > 0) {
    fig.height_scale = rc.enu_from_flipped.Scale() / mosaicker_->metres_per_pixel();
    for (auto& h : fig.heights) h *= fig.height_scale;
    Out() << "heights on the GPS track's scale: first height " << options_.mosaicker.calibration.height * fig.height_scale
          << " m (x " << fig.height_scale << ")\n";
  }
  if (rc.ok && !references.orthomosaic.empty()) CompareWithReference(references.orthomosaic);
  CompareHeightsWithTags();
  if (!references.heights.empty()) CompareHeightsWithReference(references);
}

// Vision heights (the tags withheld after the first height) against the
// altitude tags, then the tags fused with them (altitude_fusion.h) and the
// fused heights against the tags.
void SurveyRunner::CompareHeightsWithTags() {
  SurveyFigures& fig = figures_;
  const bool fit_ground = !fig.relative_altitude;
  const HeightComparison& hc = fig.height = CompareHeights(fig.heights, fig.gps_heights, fit_ground);
  if (!hc.ok) return;
  const std::string against =
      fig.relative_altitude ? "relative altitude" : "altitude minus a fitted ground level (" + std::to_string(hc.offset_m) + " m)";
  Out() << "height vs GPS " << against << " over " << hc.pairs << " frames: RMS " << hc.rms_m << " m = " << hc.rms_percent
        << " % (vision only)\n";
  std::vector<double> seconds;
  for (const auto& f : frames_) seconds.push_back(f.utime * 1e-6);
  fig.fusion = FuseAltitude(seconds, fig.heights, fig.gps_heights, fig.relative_altitude, options_.altitude_fusion);
  Out() << "heights: " << fig.fusion.why << "\n";
  if (!fig.fusion.fused) return;
  const HeightComparison& fc = fig.fused_height = CompareHeights(fig.fusion.height_m, fig.gps_heights, fit_ground);
  if (fc.ok)
    Out() << "height vs GPS " << against << " over " << fc.pairs << " frames: RMS " << fc.rms_m << " m = "
          << fc.rms_percent << " % (fused)\n";
}

// The vision heights, the fused ones and the altitude tags against another
// tool's heights above the ground, over the registered frames it holds
// (matched by file name), each with a constant offset fitted; the vision
// heights also without it.
void SurveyRunner::CompareHeightsWithReference(const SurveyReferences& references) {
  SurveyFigures& fig = figures_;
  std::vector<double> truth(frames_.size(), std::nan(""));
  for (size_t i = 0; i < frames_.size(); ++i) {
    const auto it = references.heights.find(std::filesystem::path(frames_[i].name).filename().string());
    if (it != references.heights.end() && std::isfinite(fig.heights[i])) truth[i] = it->second;
  }
  fig.reference_vision = CompareHeights(fig.heights, truth, true);
  if (!fig.reference_vision.ok) {
    Err() << "uav_mosaic_files: the height reference " << references.heights_path
          << " names no registered photo of the survey (photos are matched by file name)\n";
    return;
  }
  fig.reference_vision_raw = CompareHeights(fig.heights, truth, false);
  // The tags as the reference is compared with them: altitude minus a fitted ground level, as a percentage of it.
  fig.reference_tags = CompareHeights(truth, fig.gps_heights, true);
  if (fig.fusion.fused) fig.reference_fused = CompareHeights(fig.fusion.height_m, truth, true);
  const HeightComparison& v = fig.reference_vision;
  Out() << "height vs the reference heights above the ground over " << v.pairs << " frames (an offset fitted, "
        << v.offset_m << " m): RMS " << v.rms_m << " m = " << v.rms_percent << " % (vision only; "
        << fig.reference_vision_raw.rms_percent << " % without the offset)";
  if (fig.reference_fused.ok) Out() << ", " << fig.reference_fused.rms_percent << " % (fused)";
  if (fig.reference_tags.ok) Out() << "; the altitude tags " << fig.reference_tags.rms_percent << " %";
  Out() << "\n";
}

// Route and GPS against a reference orthomosaic of the same flight made by
// another tool: each registered photo located in it, then both fitted to it
// by a 2-D similarity (the reference's scale and orientation are unknown).
void SurveyRunner::CompareWithReference(const std::string& reference_path) {
  std::string why;
  cv::Mat reference = LoadCheckedPhoto(reference_path, options_.limits, cv::Size(), &why);
  if (reference.empty()) {
    Err() << "uav_mosaic_files: the reference orthomosaic " << why << "\n";
    return;
  }
  cv::cvtColor(reference, reference, cv::COLOR_BGR2GRAY);
  const ReferenceLocator locator(reference);
  const RouteComparison& route_vs_gps = figures_.route_least_squares;
  std::vector<ReferenceFix> fixes(frames_.size());
  std::vector<cv::Point2d> route_m(frames_.size()), gps_m(frames_.size());
  std::vector<bool> with_gps(frames_.size(), false);
  for (size_t i = 0; i < frames_.size(); ++i) {
    if (!frames_[i].registered) continue;
    fixes[i] = locator.Locate(LoadCheckedPhoto(paths_[i], options_.limits, cv::Size(), nullptr));
    route_m[i] = route_vs_gps.enu_from_flipped.Apply({frames_[i].state.route_px.x, -frames_[i].state.route_px.y});
    gps_m[i] = frames_[i].enu;
    with_gps[i] = frames_[i].tag.has_gps && !frames_[i].repeated_fix;
  }
  const ReferenceComparison& c = reference_ = vloc::mosaic::CompareWithReference(fixes, route_m, gps_m, with_gps);
  Out() << "reference orthomosaic " << reference_path << " (" << locator.reference_features() << " features): "
        << c.located << " registered photos located in it\n";
  if (!c.route.ok || !c.gps.ok) {
    Out() << "reference comparison: " << (c.route.ok ? c.gps.why : c.route.why) << "\n";
    return;
  }
  const double path = route_vs_gps.path_m;  // the GPS path of the whole flight, as in the route-vs-GPS figure
  Out() << "route vs reference (2-D similarity): RMS " << c.route.rms_m << " m = " << 100 * c.route.rms_m / path
        << " % of the " << path << " m path; GPS vs reference: RMS " << c.gps.rms_m << " m = "
        << 100 * c.gps.rms_m / path << " %\n";
}

double SurveyRunner::FusedHeight(size_t i) const {
  const AltitudeFusion& f = figures_.fusion;
  return f.fused && i < f.height_m.size() ? f.height_m[i] : std::nan("");
}

bool SurveyRunner::WriteReport(const std::string& tsv_path) {
  if (!figures_.evaluated) return true;
  const RouteComparison& rc = figures_.route;
  const HeightComparison& hc = figures_.height;
  const AltitudeFusion& fusion = figures_.fusion;
  std::ofstream out(tsv_path);
  out << "frame\tname\tstatus\tguided\tgps_used\troute_east_m\troute_north_m\tgps_east_m\tgps_north_m\tresidual_m\theight_m"
         "\tgps_height_m\tfused_height_m\theight_source\tmatches\tinliers\tmessage\n";
  out << std::setprecision(8);
  for (size_t i = 0; i < frames_.size(); ++i) {
    const auto& f = frames_[i];
    const cv::Point2d e = rc.ok ? rc.enu_from_flipped.Apply({f.state.route_px.x, -f.state.route_px.y}) : cv::Point2d();
    out << i << "\t" << std::filesystem::path(f.name).filename().string() << "\t" << ToString(f.state.status) << "\t"
        << f.state.guided << "\t" << f.gps_used << "\t" << e.x << "\t" << e.y << "\t" << f.enu.x << "\t" << f.enu.y
        << "\t" << (rc.ok && i < rc.residual_m.size() ? rc.residual_m[i] : std::nan("")) << "\t" << figures_.heights[i]
        << "\t" << (hc.ok ? figures_.gps_heights[i] - hc.offset_m : std::nan("")) << "\t" << FusedHeight(i) << "\t"
        << ToString(i < fusion.source.size() ? fusion.source[i] : HeightSource::kNone) << "\t" << f.state.num_matches
        << "\t" << f.state.num_inliers << "\t" << f.state.message << "\n";
  }
  if (!out) {
    Err() << "uav_mosaic_files: cannot write report " << tsv_path << "\n";
    return false;
  }
  return true;
}

bool SurveyRunner::WriteGeoTiff(const std::string& tif_path) {
  std::string error;
  if (!mosaicker_->WriteGeoTiff(tif_path, &error)) {
    Err() << "uav_mosaic_files: " << error << "\n";
    return false;
  }
  Out() << "GeoTIFF: " << tif_path << "\n";
  return true;
}

// Each frame at its registered place, else at its GPS position (unregistered).
bool SurveyRunner::WriteGeoJson(const std::string& geojson_path) {
  std::vector<GeoFrame> geo;
  for (size_t i = 0; i < frames_.size(); ++i) {
    const auto& f = frames_[i];
    GeoFrame g;
    g.name = std::filesystem::path(f.name).filename().string();
    g.index = static_cast<int>(i);
    g.status = ToString(f.state.status);
    g.height = std::isfinite(FusedHeight(i)) ? FusedHeight(i) : f.state.height;
    g.registered = f.registered;
    cv::Point2d ll;
    if (f.registered && mosaicker_->MosaicToLatLon(f.state.route_px, &ll)) {
      g.latitude = ll.x, g.longitude = ll.y;
    } else if (f.tag.has_gps) {
      g.latitude = f.tag.latitude, g.longitude = f.tag.longitude;
    } else {
      continue;
    }
    geo.push_back(g);
  }
  std::string error;
  if (geo.empty() || !WriteRouteGeoJson(geo, geojson_path, &error)) {
    Err() << "uav_mosaic_files: " << (geo.empty() ? "no GeoJSON: the flight is not tied to GPS" : error) << "\n";
    return false;
  }
  Out() << "GeoJSON: " << geojson_path << "\n";
  return true;
}

}  // namespace vloc::mosaic
