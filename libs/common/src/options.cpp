#include "vloc/common/options.h"

#include <algorithm>
#include <cstdio>
#include <cstdint>
#include <filesystem>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

namespace vloc {

bool Fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

namespace {

// A number as the rules print it: 3, 0.5, 1e-06.
std::string Num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.12g", v);
  return buf;
}

}  // namespace

NumberBound operator&&(const NumberBound& a, const NumberBound& b) {
  return NumberBound([a, b](double v) { return a.Holds(v) && b.Holds(v); }, a.rule() + " and " + b.rule());
}
NumberBound operator||(const NumberBound& a, const NumberBound& b) {
  return NumberBound([a, b](double v) { return a.Holds(v) || b.Holds(v); }, a.rule() + " or " + b.rule());
}
NumberBound AtLeast(double a) { return NumberBound([a](double v) { return v >= a; }, ">= " + Num(a)); }
NumberBound Above(double a) { return NumberBound([a](double v) { return v > a; }, "> " + Num(a)); }
NumberBound AtMost(double b) { return NumberBound([b](double v) { return v <= b; }, "<= " + Num(b)); }
NumberBound Below(double b) { return NumberBound([b](double v) { return v < b; }, "< " + Num(b)); }
NumberBound InRange(double a, double b) {
  return NumberBound([a, b](double v) { return v >= a && v <= b; }, "in [" + Num(a) + ", " + Num(b) + "]");
}
NumberBound InOpen(double a, double b) {
  return NumberBound([a, b](double v) { return v > a && v < b; }, "in (" + Num(a) + ", " + Num(b) + ")");
}
NumberBound InLeftOpen(double a, double b) {
  return NumberBound([a, b](double v) { return v > a && v <= b; }, "in (" + Num(a) + ", " + Num(b) + "]");
}
NumberBound InRightOpen(double a, double b) {
  return NumberBound([a, b](double v) { return v >= a && v < b; }, "in [" + Num(a) + ", " + Num(b) + ")");
}
NumberBound Is(double x) { return NumberBound([x](double v) { return v == x; }, Num(x)); }
NumberBound Odd() { return NumberBound([](double v) { return std::fmod(std::fabs(v), 2.0) == 1.0; }, "odd"); }
NumberBound Finite() { return NumberBound([](double v) { return std::isfinite(v); }, "finite"); }

Bound<std::string> OneOf(std::initializer_list<const char*> values) {
  std::vector<std::string> list(values.begin(), values.end());
  std::string rule = "one of";
  for (size_t i = 0; i < list.size(); ++i) rule += (i ? ", " : " ") + list[i];
  return Bound<std::string>(
      [list](const std::string& v) { return std::find(list.begin(), list.end(), v) != list.end(); }, rule);
}

namespace {

// What loading one config file (its includes and aliases expanded) may
// build: a 320-byte file of nested aliases (a "billion laughs") expands to
// billions of nodes, so nodes are counted as they are copied and the file
// refused past the budget; nesting deeper than the depth is refused too.
constexpr size_t kMaxConfigNodes = 100000;
constexpr int kMaxConfigNesting = 64;
constexpr int kMaxIncludeDepth = 16;
constexpr uintmax_t kMaxConfigBytes = 16u << 20;  // a config file is kilobytes

// Throws unless `path` is absent (the YAML loader then says so) or a regular
// file of at most kMaxConfigBytes: a FIFO or /dev/zero would never end.
void CheckConfigFile(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) return;
  if (!std::filesystem::is_regular_file(status))
    throw ConfigError("config file " + path + " is not a regular file; refused");
  const uintmax_t size = std::filesystem::file_size(path, ec);
  if (!ec && size > kMaxConfigBytes)
    throw ConfigError("config file " + path + " is " + std::to_string(size) + " bytes, over the " +
                      std::to_string(kMaxConfigBytes) + " a config may have; refused");
}

struct LoadBudget {
  std::string top_file;  // the file the load started from
  size_t nodes = 0;      // nodes built so far
};

// Counts one node built from `file` at `nesting` levels, throwing when the
// budget is spent.
void CountNode(LoadBudget* budget, const std::string& file, int nesting) {
  if (nesting > kMaxConfigNesting)
    throw ConfigError("config file " + file + ": nested deeper than " + std::to_string(kMaxConfigNesting) +
                      " levels; refused");
  if (++budget->nodes > kMaxConfigNodes)
    throw ConfigError("config file " + file + ": more than " + std::to_string(kMaxConfigNodes) +
                      " YAML nodes once its aliases and includes are expanded (an alias bomb?); refused" +
                      (file == budget->top_file ? std::string() : " (loading " + budget->top_file + ")"));
}

std::string KeyString(const YAML::Node& key, const std::string& file) {
  if (!key.IsScalar()) throw ConfigError("config file " + file + ": a map key that is not a plain name");
  return key.Scalar();
}

