#include "vloc/common/printable.h"

#include <algorithm>
#include <cstdio>

namespace vloc {

namespace {

bool IsControl(char c) {
  const auto u = static_cast<unsigned char>(c);
  return u < 0x20 || u == 0x7f;
}

// Bytes of the UTF-8 character that starts at text[i]; 0 when none does
// (a stray continuation or lead byte, a character cut short).
size_t Utf8Length(std::string_view text, size_t i) {
  const auto u = static_cast<unsigned char>(text[i]);
  const size_t n = u >= 0xc2 && u <= 0xdf ? 2 : u >= 0xe0 && u <= 0xef ? 3 : u >= 0xf0 && u <= 0xf4 ? 4 : 0;
  if (n == 0 || i + n > text.size()) return 0;
  for (size_t k = 1; k < n; ++k)
    if ((static_cast<unsigned char>(text[i + k]) & 0xc0) != 0x80) return 0;
  return n;
}

// The text's character at text[i] as it is printed; *used: its bytes.
std::string PrintedAt(std::string_view text, size_t i, size_t* used) {
  const char c = text[i];
  *used = 1;
  if (c == '\\') return "\\\\";
  if (c == '\n') return "\\n";
  if (!IsControl(c) && static_cast<unsigned char>(c) < 0x80) return std::string(1, c);
  if (const size_t n = IsControl(c) ? 0 : Utf8Length(text, i); n > 0) {
    *used = n;
    return std::string(text.substr(i, n));
  }
  char hex[8];
  std::snprintf(hex, sizeof(hex), "\\x%02x", static_cast<unsigned char>(c));
  return hex;
}

}  // namespace

bool HasControlCharacters(std::string_view text) { return std::any_of(text.begin(), text.end(), IsControl); }

std::string Printable(std::string_view text, std::size_t max_chars) {
  std::string out;
  for (size_t i = 0, used = 0; i < text.size(); i += used) {
    const std::string piece = PrintedAt(text, i, &used);
    if (out.size() + piece.size() > max_chars) return out + "...";
    out += piece;
  }
  return out;
}

}  // namespace vloc
