// uav_mosaic_eval: runs the simulated flight (libs/sim/uav) through the
// mosaicker offline, frame by frame, and prints the figures against ground
// truth: height error RMS (% of true height), route error (% of distance
// flown), loss of track, time per frame, mosaic update rate, peak memory.
//   uav_mosaic_eval [--config config/procs/uav_mosaicker.yaml] [--sim-config config/procs/sim_uav.yaml]
//                   [--fps F] [--duration S] [--gps-use calibration|fused] [--out out/sim_mosaic.png]
//                   [--csv out/sim_track.csv] [--no-gps] [--reregister N]
// --reregister N overrides mosaicker.reregister_every_n_frames (0 = off).
// --survey S replaces the flight plan with a lawnmower survey at 60 m over the
// simulated map lasting S s (legs 40 m apart, back over the map when it is
// covered); --memory-every T prints the process RSS and canvas tiles every
// T s of flight (memory over a long flight).
#include <glog/logging.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <numeric>

#include "vloc/common/command_line.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/common/stats.h"
#include "vloc/mosaic/uav_mosaicker.h"
#include "vloc/sim/uav_world.h"

namespace {

double StatusMb(const std::string& key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(key, 0) == 0) return std::stod(line.substr(key.size())) / 1024.0;
  return 0;
}
double PeakRssMb() { return StatusMb("VmHWM:"); }

// CPU time of the whole process (all threads, user + system), s.
double ProcessCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// Lawnmower at 60 m over the orthomap, legs along x 40 m apart (the 77 m wide
// footprint overlaps half), long enough for `seconds` of flight at the
// configured speed; when the map is covered the legs run back over it.
std::vector<double> SurveyWaypoints(const vloc::UavWorldOptions& w, double seconds) {
  const double margin = 45.0, spacing = 40.0, height = 60.0;
  const double x0 = w.orthomap.centre.x() - w.orthomap.size / 2 + margin;
  const double x1 = w.orthomap.centre.x() + w.orthomap.size / 2 - margin;
  const double y0 = w.orthomap.centre.y() - w.orthomap.size / 2 + margin;
  const int legs = std::max(2, static_cast<int>((w.orthomap.size - 2 * margin) / spacing) + 1);
  std::vector<double> wp;
  double length = 0, y = y0;
  int leg = 0, dir = 1;
  while (length < w.flight.speed * seconds + 200.0) {
    const bool east = leg % 2 == 0;
    wp.insert(wp.end(), {east ? x0 : x1, y, height, east ? x1 : x0, y, height});
    length += (x1 - x0) + spacing;
    ++leg;
    if ((dir > 0 && y + spacing > y0 + (legs - 1) * spacing) || (dir < 0 && y - spacing < y0)) dir = -dir;
    y += dir * spacing;
  }
  return wp;
}

// Median, 0 for none (the report prints numbers).
double MedianOr0(const std::vector<double>& v) { return v.empty() ? 0.0 : vloc::Median(v); }

// What the flight measured, frame by frame, against the simulator's truth.
struct FlightTally {
  int lost = 0, calibrating = 0, recovered = 0, evaluated = 0, georef = 0, blends = 0;
  double se_height = 0, max_height = 0, dist = 0, se_route = 0, max_route = 0, max_route_dropout = 0, last_route = 0;
  double render_s = 0, cpu_all_s = 0, total_s = 0;
  std::vector<double> track_ms, mosaic_ms, cpu_track_ms;

