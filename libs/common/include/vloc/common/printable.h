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

// `text` with its control characters and any byte that is no UTF-8
// character escaped (\n, \xNN) and its backslashes doubled (\\, so no
// escape can be forged); when that is longer than `max_chars`, as many
// whole characters of it as fit and "...".
std::string Printable(std::string_view text, std::size_t max_chars = std::string_view::npos);

}  // namespace vloc
