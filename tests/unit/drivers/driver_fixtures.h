#pragma once
// Small recorded-data fixtures for the driver tests, written into a temp
// folder: Navcam images + manifest (with bad rows), IMU/wheel CSVs (with bad
// values), UAV frames (folder and MJPG video) + telemetry CSV.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <string>

namespace vloc::testing {

inline std::string MakeFixtureDir(const std::string& name) {
  const std::string dir = std::filesystem::temp_directory_path().string() + "/vloc_drivers_" + name + "_" +
                          std::to_string(getpid());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// A grey image whose mean is `level` (identifies it after a round trip).
inline cv::Mat FixtureImage(int level, int width = 64, int height = 48) {
  cv::Mat m(height, width, CV_8UC1, cv::Scalar(level));
  cv::circle(m, cv::Point(width / 2, height / 2), 5, cv::Scalar(255 - level), cv::FILLED);
  return m;
}

// Site 0: pairs 0, 1 good, pair 2 a corrupt image. Site 1: pair 0 good,
// pair 1 tilt out of range, pair 2 a missing file; one row without 'time'.
// Good pairs: (0,0) level 10, (0,1) level 20, (1,0) level 40.
inline std::string WriteNavcamFixture(const std::string& dir) {
  std::filesystem::create_directories(dir + "/site0");
  std::filesystem::create_directories(dir + "/site1");
  cv::imwrite(dir + "/site0/L0.png", FixtureImage(10));
  cv::imwrite(dir + "/site0/R0.png", FixtureImage(11));
  cv::imwrite(dir + "/site0/L1.png", FixtureImage(20));
  cv::imwrite(dir + "/site0/R1.png", FixtureImage(21));
  std::ofstream(dir + "/site0/L2.png") << "this is not a png";
  cv::imwrite(dir + "/site0/R2.png", FixtureImage(31));
  cv::imwrite(dir + "/site1/L0.png", FixtureImage(40));
  cv::imwrite(dir + "/site1/R0.png", FixtureImage(41));
  cv::imwrite(dir + "/site1/L1.png", FixtureImage(50));
  cv::imwrite(dir + "/site1/R1.png", FixtureImage(51));
  cv::imwrite(dir + "/site1/L2.png", FixtureImage(60));
  const std::string manifest = dir + "/manifest.yaml";
  std::ofstream(manifest) << "angle_unit: deg\n"
                             "pairs:\n"
                             "  - {site: 0, pair: 0, pan: 30, tilt: 20, time: 100.0, left: site0/L0.png, right: site0/R0.png}\n"
                             "  - {site: 0, pair: 1, pan: 0, tilt: 20, time: 100.5, left: site0/L1.png, right: site0/R1.png}\n"
                             "  - {site: 0, pair: 2, pan: -30, tilt: 20, time: 101.0, left: site0/L2.png, right: site0/R2.png}\n"
                             "  - {site: 1, pair: 0, pan: 30, tilt: 25, time: 160.0, left: site1/L0.png, right: site1/R0.png}\n"
                             "  - {site: 1, pair: 1, pan: 0, tilt: 120, time: 160.5, left: site1/L1.png, right: site1/R1.png}\n"
                             "  - {site: 1, pair: 2, pan: -30, tilt: 25, time: 161.0, left: site1/L2.png, right: site1/R2.png}\n"
                             "  - {site: 1, pair: 3, pan: -60, tilt: 25, left: site1/L0.png, right: site1/R0.png}\n";
  return manifest;
}

// 10 IMU rows at 100 Hz, of which line 5 has 'abc' and line 8 has gz = 50 rad/s.
inline std::string WriteImuFixture(const std::string& dir) {
  const std::string path = dir + "/imu.csv";
  std::ofstream f(path);
  f << "# recorded IMU\ntime,gx,gy,gz,ax,ay,az,temperature\n";
  for (int i = 0; i < 10; ++i) {
    const double t = 10.0 + i * 0.01;
    if (i == 2) f << t << ",abc,0,0,0,0,9.81,20\n";
    else if (i == 5) f << t << ",0,0,50,0,0,9.81,20\n";
    else f << t << "," << 0.001 * i << ",0,0.01,0.1,0,9.81,20\n";
  }
  return path;
}

// 5 wheel rows (utime column), line 4 with speed 99 m/s.
inline std::string WriteWheelFixture(const std::string& dir) {
  const std::string path = dir + "/wheel.csv";
  std::ofstream f(path);
  f << "utime,distance,speed\n";
  for (int i = 0; i < 5; ++i)
    f << 10000000 + i * 20000 << "," << 0.001 * i << "," << (i == 2 ? 99.0 : 0.05) << "\n";
  return path;
}

// A folder of 5 PNG frames (level 30 * i), frame 2 corrupt.
inline std::string WriteFrameFolder(const std::string& dir) {
  const std::string folder = dir + "/frames";
  std::filesystem::create_directories(folder);
  for (int i = 0; i < 5; ++i) {
    const std::string name = folder + "/frame_" + std::to_string(i) + ".png";
    if (i == 2) std::ofstream(name) << "broken";
    else {
      cv::Mat bgr;
      cv::cvtColor(FixtureImage(30 * i + 10, 160, 120), bgr, cv::COLOR_GRAY2BGR);
      cv::imwrite(name, bgr);
    }
  }
  return folder;
}

// An MJPG .avi of `frames` frames at 10 fps; empty string when no writer.
inline std::string WriteVideo(const std::string& dir, int frames) {
  const std::string path = dir + "/flight.avi";
  cv::VideoWriter writer(path, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10.0, cv::Size(160, 120));
  if (!writer.isOpened()) return "";
  for (int i = 0; i < frames; ++i) {
    cv::Mat bgr;
    cv::cvtColor(FixtureImage(20 * i + 10, 160, 120), bgr, cv::COLOR_GRAY2BGR);
    writer.write(bgr);
  }
  return path;
}

// Telemetry at 5 Hz from t = 0: 4 rows, line 4 with latitude 95; row 3 has no fix.
inline std::string WriteTelemetry(const std::string& dir) {
  const std::string path = dir + "/telemetry.csv";
  std::ofstream(path) << "time,latitude,longitude,altitude,height_above_ground,fix\n"
                         "0.0,45.0001,9.0001,150.0,30.0,2\n"
                         "0.2,45.0002,9.0002,151.0,31.0,2\n"
                         "0.4,95.0,9.0003,152.0,32.0,2\n"
                         "0.6,,,,33.0,0\n";
  return path;
}

}  // namespace vloc::testing
