#include "vloc/lcm_io/lcm_schema.h"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <set>
#include <stdexcept>

#include "vloc/lcm_schema_text.h"

namespace vloc {
namespace {

// ---------------------------------------------------------------- parsing

struct Token {
  std::string text;
  int line = 0;
};

struct Tokens {
  std::vector<Token> tokens;
  std::map<int, std::string> line_comments;  // line -> text of its // comment
};

Tokens Tokenize(const std::string& s) {
  Tokens out;
  int line = 1;
  size_t i = 0;
  while (i < s.size()) {
    const char c = s[i];
    if (c == '\n') {
      ++line;
      ++i;
    } else if (std::isspace(static_cast<unsigned char>(c))) {
      ++i;
    } else if (s.compare(i, 2, "//") == 0) {
      const size_t end = s.find('\n', i);
      out.line_comments[line] += s.substr(i + 2, end == std::string::npos ? std::string::npos : end - i - 2);
      i = end == std::string::npos ? s.size() : end;
    } else if (s.compare(i, 2, "/*") == 0) {
      const size_t end = s.find("*/", i + 2);
      const size_t stop = end == std::string::npos ? s.size() : end + 2;
      for (size_t k = i; k < stop; ++k) line += s[k] == '\n';
      i = stop;
    } else if (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '+' || c == '.') {
      size_t j = i;
      while (j < s.size() && (std::isalnum(static_cast<unsigned char>(s[j])) || s[j] == '_' || s[j] == '.' ||
                              s[j] == '-' || s[j] == '+'))
        ++j;
      out.tokens.push_back({s.substr(i, j - i), line});
      i = j;
    } else {
      out.tokens.push_back({std::string(1, c), line});
      ++i;
    }
  }
  return out;
}

const std::map<std::string, int>& PrimitiveSizes() {
  static const std::map<std::string, int> sizes = {
      {"int8_t", 1}, {"int16_t", 2}, {"int32_t", 4}, {"int64_t", 8}, {"byte", 1},
      {"float", 4},  {"double", 8},  {"boolean", 1}, {"string", -1}};
  return sizes;
}
bool IsPrimitive(const std::string& t) { return PrimitiveSizes().count(t) > 0; }
bool IsInteger(const std::string& t) {
  return t == "int8_t" || t == "int16_t" || t == "int32_t" || t == "int64_t";
}
bool IsIdentifier(const std::string& t) {
  return !t.empty() && (std::isalpha(static_cast<unsigned char>(t[0])) || t[0] == '_');
}
std::string ShortName(const std::string& t) {
  const size_t dot = t.rfind('.');
  return dot == std::string::npos ? t : t.substr(dot + 1);
}

class Parser {
 public:
  Parser(const std::string& file, const std::string& text) : file_(file), in_(Tokenize(text)) {}

  std::vector<LcmStruct> ParseFile() {
    std::vector<LcmStruct> out;
    while (!AtEnd()) {
      const std::string word = Next().text;
      if (word == "package") {
        package_ = Identifier("a package name");
        Expect(";");
      } else if (word == "struct") {
        out.push_back(ParseStruct());
      } else {
        Fail("expected 'package' or 'struct', found '" + word + "'");
      }
    }
    return out;
  }

 private:
  LcmStruct ParseStruct() {
    LcmStruct s;
    s.package = package_;
    s.name = Identifier("a struct name");
    Expect("{");
    while (Peek() != "}") {
      if (Peek() == "const") {
        SkipConstant();
        continue;
      }
      const std::string type = Identifier("a member type");
      const size_t first_new = s.members.size();
      do {
        LcmMember m;
        m.type = IsPrimitive(type) ? type : ShortName(type);
        m.line = Line();
        m.name = Identifier("a member name");
        while (Peek() == "[") {
          Next();
          m.dims.push_back(Next().text);
          Expect("]");
        }
        s.members.push_back(m);
      } while (Peek() == "," && (Next(), true));
      const int end_line = Line();
      Expect(";");
      for (size_t k = first_new; k < s.members.size(); ++k) {
        LcmMember& m = s.members[k];
        const std::string comment = Comment(m.line) + " " + Comment(end_line);
        m.nan_allowed = (type == "double" || type == "float") && comment.find("NaN") != std::string::npos;
      }
    }
    Expect("}");
    CheckDimensions(s);
    return s;
  }

