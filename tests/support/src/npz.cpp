#include "vloc/testing/npz.h"

#include <zip.h>

#include <cstring>
#include <memory>
#include <regex>
#include <vector>

namespace vloc::testing {

namespace {

cv::Mat Fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return cv::Mat();
}

// The bytes of `member`, or empty.
std::vector<char> ReadMember(const std::string& npz_path, const std::string& member, std::string* error) {
  int code = 0;
  std::unique_ptr<zip_t, decltype(&zip_close)> archive(zip_open(npz_path.c_str(), ZIP_RDONLY, &code), &zip_close);
  if (!archive) {
    if (error) *error = npz_path + ": cannot open as a zip archive (code " + std::to_string(code) + ")";
    return {};
  }
  zip_stat_t st;
  if (zip_stat(archive.get(), member.c_str(), 0, &st) != 0 || !(st.valid & ZIP_STAT_SIZE)) {
    if (error) *error = npz_path + ": no member " + member;
    return {};
  }
  std::unique_ptr<zip_file_t, decltype(&zip_fclose)> file(zip_fopen(archive.get(), member.c_str(), 0), &zip_fclose);
  std::vector<char> bytes(st.size);
  if (!file || zip_fread(file.get(), bytes.data(), st.size) != static_cast<zip_int64_t>(st.size)) {
    if (error) *error = npz_path + ": cannot read " + member;
    return {};
  }
  return bytes;
}

}  // namespace

cv::Mat ReadNpzFloat2d(const std::string& npz_path, const std::string& member, std::string* error) {
  const std::vector<char> b = ReadMember(npz_path, member, error);
  if (b.empty()) return cv::Mat();
  // .npy: magic, version (1 or 2), header length (2 or 4 bytes LE), a Python dict literal.
  if (b.size() < 12 || std::memcmp(b.data(), "\x93NUMPY", 6) != 0) return Fail(error, member + ": not a .npy array");
  const int major = static_cast<unsigned char>(b[6]);
  const size_t len_bytes = major == 1 ? 2 : 4, start = 8 + len_bytes;
  size_t header_len = 0;
  for (size_t i = 0; i < len_bytes; ++i) header_len |= static_cast<size_t>(static_cast<unsigned char>(b[8 + i])) << (8 * i);
  if (start + header_len > b.size()) return Fail(error, member + ": truncated header");
  const std::string header(b.data() + start, header_len);
  std::smatch m;
  if (header.find("'descr': '<f4'") == std::string::npos || header.find("'fortran_order': False") == std::string::npos ||
      !std::regex_search(header, m, std::regex(R"('shape': \((\d+), (\d+)\))")))
    return Fail(error, member + ": expected a little-endian float32 C-order 2-D array, header " + header);
  const int rows = std::stoi(m[1]), cols = std::stoi(m[2]);
  const size_t data_bytes = static_cast<size_t>(rows) * cols * 4;
  if (start + header_len + data_bytes != b.size()) return Fail(error, member + ": data size does not match the shape");
  cv::Mat out(rows, cols, CV_32F);
  std::memcpy(out.data, b.data() + start + header_len, data_bytes);
  return out;
}

}  // namespace vloc::testing
