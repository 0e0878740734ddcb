#include "vloc/common/pds_label.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "vloc/common/options.h"
#include "vloc/common/printable.h"

namespace vloc {

namespace {

std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

bool SameName(const std::string& a, const std::string& b) { return Upper(a) == Upper(b); }

// ---------------------------------------------------------------- parser

class OdlParser {
 public:
  OdlParser(const std::string& text, const OdlLimits& limits) : s_(text), limits_(limits) {}

  bool Parse(OdlBlock* root, std::string* error, size_t* end_offset) {
    root->kind = "ROOT";
    root->line = 1;
    std::vector<OdlBlock*> stack{root};
    size_t statements = 0;
    while (true) {
      if (!SkipBlank()) return Err(error, "a comment is not closed (*/)");
      if (pos_ >= s_.size()) {
        if (stack.size() > 1)
          return Err(error, stack.back()->kind + " " + stack.back()->name + " (line " +
                                std::to_string(stack.back()->line) + ") is not closed before the end of the label");
        return Err(error, "no END statement (a truncated label?)");
      }
      const int line = line_;
      std::string keyword;
      if (!BareToken(&keyword) || keyword.empty())
        return Err(error, std::string("a keyword was expected, found '") + Printable({&s_[pos_], 1}) + "'");
      const std::string key = Upper(keyword);
      if (++statements > limits_.max_statements)
        return Err(error, "more than " + std::to_string(limits_.max_statements) + " statements");
      if (key == "END") return End(stack, error, end_offset);
      if (key == "END_OBJECT" || key == "END_GROUP") {
        if (!CloseBlock(key, &stack, error)) return false;
        continue;
      }
      if (!SkipBlank()) return Err(error, "a comment is not closed (*/)");
      if (pos_ >= s_.size() || s_[pos_] != '=') return Err(error, keyword + ": '=' expected after the keyword");
      ++pos_;
      if (key == "OBJECT" || key == "GROUP") {
        if (!OpenBlock(key, line, &stack, error)) return false;
        continue;
      }
      OdlAttribute a;
      a.keyword = key;
      a.line = line;
      if (!Value(&a.value, static_cast<int>(stack.size()), error, keyword)) return false;
      stack.back()->attributes.push_back(std::move(a));
    }
  }

 private:
  bool Err(std::string* error, const std::string& what) const {
    if (error) *error = "line " + std::to_string(line_) + ": " + what;
    return false;
  }

  // END: the label ends with its line (end_offset: the byte after it).
  bool End(const std::vector<OdlBlock*>& stack, std::string* error, size_t* end_offset) {
    if (stack.size() > 1)
      return Err(error, "END inside " + stack.back()->kind + " " + stack.back()->name + " (line " +
                            std::to_string(stack.back()->line) + ")");
    while (pos_ < s_.size() && s_[pos_] != '\n') ++pos_;
    if (end_offset) *end_offset = std::min(s_.size(), pos_ + 1);
    return true;
  }

  // END_OBJECT / END_GROUP [= name]: closes the innermost open block,
  // which must be of that kind (and name, when one is given).
  bool CloseBlock(const std::string& key, std::vector<OdlBlock*>* stack, std::string* error) {
    const std::string kind = key.substr(4);
    std::string name;
    if (!SkipBlank()) return Err(error, "a comment is not closed (*/)");
    if (pos_ < s_.size() && s_[pos_] == '=') {
      ++pos_;
      SkipBlank();
      if (!BareToken(&name) || name.empty()) return Err(error, key + " = needs a name");
    }
    if (stack->size() == 1) return Err(error, key + " without an open " + kind);
    OdlBlock* open = stack->back();
    if (open->kind != kind || (!name.empty() && !SameName(name, open->name)))
      return Err(error, key + (name.empty() ? "" : " = " + name) + " closes " + open->kind + " " + open->name +
                            " (line " + std::to_string(open->line) + ")");
    stack->pop_back();
    return true;
  }

