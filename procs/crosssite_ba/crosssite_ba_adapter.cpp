#include "crosssite_ba_adapter.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include "vloc/common/options.h"
#include "vloc/common/site_window.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_ba.h"
#include "vloc/lcm_io/convert_rover.h"

namespace vloc {

void CrossSiteBaProcOptions::Visit(OptionsReader& r) {
  r.Optional("navcam_config", &navcam_config, "Navcam calibration YAML", NonEmpty());
  r.Optional("tie_points_channel", &tie_points_channel, "tie_points_t in", NonEmpty());
  r.Optional("dr_channel", &dr_channel, "site_pose_t in (dead reckoning)", NonEmpty());
  r.Optional("visual_channel", &visual_channel, "localization_t out", NonEmpty());
  r.Optional("chain_previous", &chain_previous, "hold the previous site at our own estimate");
  r.Optional("queue_capacity", &queue_capacity, "messages per subscription queue", AtLeast(1));
  r.Optional("state_path", &state_path, "site estimates kept across restarts (relative: in --state-dir)");
  r.Optional("site_window", &site_window, "sites whose DR pose and estimate are kept (newest ids)", AtLeast(2));
  r.Child("ba", [&](OptionsReader& c) { ba.Visit(c); });
}

bool CrossSiteBaProcOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

CrossSiteBaAdapter::CrossSiteBaAdapter(Transport& transport, const CrossSiteBaProcOptions& options,
                                       const NavcamModel& navcam)
    : transport_(transport), options_(options), navcam_(navcam) {
  dr_stats_ = Subscribe<site_pose_t>(
      transport_, options_.dr_channel,
      [this](const std::string&, const site_pose_t& msg) {
        if (msg.site_id < 0) throw std::invalid_argument("negative site id " + std::to_string(msg.site_id));
        const PoseWithCovariance pose = PoseFromMessage(msg.pose);
        const bool new_traverse = msg.site_id == 0 && (estimates_.size() > 1 || dr_poses_.size() > 1);
        if (new_traverse) {
          LOG(WARNING) << "dead reckoning of site 0 while holding " << dr_poses_.size()
                       << " sites: a new traverse; earlier estimates dropped";
          estimates_.clear();
          dr_poses_.clear();
        }
        dr_poses_[msg.site_id] = pose;
        KeepWindow();
        if (new_traverse) RewriteState();
        else SaveSite(dr_poses_, msg.site_id);
      },
      options_.queue_capacity);
  tie_stats_ = Subscribe<tie_points_t>(
      transport_, options_.tie_points_channel,
      [this](const std::string&, const tie_points_t& msg) {
        TiePointSet set;
        try {
          set = TiePointsFromMessage(msg);
        } catch (const std::exception& e) {
          // Still answer for the site, so the traverse keeps its dead-reckoning pose.
          const CrossSiteBaSummary s = BadMessage(msg, e.what());
          LOG(ERROR) << s.BriefReport() << "; fix the front end's output";
          Publish(transport_, options_.visual_channel, LocalizationToMessage(s, msg.utime));
          return;
        }
        const CrossSiteBaSummary s = Process(std::move(set));
        Publish(transport_, options_.visual_channel, LocalizationToMessage(s, msg.utime));
      },
      options_.queue_capacity);
}

CrossSiteBaSummary CrossSiteBaAdapter::Process(TiePointSet set) {
  const int prev = set.previous_site_id, cur = set.current_site_id;
  // Dead-reckoning motion from the previous to the current site.
  Pose3 previous_from_current_dr = set.previous_site_pose.pose.inverse() * set.current_site_pose_dr.pose;
  std::string motion_source = "tie-point message";
  // A revisit (non-adjacent pair): the front end predicted it from the pose
  // graph's optimised poses, far closer than the DR drift accumulated between
  // the two sites; keep the message's motion.
  const bool revisit = cur - prev > 1;
  if (revisit) motion_source = "tie-point message (revisit of site " + std::to_string(prev) + ")";
  if (!revisit && dr_poses_.count(prev) && dr_poses_.count(cur)) {
    previous_from_current_dr = dr_poses_[prev].pose.inverse() * dr_poses_[cur].pose;
    motion_source = "SITE_POSE_DR";
  }
  std::string previous_source = "tie-point message";
  if (options_.chain_previous && estimates_.count(prev)) {
    set.previous_site_pose = estimates_[prev];
    previous_source = "own estimate";
  }
  if (dr_poses_.count(cur)) set.current_site_pose_dr.covariance = dr_poses_[cur].covariance;
  set.current_site_pose_dr.pose = set.previous_site_pose.pose * previous_from_current_dr;
  CrossSiteBaSummary s = SolveCrossSiteBa(set, navcam_, options_.ba);
  // The chain continues from the adjacent pair's result; a revisit only sets
  // the estimate when the site has none yet.
  if (!revisit || !estimates_.count(cur)) {
    estimates_[cur] = s.world_from_current;
    KeepWindow();
    SaveSite(estimates_, cur);
  }
  (s.usable ? solved_ : failed_)++;
  if (s.usable) {
    LOG(INFO) << s.BriefReport() << " [previous site from " << previous_source << ", motion from " << motion_source
              << "]";
  } else {
    LOG(WARNING) << s.BriefReport() << " [dead reckoning stands; previous site from " << previous_source
                 << ", motion from " << motion_source << "]";
  }
  return s;
}

CrossSiteBaSummary CrossSiteBaAdapter::BadMessage(const tie_points_t& msg, const std::string& why) {
  CrossSiteBaSummary s;
  s.status = CrossSiteBaStatus::kBadInput;
  s.usable = false;
  s.previous_site_id = msg.previous_site_id;
  s.current_site_id = msg.current_site_id;
  s.num_tie_points_in = msg.num_points;
  s.message = "tie-point message unusable: " + why;
  if (dr_poses_.count(msg.current_site_id)) {
    s.world_from_current = dr_poses_[msg.current_site_id];
  } else {
    try {
      s.world_from_current = PoseFromMessage(msg.current_site_pose_dr.pose);
    } catch (const std::exception&) {
      s.message += "; no dead-reckoning pose either (identity sent)";
    }
  }
  s.previous_from_current.pose = s.world_from_current.pose;
  s.previous_from_current.covariance = s.world_from_current.covariance;
  ++failed_;
  return s;
}

std::string CrossSiteBaAdapter::StatusLine() const {
  std::ostringstream o;
  o << "site pairs solved " << solved_ << ", failed " << failed_ << "; poses kept for " << dr_poses_.size()
    << " DR / " << estimates_.size() << " estimated sites; " << SubscriptionSummary({tie_stats_, dr_stats_});
  return o.str();
}

// State file: one line per pose, "estimate|dr <site id> " + WritePoseText;
// a later line for a site replaces an earlier one.
bool CrossSiteBaAdapter::Restore(const std::string& path, std::string* error) {
  state_path_ = path;
  if (path.empty() || !std::filesystem::exists(path)) return true;
  std::ifstream f(path);
  std::map<int, PoseWithCovariance> estimates, dr;
  std::string line;
  int number = 0;
  while (std::getline(f, line)) {
    ++number;
    if (f.eof() && !line.empty()) {  // no newline: the append a crash cut short
      LOG(WARNING) << "state file " << path << " line " << number << " is cut short (a crash while saving?); dropped";
      break;
    }
    std::istringstream ls(line);
    std::string kind;
    int site = -1;
    PoseWithCovariance pose;
    if (!(ls >> kind >> site) || site < 0 || (kind != "estimate" && kind != "dr") || !ReadPoseText(ls, &pose)) {
      *error = "state file " + path + " line " + std::to_string(number) +
               " is not '<estimate|dr> <site> <pose>' (move or delete the file to start afresh)";
      return false;
    }
    auto& by_site = kind == "estimate" ? estimates : dr;
    by_site[site] = pose;
    KeepNewestSites(&by_site, static_cast<size_t>(options_.site_window));
  }
  estimates_ = std::move(estimates);
  dr_poses_ = std::move(dr);
  LOG(INFO) << "reloaded " << path << ": estimates of " << estimates_.size() << " sites, dead reckoning of "
            << dr_poses_.size() << " (from " << number << " lines)";
  RewriteState();
  return true;
}

void CrossSiteBaAdapter::KeepWindow() {
  const size_t dropped = KeepNewestSites(&dr_poses_, static_cast<size_t>(options_.site_window)) +
                         KeepNewestSites(&estimates_, static_cast<size_t>(options_.site_window));
  if (dropped > 0 && window_log_.ShouldLog())
    LOG(INFO) << "kept the newest " << options_.site_window << " sites (site_window): " << dropped
              << " older poses dropped" << window_log_.Suppressed();
}

void CrossSiteBaAdapter::SaveSite(const std::map<int, PoseWithCovariance>& map, int site) {
  const auto it = map.find(site);
  if (state_path_.empty() || it == map.end()) return;  // not kept, or older than the window
  if (state_lines_ + 1 > 2 * (estimates_.size() + dr_poses_.size()) + 16) return RewriteState();
  std::ofstream f(state_path_, std::ios::app);
  f << (&map == &estimates_ ? "estimate " : "dr ") << site << ' ';
  WritePoseText(f, it->second);
  f << '\n';
  f.flush();
  if (!f) LOG(ERROR) << "crosssite_ba state not saved: cannot append to " << state_path_;
  ++state_lines_;
}

void CrossSiteBaAdapter::RewriteState() {
  if (state_path_.empty()) return;
  std::ostringstream o;
  for (const auto* map : {&estimates_, &dr_poses_})
    for (const auto& [site, pose] : *map) {
      o << (map == &estimates_ ? "estimate " : "dr ") << site << ' ';
      WritePoseText(o, pose);
      o << '\n';
    }
  std::string error;
  if (!WriteFileAtomically(state_path_, o.str(), &error)) LOG(ERROR) << "crosssite_ba state not saved: " << error;
  state_lines_ = estimates_.size() + dr_poses_.size();
}

}  // namespace vloc
