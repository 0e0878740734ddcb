#pragma once
// Options: each option is declared once, on one line of its struct's Visit:
//
//   struct XOptions {
//     int window = 41;       // px, side of the local statistics window
//     double contrast = 0.8;
//     double min_x = 0, max_x = 10;
//     LsmOptions lsm;
//     void Visit(OptionsReader& r);
//     bool Check(std::string* error) const;  // bounds (from Visit) and relations
//   };
//   void XOptions::Visit(OptionsReader& r) {
//     r.Optional("window", &window, "px, side of the local statistics window", Odd() && AtLeast(3));
//     r.Optional("contrast", &contrast, "contrast expansion constant", InLeftOpen(0, 1));
//     r.Optional("min_x", &min_x, "m, ...", NonNegative());
//     r.Optional("max_x", &max_x, "m, ...");
//     r.Child("lsm", [&](OptionsReader& c) { lsm.Visit(c); });   // a nested struct, checked through
//     r.Relation("max_x", max_x >= min_x, "must be >= min_x");   // between fields: after the reads
//   }
//   bool XOptions::Check(std::string* error) const { return CheckOptions(*this, error); }
//
// The default is the member's initializer; key, doc and bound are the Visit
// line. From it follow: loading (LoadOptions: read the YAML map, refuse keys
// no line named), echoing (the effective values, defaults included) and
// checking (CheckOptions runs Visit in check mode: every value against its
// bound, then the relations, so options built in code are checked the same
// way as loaded ones). A check error is one line naming the key path, the
// value and the rule: "window = 4: must be odd and >= 3"; LoadOptions puts
// the context in front: "config/x.yaml:wallis: window = 4: must be ...".
//
// Bounds (NaN fails every bound; a key with no bound takes any value):
//   AtLeast(a) >= a   Above(a) > a   AtMost(b) <= b   Below(b) < b
//   InRange(a, b) [a, b]   InOpen(a, b) (a, b)   InLeftOpen(a, b) (a, b]   InRightOpen(a, b) [a, b)
//   Is(v) == v   Odd()   Finite()   NonNegative() = AtLeast(0)   Positive() = Above(0)
//   OneOf({"a", "b"}) a string among these   NonEmpty() a string or list with something in it
//   Each(bound) every element of a list (or Eigen vector)
//   Rule<T>(predicate, "a power of two") any test of the one value ("must be a power of two")
//   b1 && b2 both ("must be odd and >= 3"), b1 || b2 either ("must be 0 or >= 3")
// A rule between fields is r.Relation(key, holds, "must ..."), written after
// the lines it reads; it names `key` and its value. The first failure in
// Visit's order is the one reported.
//
// Converting a struct that still has a hand-written Check:
//   1. each `if (bad) return Fail(error, "x must be ...")` becomes the bound
//      argument of x's Visit line (the doc no longer repeats the bound);
//   2. a test between fields becomes r.Relation(key, holds, "must ...") at
//      the end of Visit; a test of one value no helper says is Rule<T>(f, "...");
//   3. a child's `sub.Check(&e)` goes: r.Child(...) already checks it, and
//      its keys come with their path ("stereo.zncc_window = 8: ...");
//   4. Check's body becomes `return CheckOptions(*this, error);`.
// A struct not converted yet may still write Check by hand (Fail below);
// LoadOptions calls Check() either way.

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace vloc {

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Sets *error (when not null) and returns false: `return Fail(error, "...")`.
bool Fail(std::string* error, const std::string& message);

// Reads a YAML file; an empty one is an error. A map of the form {include: other.yaml} anywhere in it
// is replaced by the contents of other.yaml (relative to the including file).
YAML::Node LoadYamlFile(const std::string& path);

// A bound on one option's value: a test and the rule it states, e.g.
// "odd and >= 3" (the message reads "must be " + rule). An empty bound
// accepts every value.
template <class T>
class Bound {
 public:
  using IsOptionBound = void;
  Bound() = default;
  Bound(std::function<bool(const T&)> holds, std::string rule) : holds_(std::move(holds)), rule_(std::move(rule)) {}
  bool empty() const { return !holds_; }
  bool Holds(const T& value) const { return !holds_ || holds_(value); }
  const std::string& rule() const { return rule_; }

 private:
  std::function<bool(const T&)> holds_;
  std::string rule_;
};

template <class T>
Bound<T> operator&&(const Bound<T>& a, const Bound<T>& b) {
  return Bound<T>([a, b](const T& v) { return a.Holds(v) && b.Holds(v); }, a.rule() + " and " + b.rule());
}
template <class T>
Bound<T> operator||(const Bound<T>& a, const Bound<T>& b) {
  return Bound<T>([a, b](const T& v) { return a.Holds(v) || b.Holds(v); }, a.rule() + " or " + b.rule());
}

// A bound on a number, whatever its type (int, double, ...): converts to
// Bound<T> for any arithmetic T, and Each() applies it to a list's elements.
// NaN never holds.
class NumberBound {
 public:
  using IsOptionBound = void;
  NumberBound(std::function<bool(double)> holds, std::string rule) : holds_(std::move(holds)), rule_(std::move(rule)) {}
  bool Holds(double v) const { return !std::isnan(v) && holds_(v); }
  const std::string& rule() const { return rule_; }
  template <class T, class = std::enable_if_t<std::is_arithmetic_v<T>>>
  operator Bound<T>() const {  // NOLINT: implicit on purpose, AtLeast(3) is a Bound<int> and a Bound<double>
    const NumberBound b = *this;
    return Bound<T>([b](const T& v) { return b.Holds(static_cast<double>(v)); }, rule_);
  }

 private:
  std::function<bool(double)> holds_;
  std::string rule_;
};
NumberBound operator&&(const NumberBound& a, const NumberBound& b);
NumberBound operator||(const NumberBound& a, const NumberBound& b);

NumberBound AtLeast(double a);                 // >= a
NumberBound Above(double a);                   // > a
NumberBound AtMost(double b);                  // <= b
NumberBound Below(double b);                   // < b
NumberBound InRange(double a, double b);       // [a, b]
NumberBound InOpen(double a, double b);        // (a, b)
NumberBound InLeftOpen(double a, double b);    // (a, b]
NumberBound InRightOpen(double a, double b);   // [a, b)
NumberBound Is(double v);                      // == v, e.g. Is(0) || AtLeast(3)
NumberBound Odd();                             // an odd whole number
NumberBound Finite();                          // not NaN, not infinite
inline NumberBound Positive() { return Above(0); }
inline NumberBound NonNegative() { return AtLeast(0); }

// Any test of one value: Rule<std::string>(ValidChannelName, "a valid LCM channel name").
template <class T>
Bound<T> Rule(std::function<bool(const T&)> holds, std::string rule) {
  return Bound<T>(std::move(holds), std::move(rule));
}

// A string among `values`: "one of a, b, c".
Bound<std::string> OneOf(std::initializer_list<const char*> values);

// A string or a list that is not empty.
struct NonEmptyBound {
  using IsOptionBound = void;
  template <class T>
  operator Bound<T>() const {  // NOLINT: implicit on purpose
    return Bound<T>([](const T& v) { return v.size() > 0; }, "non-empty");
  }
};
inline NonEmptyBound NonEmpty() { return {}; }

// A bound on every element of a list or of an Eigen vector: "each >= 1".
struct EachBound {
  using IsOptionBound = void;
  NumberBound element;
  template <class T>
  operator Bound<T>() const {  // NOLINT: implicit on purpose
    const NumberBound e = element;
    return Bound<T>(
        [e](const T& v) {
          for (Eigen::Index i = 0; i < static_cast<Eigen::Index>(v.size()); ++i)
            if (!e.Holds(static_cast<double>(v[i]))) return false;
          return true;
        },
        "each " + element.rule());
  }
};
inline EachBound Each(NumberBound element) { return {std::move(element)}; }

namespace options_internal {
template <class T>
struct Same {
  using type = T;
};
// Two bounds of different kinds (NonEmpty() && Each(...)), typed when the
// option's type is known.
template <class A, class B, bool kAnd>
struct Pair {
  using IsOptionBound = void;
  A a;
  B b;
  template <class T>
  operator Bound<T>() const {  // NOLINT: implicit on purpose
    const Bound<T> ta = a, tb = b;
    return kAnd ? (ta && tb) : (ta || tb);
  }
};
}  // namespace options_internal

template <class A, class B, class = typename A::IsOptionBound, class = typename B::IsOptionBound>
options_internal::Pair<A, B, true> operator&&(const A& a, const B& b) {
  return {a, b};
}
template <class A, class B, class = typename A::IsOptionBound, class = typename B::IsOptionBound>
options_internal::Pair<A, B, false> operator||(const A& a, const B& b) {
  return {a, b};
}

class OptionsReader {
 public:
  // `context` names where the map came from, e.g. "config/procs/x.yaml:frontend".
  OptionsReader(YAML::Node node, std::string context);
  // A reader in check mode: it reads nothing and holds each value to its
  // bound; the first failure goes to *error. CheckOptions uses it.
  static OptionsReader Checker(std::string* error);

  // One option: key, the member it loads into (its initializer is the
  // default), the doc (unit first), the bound.
  template <class T>
  void Optional(const std::string& key, T* value, const char* doc = "",
                const Bound<typename options_internal::Same<T>::type>& bound = {}) {
    Read(key, value, /*required=*/false, doc, bound);
  }
  template <class T>
  void Required(const std::string& key, T* value, const char* doc = "",
                const Bound<typename options_internal::Same<T>::type>& bound = {}) {
    Read(key, value, /*required=*/true, doc, bound);
  }
  // A nested map; `visit` runs on it (with an empty map when the key is absent).
  // In check mode the child's keys are named "key.child_key".
  void Child(const std::string& key, const std::function<void(OptionsReader&)>& visit);
  // A rule between fields, written after the lines it reads: in check mode,
  // when `holds` is false the error is "key = value: rule".
  void Relation(const std::string& key, bool holds, const std::string& rule);
  bool checking() const { return check_error_ != nullptr; }

  // Throws ConfigError for the first key in the map that nobody visited.
  void Finish() const;

  // Effective values (defaults included) as YAML text.
  std::string Echo() const;
  const std::string& context() const { return context_; }

 private:
  template <class T>
  void Read(const std::string& key, T* value, bool required, const char* doc, const Bound<T>& bound);
  [[noreturn]] void Throw(const std::string& key, const std::string& what) const;
  void CheckFailed(const std::string& key, const std::string& rule);

  YAML::Node node_;
  std::string context_;          // load mode: where the map came from; check mode: the key path so far
  std::string* check_error_ = nullptr;  // check mode: where the first failure goes (set once)
  std::set<std::string> visited_;
  YAML::Node echo_;
};

// Options::Check from its Visit: every bound, then every relation. Returns
// false with the first failure in *error ("key = value: must be ...").
template <class Options>
bool CheckOptions(const Options& options, std::string* error) {
  std::string first;
  OptionsReader checker = OptionsReader::Checker(&first);
  Options copy = options;  // Visit takes the struct to load; check mode writes nothing
  copy.Visit(checker);
  if (first.empty()) return true;
  return Fail(error, first);
}

// Visits `node` into a default-constructed Options, rejects unknown keys,
// runs Check(). Throws ConfigError. When `echo` is not null it receives the
// effective values as YAML.
template <class Options>
Options LoadOptions(const YAML::Node& node, const std::string& context, std::string* echo = nullptr) {
  Options options;
  OptionsReader reader(node, context);
  options.Visit(reader);
  reader.Finish();
  std::string error;
  if (!options.Check(&error)) throw ConfigError(context + ": " + error);
  if (echo) *echo = reader.Echo();
  return options;
}

// The map at `section` of a YAML file (the whole file when section is
// empty), as LoadOptions would read it.
template <class Options>
Options LoadOptionsFile(const std::string& path, const std::string& section = "",
                        std::string* echo = nullptr) {
  YAML::Node root = LoadYamlFile(path);
  YAML::Node node = section.empty() ? root : root[section];
  if (!section.empty() && !node) throw ConfigError(path + ": section '" + section + "' missing");
  return LoadOptions<Options>(node, section.empty() ? path : path + ":" + section, echo);
}

}  // namespace vloc