  // One frame: its state, the truth, the GPS drop-out flag. Returns the estimated east/north (m).
  cv::Point2d Add(const vloc::mosaic::FrameState& s, const Eigen::Vector3d& truth, bool in_dropout, double lat0,
                  double lon0) {
    total_s += s.tracking_seconds + s.mosaic_seconds;
    if (s.status == vloc::mosaic::TrackStatus::kCalibrating) {
      ++calibrating;
      return s.route_local;
    }
    track_ms.push_back(1e3 * s.tracking_seconds);
    if (s.mosaic_updated) {
      mosaic_ms.push_back(1e3 * s.mosaic_seconds);
      ++blends;
    }
    if (s.status == vloc::mosaic::TrackStatus::kLost) ++lost;
    if (s.status == vloc::mosaic::TrackStatus::kRecovered) ++recovered;
    ++evaluated;
    const double eh = (s.height - truth.z()) / truth.z();
    se_height += eh * eh;
    max_height = std::max(max_height, std::abs(eh));
    cv::Point2d est(s.route_local);
    if (s.georeferenced) {
      est = vloc::mosaic::LatLonToEnu(s.latitude, s.longitude, lat0, lon0);
      const double e = std::hypot(est.x - truth.x(), est.y - truth.y());
      se_route += e * e;
      ++georef;
      max_route = std::max(max_route, e);
      if (in_dropout) max_route_dropout = std::max(max_route_dropout, e);
      last_route = e;
    }
    return est;
  }

  void Print(int frames, double fps, bool use_gps, const std::string& gps_use,
             const vloc::mosaic::MosaickerSummary& summary) const {
    std::cout << std::fixed << std::setprecision(3);
    std::cout << "flight: " << frames << " frames at " << fps << " fps, " << dist
              << " m flown horizontally, GPS " << (use_gps ? "on (drop-outs as configured)" : "off")
              << ", height filter gps_use=" << gps_use << "\n";
    std::cout << summary.calibration.Describe() << "\n";
    std::cout << "frames evaluated " << evaluated << " (calibrating " << calibrating << "), lost " << lost
              << ", recovered " << recovered << "\n";
    std::cout << "height error RMS " << 100 * std::sqrt(se_height / std::max(1, evaluated)) << " % of true height, max "
              << 100 * max_height << " %\n";
    if (georef > 0)
      std::cout << "route error (georeferenced frames " << georef << "): RMS " << std::sqrt(se_route / georef)
                << " m, max " << max_route << " m (" << 100 * max_route / dist << " % of distance), final " << last_route
                << " m, max in GPS drop-outs " << max_route_dropout << " m (" << 100 * max_route_dropout / dist << " %)\n";
    std::cout << "CPU per frame (process, all threads; independent of load): tracking+height median "
              << MedianOr0(cpu_track_ms) << " ms (frames not blended), all frames mean "
              << 1e3 * cpu_all_s / std::max(1, frames) << " ms\n";
    std::cout << "time per frame: tracking+height median " << MedianOr0(track_ms) << " ms, mosaic blend median "
              << MedianOr0(mosaic_ms) << " ms (" << blends << " blends); throughput " << frames / std::max(1e-9, total_s)
              << " frames/s, mosaic updates " << blends / std::max(1e-9, total_s) << " /s of processing; render "
              << 1e3 * render_s / std::max(1, frames) << " ms/frame (not counted)\n";
    std::cout << "memory: peak RSS " << PeakRssMb() << " MB, at the end " << StatusMb("VmRSS:")
              << " MB (process incl. simulator), canvas " << summary.canvas.bytes_in_memory / 1048576.0 << " MB, tiles "
              << summary.canvas.tiles_total << " (peak in memory " << summary.canvas.peak_tiles_in_memory << ", spilled "
              << summary.canvas.spills << ")\n";
    std::cout << summary.BriefReport() << "\n";
  }
};

// The GPS samples up to time t (s) into the mosaicker.
void FeedGps(const vloc::UavWorld& world, double t, int* gps_index, vloc::mosaic::UavMosaicker* mosaicker) {
  while (*gps_index < world.gps().NumSamples() && world.gps().SampleTime(*gps_index) <= t) {
    const vloc::UavGpsSample& g = world.gps().Sample((*gps_index)++);
    vloc::mosaic::GpsFix fix;
    fix.utime = g.utime;
    fix.valid = g.has_fix;
    fix.latitude = g.latitude;
    fix.longitude = g.longitude;
    fix.altitude = g.altitude;
    fix.height_above_ground = g.height_above_ground;
    fix.horizontal_sigma = g.horizontal_sigma;
    fix.vertical_sigma = g.vertical_sigma;
    mosaicker->AddGps(fix);
  }
}