  // OBJECT / GROUP = name: a block opened inside the innermost one.
  bool OpenBlock(const std::string& key, int line, std::vector<OdlBlock*>* stack, std::string* error) {
    SkipBlank();
    std::string name;
    if (!BareToken(&name) || name.empty()) return Err(error, key + " = needs a name");
    if (static_cast<int>(stack->size()) > limits_.max_depth)
      return Err(error, key + " " + name + " nested deeper than " + std::to_string(limits_.max_depth) + " levels");
    OdlBlock b;
    b.kind = key;
    b.name = Upper(name);
    b.line = line;
    stack->back()->children.push_back(std::move(b));
    stack->push_back(&stack->back()->children.back());
    return true;
  }

  void Advance() {
    if (s_[pos_] == '\n') ++line_;
    ++pos_;
  }

  // Skips blanks, line ends and /* comments */; false on an unclosed comment.
  bool SkipBlank() {
    while (pos_ < s_.size()) {
      const char c = s_[pos_];
      if (c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v') {
        Advance();
      } else if (c == '/' && pos_ + 1 < s_.size() && s_[pos_ + 1] == '*') {
        const size_t end = s_.find("*/", pos_ + 2);
        if (end == std::string::npos) return false;
        while (pos_ < end + 2) Advance();
      } else {
        return true;
      }
    }
    return true;
  }

  static bool Delimiter(char c) {
    return std::isspace(static_cast<unsigned char>(c)) || c == '=' || c == ',' || c == '(' || c == ')' || c == '{' ||
           c == '}' || c == '<' || c == '>' || c == '"' || c == '\'';
  }

  // A run of non-delimiters (keywords, identifiers, numbers, dates).
  bool BareToken(std::string* out) {
    const size_t start = pos_;
    while (pos_ < s_.size() && !Delimiter(s_[pos_]) && !(s_[pos_] == '/' && pos_ + 1 < s_.size() && s_[pos_ + 1] == '*'))
      ++pos_;
    out->assign(s_, start, pos_ - start);
    for (char c : *out)
      if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7e) return false;
    return true;
  }

  static bool ParseNumber(const std::string& t, OdlValue* v) {
    // Radix integers: base#digits#, e.g. 16#FF# or 2#1010#.
    const size_t hash = t.find('#');
    if (hash != std::string::npos && hash > 0 && t.back() == '#' && t.size() > hash + 2) {
      char* end = nullptr;
      const long base = std::strtol(t.substr(0, hash).c_str(), &end, 10);
      if (*end != '\0' || base < 2 || base > 16) return false;
      const std::string digits = t.substr(hash + 1, t.size() - hash - 2);
      const long long value = std::strtoll(digits.c_str(), &end, static_cast<int>(base));
      if (*end != '\0') return false;
      v->type = OdlValue::Type::kInteger;
      v->number = static_cast<double>(value);
      return true;
    }
    if (t.empty() || !(std::isdigit(static_cast<unsigned char>(t[0])) || t[0] == '-' || t[0] == '+' || t[0] == '.'))
      return false;
    char* end = nullptr;
    const double d = std::strtod(t.c_str(), &end);
    if (end == t.c_str() || *end != '\0' || !std::isfinite(d)) return false;
    const bool integer = t.find_first_of(".eE") == std::string::npos;
    v->type = integer ? OdlValue::Type::kInteger : OdlValue::Type::kReal;
    v->number = d;
    return true;
  }

  bool Value(OdlValue* v, int depth, std::string* error, const std::string& keyword) {
    if (depth > limits_.max_depth)
      return Err(error, keyword + ": values nested deeper than " + std::to_string(limits_.max_depth) + " levels");
    if (!SkipBlank()) return Err(error, "a comment is not closed (*/)");
    if (pos_ >= s_.size()) return Err(error, keyword + ": the value is missing at the end of the label");
    const char c = s_[pos_];
    if (c == '(' || c == '{') return ListValue(v, depth, error, keyword);
    if (c == '"' || c == '\'') return QuotedValue(v, error, keyword);
    return BareValue(v, error, keyword);
  }

