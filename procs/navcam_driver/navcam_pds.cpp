#include "navcam_pds.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include "vloc/common/image_header.h"
#include "vloc/common/options.h"
#include "vloc/common/pds_label.h"
#include "vloc/common/pds_product.h"

namespace vloc {

namespace fs = std::filesystem;

void NavcamPdsOptions::Visit(OptionsReader& r) {
  r.Optional("pds_pair_max_dt", &pair_max_dt, "s, most start-time difference of the LEFT and RIGHT frame of a pair",
             InRange(0.0, 3600.0));
  r.Optional("pds_max_files", &max_files, "files looked at under the PDS folder", AtLeast(1));
  r.Optional("pds_max_image_side", &max_image_side, "px, largest image width / height read", InRange(16, 65536));
}

bool NavcamPdsOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

std::string NavcamPdsSite::Describe() const {
  std::ostringstream os;
  os << "site " << site_id << ": SITE " << pds_site << " DRIVE " << pds_drive;
  if (sol >= 0) os << " (sol " << sol << ")";
  os << ": " << pairs << " stereo pair(s) of " << frames << " frame(s)";
  return os.str();
}

namespace {

std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

int64_t DaysFromCivil(int y, int m, int d) {  // Howard Hinnant's algorithm
  y -= m <= 2;
  const int era = (y >= 0 ? y : y - 399) / 400;
  const int yoe = y - era * 400;
  const int doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const int doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return int64_t(era) * 146097 + doe - 719468;
}

enum class Eye { kLeft, kRight, kOther };

// One product: its label and where its pixels are.
struct Frame {
  PdsCameraLabel label;
  std::string image_path;  // the .IMG (read as PDS) or the browse image
  std::string name;        // label file name, for the log
  int64_t utime = 0;
  Eye eye = Eye::kOther;
  double pan = 0, tilt = 0;  // rad, vloc's mast convention
  bool used = false;
};

bool IsBrowseImage(const fs::path& p) {
  const std::string ext = Upper(p.extension().string());
  return ext == ".JPG" || ext == ".JPEG" || ext == ".PNG";
}

// The eye of a frame: FRAME_ID, else INSTRUMENT_ID.
Eye EyeOf(const PdsCameraLabel& l) {
  if (l.frame_id == "LEFT") return Eye::kLeft;
  if (l.frame_id == "RIGHT") return Eye::kRight;
  if (!l.frame_id.empty()) return Eye::kOther;  // MONO
  const std::string id = Upper(l.instrument_id);
  if (id.find("LEFT") != std::string::npos) return Eye::kLeft;
  if (id.find("RIGHT") != std::string::npos) return Eye::kRight;
  return Eye::kOther;
}

// Pan / tilt in vloc's convention from the label: the derived instrument
// pointing, else the model's axis when the model is in the rover frame.
bool Pointing(const PdsCameraLabel& l, double* pan, double* tilt, std::string* why) {
  double azimuth = 0, elevation = 0;  // rover frame: x forward, y right, z down
  if (l.has_instrument_pointing) {
    azimuth = l.instrument_azimuth;
    elevation = l.instrument_elevation;
  } else {
    const std::string frame = Upper(l.camera_frame);
    if (!frame.empty() && frame.find("ROVER") == std::string::npos) {
      *why = "INSTRUMENT_AZIMUTH of ROVER_DERIVED_GEOMETRY_PARMS: missing, and the camera model is in " +
             l.camera_frame + ", not the rover frame";
      return false;
    }
    const Eigen::Vector3d& a = l.camera.a;
    azimuth = std::atan2(a.y(), a.x());
    elevation = std::asin(std::clamp(-a.z(), -1.0, 1.0));
  }
  *pan = std::remainder(-azimuth, 2 * M_PI);
  *tilt = -elevation;
  if (!std::isfinite(*pan) || !std::isfinite(*tilt) || std::abs(*tilt) > M_PI / 2) {
    *why = "INSTRUMENT_ELEVATION of ROVER_DERIVED_GEOMETRY_PARMS: out of range (|elevation| <= 90 deg)";
    return false;
  }
  return true;
}

class FolderReader {
 public:
  FolderReader(const std::string& folder, const NavcamPdsOptions& options) : folder_(folder), options_(options) {}

