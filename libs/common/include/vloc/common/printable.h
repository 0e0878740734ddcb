#pragma once
// Text from a file, a message or a process name as it may appear inside
// one log or error line, whatever its bytes.

#include <cstddef>
#include <string>
#include <string_view>

namespace vloc {

// True when `text` holds a control character (a newline in a name would
// forge a line in a log).
bool HasControlCharacters(std::string_view text);

// `text` with its control characters escaped (\n, \xNN) and its
// backslashes doubled (\\, so no escape can be forged); of a longer text
// its first `max_chars` bytes and "...".
std::string Printable(std::string_view text, std::size_t max_chars = std::string_view::npos);

}  // namespace vloc