// The mosaicker and simulator options from the files and the flags; false with one line on stderr.
bool LoadEvalOptions(const vloc::CommandLine& args, vloc::mosaic::MosaickerOptions* options,
                     vloc::UavWorldOptions* world_options) {
  const std::string config = args.Get("config", "config/procs/uav_mosaicker.yaml");
  const std::string sim_config = args.Get("sim-config", "config/procs/sim_uav.yaml");
  std::string error;
  try {
    *options = vloc::LoadOptionsFile<vloc::mosaic::MosaickerOptions>(config, "mosaicker");
    *world_options = vloc::LoadOptionsFile<vloc::UavWorldOptions>(sim_config, "world");
    if (args.Has("fps")) world_options->fps = args.GetDouble("fps", world_options->fps);
    if (args.Has("gps-use")) options->height_filter.gps_use = args.Get("gps-use");
    if (args.Has("survey")) {
      world_options->flight.waypoints = SurveyWaypoints(*world_options, args.GetDouble("survey", 600.0));
      world_options->gps.dropouts.clear();
    }
    if (args.Has("reregister")) options->reregister_every_n_frames = args.GetInt("reregister", 0);
    if (args.Has("reregister-scale")) options->reregister_scale = true;
    options->async_mosaic = false;  // blend inside ProcessFrame so each frame's mosaic time is measured
    if (!options->Check(&error) || !world_options->Check(&error)) throw vloc::ConfigError("command line: " + error);
  } catch (const std::exception& e) {
    std::cerr << "uav_mosaic_eval: " << e.what() << "\n";
    return false;
  }
  return true;
}

// One evaluated frame's CSV row (the estimate `est` east/north, m).
void WriteCsvRow(std::ofstream& csv, double t, const vloc::mosaic::FrameState& s, const Eigen::Vector3d& truth,
                 const cv::Point2d& est) {
  csv << t << "," << vloc::mosaic::ToString(s.status) << "," << s.height << "," << truth.z() << "," << est.x << ","
      << est.y << "," << truth.x() << "," << truth.y() << "," << s.gps_aided << "," << s.num_inliers << ","
      << s.num_foreground << "," << 1e3 * s.tracking_seconds << "," << 1e3 * s.mosaic_seconds << "\n";
}

// The process's memory and the canvas at flight time t.
void PrintMemory(double t, const vloc::mosaic::MosaickerSummary& now, double flown_m) {
  std::cout << "memory at t " << std::fixed << std::setprecision(0) << t << " s: RSS " << StatusMb("VmRSS:")
            << " MB, peak " << StatusMb("VmHWM:") << " MB, canvas tiles " << now.canvas.tiles_total << " ("
            << now.canvas.tiles_in_memory << " in memory, " << now.canvas.spills << " spills), " << std::setprecision(1)
            << flown_m << " m flown" << std::endl;
}

