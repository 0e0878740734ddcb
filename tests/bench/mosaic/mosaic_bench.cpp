// UAV mosaicker speed and memory (DESIGN.md budgets: tracking + height at
// 1280 x 720 >= 30 frames/s on 2 cores, mosaic update >= 5 Hz, bounded
// memory), and in the same run the plain approach: OpenCV A-KAZE on full
// frames + brute-force matching + RANSAC homography.
//   build-x/bench/mosaic_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>
#include <sys/resource.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <memory>

#include "../../unit/mosaic/synthetic_nadir.h"
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/stitching.hpp>

#include "vloc/common/options.h"
#include "vloc/mosaic/geotag.h"
#include "vloc/mosaic/height_graph.h"
#include "vloc/mosaic/survey_runner.h"
#include "vloc/mosaic/uav_mosaicker.h"

namespace {

using vloc::mosaic::testing::NadirCamera;
namespace vm = vloc::mosaic;

const NadirCamera kCam{cv::Size(1280, 720), 1000.0};

const vm::testing::SyntheticGround& Ground() {
  static const auto* ground = new vm::testing::SyntheticGround(vm::testing::MakeGround(4096, 0.05, 17));
  return *ground;
}

// 30 frames/s at 8 m/s, height 40 m climbing at 2 m/s, yawing slowly.
const std::vector<cv::Mat>& Frames() {
  static const auto* frames = [] {
    auto* v = new std::vector<cv::Mat>;
    for (int i = 0; i < 60; ++i) {
      const double t = i / 30.0;
      v->push_back(vm::testing::RenderNadir(Ground(), kCam, 8.0 * t - 20, 0.5 * t, 40.0 + 2.0 * t, 0.05 * t, 2.0, i + 1));
    }
    return v;
  }();
  return *frames;
}

vm::MosaickerOptions Options() {
  vm::MosaickerOptions o = vm::testing::OptionsForCamera(kCam, 40.0);
  o.canvas.metres_per_pixel = 0.08;
  o.matcher.downscale = 0.4;  // as config/procs/uav_mosaicker.yaml
  return o;
}

// VmHWM: = peak resident memory, VmRSS: = current (MB).
double RssMb(const std::string& key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(key, 0) == 0) return std::stod(line.substr(key.size())) / 1024.0;
  return 0;
}

