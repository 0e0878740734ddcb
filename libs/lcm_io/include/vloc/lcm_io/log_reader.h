#pragma once
// Reads an LCM log event by event and says afterwards whether the whole
// file was read: lcm::LogFile just stops at a truncated or corrupt event,
// which a tool must not mistake for the end of the log.
//   LogReader log(path);
//   if (!log.good()) ...;            // log.error() names the file
//   while (const lcm::LogEvent* ev = log.Next()) ...;
//   if (!log.EndProblem().empty()) ...;  // truncated, corrupt, empty or not a log

#include <lcm/lcm-cpp.hpp>

#include <cstdint>
#include <memory>
#include <string>

namespace vloc {

class LogReader {
 public:
  explicit LogReader(const std::string& path);
  bool good() const { return log_ != nullptr; }
  const std::string& error() const { return error_; }

  // The next event, or null at the end (or where the log stops being readable).
  const lcm::LogEvent* Next();
  int64_t events() const { return events_; }
  int64_t position() const { return good_end_; }  // bytes read as whole events
  int64_t file_size() const { return file_size_; }

  // "" when every byte of the file was read as events; else one line saying
  // where and why the reading stopped (no events at all: empty or not an
  // LCM log; bytes after the last whole event: truncated or corrupt).
  std::string EndProblem() const;

 private:
  std::string path_, error_;
  std::unique_ptr<lcm::LogFile> log_;
  int64_t events_ = 0;
  int64_t good_end_ = 0;   // byte after the last whole event
  int64_t file_size_ = 0;
  int64_t skipped_ = 0;    // bytes LCM skipped to find the next event
};

}  // namespace vloc
