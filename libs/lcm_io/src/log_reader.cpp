#include "vloc/lcm_io/log_reader.h"

#include <cstdio>
#include <filesystem>

namespace vloc {

LogReader::LogReader(const std::string& path) : path_(path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    error_ = "cannot read LCM log " + path + ": no such file";
    return;
  }
  file_size_ = static_cast<int64_t>(std::filesystem::file_size(path, ec));
  auto log = std::make_unique<lcm::LogFile>(path, "r");
  if (!log->good()) {
    error_ = "cannot read LCM log " + path + " (check the path and its permissions)";
    return;
  }
  log_ = std::move(log);
}

const lcm::LogEvent* LogReader::Next() {
  if (!log_) return nullptr;
  const int64_t before = static_cast<int64_t>(std::ftell(log_->getFilePtr()));
  const lcm::LogEvent* ev = log_->readNextEvent();
  if (ev) {
    ++events_;
    good_end_ = static_cast<int64_t>(std::ftell(log_->getFilePtr()));
    // sync word, event number, timestamp, two lengths, channel, data
    const int64_t event_bytes = 28 + static_cast<int64_t>(ev->channel.size()) + ev->datalen;
    if (good_end_ - before > event_bytes) skipped_ += good_end_ - before - event_bytes;  // LCM resynchronised
  }
  return ev;
}

std::string LogReader::EndProblem() const {
  if (!log_) return error_;
  if (events_ == 0)
    return path_ + " holds no LCM events (" + std::to_string(file_size_) + " bytes: empty, or not an LCM log)";
  if (skipped_ > 0)
    return path_ + ": " + std::to_string(skipped_) + " corrupt bytes between events were skipped (" +
           std::to_string(events_) + " events read); the log is damaged";
  if (good_end_ < file_size_)
    return path_ + " stops being a readable LCM log at byte " + std::to_string(good_end_) + " of " +
           std::to_string(file_size_) + " (truncated or corrupt); the " + std::to_string(events_) +
           " events before it were used";
  return "";
}

}  // namespace vloc