  void SkipConstant() {
    Next();  // const
    Identifier("a constant type");
    do {
      Identifier("a constant name");
      Expect("=");
      Next();
    } while (Peek() == "," && (Next(), true));
    Expect(";");
  }

  void CheckDimensions(const LcmStruct& s) {
    std::set<std::string> integers;
    for (const LcmMember& m : s.members) {
      for (const std::string& d : m.dims) {
        if (std::isdigit(static_cast<unsigned char>(d[0]))) continue;
        if (!integers.count(d))
          throw std::invalid_argument(file_ + ":" + std::to_string(m.line) + ": array size '" + d + "' of " +
                                      m.name + " is not an earlier integer member");
      }
      if (IsInteger(m.type) && m.dims.empty()) integers.insert(m.name);
    }
  }

  std::string Comment(int line) const {
    auto it = in_.line_comments.find(line);
    return it == in_.line_comments.end() ? "" : it->second;
  }
  bool AtEnd() const { return pos_ >= in_.tokens.size(); }
  const std::string& Peek() const {
    static const std::string end = "<end of file>";
    return AtEnd() ? end : in_.tokens[pos_].text;
  }
  int Line() const { return AtEnd() ? (in_.tokens.empty() ? 0 : in_.tokens.back().line) : in_.tokens[pos_].line; }
  const Token& Next() {
    if (AtEnd()) Fail("unexpected end of file");
    return in_.tokens[pos_++];
  }
  void Expect(const std::string& text) {
    if (Peek() != text) Fail("expected '" + text + "', found '" + Peek() + "'");
    Next();
  }
  std::string Identifier(const char* what) {
    if (!IsIdentifier(Peek())) Fail(std::string("expected ") + what + ", found '" + Peek() + "'");
    return Next().text;
  }
  [[noreturn]] void Fail(const std::string& what) const {
    throw std::invalid_argument(file_ + ":" + std::to_string(Line()) + ": " + what);
  }

  std::string file_;
  Tokens in_;
  size_t pos_ = 0;
  std::string package_;
};

// ------------------------------------------------------------ fingerprint
// As lcm-gen 1.3.1 computes it (lcmgen.c: lcm_struct_hash, and the
// generated _computeHash).

int64_t HashUpdate(int64_t v, char c) {
  const uint64_t shifted = static_cast<uint64_t>(v) << 8;
  return static_cast<int64_t>((shifted ^ static_cast<uint64_t>(v >> 55)) + static_cast<uint64_t>(c));
}
int64_t HashString(int64_t v, const std::string& s) {
  v = HashUpdate(v, static_cast<char>(s.size()));
  for (char c : s) v = HashUpdate(v, c);
  return v;
}
int64_t BaseHash(const LcmStruct& s) {
  int64_t v = 0x12345678;
  for (const LcmMember& m : s.members) {
    v = HashString(v, m.name);
    if (IsPrimitive(m.type)) v = HashString(v, m.type);
    v = HashUpdate(v, static_cast<char>(m.dims.size()));
    for (const std::string& d : m.dims) {
      const bool variable = !std::isdigit(static_cast<unsigned char>(d[0]));
      v = HashUpdate(v, variable ? 1 : 0);
      v = HashString(v, d);
    }
  }
  return v;
}

// ------------------------------------------------------------------ walk

class Walker {
 public:
  Walker(const std::map<std::string, LcmStruct>& structs, const uint8_t* data, size_t size)
      : structs_(structs), data_(data), size_(size) {}

  // Called for each float/double value with its member; may be empty.
  std::function<void(const LcmMember&, double)> on_float;
  // Called for each number and string length with its span; may be empty.
  std::function<void(const LcmFieldSpan&)> on_span;
  int spans_per_array = 4;

  bool Walk(const LcmStruct& s, int depth, const std::string& path) {
    if (depth > 32) return Fail(path + ": nesting deeper than 32");
    std::map<std::string, int64_t> integers;
    for (const LcmMember& m : s.members) {
      const std::string where = path.empty() ? m.name : path + "." + m.name;
      int64_t count = 1;
      for (const std::string& d : m.dims) {
        const int64_t n = std::isdigit(static_cast<unsigned char>(d[0])) ? std::stoll(d) : integers[d];
        if (n < 0) return Fail(where + ": array size " + d + " = " + std::to_string(n) + " is negative");
        if (n > 0 && count > static_cast<int64_t>(Left()) / n)
          return Fail(where + ": array of " + std::to_string(n) + " elements cannot fit in the " +
                      std::to_string(Left()) + " bytes left");
        count *= n;
      }
      if (count > static_cast<int64_t>(Left()) / MinSize(m.type))
        return Fail(where + ": " + std::to_string(count) + " elements of " + m.type + " cannot fit in the " +
                    std::to_string(Left()) + " bytes left");
      if (!WalkMember(m, count, depth, where, &integers)) return false;
    }
    return true;
  }

