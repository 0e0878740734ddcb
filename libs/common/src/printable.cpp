#include "vloc/common/printable.h"

#include <algorithm>
#include <cstdio>

namespace vloc {

namespace {
bool IsControl(char c) {
  const auto u = static_cast<unsigned char>(c);
  return u < 0x20 || u == 0x7f;
}
}  // namespace

bool HasControlCharacters(std::string_view text) { return std::any_of(text.begin(), text.end(), IsControl); }

std::string Printable(std::string_view text, std::size_t max_chars) {
  std::string out;
  for (const char c : text.substr(0, max_chars)) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '\n') {
      out += "\\n";
    } else if (IsControl(c)) {
      char hex[8];
      std::snprintf(hex, sizeof(hex), "\\x%02x", static_cast<unsigned char>(c));
      out += hex;
    } else {
      out += c;
    }
  }
  if (text.size() > max_chars) out += "...";
  return out;
}

}  // namespace vloc