  // A sequence ( ... ) or set { ... } of values separated by commas.
  bool ListValue(OdlValue* v, int depth, std::string* error, const std::string& keyword) {
    const char c = s_[pos_];
    const char close = c == '(' ? ')' : '}';
    v->type = c == '(' ? OdlValue::Type::kSequence : OdlValue::Type::kSet;
    const int open_line = line_;
    Advance();
    SkipBlank();
    if (pos_ < s_.size() && s_[pos_] == close) {
      Advance();
      return true;
    }
    while (true) {
      OdlValue item;
      if (!Value(&item, depth + 1, error, keyword)) return false;
      v->items.push_back(std::move(item));
      if (!SkipBlank()) return Err(error, "a comment is not closed (*/)");
      if (pos_ >= s_.size())
        return Err(error, keyword + ": '" + std::string(1, c) + "' of line " + std::to_string(open_line) +
                              " is not closed");
      if (s_[pos_] == ',') {
        Advance();
        continue;
      }
      if (s_[pos_] == close) {
        Advance();
        return true;
      }
      return Err(error, keyword + ": ',' or '" + std::string(1, close) + "' expected, found '" +
                            Printable({&s_[pos_], 1}) + "'");
    }
  }

  // A "string" or 'symbol'; a line break and the blanks around it are one space.
  bool QuotedValue(OdlValue* v, std::string* error, const std::string& keyword) {
    const char c = s_[pos_];
    const int open_line = line_;
    Advance();
    const size_t end = s_.find(c, pos_);
    if (end == std::string::npos)
      return Err(error, keyword + ": the " + std::string(c == '"' ? "string" : "symbol") + " opened on line " +
                            std::to_string(open_line) + " is not closed");
    std::string raw = s_.substr(pos_, end - pos_);
    while (pos_ <= end) Advance();
    std::string text;
    for (size_t i = 0; i < raw.size(); ++i) {
      if (raw[i] == '\r' || raw[i] == '\n') {
        while (!text.empty() && (text.back() == ' ' || text.back() == '\t')) text.pop_back();
        size_t j = i;
        while (j < raw.size() && std::isspace(static_cast<unsigned char>(raw[j]))) ++j;
        if (!text.empty() && j < raw.size()) text += ' ';
        i = j - 1;
      } else {
        text += raw[i];
      }
    }
    v->type = c == '"' ? OdlValue::Type::kString : OdlValue::Type::kSymbol;
    v->text = text;
    return true;
  }

  // An identifier, or a number with an optional unit: 12.5 <m>.
  bool BareValue(OdlValue* v, std::string* error, const std::string& keyword) {
    const char c = s_[pos_];
    std::string token;
    if (!BareToken(&token)) return Err(error, keyword + ": a value holds a control or non-ASCII byte");
    if (token.empty()) return Err(error, keyword + ": a value was expected, found '" + Printable({&c, 1}) + "'");
    v->text = token;
    if (!ParseNumber(token, v)) {
      v->type = OdlValue::Type::kIdentifier;
      return true;
    }
    const size_t save_pos = pos_;
    const int save_line = line_;
    if (!SkipBlank()) return Err(error, "a comment is not closed (*/)");
    if (pos_ < s_.size() && s_[pos_] == '<') {
      const size_t end = s_.find('>', pos_);
      const size_t nl = s_.find('\n', pos_);
      if (end == std::string::npos || (nl != std::string::npos && nl < end))
        return Err(error, keyword + ": the unit '<' is not closed on its line");
      std::string unit = s_.substr(pos_ + 1, end - pos_ - 1);
      unit.erase(0, unit.find_first_not_of(" \t"));
      unit.erase(unit.find_last_not_of(" \t") + 1);
      v->unit = unit;
      pos_ = end + 1;
    } else {
      pos_ = save_pos;
      line_ = save_line;
    }
    return true;
  }

  const std::string& s_;
  OdlLimits limits_;
  size_t pos_ = 0;
  int line_ = 1;
};

bool ReadHead(const std::string& path, size_t max_bytes, std::string* text, bool* whole, std::string* error) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return Fail(error, path + ": cannot open");
  text->resize(max_bytes);
  f.read(&(*text)[0], static_cast<std::streamsize>(max_bytes));
  text->resize(static_cast<size_t>(f.gcount()));
  *whole = f.peek() == std::char_traits<char>::eof();
  return true;
}

// ------------------------------------------------------- label fields

// A keyword's value, as numbers: the reader's checks in one place.
class Fields {
 public:
  Fields(const std::string& file, std::string* error) : file_(file), error_(error) {}