  size_t pos() const { return pos_; }
  const std::string& error() const { return error_; }
  bool Fail(const std::string& e) {
    if (error_.empty()) error_ = e;
    return false;
  }
  int64_t ReadInt(int bytes) {
    uint64_t v = 0;
    for (int k = 0; k < bytes; ++k) v = (v << 8) | data_[pos_ + static_cast<size_t>(k)];
    pos_ += static_cast<size_t>(bytes);
    if (bytes < 8 && (v >> (8 * bytes - 1)) & 1) v |= ~uint64_t{0} << (8 * bytes);  // sign-extend
    return static_cast<int64_t>(v);
  }
  size_t Left() const { return size_ - pos_; }

 private:
  bool WalkMember(const LcmMember& m, int64_t count, int depth, const std::string& where,
                  std::map<std::string, int64_t>* integers) {
    if (m.type == "string") {
      for (int64_t k = 0; k < count; ++k) {
        if (Left() < 4) return Fail(where + ": string length cut off");
        if (on_span && k < spans_per_array)
          on_span({Indexed(where, m, k), "int32_t", pos_, 4, LcmFieldSpan::Kind::kStringLength});
        const int64_t length = ReadInt(4);
        if (length < 1 || length > static_cast<int64_t>(Left()))
          return Fail(where + ": string length " + std::to_string(length) + " outside [1, " +
                      std::to_string(Left()) + " bytes left]");
        pos_ += static_cast<size_t>(length);
      }
      return true;
    }
    if (!IsPrimitive(m.type)) {
      const LcmStruct& nested = structs_.at(m.type);
      const auto on_span_saved = on_span;
      for (int64_t k = 0; k < count; ++k) {
        if (k == spans_per_array) on_span = nullptr;  // spans of the first elements only
        const bool ok = Walk(nested, depth + 1, Indexed(where, m, k));
        if (!ok) {
          on_span = on_span_saved;
          return false;
        }
      }
      on_span = on_span_saved;
      return true;
    }
    const int size = PrimitiveSizes().at(m.type);
    const size_t bytes = static_cast<size_t>(count) * static_cast<size_t>(size);
    if (bytes > Left()) return Fail(where + ": cut off");
    if (on_span)
      for (int64_t k = 0; k < std::min<int64_t>(count, spans_per_array); ++k)
        on_span({Indexed(where, m, k), m.type, pos_ + static_cast<size_t>(k * size), static_cast<size_t>(size),
                 LcmFieldSpan::Kind::kNumber});
    if (IsInteger(m.type) && m.dims.empty()) {
      (*integers)[m.name] = ReadInt(size);
      return true;
    }
    if (on_float && (m.type == "double" || m.type == "float")) {
      for (int64_t k = 0; k < count; ++k) {
        const int64_t bits = ReadInt(size);
        double value;
        if (size == 8) {
          std::memcpy(&value, &bits, 8);
        } else {
          const int32_t b32 = static_cast<int32_t>(bits);
          float f;
          std::memcpy(&f, &b32, 4);
          value = f;
        }
        on_float(m, value);
      }
      return true;
    }
    pos_ += bytes;
    return true;
  }

  static std::string Indexed(const std::string& where, const LcmMember& m, int64_t k) {
    return m.dims.empty() ? where : where + "[" + std::to_string(k) + "]";
  }

  int64_t MinSize(const std::string& type) const {
    if (type == "string") return 5;
    auto p = PrimitiveSizes().find(type);
    if (p != PrimitiveSizes().end()) return p->second;
    int64_t sum = 0;
    for (const LcmMember& m : structs_.at(type).members)
      if (m.dims.empty()) sum += MinSize(m.type);
    return std::max<int64_t>(sum, 1);
  }

  const std::map<std::string, LcmStruct>& structs_;
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  std::string error_;
};

std::string Hex(int64_t v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "0x%016llx", static_cast<unsigned long long>(v));
  return buf;
}

}  // namespace

