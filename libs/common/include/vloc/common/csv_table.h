#pragma once
// A small reader for the CSV files of recorded sensor data: one header row
// of named columns, comma-separated values, '#' comment lines and blank
// lines ignored, surrounding spaces trimmed. Header-only. Drivers look up
// columns by name and report every bad value in one line with its line
// number (see procs/imu_odometry_driver, procs/uav_video_driver).

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <initializer_list>
#include <sstream>
#include <string>
#include <vector>

namespace vloc {

struct CsvTable {
  std::string path;
  std::vector<std::string> header;              // column names as written
  std::vector<std::vector<std::string>> rows;   // fields per data row
  std::vector<int> line_numbers;                // 1-based file line of each row
  std::vector<std::string> problems;            // rows skipped while reading (wrong field count)

  // Index of the first column whose name is one of `names`, else -1.
  int Column(std::initializer_list<const char*> names) const {
    for (const char* n : names)
      for (size_t i = 0; i < header.size(); ++i)
        if (header[i] == n) return static_cast<int>(i);
    return -1;
  }
};

inline std::string TrimCsvField(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r\n\"");
  if (b == std::string::npos) return "";
  const size_t e = s.find_last_not_of(" \t\r\n\"");
  return s.substr(b, e - b + 1);
}

// Strict number parse: the whole field must be a finite number.
inline bool ParseCsvNumber(const std::string& text, double* value) {
  if (text.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (errno != 0 || end != text.c_str() + text.size() || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

// False with one line in *error when the file cannot be read or has no header.
inline bool ReadCsvTable(const std::string& path, CsvTable* table, std::string* error) {
  std::ifstream in(path);
  table->path = path;
  if (!in) {
    *error = path + ": cannot open (missing or not readable; check the path)";
    return false;
  }
  std::string line;
  int number = 0;
  auto split = [](const std::string& l) {
    std::vector<std::string> fields;
    std::stringstream ss(l);
    std::string f;
    while (std::getline(ss, f, ',')) fields.push_back(TrimCsvField(f));
    if (!l.empty() && l.back() == ',') fields.push_back("");
    return fields;
  };
  while (std::getline(in, line)) {
    ++number;
    const std::string t = TrimCsvField(line);
    if (t.empty() || t[0] == '#') continue;
    if (table->header.empty()) {
      table->header = split(t);
      continue;
    }
    std::vector<std::string> fields = split(t);
    if (fields.size() != table->header.size()) {
      table->problems.push_back(path + " line " + std::to_string(number) + ": " + std::to_string(fields.size()) +
                                " fields, the header has " + std::to_string(table->header.size()) + "; row skipped");
      continue;
    }
    table->rows.push_back(std::move(fields));
    table->line_numbers.push_back(number);
  }
  if (table->header.empty()) {
    *error = path + ": empty (expected a header row of column names)";
    return false;
  }
  return true;
}

}  // namespace vloc