  bool Missing(const std::string& keyword, const std::string& where) const {
    return Fail(error_, file_ + ": " + keyword + Where(where) + ": missing");
  }
  bool Bad(const std::string& keyword, const std::string& where, const std::string& what) const {
    return Fail(error_, file_ + ": " + keyword + Where(where) + ": " + what);
  }

  bool Vector3(const OdlBlock& b, const std::string& keyword, Eigen::Vector3d* out) const {
    const OdlAttribute* a = b.Find(keyword);
    if (!a) return Missing(keyword, b.name);
    std::vector<double> v;
    if (!Numbers(*a, b.name, &v)) return false;
    if (v.size() != 3) return Bad(keyword, b.name, "needs 3 numbers, has " + std::to_string(v.size()));
    *out = Eigen::Vector3d(v[0], v[1], v[2]);
    return true;
  }

  bool Numbers(const OdlAttribute& a, const std::string& where, std::vector<double>* out) const {
    out->clear();
    if (a.value.IsNumber()) {
      out->push_back(a.value.number);
      return true;
    }
    if (a.value.type != OdlValue::Type::kSequence) return Bad(a.keyword, where, "a number or a sequence of numbers expected");
    for (const OdlValue& item : a.value.items) {
      if (!item.IsNumber()) return Bad(a.keyword, where, "'" + item.text + "' is not a number");
      out->push_back(item.number);
    }
    return true;
  }

  bool Integers(const OdlAttribute& a, const std::string& where, std::vector<int>* out) const {
    std::vector<double> v;
    if (!Numbers(a, where, &v)) return false;
    out->clear();
    for (double d : v) {
      if (d != std::floor(d) || std::abs(d) > 2e9) return Bad(a.keyword, where, "integers expected");
      out->push_back(static_cast<int>(d));
    }
    return true;
  }

  // An angle with its unit (rad or deg; `default_unit` when it has none).
  bool Angle(const OdlValue& v, const std::string& keyword, const std::string& where, const std::string& default_unit,
             double* rad) const {
    if (!v.IsNumber()) return Bad(keyword, where, "'" + v.text + "' is not a number");
    const std::string unit = Upper(v.unit.empty() ? default_unit : v.unit);
    if (unit == "RAD") *rad = v.number;
    else if (unit == "DEG" || unit == "DEGREE" || unit == "DEGREES") *rad = v.number * M_PI / 180.0;
    else return Bad(keyword, where, "unit <" + v.unit + "> is not an angle (rad or deg)");
    return true;
  }

  static std::string Text(const OdlBlock& b, const std::string& keyword) {
    const OdlAttribute* a = b.Find(keyword);
    return a && !a->value.IsList() ? a->value.text : std::string();
  }

 private:
  static std::string Where(const std::string& where) { return where.empty() ? "" : " of " + where; }
  std::string file_;
  std::string* error_;
};