void LcmSchema::AddSource(const std::string& file_name, const std::string& text) {
  std::vector<LcmStruct> parsed = Parser(file_name, text).ParseFile();
  for (LcmStruct& s : parsed) structs_[s.name] = std::move(s);
}

const LcmSchema& LcmSchema::Vloc() {
  static const LcmSchema schema = [] {
    LcmSchema s;
    for (int i = 0; i < kNumLcmSchemaFiles; ++i) s.AddSource(kLcmSchemaFiles[i].name, kLcmSchemaFiles[i].text);
    for (const auto& [name, st] : s.structs_)
      for (const LcmMember& m : st.members)
        if (!IsPrimitive(m.type) && !s.structs_.count(m.type))
          throw std::invalid_argument(name + "." + m.name + ": unknown type " + m.type);
    return s;
  }();
  return schema;
}

bool LcmSchema::Has(const std::string& type) const { return structs_.count(ShortName(type)) > 0; }

const LcmStruct* LcmSchema::Find(const std::string& type) const {
  auto it = structs_.find(ShortName(type));
  return it == structs_.end() ? nullptr : &it->second;
}

std::vector<std::string> LcmSchema::TypeNames() const {
  std::vector<std::string> names;
  for (const auto& kv : structs_) names.push_back(kv.first);
  return names;
}

int64_t LcmSchema::Fingerprint(const std::string& type) const {
  std::function<uint64_t(const std::string&, std::vector<std::string>&)> hash =
      [&](const std::string& t, std::vector<std::string>& parents) -> uint64_t {
    for (const std::string& p : parents)
      if (p == t) return 0;
    const LcmStruct& s = structs_.at(t);
    parents.push_back(t);
    uint64_t h = static_cast<uint64_t>(BaseHash(s));
    for (const LcmMember& m : s.members)
      if (!IsPrimitive(m.type)) h += hash(m.type, parents);
    parents.pop_back();
    return (h << 1) + ((h >> 63) & 1);
  };
  std::vector<std::string> parents;
  return static_cast<int64_t>(hash(ShortName(type), parents));
}

std::string LcmSchema::TypeOfFingerprint(int64_t hash) const {
  for (const auto& kv : structs_)
    if (Fingerprint(kv.first) == hash) return kv.first;
  return "";
}

bool LcmSchema::Check(const std::string& type, const uint8_t* data, size_t size, std::string* error) const {
  const LcmStruct* s = Find(type);
  auto fail = [&](const std::string& e) {
    if (error) *error = e;
    return false;
  };
  if (!s) return fail("no schema for type " + type);
  if (size < 8) return fail(std::to_string(size) + " bytes: too short for a fingerprint");
  Walker walker(structs_, data, size);
  const int64_t hash = walker.ReadInt(8);
  const int64_t expected = Fingerprint(s->name);
  if (hash != expected) {
    const std::string other = TypeOfFingerprint(hash);
    return fail("fingerprint " + Hex(hash) + " is not " + s->name + "'s (" + Hex(expected) + "): " +
                (other.empty() ? "unknown type or another version" : "a " + other));
  }
  if (!walker.Walk(*s, 0, "")) return fail(walker.error());
  if (walker.Left() != 0) return fail(std::to_string(walker.Left()) + " bytes trail the message");
  return true;
}

int LcmSchema::CountNonFinite(const std::string& type, const uint8_t* data, size_t size,
                              std::string* first) const {
  std::string error;
  if (!Check(type, data, size, &error)) {
    if (first) *first = error;
    return 1;
  }
  int count = 0;
  Walker walker(structs_, data, size);
  walker.on_float = [&](const LcmMember& m, double v) {
    if (std::isinf(v) || (std::isnan(v) && !m.nan_allowed)) {
      if (count++ == 0 && first) *first = m.name + " = " + std::to_string(v);
    }
  };
  walker.ReadInt(8);
  walker.Walk(*Find(type), 0, "");
  return count;
}

std::vector<LcmFieldSpan> LcmSchema::Spans(const std::string& type, const uint8_t* data, size_t size,
                                           int per_array) const {
  std::vector<LcmFieldSpan> spans;
  if (!Check(type, data, size)) return spans;
  Walker walker(structs_, data, size);
  walker.spans_per_array = per_array;
  walker.on_span = [&](const LcmFieldSpan& span) { spans.push_back(span); };
  walker.ReadInt(8);
  walker.Walk(*Find(type), 0, "");
  return spans;
}

}  // namespace vloc
