#include "navcam_manifest.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "vloc/common/image_header.h"
#include "vloc/common/pds_label.h"

namespace vloc {

namespace {

// Reads `key` of a row; false with a message when missing or of the wrong type.
template <class T>
bool Field(const YAML::Node& row, const char* key, T* value, std::string* error) {
  const YAML::Node n = row[key];
  if (!n) {
    *error = std::string("missing '") + key + "'";
    return false;
  }
  try {
    *value = n.as<T>();
  } catch (const YAML::Exception&) {
    *error = std::string("'") + key + "' is '" + YAML::Dump(n) + "', expected " +
             (std::is_same_v<T, std::string> ? "a file name" : "a number");
    return false;
  }
  return true;
}

// "manifest PATH line L, row R".
std::string RowName(const std::string& path, int row, int line) {
  return "manifest " + path + " line " + std::to_string(line) + ", row " + std::to_string(row);
}

// Refuses, per site (a run of equal site ids in time order), rows whose pair
// index repeats an earlier row's or is not below the site's row count
// (num_pairs as published): until every index of every site lies in
// [0, rows). Each refusal is one line in *problems.
void RefuseBadPairIndices(const std::string& path, std::vector<NavcamManifestEntry>* entries,
                          std::vector<std::string>* problems) {
  std::vector<NavcamManifestEntry> kept;
  for (size_t begin = 0; begin < entries->size();) {
    size_t end = begin;
    while (end < entries->size() && (*entries)[end].site_id == (*entries)[begin].site_id) ++end;
    std::vector<NavcamManifestEntry> site((*entries).begin() + static_cast<long>(begin),
                                          (*entries).begin() + static_cast<long>(end));
    for (bool refused = true; refused;) {
      refused = false;
      std::vector<bool> used(site.size(), false);
      for (size_t i = 0; i < site.size(); ++i) {
        const NavcamManifestEntry& e = site[i];
        const int rows = static_cast<int>(site.size());
        std::string why;
        if (e.pair_index >= rows)
          why = "pair index " + std::to_string(e.pair_index) + " is not below num_pairs " + std::to_string(rows) +
                " (the site's rows: number them 0.." + std::to_string(rows - 1) + ")";
        else if (e.pair_index >= kMaxPairsPerSite)
          why = "pair index " + std::to_string(e.pair_index) + " is not below " + std::to_string(kMaxPairsPerSite) +
                " (most pairs a site may hold)";
        else if (used[static_cast<size_t>(e.pair_index)])
          why = "pair index " + std::to_string(e.pair_index) + " repeats an earlier row of the site";
        if (why.empty()) {
          used[static_cast<size_t>(e.pair_index)] = true;
          continue;
        }
        problems->push_back(RowName(path, e.row, e.line) + " (site " + std::to_string(e.site_id) + " pair " +
                            std::to_string(e.pair_index) + "): " + why + "; row skipped");
        site.erase(site.begin() + static_cast<long>(i));
        refused = true;  // the site has fewer rows now: check again
        break;
      }
    }
    kept.insert(kept.end(), site.begin(), site.end());
    begin = end;
  }
  entries->swap(kept);
}

}  // namespace

namespace {

// The manifest's YAML and its 'pairs' list: false with the problem in out.
bool LoadManifestYaml(const std::string& path, YAML::Node* root, NavcamManifest* out) {
  try {
    *root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    out->problems.push_back("manifest " + path + " cannot be read: no such file (give the path of the manifest YAML)");
    return false;
  } catch (const YAML::Exception& e) {
    out->problems.push_back("manifest " + path + " is not valid YAML: " + e.what());
    return false;
  }
  const YAML::Node pairs = (*root)["pairs"];
  if (!root->IsMap() || !pairs || !pairs.IsSequence()) {
    out->problems.push_back("manifest " + path + " has no 'pairs' list (see procs/navcam_driver/navcam_manifest.h)");
    return false;
  }
  return true;
}

// Row `row_number` of the list: its entry (angles in rad, paths beside the
// manifest), or nullopt with the problem that skips it.
std::optional<NavcamManifestEntry> ReadRow(const YAML::Node& row, int row_number, const std::string& path,
                                           double angle_scale, std::vector<std::string>* problems) {
  NavcamManifestEntry e;
  e.row = row_number;
  e.line = row.Mark().line + 1;
  const std::string where = RowName(path, e.row, e.line);
  double time = 0, pan = 0, tilt = 0;
  std::string left, right, error;
  if (!row.IsMap()) {
    problems->push_back(where + ": not a map of site/pair/pan/tilt/time/left/right; row skipped");
    return std::nullopt;
  }
  if (!Field(row, "site", &e.site_id, &error) || !Field(row, "pair", &e.pair_index, &error) ||
      !Field(row, "pan", &pan, &error) || !Field(row, "tilt", &tilt, &error) || !Field(row, "time", &time, &error) ||
      !Field(row, "left", &left, &error) || !Field(row, "right", &right, &error)) {
    problems->push_back(where + ": " + error + "; row skipped");
    return std::nullopt;
  }
  e.pan = pan * angle_scale;
  e.tilt = tilt * angle_scale;
  if (e.site_id < 0 || e.pair_index < 0) error = "site and pair must be >= 0";
  else if (!std::isfinite(e.pan) || std::abs(e.pan) > 2 * M_PI) error = "pan " + std::to_string(pan) + " out of range (|pan| <= 360 deg)";
  else if (!std::isfinite(e.tilt) || std::abs(e.tilt) > M_PI / 2) error = "tilt " + std::to_string(tilt) + " out of range (|tilt| <= 90 deg)";
  else if (!std::isfinite(time) || time < 0) error = "time " + std::to_string(time) + " must be a finite number of seconds >= 0";
  const std::string which = where + " (site " + std::to_string(e.site_id) + " pair " + std::to_string(e.pair_index) + ")";
  if (!error.empty()) {
    problems->push_back(which + ": " + error + "; row skipped");
    return std::nullopt;
  }
  e.utime = static_cast<int64_t>(std::llround(time * 1e6));
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  e.left_path = (dir / left).string();
  e.right_path = (dir / right).string();
  for (const std::string* p : {&e.left_path, &e.right_path}) {
    if (!std::filesystem::is_regular_file(*p)) {
      problems->push_back(which + ": image file " + *p + " missing; row skipped");
      return std::nullopt;
    }
  }
  return e;
}

}  // namespace

NavcamManifest ReadNavcamManifest(const std::string& path) {
  NavcamManifest out;
  YAML::Node root;
  if (!LoadManifestYaml(path, &root, &out)) return out;
  out.readable = true;
  double angle_scale = 1.0;
  const std::string unit = root["angle_unit"] ? root["angle_unit"].as<std::string>("") : "rad";
  if (unit == "deg") angle_scale = M_PI / 180.0;
  else if (unit != "rad")
    out.problems.push_back("manifest " + path + ": angle_unit '" + unit + "' unknown (use rad or deg); assuming rad");
  int row_number = 0;
  for (const YAML::Node& row : root["pairs"])
    if (auto e = ReadRow(row, ++row_number, path, angle_scale, &out.problems)) out.entries.push_back(*e);
  std::stable_sort(out.entries.begin(), out.entries.end(),
                   [](const NavcamManifestEntry& a, const NavcamManifestEntry& b) { return a.utime < b.utime; });
  RefuseBadPairIndices(path, &out.entries, &out.problems);
  return out;
}

namespace {

bool IsPdsProduct(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return ext == ".IMG" || ext == ".LBL";  // a detached label is read with the .IMG it names
}

// 8-bit grey or BGR, as the file holds it (see LoadNavcamPair).
cv::Mat LoadImage(const std::string& path, std::string* why) {
  cv::Mat image;
  if (IsPdsProduct(path)) {
    std::string error;
    if (!ReadPdsImage(path, &image, &error)) {
      *why = "unreadable (" + error + ")";
      return cv::Mat();
    }
  } else {
    // The header is checked before anything is decoded: a file that claims 30,000 x 30,000 px is refused, not decoded.
    std::vector<uint8_t> bytes;
    ImageHeader header;
    std::string error;
    if (!ReadCheckedImageFile(path, ImageLimits(), &bytes, &header, &error)) {
      *why = "cannot be decoded (" + error + ")";
      return image;
    }
    image = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
    if (image.empty()) {
      *why = "cannot be decoded (not an image or corrupt)";
      return image;
    }
  }
  if (image.depth() == CV_16U) {
    double max = 0;
    cv::minMaxLoc(image.reshape(1), nullptr, &max);
    image.convertTo(image, CV_8U, max <= 4095 ? 1.0 / 16 : 1.0 / 256);
  } else if (image.depth() != CV_8U) {
    *why = "is not an 8- or 16-bit image";
    return cv::Mat();
  }
  if (image.channels() == 4) cv::cvtColor(image, image, cv::COLOR_BGRA2BGR);
  if (image.channels() == 2) cv::extractChannel(image, image, 0);  // grey + alpha
  return image;
}

}  // namespace

bool LoadNavcamPair(const NavcamManifestEntry& entry, StereoPair* pair, std::string* error) {
  const std::string where = "site " + std::to_string(entry.site_id) + " pair " + std::to_string(entry.pair_index);
  std::string why;
  pair->left = LoadImage(entry.left_path, &why);
  if (pair->left.empty()) {
    *error = where + ": left image " + entry.left_path + " " + why + "; pair skipped";
    return false;
  }
  pair->right = LoadImage(entry.right_path, &why);
  if (pair->right.empty()) {
    *error = where + ": right image " + entry.right_path + " " + why + "; pair skipped";
    return false;
  }
  if (pair->left.size() != pair->right.size()) {
    *error = where + ": left and right images differ in size; pair skipped";
    return false;
  }
  if (pair->left.channels() != pair->right.channels()) {
    for (cv::Mat* m : {&pair->left, &pair->right})
      if (m->channels() == 3) cv::cvtColor(*m, *m, cv::COLOR_BGR2GRAY);
  }
  pair->utime = entry.utime;
  pair->site_id = entry.site_id;
  pair->pair_index = entry.pair_index;
  pair->mast_pan = entry.pan;
  pair->mast_tilt = entry.tilt;
  return true;
}

}  // namespace vloc