bool ReadCamera(const OdlBlock& label, const Fields& f, PdsCameraLabel* out) {
  const OdlBlock* g = label.FindBlock("GEOMETRIC_CAMERA_MODEL_PARMS");
  if (!g) g = label.FindBlock("GEOMETRIC_CAMERA_MODEL");  // MER's name for the group
  if (!g) return f.Missing("GEOMETRIC_CAMERA_MODEL_PARMS", "");
  const std::string type = Upper(Fields::Text(*g, "MODEL_TYPE"));
  if (type.empty()) return f.Missing("MODEL_TYPE", g->name);
  CahvModel& m = out->camera;
  if (type == "CAHV") m.kind = CahvKind::kCahv;
  else if (type == "CAHVOR") m.kind = CahvKind::kCahvor;
  else if (type == "CAHVORE") m.kind = CahvKind::kCahvore;
  else return f.Bad("MODEL_TYPE", g->name, "'" + type + "' is not CAHV, CAHVOR or CAHVORE");
  Eigen::Vector3d* components[] = {&m.c, &m.a, &m.h, &m.v, &m.o, &m.r, &m.e};
  const int n = m.kind == CahvKind::kCahv ? 4 : m.kind == CahvKind::kCahvor ? 6 : 7;
  for (int k = 0; k < n; ++k)
    if (!f.Vector3(*g, "MODEL_COMPONENT_" + std::to_string(k + 1), components[k])) return false;
  if (m.kind == CahvKind::kCahv) m.o = m.a;
  if (m.kind == CahvKind::kCahvore) {
    // T (MODEL_COMPONENT_8): 1 perspective, 2 fisheye, 3 general with
    // linearity P (MODEL_COMPONENT_9).
    const OdlAttribute* t = g->Find("MODEL_COMPONENT_8");
    if (!t) return f.Missing("MODEL_COMPONENT_8", g->name);
    if (!t->value.IsNumber()) return f.Bad("MODEL_COMPONENT_8", g->name, "the CAHVORE type (1, 2 or 3) expected");
    const int kind = static_cast<int>(t->value.number);
    if (kind == 1) m.linearity = 1.0;
    else if (kind == 2) m.linearity = 0.0;
    else if (kind == 3) {
      const OdlAttribute* p = g->Find("MODEL_COMPONENT_9");
      if (!p) return f.Missing("MODEL_COMPONENT_9", g->name);
      if (!p->value.IsNumber()) return f.Bad("MODEL_COMPONENT_9", g->name, "the linearity (a number) expected");
      m.linearity = p->value.number;
    } else {
      return f.Bad("MODEL_COMPONENT_8", g->name, "the CAHVORE type must be 1, 2 or 3, is " + t->value.text);
    }
  }
  // Labels print 6 digits: A and O are unit to about 1e-6; normalise them.
  for (auto [vec, name] : {std::pair<Eigen::Vector3d*, const char*>{&m.a, "MODEL_COMPONENT_2"},
                           std::pair<Eigen::Vector3d*, const char*>{&m.o, "MODEL_COMPONENT_5"}}) {
    if (!(std::abs(vec->norm() - 1) < 1e-3)) return f.Bad(name, g->name, "not a unit vector");
    vec->normalize();
  }
  std::string why;
  if (!m.Check(&why)) return f.Bad("MODEL_TYPE", g->name, why);
  out->camera_frame = Fields::Text(*g, "REFERENCE_COORD_SYSTEM_NAME");
  if (const OdlAttribute* idx = g->Find("REFERENCE_COORD_SYSTEM_INDEX"))
    if (!f.Integers(*idx, g->name, &out->camera_frame_index)) return false;
  return true;
}

bool ReadRoverPose(const OdlBlock& label, const Fields& f, PdsCameraLabel* out) {
  const OdlBlock* g = label.FindBlock("ROVER_COORD_SYSTEM_PARMS");
  if (!g) return true;  // optional
  Eigen::Vector3d offset;
  if (!f.Vector3(*g, "ORIGIN_OFFSET_VECTOR", &offset)) return false;
  const OdlAttribute* q = g->Find("ORIGIN_ROTATION_QUATERNION");
  if (!q) return f.Missing("ORIGIN_ROTATION_QUATERNION", g->name);
  std::vector<double> v;
  if (!f.Numbers(*q, g->name, &v)) return false;
  if (v.size() != 4) return f.Bad(q->keyword, g->name, "needs 4 numbers (s, x, y, z), has " + std::to_string(v.size()));
  Eigen::Quaterniond quat(v[0], v[1], v[2], v[3]);
  if (!(std::abs(quat.norm() - 1) < 1e-3)) return f.Bad(q->keyword, g->name, "not a unit quaternion");
  quat.normalize();
  out->site_from_rover = MakePose(quat.toRotationMatrix(), offset);
  out->rover_pose_frame = Fields::Text(*g, "REFERENCE_COORD_SYSTEM_NAME");
  out->has_rover_pose = true;
  return true;
}

bool ReadCounters(const OdlBlock& label, const Fields& f, PdsCameraLabel* out) {
  const OdlAttribute* c = label.Find("ROVER_MOTION_COUNTER");
  if (!c) return true;
  if (!f.Integers(*c, "", &out->motion_counter)) return false;
  int site_index = 0, drive_index = 1;
  if (const OdlAttribute* names = label.Find("ROVER_MOTION_COUNTER_NAME"))
    for (size_t k = 0; k < names->value.items.size(); ++k) {
      if (SameName(names->value.items[k].text, "SITE")) site_index = static_cast<int>(k);
      if (SameName(names->value.items[k].text, "DRIVE")) drive_index = static_cast<int>(k);
    }
  if (site_index < static_cast<int>(out->motion_counter.size())) out->site = out->motion_counter[site_index];
  if (drive_index < static_cast<int>(out->motion_counter.size())) out->drive = out->motion_counter[drive_index];
  return true;
}