  NavcamPdsFolder Read() {
    std::vector<fs::path> files;
    if (!List(&files)) return std::move(out_);
    out_.manifest.readable = true;
    std::set<std::string> claimed;  // images some label points to
    for (const fs::path& p : files) {
      const std::string ext = Upper(p.extension().string());
      if (ext == ".LBL") {
        // Its browse image belongs to it even when the label is unusable:
        // one line for the product, not a second one for an orphan image.
        const std::string browse = FindPdsBrowseImage(p.string());
        if (!browse.empty()) claimed.insert(fs::path(browse).lexically_normal().string());
        ReadProduct(p, &claimed);
      }
      else if (ext == ".IMG" && !HasDetachedLabel(p)) ReadProduct(p, &claimed);
    }
    for (const fs::path& p : files)
      if (IsBrowseImage(p) && !claimed.count(p.lexically_normal().string()))
        Problem(p.string() + ": no PDS label beside it (X.LBL for X.jpg, or ...M1.LBL for ...M_.jpg); skipped");
    GroupSites();
    return std::move(out_);
  }

 private:
  void Problem(const std::string& line) { out_.manifest.problems.push_back(line); }

  bool List(std::vector<fs::path>* files) {
    std::error_code ec;
    if (!fs::is_directory(folder_, ec)) {
      Problem("PDS folder " + folder_ + " is not a folder (give the folder holding the .LBL / .IMG products)");
      return false;
    }
    for (fs::recursive_directory_iterator it(folder_, fs::directory_options::skip_permission_denied, ec), end;
         !ec && it != end; it.increment(ec)) {
      if (!it->is_regular_file(ec)) continue;
      if (static_cast<int>(files->size()) >= options_.max_files) {
        Problem("PDS folder " + folder_ + " holds more than " + std::to_string(options_.max_files) +
                " files (pds_max_files); give the folder of one traverse");
        return false;
      }
      files->push_back(it->path());
    }
    if (ec) {
      Problem("PDS folder " + folder_ + " cannot be listed: " + ec.message());
      return false;
    }
    std::sort(files->begin(), files->end());
    return true;
  }

  static bool HasDetachedLabel(const fs::path& img) {
    for (const char* ext : {".LBL", ".lbl"})
      if (fs::is_regular_file(fs::path(img).replace_extension(ext))) return true;
    return false;
  }

  // Reads one label (.LBL or attached in an .IMG) and finds its pixels.
  void ReadProduct(const fs::path& path, std::set<std::string>* claimed) {
    Frame f;
    f.name = path.string();
    std::string error;
    if (!ReadPdsCameraLabel(path.string(), &f.label, &error)) {
      Problem(error + "; skipped");
      return;
    }
    const PdsCameraLabel& l = f.label;
    const bool attached = Upper(path.extension().string()) == ".IMG";
    // The pixels: the .IMG itself, the one ^IMAGE names, or a browse image.
    if (attached) {
      f.image_path = path.string();
    } else {
      if (!l.image_file.empty()) {  // the .IMG beside it (as written, upper or lower case): read through the label
        std::string lower = l.image_file;
        for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        for (const std::string& name : {l.image_file, Upper(l.image_file), lower})
          if (fs::is_regular_file(path.parent_path() / name)) f.image_path = path.string();
      }
      if (f.image_path.empty()) {
        f.image_path = FindPdsBrowseImage(path.string());
        if (f.image_path.empty()) {
          Problem(f.name + ": ^IMAGE: its file " + (l.image_file.empty() ? "(none named)" : l.image_file) +
                  " is absent and no browse image (.jpg, .png) lies beside the label; skipped");
          return;
        }
        claimed->insert(fs::path(f.image_path).lexically_normal().string());
        if (!CheckBrowseImage(f)) return;
      }
    }
    if (l.lines > options_.max_image_side || l.line_samples > options_.max_image_side) {
      Problem(f.name + ": LINES of IMAGE: " + std::to_string(l.lines) + " x " + std::to_string(l.line_samples) +
              " is over pds_max_image_side " + std::to_string(options_.max_image_side) + "; skipped");
      return;
    }
    if (l.start_time.empty()) {
      Problem(f.name + ": START_TIME: missing (pairs and sites are ordered by it); skipped");
      return;
    }
    if (!ParsePdsUtcTime(l.start_time, &f.utime)) {
      Problem(f.name + ": START_TIME: '" + l.start_time + "' is not a UTC time (2012-10-06T17:18:59.259); skipped");
      return;
    }
    if (l.site < 0 || l.drive < 0) {
      Problem(f.name + ": ROVER_MOTION_COUNTER: " + std::string(l.motion_counter.empty() ? "missing" : "no SITE / DRIVE") +
              " (sites are grouped by it); skipped");
      return;
    }
    f.eye = EyeOf(l);
    if (f.eye == Eye::kOther) {
      Problem(f.name + ": FRAME_ID: '" + l.frame_id + "' (INSTRUMENT_ID '" + l.instrument_id +
              "') is not LEFT or RIGHT: not one eye of a stereo pair; skipped");
      return;
    }
    if (!Pointing(l, &f.pan, &f.tilt, &error)) {
      Problem(f.name + ": " + error + "; skipped");
      return;
    }
    frames_.push_back(std::move(f));
  }

