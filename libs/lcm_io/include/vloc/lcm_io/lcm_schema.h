#pragma once
// Bytes from the bus are untrusted input. The C++ decoders of lcm-gen 1.3.1
// trust them: a string length of 0 or of 2^31 makes them read far past the
// buffer (SIGSEGV), an array count of 2^31 makes them allocate gigabytes.
// LcmSchema checks raw bytes against the message type's schema before any
// decoder sees them. The schemas are parsed from the project's .lcm files,
// embedded at build time, so the check holds for every generated type,
// present and future; a test proves each parsed schema gives the same
// fingerprint as lcm-gen's getHash().
//
// The same walk finds non-finite numbers: a float or double field may be
// NaN only when its comment in the .lcm file says so (e.g. "NaN when not
// georeferenced"); infinities never.

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace vloc {

struct LcmMember {
  std::string name;
  std::string type;                 // primitive name, or the struct's short name
  std::vector<std::string> dims;    // each a number or the name of an earlier integer member
  bool nan_allowed = false;         // float/double whose comment documents NaN
  int line = 0;
};

struct LcmStruct {
  std::string name;                 // short name, e.g. "tie_points_t"
  std::string package;              // e.g. "vloc"
  std::vector<LcmMember> members;   // constants excluded
};

// Where one value sits in an encoded message (for structure-aware tests).
struct LcmFieldSpan {
  enum class Kind { kNumber, kStringLength };
  std::string path;    // e.g. "points[3].observations[0].u"
  std::string type;    // primitive type of the value ("int32_t" for a string length)
  size_t offset = 0;   // byte offset in the encoded message
  size_t size = 0;     // bytes
  Kind kind = Kind::kNumber;
};

class LcmSchema {
 public:
  // Parses the text of one .lcm file. Throws std::invalid_argument naming
  // `file_name`, the line and what was expected.
  void AddSource(const std::string& file_name, const std::string& text);

  // The schemas of all of vloc's message types (parsed once, thread-safe).
  static const LcmSchema& Vloc();

  bool Has(const std::string& type) const;
  std::vector<std::string> TypeNames() const;
  const LcmStruct* Find(const std::string& type) const;

  // The fingerprint lcm-gen computes for `type` (what Msg::getHash() returns).
  int64_t Fingerprint(const std::string& type) const;
  // The type whose fingerprint is `hash`, or "" when none.
  std::string TypeOfFingerprint(int64_t hash) const;

  // True when data[0, size) is exactly one complete encoding of `type`:
  // the fingerprint matches, every string length is in [1, bytes left],
  // every array count fits in the bytes left, nothing trails. Otherwise
  // false and *error (when not null) names the field and the problem.
  bool Check(const std::string& type, const uint8_t* data, size_t size, std::string* error = nullptr) const;

  // The number of float/double values that are infinite, or NaN where the
  // schema does not allow NaN; *first (when not null) names the first such
  // field. Bytes that fail Check() count as one bad value.
  int CountNonFinite(const std::string& type, const uint8_t* data, size_t size,
                     std::string* first = nullptr) const;

  // The numbers and string lengths of a well-formed message (Check() true;
  // else empty), at most `per_array` elements of each array.
  std::vector<LcmFieldSpan> Spans(const std::string& type, const uint8_t* data, size_t size,
                                  int per_array = 4) const;

 private:
  std::map<std::string, LcmStruct> structs_;  // by short name
};

}  // namespace vloc