bool ReadMast(const OdlBlock& label, const Fields& f, PdsCameraLabel* out) {
  if (const OdlBlock* g = label.FindBlock("RSM_ARTICULATION_STATE_PARMS")) {
    const OdlAttribute* angles = g->Find("ARTICULATION_DEVICE_ANGLE");
    const OdlAttribute* names = g->Find("ARTICULATION_DEVICE_ANGLE_NAME");
    if (!angles) return f.Missing("ARTICULATION_DEVICE_ANGLE", g->name);
    if (!names) return f.Missing("ARTICULATION_DEVICE_ANGLE_NAME", g->name);
    if (angles->value.items.size() != names->value.items.size())
      return f.Bad("ARTICULATION_DEVICE_ANGLE", g->name, "has " + std::to_string(angles->value.items.size()) +
                                                             " angles for " + std::to_string(names->value.items.size()) +
                                                             " names");
    bool az = false, el = false;
    for (size_t k = 0; k < names->value.items.size(); ++k) {
      const std::string name = Upper(names->value.items[k].text);
      double* target = name == "AZIMUTH-MEASURED" ? &out->mast_azimuth
                       : name == "ELEVATION-MEASURED" ? &out->mast_elevation
                                                      : nullptr;
      if (!target) continue;
      if (!f.Angle(angles->value.items[k], angles->keyword, g->name, "rad", target)) return false;
      (name[0] == 'A' ? az : el) = true;
    }
    if (!az || !el) return f.Bad("ARTICULATION_DEVICE_ANGLE_NAME", g->name, "no AZIMUTH-MEASURED / ELEVATION-MEASURED");
    out->has_mast_angles = true;
  }
  if (const OdlBlock* g = label.FindBlock("ROVER_DERIVED_GEOMETRY_PARMS")) {
    const OdlAttribute* az = g->Find("INSTRUMENT_AZIMUTH");
    const OdlAttribute* el = g->Find("INSTRUMENT_ELEVATION");
    if (az && el) {
      if (!f.Angle(az->value, az->keyword, g->name, "deg", &out->instrument_azimuth)) return false;
      if (!f.Angle(el->value, el->keyword, g->name, "deg", &out->instrument_elevation)) return false;
      out->has_instrument_pointing = true;
    }
  }
  return true;
}

bool ReadImagePointer(const OdlBlock& label, const Fields& f, PdsCameraLabel* out) {
  const OdlAttribute* p = label.Find("^IMAGE");
  if (!p) return true;
  int record_bytes = 0;
  if (const OdlAttribute* rb = label.Find("RECORD_BYTES")) {
    if (!rb->value.IsNumber() || !(rb->value.number >= 1 && rb->value.number <= 1e7))
      return f.Bad("RECORD_BYTES", "", "a positive integer expected");
    record_bytes = static_cast<int>(rb->value.number);
  }
  const OdlValue* location = &p->value;
  if (p->value.type == OdlValue::Type::kString) {
    out->image_file = p->value.text;
    out->image_offset_bytes = 0;
    location = nullptr;
  } else if (p->value.type == OdlValue::Type::kSequence) {
    if (p->value.items.size() != 2 || p->value.items[0].type != OdlValue::Type::kString)
      return f.Bad("^IMAGE", "", "(\"FILE\", offset) expected");
    out->image_file = p->value.items[0].text;
    location = &p->value.items[1];
  }
  if (location) {
    if (location->type != OdlValue::Type::kInteger || !(location->number >= 1))
      return f.Bad("^IMAGE", "", "the offset must be an integer >= 1");
    if (SameName(location->unit, "BYTES")) {
      out->image_offset_bytes = static_cast<int64_t>(location->number) - 1;
    } else {
      if (!location->unit.empty()) return f.Bad("^IMAGE", "", "unit <" + location->unit + "> is not <BYTES>");
      if (record_bytes <= 0) return f.Missing("RECORD_BYTES", "");
      out->image_offset_bytes = (static_cast<int64_t>(location->number) - 1) * record_bytes;
    }
  }
  if (const OdlBlock* img = label.FindBlock("IMAGE")) {
    auto integer = [&](const char* key, int* v, int lo, int hi, bool required) {
      const OdlAttribute* a = img->Find(key);
      if (!a) return required ? f.Missing(key, "IMAGE") : true;
      if (a->value.type != OdlValue::Type::kInteger || a->value.number < lo || a->value.number > hi)
        return f.Bad(key, "IMAGE", "an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "] expected");
      *v = static_cast<int>(a->value.number);
      return true;
    };
    out->bands = 1;
    if (!integer("LINES", &out->lines, 1, 1 << 20, true) || !integer("LINE_SAMPLES", &out->line_samples, 1, 1 << 20, true) ||
        !integer("SAMPLE_BITS", &out->sample_bits, 1, 64, true) || !integer("BANDS", &out->bands, 1, 4096, false))
      return false;
    out->sample_type = Upper(Fields::Text(*img, "SAMPLE_TYPE"));
  }
  return true;
}