  // The browse image's size against the label's IMAGE object.
  bool CheckBrowseImage(const Frame& f) {
    ImageHeader header;
    std::string error;
    if (!ReadImageFileHeader(f.image_path, &header, &error)) {
      Problem(error + " (the browse image of " + f.name + "); skipped");
      return false;
    }
    if (header.width > options_.max_image_side || header.height > options_.max_image_side) {
      Problem(f.image_path + ": " + header.Describe() + " is over pds_max_image_side " +
              std::to_string(options_.max_image_side) + "; skipped");
      return false;
    }
    if (f.label.lines > 0 && (header.width != f.label.line_samples || header.height != f.label.lines)) {
      Problem(f.name + ": LINES / LINE_SAMPLES of IMAGE: the label says " + std::to_string(f.label.line_samples) +
              " x " + std::to_string(f.label.lines) + ", its browse image " + f.image_path + " is " +
              std::to_string(header.width) + " x " + std::to_string(header.height) +
              " (a thumbnail? the camera model is for the full frame); skipped");
      return false;
    }
    return true;
  }

  // Sites by (SITE, DRIVE), then pairs inside each site by SEQUENCE_ID and time.
  void GroupSites() {
    std::map<std::pair<int, int>, std::vector<Frame*>> by_site;
    for (Frame& f : frames_) by_site[{f.label.site, f.label.drive}].push_back(&f);
    std::vector<std::vector<Frame*>> sites;
    for (auto& [key, list] : by_site) {
      std::sort(list.begin(), list.end(), [](const Frame* a, const Frame* b) {
        return std::tie(a->utime, a->name) < std::tie(b->utime, b->name);
      });
      sites.push_back(list);
    }
    std::sort(sites.begin(), sites.end(), [](const auto& a, const auto& b) { return a.front()->utime < b.front()->utime; });
    std::vector<NavcamManifestEntry> entries;
    for (size_t s = 0; s < sites.size(); ++s) {
      NavcamPdsSite site;
      site.site_id = static_cast<int>(s);
      site.pds_site = sites[s].front()->label.site;
      site.pds_drive = sites[s].front()->label.drive;
      site.sol = sites[s].front()->label.sol;
      site.frames = static_cast<int>(sites[s].size());
      PairSite(sites[s], &site, &entries);
      out_.sites.push_back(site);
    }
    out_.manifest.entries = std::move(entries);
  }

