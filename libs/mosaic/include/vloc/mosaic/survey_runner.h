#pragma once
// A survey folder through the mosaicker, as uav_mosaic_files runs it and the
// tests check it: the photos' headers and geotags, the focal length and first
// height (and where each came from), every photo registered with its GPS fix,
// the mosaic (or the affine-invariant fallback for untagged oblique photos),
// the route and heights against the GPS, the report and GeoJSON.
//
//   SurveyOptions o = LoadSurveyOptions("config/procs/uav_mosaic_files.yaml");
//   SurveyRunner runner(o, &std::cout, &std::cerr);     // null streams: silent
//   if (!runner.LoadPhotos(paths) || !runner.ChooseCamera() || !runner.ChooseFirstHeight()) return 1;
//   runner.RegisterAll();
//   runner.WriteMosaic("out/m.png");
//   runner.Evaluate();                                   // route and heights vs GPS
//   runner.WriteReport("out/m.tsv");  runner.WriteGeoJson("out/m.geojson");
//   return runner.ExitCode();                            // 0 all registered, 2 some refused or lost
//
// Focal length (px): the calibration file, else focal_px, else EXIF (focal
// length and sensor width, or the 35 mm equivalent), else the image width.
// First height: an ArUco marker in the first photo, else the DJI relative
// altitude, else height_m, else 100 m (heights then relative).
// Several flights in one folder: photos of another camera are resampled to
// the survey's (ChooseCamera: the most common size, its focal length) or
// refused by name; a photo taken reseat_after_gap_s after the last
// registered one is searched for in the mosaic around its GPS position.
// Heights: vision only, and fused with the altitude tags when they agree
// (altitude_fusion.h).

#include <opencv2/core.hpp>

#include <chrono>
#include <future>
#include <cstdint>
#include <iosfwd>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vloc/common/image_header.h"
#include "vloc/mosaic/altitude_fusion.h"
#include "vloc/mosaic/geotag.h"
#include "vloc/mosaic/lens_search.h"
#include "vloc/mosaic/survey_eval.h"
#include "vloc/mosaic/survey_photos.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic {

struct SurveyOptions {
  MosaickerOptions mosaicker;          // the stills settings ("mosaicker" of config/procs/uav_mosaic_files.yaml)
  ImageLimits limits;                  // photo_limits: photos over these are refused by name
  AltitudeFusionOptions altitude_fusion;  // altitude_fusion: the photos' altitude tags fused with the vision height
  std::string calibration_file;        // camera YAML; "" = the focal from focal_px, EXIF or the image width
  std::optional<double> focal_px;      // px, the focal length (no calibration file); must be in (0, 1e6)
  std::optional<double> height_m;      // m, the first height when no marker or relative altitude; (0, 10 km]
  bool use_gps = true;                 // false: geotags not given to the mosaicker (--no-gps)
  int drop_gps_first = -1;             // frames [first, last] (0-based) get no GPS: a simulated drop-out
  int drop_gps_last = -2;
  double gps_sigma = 3.0;              // m, horizontal sigma of the photos' GPS
  bool oblique_fallback = true;        // untagged photos the mosaicker loses: pairwise affine-invariant mosaic
  bool prefetch = true;                // decode the next photo and find its features while this one registers
  bool keep_height_observations = false;  // the height links and ties kept with their points (SelfCalibrateLens)
};

// The stills settings of a config file: "mosaicker" and "photo_limits" (when present). Throws ConfigError.
SurveyOptions LoadSurveyOptions(const std::string& config_path);

struct SurveyFrame {
  std::string name;
  ImageGeotag tag;
  bool gps_used = false;       // tag given to the mosaicker
  bool dropped = false;        // tag withheld (drop_gps_*): compared, not in the fit
  bool repeated_fix = false;   // the camera tagged it with the previous photo's fix (same GPS time): no new position
  FrameState state;
  int64_t utime = 0;           // us since the first photo (EXIF capture time, else one second a photo)
  bool registered = false;
  cv::Point2d enu;             // GPS east/north of the frame (m, from the first tagged frame)
};

// The figures of a run against the GPS (Evaluate).
struct SurveyFigures {
  bool evaluated = false;              // geotags to compare with
  RouteComparison route_least_squares; // 2-D similarity fit
  RouteComparison route;               // robust fit
  bool relative_altitude = false;      // the first photo carries a DJI relative altitude
  double height_scale = 1.0;           // heights put on the GPS track's scale (no relative altitude)
  std::vector<double> heights, gps_heights;  // m, per frame (NaN when not registered): vision heights, altitude tags
  HeightComparison height;             // vision heights (altitude tags withheld) against the tags
  AltitudeFusion fusion;               // the tags fused with the vision heights, or why not
  HeightComparison fused_height;       // fused heights against the tags (when fused)
  // Against another tool's heights above the ground (SurveyReferences::heights) over the registered frames it holds,
  // with a constant offset fitted (the vision heights also without it: the two tools' absolute levels can differ by
  // a few %, README); reference_tags: the reference against the tags minus a fitted ground level, i.e. the tags' own
  // error. pairs = 0 when not compared.
  HeightComparison reference_vision, reference_vision_raw, reference_fused, reference_tags;
};