// A scalar or null as a node of its own. Handing yaml-cpp a node of the
// parsed document instead merges that document's whole node set into every
// node it joins, and they into each other: quadratic in the nodes.
YAML::Node CopyLeaf(const YAML::Node& node) {
  if (!node.IsScalar()) return YAML::Node(node.IsDefined() ? node.Type() : YAML::NodeType::Null);
  YAML::Node copy(node.Scalar());
  copy.SetTag(node.Tag());
  copy.SetStyle(node.Style());
  return copy;
}

// `overrides` laid over `base`: maps merge key by key, anything else
// replaces. Both come from ResolveIncludes (counted there); the merged map
// is built in one pass over each (yaml-cpp's own key lookup is linear).
YAML::Node Merge(const YAML::Node& base, const YAML::Node& overrides, const std::string& file) {
  if (!base.IsMap() || !overrides.IsMap()) return overrides;
  std::unordered_map<std::string, YAML::Node> over;
  for (const auto& kv : overrides) over.emplace(KeyString(kv.first, file), kv.second);
  YAML::Node out(YAML::NodeType::Map);
  std::unordered_set<std::string> placed;
  for (const auto& kv : base) {
    const std::string key = KeyString(kv.first, file);
    const auto it = over.find(key);
    out.force_insert(key, it == over.end() ? kv.second : Merge(kv.second, it->second, file));
    placed.insert(key);
  }
  for (const auto& kv : overrides) {
    const std::string key = KeyString(kv.first, file);
    if (placed.insert(key).second) out.force_insert(key, kv.second);
  }
  return out;
}

// A copy of `node` (read from `file`) with every {include: FILE, ...} map
// replaced by that file's content, the other keys laid over it. Every node
// copied counts against *budget: aliases are expanded here, once per use.
YAML::Node ResolveIncludes(const YAML::Node& node, const std::filesystem::path& file, int include_depth, int nesting,
                           LoadBudget* budget) {
  if (include_depth > kMaxIncludeDepth)
    throw ConfigError("config include nesting deeper than " + std::to_string(kMaxIncludeDepth) + " (include loop?)");
  CountNode(budget, file.string(), nesting);
  const std::filesystem::path dir = file.parent_path();
  if (node.IsMap()) {
    if (node["include"] && node["include"].IsScalar()) {
      // {include: FILE, key: value, ...}: the file, with the other keys laid over it (a profile over a base config).
      const auto path = dir / node["include"].as<std::string>();
      YAML::Node included;
      CheckConfigFile(path.string());
      try {
        included = YAML::LoadFile(path.string());
      } catch (const YAML::Exception& e) {
        throw ConfigError("cannot read included config " + path.string() + ": " + e.what());
      }
      const YAML::Node base = ResolveIncludes(included, path, include_depth + 1, nesting, budget);
      if (node.size() == 1) return base;
      if (!base.IsMap()) throw ConfigError("included config " + path.string() + " is not a map: keys cannot be laid over it");
      YAML::Node overrides(YAML::NodeType::Map);
      for (const auto& kv : node) {
        const std::string key = KeyString(kv.first, file.string());
        if (key != "include")
          overrides.force_insert(key, ResolveIncludes(kv.second, file, include_depth, nesting + 1, budget));
      }
      return Merge(base, overrides, file.string());
    }
    YAML::Node out(YAML::NodeType::Map);
    for (const auto& kv : node) {
      CountNode(budget, file.string(), nesting + 1);  // the key
      out.force_insert(KeyString(kv.first, file.string()),
                       ResolveIncludes(kv.second, file, include_depth, nesting + 1, budget));
    }
    return out;
  }
  if (node.IsSequence()) {
    YAML::Node out(YAML::NodeType::Sequence);
    for (const auto& v : node) out.push_back(ResolveIncludes(v, file, include_depth, nesting + 1, budget));
    return out;
  }
  return CopyLeaf(node);
}

size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

template <class T>
const char* TypeName() {
  if constexpr (std::is_same_v<T, bool>) return "true or false";
  else if constexpr (std::is_integral_v<T>) return "an integer";
  else if constexpr (std::is_floating_point_v<T>) return "a number";
  else if constexpr (std::is_same_v<T, std::string>) return "a string";
  else return "a list";
}

template <class T>
T Decode(const YAML::Node& n) {
  if constexpr (std::is_same_v<T, Eigen::Vector2d> || std::is_same_v<T, Eigen::Vector3d>) {
    T v;
    if (!n.IsSequence() || n.size() != static_cast<size_t>(v.size())) throw YAML::BadConversion(n.Mark());
    for (int i = 0; i < v.size(); ++i) v[i] = n[i].as<double>();
    return v;
  } else {
    return n.as<T>();
  }
}

template <class T>
YAML::Node Encode(const T& v) {
  if constexpr (std::is_same_v<T, Eigen::Vector2d> || std::is_same_v<T, Eigen::Vector3d>) {
    YAML::Node n(YAML::NodeType::Sequence);
    for (int i = 0; i < v.size(); ++i) n.push_back(v[i]);
    n.SetStyle(YAML::EmitterStyle::Flow);
    return n;
  } else if constexpr (std::is_floating_point_v<T>) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.12g", static_cast<double>(v));
    return YAML::Node(std::string(buf));
  } else {
    YAML::Node n;
    n = v;
    if constexpr (!std::is_arithmetic_v<T> && !std::is_same_v<T, std::string>) n.SetStyle(YAML::EmitterStyle::Flow);
    return n;
  }
}

}  // namespace

