#include "uav_video_input.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "vloc/common/csv_table.h"
#include "vloc/mosaic/geotag.h"

namespace vloc {

bool UavVideoSource::Open(const std::string& path, double fps, std::string* error) {
  namespace fs = std::filesystem;
  if (fs::is_directory(path)) {
    for (const auto& entry : fs::directory_iterator(path)) {
      if (!entry.is_regular_file()) continue;
      std::string ext = entry.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
      if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff" || ext == ".bmp")
        files_.push_back(entry.path().string());
    }
    std::sort(files_.begin(), files_.end());
    if (files_.empty()) {
      *error = "video folder " + path + " holds no .png/.jpg/.tif/.bmp images";
      return false;
    }
    fps_ = fps > 0 ? fps : 30.0;
    if (fps <= 0) {
      // Photos: their EXIF capture times when every one has one and they increase.
      std::vector<int64_t> times;
      for (const auto& file : files_) {
        mosaic::ImageGeotag tag;
        if (!mosaic::ReadGeotag(file, &tag, nullptr) || !tag.has_time || (!times.empty() && tag.utime <= times.back()))
          break;
        times.push_back(tag.utime);
      }
      if (times.size() == files_.size()) {
        const int64_t first = times.front();
        for (auto& t : times) t -= first;
        file_utimes_ = times;
      }
    }
    return true;
  }
  if (path.find('%') == std::string::npos && !fs::exists(path)) {
    *error = "video " + path + " missing (give a video file, an image pattern like frames/%05d.png or a folder)";
    return false;
  }
  if (!capture_.open(path)) {
    *error = "video " + path + " cannot be opened by OpenCV (unknown format or corrupt)";
    return false;
  }
  const double container_fps = capture_.get(cv::CAP_PROP_FPS);
  fps_ = fps > 0 ? fps : (container_fps > 0 && container_fps < 1000 ? container_fps : 30.0);
  return true;
}

UavVideoSource::Status UavVideoSource::Next(cv::Mat* frame, int64_t* utime, std::string* problem) {
  *utime = static_cast<int64_t>(std::llround(index_ * 1e6 / fps_));
  if (!files_.empty()) {
    if (next_file_ >= files_.size()) return Status::kEnd;
    if (!file_utimes_.empty()) *utime = file_utimes_[next_file_];
    const std::string& file = files_[next_file_++];
    ++index_;
    *frame = cv::imread(file, cv::IMREAD_COLOR);
    if (frame->empty()) {
      *problem = "frame " + std::to_string(index_ - 1) + " " + file + " cannot be decoded (not an image or corrupt); skipped";
      return Status::kSkipped;
    }
    return Status::kFrame;
  }
  if (!capture_.read(*frame) || frame->empty()) return Status::kEnd;
  ++index_;
  if (frame->channels() == 1) cv::cvtColor(*frame, *frame, cv::COLOR_GRAY2BGR);
  return Status::kFrame;
}

TelemetryCsv UavVideoSource::GeotagTelemetry(double horizontal_sigma, std::string* how) const {
  TelemetryCsv out;
  int tagged = 0, relative = 0;
  for (size_t i = 0; i < files_.size(); ++i) {
    mosaic::ImageGeotag tag;
    std::string error;
    if (!mosaic::ReadGeotag(files_[i], &tag, &error)) {
      out.problems.push_back(error + "; no GPS for this photo");
      continue;
    }
    if (!tag.has_gps) continue;
    TelemetryFix f;
    f.utime = file_utimes_.empty() ? static_cast<int64_t>(std::llround(i * 1e6 / fps_)) : file_utimes_[i];
    f.fix = std::isfinite(tag.altitude) ? 2 : 1;
    f.latitude = tag.latitude;
    f.longitude = tag.longitude;
    f.altitude = std::isfinite(tag.altitude) ? tag.altitude : 0.0;
    f.height_above_ground = tag.relative_altitude;
    f.horizontal_sigma = horizontal_sigma;
    f.vertical_sigma = std::numeric_limits<double>::quiet_NaN();
    out.fixes.push_back(f);
    ++tagged;
    relative += std::isfinite(tag.relative_altitude) ? 1 : 0;
  }
  out.readable = tagged > 0;
  if (how)
    *how = std::to_string(tagged) + " of " + std::to_string(files_.size()) + " photos geotagged (EXIF GPS)" +
           (relative > 0 ? ", " + std::to_string(relative) + " with a DJI relative altitude (height above ground)" : "") +
           (file_utimes_.empty() ? "; times i / fps" : "; EXIF capture times");
  return out;
}

namespace {

// The telemetry table's columns by name (-1: absent); `us`: the time is
// utime (microseconds), else seconds.
struct TelemetryColumns {
  int time = -1, lat = -1, lon = -1, alt = -1, hag = -1, fix = -1, hs = -1, vs = -1;
  bool us = false;
};
TelemetryColumns ColumnsOf(const CsvTable& table) {
  TelemetryColumns c;
  c.time = table.Column({"utime"});
  c.us = c.time >= 0;
  if (!c.us) c.time = table.Column({"time", "t", "timestamp"});
  c.lat = table.Column({"latitude", "lat"}), c.lon = table.Column({"longitude", "lon"});
  c.alt = table.Column({"altitude", "alt"});
  c.hag = table.Column({"height_above_ground", "height"}), c.fix = table.Column({"fix"});
  c.hs = table.Column({"horizontal_sigma"}), c.vs = table.Column({"vertical_sigma"});
  return c;
}

// One row's fix: false with the problem that skips it (a value that is no
// number or out of its range; a time before `previous`).
bool ReadFixRow(const std::vector<std::string>& row, const std::string& where, const TelemetryColumns& c,
                double time_offset, int64_t previous, TelemetryFix* f, std::string* problem) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto number = [&](int column, const char* name, double lo, double hi, double* value) {
    if (column < 0) {
      *value = nan;
      return true;
    }
    const std::string& text = row[static_cast<size_t>(column)];
    if (!ParseCsvNumber(text, value)) {
      *problem = where + ": column '" + name + "' value '" + text + "' is not a number; row skipped";
      return false;
    }
    if (*value < lo || *value > hi) {
      *problem = where + ": column '" + name + "' = " + text + " out of range [" + std::to_string(lo) + ", " +
                 std::to_string(hi) + "]; row skipped";
      return false;
    }
    return true;
  };
  double t = 0, fix_value = 2;
  if (!number(c.time, c.us ? "utime" : "time", -1e12, 1e15, &t) || !number(c.fix, "fix", 0, 2, &fix_value)) return false;
  f->fix = c.fix < 0 ? 2 : static_cast<int>(fix_value);
  if (f->fix == 0) {
    f->latitude = f->longitude = f->altitude = nan;
  } else if (!number(c.lat, "latitude", -90, 90, &f->latitude) || !number(c.lon, "longitude", -180, 180, &f->longitude) ||
             !number(c.alt, "altitude", -500, 20000, &f->altitude)) {
    return false;
  }
  if (!number(c.hag, "height_above_ground", 0, 5000, &f->height_above_ground) ||
      !number(c.hs, "horizontal_sigma", 0, 1000, &f->horizontal_sigma) ||
      !number(c.vs, "vertical_sigma", 0, 1000, &f->vertical_sigma))
    return false;
  f->utime = c.us ? static_cast<int64_t>(std::llround(t + time_offset * 1e6))
                  : static_cast<int64_t>(std::llround((t + time_offset) * 1e6));
  if (f->utime < previous) {
    *problem = where + ": time goes back; row skipped";
    return false;
  }
  return true;
}

}  // namespace

TelemetryCsv ReadTelemetryCsv(const std::string& path, double time_offset) {
  TelemetryCsv out;
  CsvTable table;
  std::string error;
  if (!ReadCsvTable(path, &table, &error)) {
    out.problems.push_back(error + "; telemetry skipped");
    return out;
  }
  out.problems = table.problems;
  const TelemetryColumns c = ColumnsOf(table);
  if (c.time < 0 || c.lat < 0 || c.lon < 0 || c.alt < 0) {
    out.problems.push_back(path + ": header needs time (or utime), latitude, longitude, altitude columns; telemetry skipped");
    return out;
  }
  out.readable = true;
  int64_t previous = std::numeric_limits<int64_t>::min();
  for (size_t r = 0; r < table.rows.size(); ++r) {
    const std::string where = path + " line " + std::to_string(table.line_numbers[r]);
    TelemetryFix f;
    std::string problem;
    if (!ReadFixRow(table.rows[r], where, c, time_offset, previous, &f, &problem)) {
      out.problems.push_back(problem);
      continue;
    }
    previous = f.utime;
    out.fixes.push_back(f);
  }
  return out;
}

}  // namespace vloc
