#include "sensor_csv.h"

#include <cmath>

#include "vloc/common/csv_table.h"

namespace vloc {
namespace {

struct ColumnSpec {
  const char* label;  // for messages
  std::vector<const char*> names;
};

// Reads the table and resolves the time column and `columns`; false with a
// file-level problem when something is missing.
bool OpenTable(const std::string& path, const std::vector<ColumnSpec>& columns, CsvTable* table, int* time_column,
               bool* time_in_us, std::vector<int>* indices, std::vector<std::string>* problems) {
  std::string error;
  if (!ReadCsvTable(path, table, &error)) {
    problems->push_back(error + "; file skipped");
    return false;
  }
  problems->insert(problems->end(), table->problems.begin(), table->problems.end());
  *time_column = table->Column({"utime"});
  *time_in_us = *time_column >= 0;
  if (*time_column < 0) *time_column = table->Column({"time", "t", "timestamp"});
  std::string needed = "time (s) or utime (us)";
  for (const auto& c : columns) needed += std::string(", ") + c.label;
  if (*time_column < 0) {
    problems->push_back(path + ": no time or utime column in the header (need " + needed + "); file skipped");
    return false;
  }
  for (const auto& c : columns) {
    int index = -1;
    for (const char* n : c.names) {
      index = table->Column({n});
      if (index >= 0) break;
    }
    if (index < 0) {
      problems->push_back(path + ": no column '" + c.label + "' in the header (need " + needed + "); file skipped");
      return false;
    }
    indices->push_back(index);
  }
  return true;
}

// Parses row `r`: time and the columns, with |value| <= limit per column.
bool ParseRow(const CsvTable& table, size_t r, int time_column, bool time_in_us, const std::vector<ColumnSpec>& specs,
              const std::vector<int>& indices, const std::vector<double>& limits, const std::vector<const char*>& units,
              int64_t previous_utime, int64_t* utime, std::vector<double>* values, std::string* problem) {
  const auto& row = table.rows[r];
  const std::string where = table.path + " line " + std::to_string(table.line_numbers[r]);
  double t = 0;
  if (!ParseCsvNumber(row[static_cast<size_t>(time_column)], &t) || t < 0) {
    *problem = where + ": time '" + row[static_cast<size_t>(time_column)] + "' is not a number >= 0; row skipped";
    return false;
  }
  *utime = time_in_us ? static_cast<int64_t>(std::llround(t)) : static_cast<int64_t>(std::llround(t * 1e6));
  if (*utime < previous_utime) {
    *problem = where + ": time goes back (" + row[static_cast<size_t>(time_column)] + "); row skipped";
    return false;
  }
  values->clear();
  for (size_t k = 0; k < indices.size(); ++k) {
    const std::string& text = row[static_cast<size_t>(indices[k])];
    double v = 0;
    if (!ParseCsvNumber(text, &v)) {
      *problem = where + ": column '" + specs[k].label + "' value '" + text + "' is not a number; row skipped";
      return false;
    }
    if (std::abs(v) > limits[k]) {
      *problem = where + ": column '" + specs[k].label + "' = " + text + " " + units[k] + " out of range (|value| <= " +
                 std::to_string(limits[k]) + "); row skipped";
      return false;
    }
    values->push_back(v);
  }
  return true;
}

// Reads every row of `path` with the time and `specs` columns (|value| <=
// `bounds`), and hands the values to `fill`, which may reject the row with
// a problem line. Keeps the rows in time order.
template <class Sample, class Fill>
bool ReadSamples(const std::string& path, const std::vector<ColumnSpec>& specs, const std::vector<double>& bounds,
                 const std::vector<const char*>& units, std::vector<Sample>* samples,
                 std::vector<std::string>* problems, Fill fill) {
  CsvTable table;
  int time_column = -1;
  bool us = false;
  std::vector<int> indices;
  if (!OpenTable(path, specs, &table, &time_column, &us, &indices, problems)) return false;
  int64_t previous = 0;
  std::vector<double> v;
  for (size_t r = 0; r < table.rows.size(); ++r) {
    Sample s;
    std::string problem;
    if (!ParseRow(table, r, time_column, us, specs, indices, bounds, units, previous, &s.utime, &v, &problem) ||
        !fill(v, table.path + " line " + std::to_string(table.line_numbers[r]), &s, &problem)) {
      problems->push_back(problem);
      continue;
    }
    previous = s.utime;
    samples->push_back(s);
  }
  return true;
}

}  // namespace

ImuCsv ReadImuCsv(const std::string& path, const SensorCsvLimits& limits) {
  ImuCsv out;
  const std::vector<ColumnSpec> specs = {{"gx", {"gx", "wx", "gyro_x"}}, {"gy", {"gy", "wy", "gyro_y"}},
                                         {"gz", {"gz", "wz", "gyro_z"}}, {"ax", {"ax", "acc_x"}},
                                         {"ay", {"ay", "acc_y"}},        {"az", {"az", "acc_z"}}};
  const double w = limits.max_angular_velocity, a = limits.max_acceleration;
  out.readable = ReadSamples(path, specs, {w, w, w, a, a, a}, {"rad/s", "rad/s", "rad/s", "m/s^2", "m/s^2", "m/s^2"},
                             &out.samples, &out.problems,
                             [](const std::vector<double>& v, const std::string&, ImuSample* s, std::string*) {
                               s->angular_velocity = Eigen::Vector3d(v[0], v[1], v[2]);
                               s->linear_acceleration = Eigen::Vector3d(v[3], v[4], v[5]);
                               return true;
                             });
  return out;
}

WheelCsv ReadWheelCsv(const std::string& path, const SensorCsvLimits& limits) {
  WheelCsv out;
  const std::vector<ColumnSpec> specs = {{"distance", {"distance", "odometer"}}, {"speed", {"speed", "velocity"}}};
  out.readable = ReadSamples(
      path, specs, {1e7, limits.max_speed}, {"m", "m/s"}, &out.samples, &out.problems,
      [](const std::vector<double>& v, const std::string& where, WheelOdometrySample* s, std::string* problem) {
        if (v[0] < 0) {
          *problem = where + ": column 'distance' = " + std::to_string(v[0]) +
                     " m out of range (cumulative distance must be >= 0); row skipped";
          return false;
        }
        s->distance = v[0];
        s->speed = v[1];
        return true;
      });
  return out;
}

}  // namespace vloc
