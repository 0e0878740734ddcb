#include "vloc/console/static_files.h"

#include <map>
#include <sstream>

namespace vloc {

namespace {

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// True when `file` lies inside `root` (both canonical).
bool IsWithin(const std::filesystem::path& root, const std::filesystem::path& file) {
  const std::string r = root.string(), f = file.string();
  return f.size() > r.size() && f.compare(0, r.size(), r) == 0 && f[r.size()] == '/';
}

// Rejects what no file of ours is named: "..", ".", dot-files, empty names inside.
bool CheckComponents(const std::string& path, std::string* why) {
  std::istringstream in(path.substr(1));
  std::string part;
  while (std::getline(in, part, '/')) {
    if (part.empty()) continue;
    if (part[0] == '.') {
      *why = "path component '" + part + "' is not allowed";
      return false;
    }
  }
  return true;
}

}  // namespace

bool PercentDecode(const std::string& in, std::string* out) {
  out->clear();
  for (size_t i = 0; i < in.size(); ++i) {
    if (in[i] != '%') {
      out->push_back(in[i]);
      continue;
    }
    if (i + 2 >= in.size()) return false;
    const int hi = HexValue(in[i + 1]), lo = HexValue(in[i + 2]);
    if (hi < 0 || lo < 0) return false;
    out->push_back(static_cast<char>(hi * 16 + lo));
    i += 2;
  }
  return true;
}

bool ResolveStaticPath(const std::filesystem::path& root, const std::string& url_path, std::filesystem::path* file,
                       std::string* why) {
  std::string path;
  if (!PercentDecode(url_path, &path)) {
    *why = "malformed percent-encoding";
    return false;
  }
  if (path.empty() || path[0] != '/') {
    *why = "path must start with '/'";
    return false;
  }
  if (path.find('\0') != std::string::npos || path.find('\\') != std::string::npos) {
    *why = "NUL or backslash in path";
    return false;
  }
  if (path.back() == '/') path += "index.html";
  if (!CheckComponents(path, why)) return false;
  std::error_code ec;
  const size_t start = path.find_first_not_of('/');  // "//etc" is relative to the root too
  const std::filesystem::path real =
      std::filesystem::canonical(root / (start == std::string::npos ? "" : path.substr(start)), ec);
  if (ec) {
    *why = "no such file";
    return false;
  }
  if (!IsWithin(root, real)) {
    *why = "outside the web folder";
    return false;
  }
  if (!std::filesystem::is_regular_file(real, ec)) {
    *why = "not a file";
    return false;
  }
  *file = real;
  return true;
}

std::string ContentTypeOf(const std::filesystem::path& file) {
  static const std::map<std::string, std::string> kTypes = {{".html", "text/html; charset=utf-8"},
                                                            {".js", "text/javascript; charset=utf-8"},
                                                            {".css", "text/css; charset=utf-8"},
                                                            {".png", "image/png"},
                                                            {".jpg", "image/jpeg"},
                                                            {".svg", "image/svg+xml"},
                                                            {".json", "application/json"},
                                                            {".ico", "image/x-icon"}};
  const auto it = kTypes.find(file.extension().string());
  return it == kTypes.end() ? "application/octet-stream" : it->second;
}

}  // namespace vloc