// References made by other tools for the same flight, for Evaluate.
struct SurveyReferences {
  std::string orthomosaic;                // an orthomosaic (e.g. OpenDroneMap's): the route and the GPS against it
  std::map<std::string, double> heights;  // photo file name -> height above the ground, m (ReadReferenceHeights)
  std::string heights_path;               // where they were read (for messages)
};

// Seconds over the survey. With prefetch, decoding and features overlap registration: wall < the sum.
struct SurveyTimes {
  double wall = 0;          // decoding, features, registration and blending of every photo
  double decoding = 0;      // reading and decoding the photos
  double features = 0;      // undistortion and features
  double registration = 0;  // matching, pose, height (FrameState::tracking_seconds without features)
  double blending = 0;
};

class SurveyRunner {
 public:
  // out: per-photo lines and figures; err: refusals and errors (one line each). Null = silent.
  SurveyRunner(const SurveyOptions& options, std::ostream* out, std::ostream* err);
  ~SurveyRunner();

  // The photos' headers (limits), then their geotags. False (with a line on
  // err) when fewer than two photos are usable.
  bool LoadPhotos(const std::vector<std::string>& paths);
  // Decoded views instead of photos (no geotags, one second apart).
  void LoadViews(const std::vector<std::string>& names, const std::vector<cv::Mat>& views);
  // The focal length, then every photo fitted to the survey's camera (refused by name when it cannot be).
  bool ChooseCamera();
  bool ChooseFirstHeight();
  // Every photo through the mosaicker with its fix.
  void RegisterAll();
  // The mosaic (PNG + world file), or the oblique fallback's.
  bool WriteMosaic(const std::string& png_path);
  // The mosaicker's summary and the timing line.
  void PrintSummary(const std::string& png_path) const;
  // Route and heights against the GPS (when tagged); with references of the
  // same flight made by other tools, the route and the GPS against an
  // orthomosaic, the heights and the altitude tags against heights above
  // the ground.
  void Evaluate(const SurveyReferences& references = {});
  const ReferenceComparison& reference() const { return reference_; }
  bool WriteReport(const std::string& tsv_path);
  bool WriteGeoTiff(const std::string& tif_path);
  bool WriteGeoJson(const std::string& geojson_path);
  // 0 every photo registered; 2 a photo or tag refused, or a frame not registered.
  int ExitCode() const { return failures_ == 0 && refusals_ == 0 ? 0 : 2; }

  const std::vector<SurveyFrame>& frames() const { return frames_; }
  const SurveyFigures& figures() const { return figures_; }
  const SurveyTimes& times() const { return times_; }
  const MosaickerOptions& mosaicker_options() const { return options_.mosaicker; }
  int registered() const;
  bool used_oblique() const { return used_oblique_; }
  UavMosaicker& mosaicker() { return *mosaicker_; }

 private:
  cv::Mat Load(size_t i, std::string* error) const;
  void ReadGeotags();
  size_t ReferencePhoto() const;       // the first photo of the survey's size: its EXIF gives the focal length
  bool FitCameras();
  void MarkRepeatedFixes();
  // The tags place the photos: GPS asked for and at least two usable photos tagged.
  bool UseGps() const { return options_.use_gps && tagged_ >= 2; }
  void ChooseTimes();
  struct Loaded;
  Loaded Prepare(size_t i, FramePreparer* preparer) const;
  void RegisterOne(size_t i, Loaded loaded);
  bool WriteObliqueMosaic(const std::string& png_path);
  void CompareWithReference(const std::string& reference_path);
  void CompareHeightsWithTags();
  void CompareHeightsWithReference(const SurveyReferences& references);
  double FusedHeight(size_t i) const;  // m, NaN when the tags were not fused
  std::ostream& Out() const;
  std::ostream& Err() const;

  SurveyOptions options_;
  std::ostream* out_;
  std::ostream* err_;
  std::vector<std::string> paths_;
  std::vector<cv::Mat> views_;         // LoadViews
  cv::Mat first_;
  cv::Size size_;                      // the survey's photo size: the most common one
  std::vector<cv::Size> sizes_;        // each photo's own size
  std::vector<CameraFit> fits_;        // each photo brought to the survey's camera
  std::vector<SurveyFrame> frames_;
  int tagged_ = 0, refusals_ = 0, failures_ = 0;
  bool times_ok_ = false, used_oblique_ = false;
  const ImageGeotag* origin_ = nullptr;  // the first tagged photo's tag
  std::unique_ptr<UavMosaicker> mosaicker_;
  SurveyTimes times_;
  SurveyFigures figures_;
  ReferenceComparison reference_;
};

// The lens's k1 self-calibrated from a first run over the photos (lens_search.h): every height link and tie of the
// run re-measured under candidate k1 (no GPS used); *camera is the run's camera with the best k1. out: the search's
// lines (the run itself is silent); false with one line on err when the photos or the search fail.
bool SelfCalibrateLens(const SurveyOptions& options, const std::vector<std::string>& paths, std::ostream* out,
                       std::ostream* err, PinholeCamera* camera, LensSearch* search);

// A camera as the YAML a calibration file holds (LoadOptionsFile<PinholeCamera> reads it back), after comment lines.
bool WriteCameraFile(const std::string& path, const PinholeCamera& camera, const std::string& comment,
                     std::string* error);

}  // namespace vloc::mosaic
