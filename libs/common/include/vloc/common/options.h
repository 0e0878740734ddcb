#pragma once
// Options loading from YAML. Every options struct has
//   void Visit(OptionsReader& reader);   // names every key it knows
//   bool Check(std::string* error) const; // range checks, one line per error
// LoadOptions() visits a YAML map, rejects keys nobody named, checks the
// ranges and can echo the effective values. Errors are ConfigError with one
// line that names the file, the key and the fix.

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <functional>
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

class OptionsReader {
 public:
  // `context` names where the map came from, e.g. "config/procs/x.yaml:frontend".
  OptionsReader(YAML::Node node, std::string context);

  template <class T>
  void Optional(const std::string& key, T* value, const char* comment = "") {
    Read(key, value, /*required=*/false, comment);
  }
  template <class T>
  void Required(const std::string& key, T* value, const char* comment = "") {
    Read(key, value, /*required=*/true, comment);
  }
  // A nested map; `visit` runs on it (with an empty map when the key is absent).
  void Child(const std::string& key, const std::function<void(OptionsReader&)>& visit);

  // Throws ConfigError for the first key in the map that nobody visited.
  void Finish() const;

  // Effective values (defaults included) as YAML text.
  std::string Echo() const;
  const std::string& context() const { return context_; }

 private:
  template <class T>
  void Read(const std::string& key, T* value, bool required, const char* comment);
  [[noreturn]] void Throw(const std::string& key, const std::string& what) const;

  YAML::Node node_;
  std::string context_;
  std::set<std::string> visited_;
  YAML::Node echo_;
};

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