std::string Directory(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? std::string() : path.substr(0, slash + 1);
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

// ------------------------------------------------------------ OdlBlock

const OdlAttribute* OdlBlock::Find(const std::string& keyword) const {
  const std::string key = Upper(keyword);
  for (const OdlAttribute& a : attributes)
    if (a.keyword == key) return &a;
  return nullptr;
}

const OdlBlock* OdlBlock::FindBlock(const std::string& block_name) const {
  const std::string key = Upper(block_name);
  for (const OdlBlock& b : children)
    if (b.name == key) return &b;
  return nullptr;
}

const OdlAttribute* OdlBlock::FindPath(const std::string& path) const {
  const size_t slash = path.find('/');
  if (slash == std::string::npos) return Find(path);
  const OdlBlock* b = FindBlock(path.substr(0, slash));
  return b ? b->FindPath(path.substr(slash + 1)) : nullptr;
}

bool ParseOdl(const std::string& text, const OdlLimits& limits, OdlBlock* root, std::string* error, size_t* end_offset) {
  *root = OdlBlock();
  OdlParser parser(text, limits);
  return parser.Parse(root, error, end_offset);
}

bool ParseOdlFile(const std::string& path, const OdlLimits& limits, OdlBlock* root, std::string* error) {
  std::string text;
  bool whole = false;
  if (!ReadHead(path, limits.max_bytes, &text, &whole, error)) return false;
  std::string why;
  if (ParseOdl(text, limits, root, &why)) return true;
  if (!whole && why.find("no END") != std::string::npos)
    return Fail(error, path + ": no END within the first " + std::to_string(limits.max_bytes) + " bytes (a label that long?)");
  return Fail(error, path + ": " + why);
}

bool ReadPdsCameraLabel(const std::string& path, PdsCameraLabel* out, std::string* error, const OdlLimits& limits) {
  *out = PdsCameraLabel();
  out->label_path = path;
  OdlBlock label;
  if (!ParseOdlFile(path, limits, &label, error)) return false;
  const Fields f(path, error);
  if (!label.Find("PDS_VERSION_ID")) return f.Missing("PDS_VERSION_ID", "");
  out->product_id = Fields::Text(label, "PRODUCT_ID");
  out->instrument_id = Fields::Text(label, "INSTRUMENT_ID");
  out->frame_id = Upper(Fields::Text(label, "FRAME_ID"));
  out->start_time = Fields::Text(label, "START_TIME");
  out->spacecraft_clock = Fields::Text(label, "SPACECRAFT_CLOCK_START_COUNT");
  out->sequence_id = Fields::Text(label, "SEQUENCE_ID");
  if (const OdlAttribute* sol = label.Find("PLANET_DAY_NUMBER")) {
    if (sol->value.type != OdlValue::Type::kInteger || sol->value.number < 0 || sol->value.number > 1e6)
      return f.Bad("PLANET_DAY_NUMBER", "", "a sol number (integer >= 0) expected");
    out->sol = static_cast<int>(sol->value.number);
  }
  return ReadCamera(label, f, out) && ReadRoverPose(label, f, out) && ReadCounters(label, f, out) &&
         ReadMast(label, f, out) && ReadImagePointer(label, f, out);
}

bool ReadPdsImage(const std::string& path, cv::Mat* image, std::string* error, const OdlLimits& limits,
                  int64_t max_pixels) {
  OdlBlock label;
  if (!ParseOdlFile(path, limits, &label, error)) return false;
  PdsCameraLabel info;
  const Fields f(path, error);
  if (!ReadImagePointer(label, f, &info)) return false;
  if (info.image_offset_bytes < 0) return f.Missing("^IMAGE", "");
  if (info.lines == 0) return f.Missing("IMAGE", "");
  if (static_cast<int64_t>(info.lines) * info.line_samples > max_pixels)
    return f.Bad("LINES", "IMAGE", std::to_string(info.lines) + " x " + std::to_string(info.line_samples) +
                                       " is over the limit of " + std::to_string(max_pixels) + " pixels");
  if (info.sample_bits != 8 && info.sample_bits != 16) return f.Bad("SAMPLE_BITS", "IMAGE", "8 or 16 supported");
  const std::string& type = info.sample_type;
  const bool lsb = type.find("LSB") == 0 || type.find("PC_") == 0 || type.find("VAX") == 0;
  const bool is_signed = info.sample_bits == 16 && type.find("UNSIGNED") == std::string::npos;
  if (type.find("REAL") != std::string::npos || type.find("FLOAT") != std::string::npos)
    return f.Bad("SAMPLE_TYPE", "IMAGE", type + " is not supported (integers only)");
  int prefix = 0, suffix = 0;
  if (const OdlBlock* img = label.FindBlock("IMAGE")) {
    for (auto [key, v] : {std::pair<const char*, int*>{"LINE_PREFIX_BYTES", &prefix}, {"LINE_SUFFIX_BYTES", &suffix}})
      if (const OdlAttribute* a = img->Find(key)) {
        if (a->value.type != OdlValue::Type::kInteger || a->value.number < 0 || a->value.number > 1e6)
          return f.Bad(key, "IMAGE", "a byte count expected");
        *v = static_cast<int>(a->value.number);
      }
  }
  // The image file: the label's own (attached) or the one it names, beside it.
  std::string file = path;
  if (!info.image_file.empty()) {
    const std::string dir = Directory(path);
    file.clear();
    for (const std::string& name : {info.image_file, Lower(info.image_file), Upper(info.image_file)})
      if (std::ifstream(dir + name).good()) {
        file = dir + name;
        break;
      }
    if (file.empty()) return f.Bad("^IMAGE", "", "its file " + dir + info.image_file + " is absent");
  }
  std::ifstream in(file, std::ios::binary | std::ios::ate);
  if (!in) return f.Bad("^IMAGE", "", "cannot open " + file);
  const int64_t size = static_cast<int64_t>(in.tellg());
  const int bytes = info.sample_bits / 8;
  const int64_t line_bytes = prefix + static_cast<int64_t>(info.line_samples) * bytes + suffix;
  if (info.image_offset_bytes + line_bytes * info.lines > size)
    return f.Bad("^IMAGE", "", file + " holds " + std::to_string(size) + " bytes, the image needs " +
                                   std::to_string(info.image_offset_bytes + line_bytes * info.lines));
  *image = cv::Mat(info.lines, info.line_samples, bytes == 1 ? CV_8UC1 : CV_16UC1);
  std::vector<unsigned char> row(static_cast<size_t>(line_bytes));
  for (int y = 0; y < info.lines; ++y) {
    in.seekg(info.image_offset_bytes + line_bytes * y);
    in.read(reinterpret_cast<char*>(row.data()), line_bytes);
    if (!in) return f.Bad("^IMAGE", "", "short read in " + file);
    const unsigned char* src = row.data() + prefix;
    if (bytes == 1) {
      std::memcpy(image->ptr<uint8_t>(y), src, info.line_samples);
      continue;
    }
    uint16_t* dst = image->ptr<uint16_t>(y);
    for (int x = 0; x < info.line_samples; ++x) {
      const unsigned char b0 = src[2 * x], b1 = src[2 * x + 1];
      const uint16_t u = lsb ? static_cast<uint16_t>(b0 | (b1 << 8)) : static_cast<uint16_t>((b0 << 8) | b1);
      dst[x] = is_signed ? static_cast<uint16_t>(std::max<int>(0, static_cast<int16_t>(u))) : u;
    }
  }
  return true;
}

}  // namespace vloc