// The flight, frame by frame: the GPS up to each frame's time fed (with
// `use_gps`), the frame rendered (timed apart) and processed (its process
// CPU timed), tallied against the truth; the CSV rows (when open) and the
// memory every `memory_every` s of flight (0 = never).
FlightTally Fly(const vloc::UavWorld& world, const vloc::UavWorldOptions& world_options, int frames, bool use_gps,
                double memory_every, vloc::mosaic::UavMosaicker* mosaicker, std::ofstream* csv) {
  const double lat0 = world_options.gps.origin_latitude, lon0 = world_options.gps.origin_longitude;
  double next_memory = memory_every;
  int gps_index = 0;
  FlightTally tally;
  Eigen::Vector3d prev_truth = world.flight().StateAt(0).position;
  for (int i = 0; i < frames; ++i) {
    const double t = world.FrameTime(i);
    if (use_gps) FeedGps(world, t, &gps_index, mosaicker);
    const auto r0 = std::chrono::steady_clock::now();
    const cv::Mat frame = world.RenderFrame(t);
    tally.render_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - r0).count();
    const double cpu0 = ProcessCpuSeconds();
    const vloc::mosaic::FrameState s = mosaicker->ProcessFrame(frame, world.FrameUtime(i));
    const double cpu_s = ProcessCpuSeconds() - cpu0;
    tally.cpu_all_s += cpu_s;
    if (!s.mosaic_updated && s.status != vloc::mosaic::TrackStatus::kCalibrating) tally.cpu_track_ms.push_back(1e3 * cpu_s);
    const vloc::UavState truth = world.flight().StateAt(t);
    tally.dist += (truth.position.head<2>() - prev_truth.head<2>()).norm();
    prev_truth = truth.position;
    const cv::Point2d est = tally.Add(s, truth.position, world.gps().InDropout(t), lat0, lon0);
    if (s.status == vloc::mosaic::TrackStatus::kCalibrating) continue;
    if (csv->is_open()) WriteCsvRow(*csv, t, s, truth.position, est);
    if (memory_every > 0 && t >= next_memory) {
      PrintMemory(t, mosaicker->summary(), tally.dist);
      next_memory += memory_every;
    }
    if (i % 300 == 0)
      LOG(INFO) << "t " << t << " s: height " << s.height << " (true " << truth.position.z() << "), "
                << vloc::mosaic::ToString(s.status);
  }
  return tally;
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv, {"config", "sim-config", "fps", "duration", "gps-use", "out", "csv", "no-gps", "reregister", "reregister-scale", "survey", "memory-every", "help"}, &error) ||
      args.Has("help")) {
    std::cerr << (error.empty() ? "" : "uav_mosaic_eval: " + error + "\n")
              << "usage: uav_mosaic_eval [--config config/procs/uav_mosaicker.yaml] [--sim-config "
                 "config/procs/sim_uav.yaml] [--fps F] [--duration S] [--gps-use calibration|fused] [--out PNG] "
                 "[--csv FILE] [--no-gps] [--reregister N [--reregister-scale]] [--survey S] [--memory-every T]\n";
    return error.empty() ? 0 : 1;
  }
  vloc::mosaic::MosaickerOptions options;
  vloc::UavWorldOptions world_options;
  if (!LoadEvalOptions(args, &options, &world_options)) return 1;
  const bool use_gps = !args.Has("no-gps");
  vloc::UavWorld world(world_options);
  if (args.Has("memory-every"))
    std::cout << "memory with the simulated world built: RSS " << StatusMb("VmRSS:") << " MB, peak " << PeakRssMb()
              << " MB" << std::endl;
  const double duration = args.GetDouble("duration", args.GetDouble("survey", 0.0));
  int frames = world.NumFrames();
  if (duration > 0) frames = std::min(frames, static_cast<int>(duration * world_options.fps));
  vloc::mosaic::UavMosaicker mosaicker(options);
  std::ofstream csv;
  if (args.Has("csv")) {
    csv.open(args.Get("csv"));
    csv << "t,status,height,true_height,east,north,true_east,true_north,gps_aided,inliers,foreground,track_ms,mosaic_ms\n";
  }
  const FlightTally tally =
      Fly(world, world_options, frames, use_gps, args.GetDouble("memory-every", 0.0), &mosaicker, &csv);
  tally.Print(frames, world_options.fps, use_gps, options.height_filter.gps_use, mosaicker.summary());
  if (args.Has("out")) {
    if (!mosaicker.WriteMosaic(args.Get("out"), &error)) {
      std::cerr << "uav_mosaic_eval: " << error << "\n";
      return 1;
    }
    std::cout << "mosaic: " << args.Get("out") << "\n";
  }
  return 0;
}