  void PairSite(const std::vector<Frame*>& frames, NavcamPdsSite* site, std::vector<NavcamManifestEntry>* entries) {
    const int64_t max_dt = static_cast<int64_t>(std::llround(options_.pair_max_dt * 1e6));
    // Candidate (left, right) of one sequence within max_dt, nearest first.
    std::vector<std::tuple<int64_t, Frame*, Frame*>> candidates;
    for (Frame* l : frames)
      for (Frame* r : frames)
        if (l->eye == Eye::kLeft && r->eye == Eye::kRight && l->label.sequence_id == r->label.sequence_id &&
            std::abs(l->utime - r->utime) <= max_dt)
          candidates.emplace_back(std::abs(l->utime - r->utime), l, r);
    std::stable_sort(candidates.begin(), candidates.end(),
                     [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });
    std::vector<std::pair<Frame*, Frame*>> pairs;
    for (auto& [dt, l, r] : candidates) {
      if (l->used || r->used) continue;
      l->used = r->used = true;
      pairs.emplace_back(l, r);
    }
    std::sort(pairs.begin(), pairs.end(), [](const auto& a, const auto& b) {
      return std::tie(a.first->utime, a.first->name) < std::tie(b.first->utime, b.first->name);
    });
    for (const Frame* f : frames)
      if (!f->used)
        Problem(f->name + ": FRAME_ID " + f->label.frame_id + ": no " + (f->eye == Eye::kLeft ? "RIGHT" : "LEFT") +
                " frame of SEQUENCE_ID '" + f->label.sequence_id + "' within " + FormatDt() + " at SITE " +
                std::to_string(f->label.site) + " DRIVE " + std::to_string(f->label.drive) +
                " (vloc site " + std::to_string(site->site_id) + "): not a stereo pair; not published");
    for (const auto& [l, r] : pairs) {
      if (site->pairs >= kMaxPairsPerSite) {
        Problem(l->name + ": vloc site " + std::to_string(site->site_id) + " already holds " +
                std::to_string(kMaxPairsPerSite) + " pairs (most a site may hold); pair skipped");
        continue;
      }
      NavcamManifestEntry e;
      e.utime = l->utime;
      e.site_id = site->site_id;
      e.pair_index = site->pairs++;
      e.pan = l->pan;
      e.tilt = l->tilt;
      e.left_path = l->image_path;
      e.right_path = r->image_path;
      e.has_rover_pose = l->label.has_rover_pose;
      e.site_from_rover = l->label.site_from_rover;
      entries->push_back(e);
    }
  }

  std::string FormatDt() const {
    std::ostringstream os;
    os << options_.pair_max_dt << " s";
    return os.str();
  }

  std::string folder_;
  NavcamPdsOptions options_;
  NavcamPdsFolder out_;
  std::vector<Frame> frames_;
};

}  // namespace

bool ParsePdsUtcTime(const std::string& text_in, int64_t* utime) {
  std::string text = text_in;
  if (!text.empty() && (text.back() == 'Z' || text.back() == 'z')) text.pop_back();
  int y = 0, mo = 0, d = 0, doy = 0, h = 0, mi = 0;
  double sec = 0;
  int n = 0;
  int64_t days = 0;
  if (std::sscanf(text.c_str(), "%4d-%2d-%2dT%2d:%2d:%lf%n", &y, &mo, &d, &h, &mi, &sec, &n) == 6 &&
      n == static_cast<int>(text.size())) {
    if (mo < 1 || mo > 12 || d < 1 || d > 31) return false;
    days = DaysFromCivil(y, mo, d);
  } else if (std::sscanf(text.c_str(), "%4d-%3dT%2d:%2d:%lf%n", &y, &doy, &h, &mi, &sec, &n) == 5 &&
             n == static_cast<int>(text.size())) {
    if (doy < 1 || doy > 366) return false;
    days = DaysFromCivil(y, 1, 1) + doy - 1;
  } else {
    return false;
  }
  if (y < 1970 || y > 2200 || h > 23 || mi > 59 || !(sec >= 0 && sec < 61)) return false;
  *utime = ((days * 24 + h) * 60 + mi) * 60 * 1000000LL + std::llround(sec * 1e6);
  return true;
}

NavcamPdsFolder ReadNavcamPdsFolder(const std::string& folder, const NavcamPdsOptions& options) {
  return FolderReader(folder, options).Read();
}

}  // namespace vloc