YAML::Node LoadYamlFile(const std::string& path) {
  YAML::Node root;
  CheckConfigFile(path);
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw ConfigError("cannot read config file " + path + ": no such file or not readable");
  } catch (const YAML::Exception& e) {
    throw ConfigError("config file " + path + " is not valid YAML: " + e.what());
  }
  if (root.IsNull())
    throw ConfigError("config file " + path +
                      " is empty: nothing would be set on purpose (write {} to take every default)");
  LoadBudget budget{path};
  return ResolveIncludes(root, std::filesystem::path(path), 0, 0, &budget);
}

OptionsReader::OptionsReader(YAML::Node node, std::string context)
    : node_(std::move(node)), context_(std::move(context)), echo_(YAML::NodeType::Map) {
  if (node_ && !node_.IsNull() && !node_.IsMap())
    throw ConfigError(context_ + ": expected a map of options");
}

void OptionsReader::Throw(const std::string& key, const std::string& what) const {
  throw ConfigError(context_ + "." + key + ": " + what);
}

OptionsReader OptionsReader::Checker(std::string* error) {
  OptionsReader checker(YAML::Node(), "");
  checker.check_error_ = error;
  return checker;
}

void OptionsReader::CheckFailed(const std::string& key, const std::string& rule) {
  if (!check_error_->empty()) return;  // the first failure is the one reported
  std::string value;
  const YAML::Node& echo = echo_;  // const: looking a key up must not add it
  if (echo[key]) {
    YAML::Emitter out;
    out.SetMapFormat(YAML::Flow);
    out.SetSeqFormat(YAML::Flow);
    out << echo[key];
    value = out.c_str();
  }
  *check_error_ = context_ + key + (value.empty() ? "" : " = " + value) + ": " + rule;
}

void OptionsReader::Relation(const std::string& key, bool holds, const std::string& rule) {
  if (checking() && !holds) CheckFailed(key, rule);
}

template <class T>
void OptionsReader::Read(const std::string& key, T* value, bool required, const char* /*doc*/,
                         const Bound<T>& bound) {
  if (checking()) {  // the value, for a relation's message; then its bound
    if (!check_error_->empty()) return;
    echo_[key] = Encode(*value);
    if (!bound.Holds(*value)) CheckFailed(key, "must be " + bound.rule());
    return;
  }
  visited_.insert(key);
  const YAML::Node n = (node_ && node_.IsMap()) ? node_[key] : YAML::Node();
  if (!n || n.IsNull()) {
    if (required) Throw(key, "required key missing; add it to the config file");
  } else {
    try {
      *value = Decode<T>(n);
    } catch (const YAML::Exception&) {
      Throw(key, std::string("expected ") + TypeName<T>() + ", got '" + YAML::Dump(n) + "'");
    }
  }
  echo_[key] = Encode(*value);
}

#define VLOC_INSTANTIATE(T) \
  template void OptionsReader::Read<T>(const std::string&, T*, bool, const char*, const Bound<T>&);
VLOC_INSTANTIATE(bool)
VLOC_INSTANTIATE(int)
VLOC_INSTANTIATE(int64_t)
VLOC_INSTANTIATE(uint64_t)
VLOC_INSTANTIATE(double)
VLOC_INSTANTIATE(float)
VLOC_INSTANTIATE(std::string)
VLOC_INSTANTIATE(std::vector<double>)
VLOC_INSTANTIATE(std::vector<int>)
VLOC_INSTANTIATE(std::vector<std::string>)
VLOC_INSTANTIATE(Eigen::Vector2d)
VLOC_INSTANTIATE(Eigen::Vector3d)
#undef VLOC_INSTANTIATE

void OptionsReader::Child(const std::string& key, const std::function<void(OptionsReader&)>& visit) {
  if (checking()) {
    if (!check_error_->empty()) return;
    OptionsReader child = Checker(check_error_);
    child.context_ = context_ + key + ".";
    visit(child);
    return;
  }
  visited_.insert(key);
  const YAML::Node n = (node_ && node_.IsMap()) ? node_[key] : YAML::Node();
  OptionsReader child(n ? n : YAML::Node(YAML::NodeType::Map), context_ + "." + key);
  visit(child);
  child.Finish();
  echo_[key] = child.echo_;
}

void OptionsReader::Finish() const {
  if (!node_ || !node_.IsMap()) return;
  for (const auto& kv : node_) {
    const std::string key = kv.first.as<std::string>();
    if (visited_.count(key)) continue;
    std::string best;
    size_t best_d = 3;
    for (const auto& k : visited_) {
      const size_t d = EditDistance(key, k);
      if (d < best_d) best_d = d, best = k;
    }
    Throw(key, "unknown key" + (best.empty() ? std::string("; remove it") : "; did you mean '" + best + "'?"));
  }
}

std::string OptionsReader::Echo() const {
  YAML::Emitter out;
  out << echo_;
  return out.c_str();
}

}  // namespace vloc
