// The mosaicker on real geotagged surveys (../shared/data, see its README):
// uav_caliterra, 75 photos of a construction site, EXIF GPS: every frame
// must register, the route must follow the GPS track after a 2-D similarity
// fit, and a GPS drop-out over a stretch of frames must not stop the route.
// uav_seneca, 167 photos of early-season fields from a fixed wing without a
// gimbal: at least 90 % registered, the rest LOST with a reason. Skipped with
// a message when the data is absent.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>

#include <exiv2/exiv2.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdlib>
#include <iomanip>
#include <sstream>

#include "vloc/common/options.h"
#include "vloc/mosaic/survey_eval.h"
#include "vloc/mosaic/survey_runner.h"

namespace vloc::mosaic {
namespace {

const char* kCaliterra = "../shared/data/real/uav_caliterra/images";
const char* kCaliterraReference = "../shared/data/real/uav_caliterra/reference_orthomosaic.jpg";
const std::string kCaliterraHeights = VLOC_SOURCE_DIR "/tests/data/mosaic/uav_caliterra_reference_heights.tsv";
const char* kSeneca = "../shared/data/real/uav_seneca/images";
// Heights above the ground from COLMAP's reconstruction of the same photos (scripts/survey_reference.py).
const std::string kSenecaHeights = VLOC_SOURCE_DIR "/tests/data/mosaic/uav_seneca_reference_heights.tsv";

// Every photo through the survey runner (what uav_mosaic_files runs) with
// the stills settings, GPS tags of frames [drop_a, drop_b] withheld.
// expected_focal: px, from the data's README (focal length / sensor width x image width).
struct SurveyRun {
  int frames = 0, registered = 0;
  RouteComparison route;
  ReferenceComparison reference;
  SurveyFigures figures;
  MosaickerSummary summary;
  std::vector<FrameState> states;
  LensSearch lens;  // the lens's k1 from the run's height ties (when asked)
};

SurveyRun RunSurvey(const std::string& folder, double expected_focal, int drop_a = -1, int drop_b = -2,
                    const SurveyReferences& references = {}, bool search_lens = false) {
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(folder)) files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  SurveyOptions options = LoadSurveyOptions("config/procs/uav_mosaic_files.yaml");
  options.drop_gps_first = drop_a, options.drop_gps_last = drop_b;
  options.keep_height_observations = search_lens;
  SurveyRunner runner(options, nullptr, &std::cerr);
  EXPECT_TRUE(runner.LoadPhotos(files) && runner.ChooseCamera() && runner.ChooseFirstHeight());
  EXPECT_NEAR(runner.mosaicker_options().camera.fx, expected_focal, 0.5);
  runner.RegisterAll();
  runner.Evaluate(references);
  SurveyRun run;
  run.frames = static_cast<int>(runner.frames().size());
  run.registered = runner.registered();
  run.route = runner.figures().route;
  run.reference = runner.reference();
  run.figures = runner.figures();
  run.summary = runner.mosaicker().summary();
  for (const auto& f : runner.frames()) run.states.push_back(f.state);
  if (search_lens)
    run.lens = SearchRadialDistortion(*runner.mosaicker().height_observations(), runner.mosaicker_options().camera,
                                      options.mosaicker.height_graph);
  std::cout << folder << ": " << run.registered << " of " << run.frames << " registered in " << runner.times().wall
            << " s\n";
  return run;
}

TEST(RealSurvey, CaliterraEveryFrameRegisteredRouteFollowsGpsThroughADropOut) {
  if (!std::filesystem::is_directory(kCaliterra))
    GTEST_SKIP() << kCaliterra << " absent (real data lives beside the repo, see ../shared/data/README.md): skipped";
  // GPS tags of frames 30-39 dropped (about 100 m of flight).
  SurveyReferences references;
  references.orthomosaic = kCaliterraReference;
  std::string error;
  ASSERT_TRUE(ReadReferenceHeights(kCaliterraHeights, &references.heights, &error)) << error;
  const SurveyRun run = RunSurvey(kCaliterra, 729.3, 30, 39, references);  // 4.5 mm on a 6.17 mm sensor at 1000 px
  EXPECT_EQ(run.frames, 75);
  EXPECT_EQ(run.registered, 75);
  for (const auto& s : run.states)
    if (s.status == TrackStatus::kLost) ADD_FAILURE() << "frame " << s.frame_index << " LOST: " << s.message;
  ASSERT_TRUE(run.route.ok) << run.route.why;
  std::cout << "uav_caliterra: " << run.registered << " of " << run.frames << " registered; route RMS " << run.route.rms_m
            << " m = " << run.route.rms_percent() << " % of " << run.route.path_m << " m; GPS drop-out (frames 30-39): RMS "
            << run.route.held_out_rms_m << " m\n";
  EXPECT_GT(run.route.path_m, 600);
  // Measured 2.2 % of the path (a camera GPS good to several metres, an
  // ungimballed camera); the target is 2 %. 3.5 % catches a broken chain
  // (a misregistered frame moves the route by a frame width, ~50-150 m here).
  EXPECT_LT(run.route.rms_percent(), 3.5) << "route RMS " << run.route.rms_m << " m over " << run.route.path_m << " m";
  // Through the drop-out the route is vision alone: within the same bound.
  EXPECT_EQ(run.route.held_out, 10);
  EXPECT_LT(run.route.held_out_rms_m, 0.035 * run.route.path_m);
  // The camera's GPS altitude climbs 113 m while the photos keep their scale: not fused, and said why.
  EXPECT_FALSE(run.figures.fusion.fused);
  EXPECT_NE(run.figures.fusion.why.find("disagrees"), std::string::npos) << run.figures.fusion.why;

  // Against OpenDroneMap's orthomosaic of the same flight (an independent
  // reconstruction): the route must be closer to it than the camera's GPS is,
  // which shows where the route-vs-GPS residual comes from.
  const ReferenceComparison& c = run.reference;
  const RouteComparison& route = c.route;
  const RouteComparison& gps = c.gps;
  ASSERT_TRUE(route.ok && gps.ok);
  std::cout << "against the reference orthomosaic (" << route.pairs << " photos located): route RMS " << route.rms_m
            << " m = " << 100 * route.rms_m / run.route.path_m << " %, GPS RMS " << gps.rms_m << " m = "
            << 100 * gps.rms_m / run.route.path_m << " % of the path\n";
  EXPECT_GE(route.pairs, 50);  // 66 of 75 located (the reference is coarse: 3,300 SIFT features)
  // Measured 7.2 m = 0.97 % (route) against 14.9 m = 2.0 % (GPS); the
  // reference's own registration noise is a few metres.
  EXPECT_LT(route.rms_m, gps.rms_m);
  EXPECT_LT(route.rms_m, 0.015 * run.route.path_m);

  // The heights against COLMAP's reconstruction of the same photos, aligned to the GPS east/north (its altitude
  // drifts: scripts/survey_reference.py --level-gps; two reconstructions aligned differently agree to 0.47 % after a
  // scale): measured 0.94 % with an offset fitted (6.1 % without); the tags, 113 m of climb, 65 %.
  const SurveyFigures& fig = run.figures;
  ASSERT_TRUE(fig.reference_vision.ok && fig.reference_tags.ok);
  std::cout << "uav_caliterra heights against the reference over " << fig.reference_vision.pairs << " photos: vision only "
            << fig.reference_vision.rms_percent << " % (" << fig.reference_vision_raw.rms_percent
            << " % without the offset), the altitude tags " << fig.reference_tags.rms_percent << " %\n";
  EXPECT_GE(fig.reference_vision.pairs, 70);
  EXPECT_LT(fig.reference_vision.rms_percent, 2.0);
  EXPECT_GT(fig.reference_tags.rms_percent, 10 * fig.reference_vision.rms_percent);
}

TEST(RealSurvey, SenecaNinetyPercentRegisteredTheRestLostWithAReason) {
  if (!std::filesystem::is_directory(kSeneca))
    GTEST_SKIP() << kSeneca << " absent (real data lives beside the repo, see ../shared/data/README.md): skipped";
  SurveyReferences references;
  std::string error;
  ASSERT_TRUE(ReadReferenceHeights(kSenecaHeights, &references.heights, &error)) << error;
  const SurveyRun run = RunSurvey(kSeneca, 669.5, -1, -2, references, true);  // 4.3 mm on a 6.17 mm sensor at 960 px
  EXPECT_EQ(run.frames, 167);
  std::cout << "uav_seneca: " << run.registered << " of " << run.frames << " registered; route RMS " << run.route.rms_m
            << " m = " << run.route.rms_percent() << " % of " << run.route.path_m << " m\n";
  // Measured 165 of 167 (A-KAZE alone: 116).
  EXPECT_GE(run.registered, static_cast<int>(std::ceil(0.9 * run.frames)));
  int lost = 0;
  for (const auto& s : run.states) {
    if (s.status != TrackStatus::kLost) continue;
    ++lost;
    EXPECT_FALSE(s.message.empty()) << "frame " << s.frame_index << " LOST without a reason";
  }
  EXPECT_EQ(lost, run.frames - run.registered);
  // Every loss is followed by a re-acquisition (the last frame excepted).
  for (size_t i = 0; i + 1 < run.states.size(); ++i)
    if (run.states[i].status == TrackStatus::kLost && run.states[i + 1].status == TrackStatus::kTracking)
      ADD_FAILURE() << "frame " << i + 1 << " TRACKING straight after a LOST frame (should be RECOVERED)";
  ASSERT_TRUE(run.route.ok) << run.route.why;
  // Measured 0.36 % of a 6.9 km path; a misregistered frame moves the route by a frame width (~100 m).
  EXPECT_LT(run.route.rms_percent(), 1.0) << "route RMS " << run.route.rms_m << " m over " << run.route.path_m << " m";
  // Heights against the GPS altitude minus a fitted ground: vision only (measured 3.14 % with 284 height ties to the
  // adjacent strips, 4.79 % from the chain of 146 keyframes alone; the GPS altitude's own frame-to-frame noise,
  // estimated from the ties, the chain and the GPS together, is 1.7-1.9 %) and fused with the tags (2.11 %; the
  // tags' own sigma, 3 m, is 4.6 % of 65 m).
  const SurveyFigures& fig = run.figures;
  ASSERT_TRUE(fig.height.ok && fig.fusion.fused) << fig.fusion.why;
  std::cout << "uav_seneca heights: vision only " << fig.height.rms_percent << " %, fused " << fig.fused_height.rms_percent
            << " % (" << fig.fusion.why << ")\n";
  EXPECT_LT(fig.height.rms_percent, 3.8);
  EXPECT_GE(run.summary.height_ties, 200) << "height ties to the adjacent strips (measured 284)";
  EXPECT_LT(fig.fused_height.rms_percent, fig.height.rms_percent);  // the fusion follows the tags (0.67x)
  EXPECT_LT(fig.fused_height.rms_percent, 100 * 3.0 / 65);
  // Against a better truth than the tags: COLMAP's reconstruction of the same photos (bundle adjustment, aligned to
  // the GPS; heights above the ground each photo sees, reproduced by a second run to 0.011 m RMS). The tags
  // (altitude minus a fitted level) are 2.67 % off it, the vision heights 1.30 %, fused 1.19 %: what keeps the figure
  // against the tags above 2 % is the tags. An offset is fitted as against the tags (a nadir survey's absolute
  // height trades against the focal length: COLMAP self-calibrates 680.6 px, the EXIF says 669; without it 4.30 %).
  const HeightComparison& vision = fig.reference_vision;
  ASSERT_TRUE(vision.ok && fig.reference_fused.ok && fig.reference_tags.ok);
  std::cout << "uav_seneca heights against the reference over " << vision.pairs << " photos: vision only "
            << vision.rms_percent << " % (" << fig.reference_vision_raw.rms_percent << " % without the offset), fused "
            << fig.reference_fused.rms_percent << " %, the altitude tags " << fig.reference_tags.rms_percent << " %\n";
  EXPECT_GE(vision.pairs, 160);
  EXPECT_LT(vision.rms_percent, 2.0);  // 2 %: the target (the reference's own noise is ~0.02 %)
  EXPECT_LT(fig.reference_fused.rms_percent, 2.0);
  EXPECT_LT(vision.rms_percent, 0.7 * fig.reference_tags.rms_percent);
  // Fused with the tags, the heights are nearer the truth than either alone (the fusion takes the tags' slow
  // wander, 5.5 % peak to peak against the reference, for no drift of the chain's, 2.2 %; a bias drift of 0.004 /
  // s^0.5 took it for one: fused 1.65 %). The reference's own noise, ~0.02 %, is well inside the 0.1 % margin.
  EXPECT_LT(fig.reference_fused.rms_percent, vision.rms_percent);
  EXPECT_LT(fig.reference_fused.rms_percent, fig.reference_tags.rms_percent);
  // The compact camera's lens from the height ties alone (lens_search.h): measured k1 -0.028 (residual 0.77 sigmas
  // against 0.91 without; full runs at steps of 0.02 put it at -0.04); its curve is shallow near the minimum, steep
  // beyond +-0.04 of it (1.4 sigmas at -0.08 and +0.03 -> 1.2).
  ASSERT_TRUE(run.lens.ok) << run.lens.why;
  std::cout << "uav_seneca lens: k1 " << run.lens.k1 << " from " << run.lens.pairs << " links and ties, residual "
            << run.lens.residual << " sigmas (" << run.lens.residual_as_run << " without)\n";
  EXPECT_GT(run.lens.k1, -0.06);
  EXPECT_LT(run.lens.k1, -0.01);
  EXPECT_LT(run.lens.residual, 0.9 * run.lens.residual_as_run);
  EXPECT_GE(run.lens.pairs, 300);
}


// The photo at `from` written to `to` at `size`, its EXIF kept but for the
// capture time and (when > 0) the focal length.
void WritePhoto(const std::string& from, const std::string& to, cv::Size size, const std::string& time, int focal_10mm) {
  cv::Mat image = cv::imread(from, cv::IMREAD_COLOR);
  cv::resize(image, image, size, 0, 0, cv::INTER_AREA);
  ASSERT_TRUE(cv::imwrite(to, image, {cv::IMWRITE_JPEG_QUALITY, 92}));
  auto original = Exiv2::ImageFactory::open(from);
  original->readMetadata();
  auto copy = Exiv2::ImageFactory::open(to);
  copy->setExifData(original->exifData());
  copy->exifData()["Exif.Photo.DateTimeOriginal"] = time;
  if (focal_10mm > 0) copy->exifData()["Exif.Photo.FocalLength"] = Exiv2::URational(focal_10mm, 10);
  copy->writeMetadata();
}

// A folder holding two flights over one site (made from uav_caliterra): the
// first 30 photos as taken, then, 15 minutes later, a second flight of 29 photos by
// another camera (800 x 600 px: 583 px focal length against the survey's
// 729) flying the last 29 photos' places backwards from the far end, and
// one photo of a camera whose view is narrower than the survey's (a 9 mm
// lens at 800 px: it cannot cover the survey's frame). Every photo of both
// flights registers into one mosaic, the narrow one is refused by name.
TEST(RealSurvey, TwoFlightsByTwoCamerasRegisterIntoOneMosaic) {
  if (!std::filesystem::is_directory(kCaliterra))
    GTEST_SKIP() << kCaliterra << " absent (real data lives beside the repo, see ../shared/data/README.md): skipped";
  std::vector<std::string> originals;
  for (const auto& e : std::filesystem::directory_iterator(kCaliterra)) originals.push_back(e.path().string());
  std::sort(originals.begin(), originals.end());
  ASSERT_EQ(originals.size(), 75u);
  const char* tmp = std::getenv("TMPDIR");
  const std::filesystem::path folder = std::filesystem::path(tmp ? tmp : "/tmp") / "two_flights";
  std::filesystem::remove_all(folder);
  std::filesystem::create_directories(folder);
  std::vector<std::string> files;
  for (int i = 0; i < 30; ++i) {
    files.push_back((folder / std::filesystem::path(originals[i]).filename()).string());
    std::filesystem::copy_file(originals[i], files.back());
  }
  for (int k = 0; k < 29; ++k) {  // the second flight: 13:40:00 on, 2 s apart (the first ended near 13:22)
    std::ostringstream name, time;
    name << "flight2_" << std::setw(3) << std::setfill('0') << k << ".jpg";
    time << "2014:10:19 13:" << 40 + (2 * k) / 60 << ":" << std::setw(2) << std::setfill('0') << (2 * k) % 60;
    files.push_back((folder / name.str()).string());
    WritePhoto(originals[74 - k], files.back(), cv::Size(800, 600), time.str(), 0);
  }
  const std::string narrow = (folder / "flight2_narrow.jpg").string();
  WritePhoto(originals[50], narrow, cv::Size(800, 600), "2014:10:19 13:41:01", 90);
  files.push_back(narrow);
  std::sort(files.begin(), files.end());

  SurveyOptions options = LoadSurveyOptions("config/procs/uav_mosaic_files.yaml");
  std::ostringstream out, err;
  SurveyRunner runner(options, &out, &err);
  ASSERT_TRUE(runner.LoadPhotos(files) && runner.ChooseCamera() && runner.ChooseFirstHeight()) << err.str();
  EXPECT_NE(err.str().find("flight2_narrow.jpg: 800 x 600 at a focal length of"), std::string::npos) << err.str();
  EXPECT_NE(err.str().find("narrower view than the survey's camera"), std::string::npos) << err.str();
  EXPECT_NE(out.str().find("29 photos of another camera resampled to the survey's 1000 x 750 px"), std::string::npos)
      << out.str();
  runner.RegisterAll();
  EXPECT_NE(out.str().find("flight2_000.jpg: taken"), std::string::npos) << "the second flight not announced\n" << out.str().substr(0, 3000);
  ASSERT_EQ(runner.frames().size(), 59u);
  int first = 0, second = 0;
  for (size_t i = 0; i < 59; ++i) {
    const SurveyFrame& f = runner.frames()[i];
    (i < 30 ? first : second) += f.registered ? 1 : 0;
    if (!f.registered || i == 30)
      std::cout << f.name << ": " << ToString(f.state.status) << " " << f.state.message << "\n";
  }
  std::cout << "two flights: " << first << " of 30 and " << second << " of 29 registered\n";
  EXPECT_EQ(first, 30);
  // The second flight's first photo may be placed by its GPS (new ground) rather than registered.
  EXPECT_GE(second, 28);
  runner.Evaluate();
  const RouteComparison& route = runner.figures().route;
  ASSERT_TRUE(route.ok) << route.why;
  std::cout << "two flights: route RMS " << route.rms_m << " m = " << route.rms_percent() << " % of " << route.path_m
            << " m\n";
  // One survey's figure (2.3 %, the camera GPS's own error): both flights in one frame, no worse than 3.5 %.
  EXPECT_LT(route.rms_percent(), 3.5);
  EXPECT_TRUE(runner.WriteMosaic((folder / "mosaic.png").string())) << err.str();
  std::filesystem::remove_all(folder);
}

}  // namespace
}  // namespace vloc::mosaic