// CPU time of the whole process (all threads, user + system), s: per-frame CPU
// cost that does not depend on what else the machine is running.
double ProcessCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// Tracking + height: features of the new frame, matching against the
// previous one, homography, eq. 2 filter, eq. 3 fit (what ProcessFrame does
// per frame apart from blending).
void BM_TrackingAndHeight(benchmark::State& state) {
  const auto& frames = Frames();
  vm::MatcherOptions options = Options().matcher;
  options.num_threads = static_cast<int>(state.range(0));
  cv::setNumThreads(options.num_threads);
  vm::FrameFeatures prev = vm::ExtractFeatures(frames[0], options);
  size_t i = 1;
  double h = 40.0;
  const double cpu0 = ProcessCpuSeconds();
  for (auto _ : state) {
    vm::FrameFeatures cur = vm::ExtractFeatures(frames[i], options);
    const vm::MotionEstimate m = vm::EstimateMotion(prev, cur, options);
    if (!m.ok) state.SkipWithError(m.why.c_str());
    h /= m.lambda;
    benchmark::DoNotOptimize(h);
    prev = std::move(cur);
    if (++i == frames.size()) {
      i = 1;
      prev = vm::ExtractFeatures(frames[0], options);
      h = 40.0;
    }
  }
  state.counters["frames_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["cpu_ms_per_frame"] = 1e3 * (ProcessCpuSeconds() - cpu0) / std::max<int64_t>(1, state.iterations());
}
BENCHMARK(BM_TrackingAndHeight)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// The plain approach: A-KAZE (OpenCV defaults) on full 1280 x 720 frames,
// brute-force kNN Hamming matching with the ratio test, RANSAC homography.
void BM_PlainAkazeFullFrameBruteForce(benchmark::State& state) {
  const auto& frames = Frames();
  cv::setNumThreads(2);
  auto akaze = cv::AKAZE::create();
  cv::BFMatcher matcher(cv::NORM_HAMMING);
  std::vector<cv::KeyPoint> kp_prev;
  cv::Mat d_prev;
  akaze->detectAndCompute(frames[0], cv::noArray(), kp_prev, d_prev);
  size_t i = 1;
  for (auto _ : state) {
    std::vector<cv::KeyPoint> kp;
    cv::Mat d;
    akaze->detectAndCompute(frames[i], cv::noArray(), kp, d);
    std::vector<std::vector<cv::DMatch>> knn;
    matcher.knnMatch(d_prev, d, knn, 2);
    std::vector<cv::Point2f> a, b;
    for (const auto& k : knn)
      if (k.size() == 2 && k[0].distance < 0.8f * k[1].distance) {
        a.push_back(kp_prev[k[0].queryIdx].pt);
        b.push_back(kp[k[0].trainIdx].pt);
      }
    if (a.size() >= 4) benchmark::DoNotOptimize(cv::findHomography(a, b, cv::RANSAC, 3.0));
    state.counters["features"] = static_cast<double>(kp.size());
    kp_prev = std::move(kp);
    d_prev = d;
    if (++i == frames.size()) i = 1;
  }
  state.counters["frames_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_PlainAkazeFullFrameBruteForce)->Unit(benchmark::kMillisecond)->UseRealTime();

// One mosaic update: multi-band blend of a 1280 x 720 frame into the tiled
// canvas at 0.08 m/px, frame height 40 m (arg 0) or 80 m (arg 1).
void BM_MosaicUpdate(benchmark::State& state) {
  cv::setNumThreads(2);
  vm::CanvasOptions options;
  vm::TiledCanvas canvas(options);
  const double height = state.range(0) == 0 ? 40.0 : 80.0;
  const double s = height / kCam.f / 0.08;
  const auto& frames = Frames();
  size_t i = 0;
  double x = 0;
  for (auto _ : state) {
    const vm::Similarity2 S{s, 0, x - s * kCam.cx(), -s * kCam.cy()};
    canvas.Blend(frames[i], S);
    x += 3.0;  // 8 m/s at 10 updates/s = 0.8 m = 10 px; overlap as in flight
    if (++i == frames.size()) i = 0;
  }
  state.counters["updates_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_MosaicUpdate)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// The whole per-frame pipeline (tracking, height, route, blending every 3rd
// frame): arg 0 = blending inside ProcessFrame, 1 = async_mosaic (worker thread),
// 2 = async_mosaic with OpenCV on one thread (num_threads 1).
void BM_FullPipeline(benchmark::State& state) {
  const auto& frames = Frames();
  std::unique_ptr<vm::UavMosaicker> m;
  vm::MosaickerOptions options = Options();
  options.async_mosaic = state.range(0) >= 1;
  if (state.range(0) == 2) options.num_threads = 1;  // tracking thread + blending thread, OpenCV single-threaded
  size_t i = 0;
  int64_t blends = 0;
  double mosaic_s = 0;
  auto finish = [&] {
    if (!m) return;
    blends += m->summary().blends - 1;  // the first frame's blend is set-up, not timed
    m.reset();
  };
  const double cpu0 = ProcessCpuSeconds();
  for (auto _ : state) {
    if (i == 0) {
      state.PauseTiming();
      finish();
      m = std::make_unique<vm::UavMosaicker>(options);
      m->ProcessFrame(frames[0], 0);
      i = 1;
      state.ResumeTiming();
    }
    const vm::FrameState s = m->ProcessFrame(frames[i], static_cast<int64_t>(i * 33333));
    mosaic_s += s.mosaic_seconds;
    if (++i == frames.size()) i = 0;
  }
  finish();
  state.counters["frames_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["mosaic_updates_per_s"] = benchmark::Counter(static_cast<double>(blends), benchmark::Counter::kIsRate);
  if (state.range(0) == 0) state.counters["blend_ms"] = blends ? 1e3 * mosaic_s / blends : 0.0;
  // Includes the set-up frames of each restart (1 in 60).
  state.counters["cpu_ms_per_frame"] = 1e3 * (ProcessCpuSeconds() - cpu0) / std::max<int64_t>(1, state.iterations());
}
BENCHMARK(BM_FullPipeline)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// Memory over a 10-minute flight: 8 m/s lawnmower at 60 m over wrapped
// synthetic ground, one frame every 1.25 s of flight (the canvas and its memory
// depend on the ground covered, not on the frame rate). Reports the canvas
// tiles and the process's peak RSS.
void BM_TenMinuteFlightMemory(benchmark::State& state) {
  for (auto _ : state) {
    const double rss_before = RssMb("VmRSS:");
    vm::MosaickerOptions o = Options();
    o.calibration.height = 60.0;
    o.keyframe_min_overlap = 0.3;
    o.mosaic_every_n_frames = 1;
    vm::UavMosaicker m(o);
    const NadirCamera cam = kCam;
    int lost = 0;
    // Legs of 600 m east/west, 60 m apart; image top = direction of travel.
    double x = 0, y = 0, dir = 1;
    const double step = 10.0;
    for (int i = 0; i < 480; ++i) {
      const double yaw = dir > 0 ? -M_PI / 2 : M_PI / 2;
      cv::Mat frame;
      cv::warpAffine(Ground().image, frame, vm::testing::GroundFromView(Ground(), cam, x, y, 60.0, yaw), cam.size,
                     cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_WRAP);
      const vm::FrameState s = m.ProcessFrame(frame, static_cast<int64_t>(i) * 1250000);
      if (s.status == vm::TrackStatus::kLost) {
        ++lost;
        std::cerr << "frame " << i << " lost: " << s.message << "\n";
      }
      x += dir * step;
      if (std::abs(x) > 300) {  // turn: move north one leg spacing in 4 steps
        for (int k = 0; k < 4 && i < 479; ++k) {
          y += 15.0;
          ++i;
          cv::Mat turn;
          cv::warpAffine(Ground().image, turn, vm::testing::GroundFromView(Ground(), cam, x, y, 60.0, yaw), cam.size,
                         cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_WRAP);
          lost += m.ProcessFrame(turn, static_cast<int64_t>(i) * 1250000).status == vm::TrackStatus::kLost;
        }
        dir = -dir;
      }
    }
    const vm::MosaickerSummary s = m.summary();
    state.counters["tiles_total"] = s.canvas.tiles_total;
    state.counters["tiles_peak_in_memory"] = s.canvas.peak_tiles_in_memory;
    state.counters["tiles_spilled"] = static_cast<double>(s.canvas.spills);
    state.counters["canvas_MB"] = s.canvas.bytes_in_memory / 1048576.0;
    state.counters["peak_rss_MB"] = RssMb("VmHWM:");  // whole process, incl. building the synthetic ground
    state.counters["rss_growth_MB"] = RssMb("VmRSS:") - rss_before;  // resident memory added by the flight
    state.counters["lost_frames"] = lost;
  }
}
BENCHMARK(BM_TenMinuteFlightMemory)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

// Real stills, in the same run as OpenCV's Stitcher (SCANS) on the same
// photos: the first photos of uav_caliterra (1000 x 750), of uav_seneca
// (960 x 720), and of uav_caliterra upscaled to 4000 x 3000 (12 MP, written
// once to a temporary folder, without geotags). The survey runner (what
// uav_mosaic_files runs) with
//   Arg 0 "full resolution, serial": features on the full frame, one thread of work after another (the stills
//         settings before issue 31);
//   Arg 1 "stills settings": config/procs/uav_mosaic_files.yaml as it is (reduced-level features, the next photo
//         prepared while this one registers, blending on a worker, heights tied to earlier overlapping photos);
//   Arg 2 "stills settings without height ties" (height_graph.ties 0: the heights of the registration chain alone).
// Counters: photos_per_s (wall), registered, and per photo the seconds of features, registration and blending
// (summed over threads: with prefetch they overlap).
//   build/bench/mosaic_bench --benchmark_filter=Stills --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
struct StillsSet {
  const char* name;
  std::vector<std::string> paths;
  std::vector<cv::Mat> images;
};

std::vector<std::string> FirstPhotos(const std::string& folder, size_t n) {
  std::vector<std::string> files;
  if (!std::filesystem::is_directory(folder)) return files;
  for (const auto& e : std::filesystem::directory_iterator(folder)) files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  if (files.size() > n) files.resize(n);
  return files;
}

const std::vector<StillsSet>& StillsSets() {
  static const auto* sets = [] {
    auto* v = new std::vector<StillsSet>;
    v->push_back({"uav_caliterra 1000x750", FirstPhotos("../shared/data/real/uav_caliterra/images", 12), {}});
    v->push_back({"uav_seneca 960x720", FirstPhotos("../shared/data/real/uav_seneca/images", 12), {}});
    // 12 MP: caliterra's first photos upscaled 4x (cubic), as a 4000 x 3000 camera would give them.
    StillsSet big{"uav_caliterra x4 4000x3000", {}, {}};
    const std::string dir = (std::filesystem::temp_directory_path() / "vloc_mosaic_bench_12mp").string();
    std::filesystem::create_directories(dir);
    for (const auto& p : FirstPhotos("../shared/data/real/uav_caliterra/images", 6)) {
      const std::string out = dir + "/" + std::filesystem::path(p).filename().string();
      if (!std::filesystem::exists(out)) {
        cv::Mat up;
        cv::resize(cv::imread(p, cv::IMREAD_COLOR), up, cv::Size(4000, 3000), 0, 0, cv::INTER_CUBIC);
        cv::imwrite(out, up, {cv::IMWRITE_JPEG_QUALITY, 92});
      }
      big.paths.push_back(out);
    }
    v->push_back(big);
    for (auto& set : *v)
      for (const auto& p : set.paths) set.images.push_back(cv::imread(p, cv::IMREAD_COLOR));
    return v;
  }();
  return *sets;
}

enum StillsMode { kFullSerial = 0, kStills = 1, kStillsWithoutTies = 2 };

vm::SurveyOptions StillsOptions(int mode) {
  vm::SurveyOptions o = vm::LoadSurveyOptions("config/procs/uav_mosaic_files.yaml");
  if (mode == kStillsWithoutTies) o.mosaicker.height_graph.ties = 0;
  if (mode == kFullSerial) {
    o.mosaicker.matcher.downscale = 1.0;
    o.mosaicker.matcher.detect_width = 0;
    o.mosaicker.fallback_downscale = 0;
    o.mosaicker.async_mosaic = false;
    o.prefetch = false;
  }
  return o;
}

void BM_Stills(benchmark::State& state) {
  const StillsSet& set = StillsSets().at(static_cast<size_t>(state.range(0)));
  if (set.paths.size() < 2) {
    state.SkipWithError("../shared/data/real absent");
    return;
  }
  static const char* const kModes[] = {", full resolution, serial", ", stills settings", ", stills without height ties"};
  state.SetLabel(std::string(set.name) + kModes[state.range(1)]);
  int registered = 0;
  vm::SurveyTimes times;
  double wall = 0, cpu = 0;
  for (auto _ : state) {
    const double cpu0 = ProcessCpuSeconds();
    vm::SurveyRunner runner(StillsOptions(static_cast<int>(state.range(1))), nullptr, nullptr);
    if (!runner.LoadPhotos(set.paths) || !runner.ChooseCamera() || !runner.ChooseFirstHeight()) {
      state.SkipWithError("photos not loaded");
      return;
    }
    runner.RegisterAll();
    registered = runner.registered();
    times = runner.times();
    wall += times.wall;
    cpu += ProcessCpuSeconds() - cpu0;
  }
  const double n = static_cast<double>(set.paths.size());
  state.counters["photos_per_s"] = n * state.iterations() / std::max(1e-9, wall);
  state.counters["registered"] = registered;
  state.counters["features_s"] = times.features / n;
  state.counters["registration_s"] = times.registration / n;
  state.counters["blending_s"] = times.blending / n;
  state.counters["decoding_s"] = times.decoding / n;
  state.counters["cpu_s_per_photo"] = cpu / (n * state.iterations());  // all threads: what 2 quiet cores share
}
BENCHMARK(BM_Stills)->ArgsProduct({{0, 1, 2}, {kFullSerial, kStills, kStillsWithoutTies}})->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);

void BM_StillsStitcherScans(benchmark::State& state) {
  const StillsSet& set = StillsSets().at(static_cast<size_t>(state.range(0)));
  if (set.images.size() < 2) {
    state.SkipWithError("../shared/data/real absent");
    return;
  }
  state.SetLabel(set.name);
  int status = -1, joined = 0;
  double cpu = 0;
  for (auto _ : state) {
    const double cpu0 = ProcessCpuSeconds();
    cv::setNumThreads(2);
    auto stitcher = cv::Stitcher::create(cv::Stitcher::SCANS);
    cv::Mat pano;
    status = static_cast<int>(stitcher->stitch(set.images, pano));
    joined = status == 0 ? static_cast<int>(stitcher->component().size()) : 0;
    cpu += ProcessCpuSeconds() - cpu0;
  }
  state.counters["cpu_s_per_photo"] = cpu / (set.images.size() * state.iterations());
  state.counters["photos_per_s"] = benchmark::Counter(static_cast<double>(set.images.size()) * state.iterations(),
                                                      benchmark::Counter::kIsRate);
  state.counters["stitch_ok"] = status == 0;
  state.counters["joined"] = joined;  // photos in the panorama
}
BENCHMARK(BM_StillsStitcherScans)->DenseRange(0, 2)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);

// The height graph of a long survey solved photo by photo, as the mosaicker does: strips of 20 frames, each frame
// linked to the one before and tied to four earlier ones (three beside it on the strip before, one two strips back). Arg 0: frames; arg 1: the window
// (height_graph.window; 0 = every frame solved at every photo, the cost growing with the survey). The last solve's
// time and the whole survey's.
void BM_HeightGraphSurvey(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0)), per_strip = 20;
  vm::HeightGraphOptions o;
  o.window = static_cast<int>(state.range(1));
  double last_ms = 0;
  for (auto _ : state) {
    cv::RNG rng(7);
    vm::HeightGraph g(o);
    double chained = 0;
    g.AddFrame(0, chained);
    for (int i = 1; i < n; ++i) {
      const double link = rng.gaussian(0.02);
      chained += link;
      g.AddFrame(i, chained);
      g.AddTie(i - 1, i, link, 0.02);
      // Ties as seneca's photos make them: the three frames beside on the strip before, one on the strip before that.
      for (int back = 1; back <= 2; ++back) {
        if (i < back * per_strip) break;
        const int beside = (i / per_strip - 1) * per_strip + (per_strip - 1 - i % per_strip) - (back - 1) * per_strip;
        for (int d = back == 1 ? -1 : 0; d <= (back == 1 ? 1 : 0); ++d)
          if (beside + d >= 0 && beside + d < i - 1) g.AddTie(beside + d, i, rng.gaussian(0.02), 0.02);
      }
      const auto t0 = std::chrono::steady_clock::now();
      g.Solve();
      last_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    }
    if (g.Windowed()) g.SolveAll();
  }
  state.counters["last_solve_ms"] = last_ms;
}
BENCHMARK(BM_HeightGraphSurvey)->Args({1000, 0})->Args({1000, 600})->Args({3000, 0})->Args({3000, 600})
    ->Args({10000, 600})->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);

BENCHMARK_MAIN();
