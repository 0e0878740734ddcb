#pragma once
// The console serves the files of one folder and nothing else: a URL path
// is percent-decoded once, must be absolute, may not hold "..", dot-files,
// backslashes or NUL, and must resolve (symlinks followed) to a regular
// file inside the folder.

#include <filesystem>
#include <string>

namespace vloc {

// Decodes %XX escapes (and nothing else); false on a malformed escape.
bool PercentDecode(const std::string& in, std::string* out);

// The file `url_path` (the part of the request target before '?') names
// under `root` (canonical). False and *why (one line) when it names none.
bool ResolveStaticPath(const std::filesystem::path& root, const std::string& url_path, std::filesystem::path* file,
                       std::string* why);

// MIME type by extension ("application/octet-stream" when unknown).
std::string ContentTypeOf(const std::filesystem::path& file);

}  // namespace vloc
