#include "map_localizer_adapter.h"

#include <glog/logging.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "vloc/common/site_window.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"

namespace vloc {

namespace {

bool IsXy(const std::vector<double>& xy) { return xy.size() == 2; }

bool IsLatLonOrEmpty(const std::vector<double>& o) {
  return o.empty() || (o.size() == 2 && std::abs(o[0]) <= 90 && std::abs(o[1]) <= 180);
}

}  // namespace

void MapLocalizerProcOptions::Visit(OptionsReader& r) {
  r.Optional("navcam_config", &navcam_config, "Navcam calibration file");
  r.Optional("map_path", &map_path, "GeoTIFF or PNG + world file of the aerial map", NonEmpty());
  r.Optional("map_offset_xy", &map_offset_xy, "m, subtracted from the map coordinates",
             Rule<std::vector<double>>(IsXy, "two numbers [x, y]"));
  r.Optional("map_geographic_origin", &map_geographic_origin,
             "[lat, lon] deg: the map is in WGS84 degrees and this is the world origin ([] = metres)",
             Rule<std::vector<double>>(IsLatLonOrEmpty, "[] or [latitude, longitude] in degrees"));
  r.Optional("map_m_per_px", &map_m_per_px, "m, resample the map to this cell size (0 = the file's)",
             NonNegative() && Finite());
  r.Optional("reload_map_on_change", &reload_map_on_change,
             "re-read the map file when it changes; the newest sites without a fix are tried again on it");
  r.Optional("wait_for_map_s", &wait_for_map_s, "s, sites wait this long for a map file not there yet",
             NonNegative());
  r.Optional("stereo_channel", &stereo_channel, "stereo_image_t in", NonEmpty());
  r.Optional("traverse_channel", &traverse_channel, "traverse_t in", NonEmpty());
  r.Optional("dr_channel", &dr_channel, "site_pose_t in (prior before the graph has the site)");
  r.Optional("fix_channel", &fix_channel, "site_pose_t out", NonEmpty());
  r.Optional("fix_every", &fix_every, "attempt a fix at every n-th site", AtLeast(1));
  r.Optional("queue_capacity", &queue_capacity, "messages per subscription queue", AtLeast(1));
  r.Optional("max_pairs_per_site", &max_pairs_per_site, "a site's num_pairs above this is refused",
             InRange(1, kMaxPairsPerSite));
  r.Optional("max_sites_waiting", &max_sites_waiting, "sites collecting pairs or waiting for a prior at once",
             AtLeast(1));
  r.Optional("site_window", &site_window, "newest sites whose graph / DR poses are remembered");
  r.Child("ortho", [this](OptionsReader& c) { ortho.Visit(c); });
  r.Child("registration", [this](OptionsReader& c) { registration.Visit(c); });
  r.Relation("site_window", site_window >= max_sites_waiting, "must be >= max_sites_waiting");
}

bool MapLocalizerProcOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

maploc::MapGeoreference MapLocalizerProcOptions::Georeference() const {
  maploc::MapGeoreference g;
  g.offset_xy = Eigen::Vector2d(map_offset_xy[0], map_offset_xy[1]);
  g.geographic = map_geographic_origin.size() == 2;
  if (g.geographic) {
    g.origin_latitude = map_geographic_origin[0];
    g.origin_longitude = map_geographic_origin[1];
  }
  g.m_per_px = map_m_per_px;
  return g;
}

namespace {

int64_t FileTime(const std::string& path) {
  std::error_code ec;
  const auto t = std::filesystem::last_write_time(path, ec);
  return ec ? 0 : static_cast<int64_t>(t.time_since_epoch().count());
}

}  // namespace

MapLocalizerAdapter::MapLocalizerAdapter(Transport& transport, const MapLocalizerProcOptions& options,
                                         const NavcamModel& navcam, maploc::MapRaster map)
    : transport_(transport), options_(options), navcam_(navcam) {
  if (!map.gray.empty()) {
    map_mtime_ = FileTime(options_.map_path);
    UseMap(std::move(map));
  }
  stereo_stats_ = Subscribe<stereo_image_t>(
      transport_, options_.stereo_channel, [this](const std::string&, const stereo_image_t& m) { OnStereo(m); },
      options_.queue_capacity);
  traverse_stats_ = Subscribe<traverse_t>(
      transport_, options_.traverse_channel, [this](const std::string&, const traverse_t& m) { OnTraverse(m); },
      options_.queue_capacity);
  if (!options_.dr_channel.empty())
    dr_stats_ = Subscribe<site_pose_t>(
        transport_, options_.dr_channel, [this](const std::string&, const site_pose_t& m) { OnDeadReckoning(m); },
        options_.queue_capacity);
}

void MapLocalizerAdapter::OnStereo(const stereo_image_t& msg) {
  const bool plausible = msg.site_id >= 0 && msg.num_pairs >= 1 && msg.num_pairs <= options_.max_pairs_per_site &&
                         msg.pair_index >= 0 && msg.pair_index < msg.num_pairs &&
                         (newest_site_ < 0 || msg.site_id <= newest_site_ + kMaxSiteIdJump);
  if (!plausible) {
    ++skipped_pairs_;
    LOG(WARNING) << "stereo pair with implausible site " << msg.site_id << " / pair " << msg.pair_index << " of "
                 << msg.num_pairs << " (pair_index below num_pairs, num_pairs at most max_pairs_per_site "
                 << options_.max_pairs_per_site << "): skipped";
    return;
  }
  if (msg.site_id % options_.fix_every != 0) return;  // no fix attempted at this site
  if (localised_.count(msg.site_id)) {
    ++pairs_after_done_;
    if (after_done_log_.ShouldLog())
      LOG(WARNING) << "site " << msg.site_id << " pair " << msg.pair_index
                   << " arrived after the site was localised (a repeat?): ignored" << after_done_log_.Suppressed();
    return;
  }
  const auto known = waiting_.find(msg.site_id);
  if (known != waiting_.end() && known->second.num_pairs != msg.num_pairs) {
    ++skipped_pairs_;
    LOG(WARNING) << "site " << msg.site_id << " pair " << msg.pair_index << " says " << msg.num_pairs
                 << " pairs, the site's earlier pairs " << known->second.num_pairs << ": skipped";
    return;
  }
  StereoPair pair = StereoPairFromMessage(msg);  // throws on undecodable images: counted by Subscribe
  newest_site_ = std::max(newest_site_, static_cast<int>(msg.site_id));
  WaitingSite& site = waiting_[msg.site_id];
  site.num_pairs = msg.num_pairs;
  const bool repeat = site.pairs.count(msg.pair_index) > 0;
  site.pairs[msg.pair_index] = std::move(pair);
  if (repeat) {
    ++pairs_replaced_;
    if (repeat_log_.ShouldLog())
      LOG(WARNING) << "site " << msg.site_id << " pair " << msg.pair_index
                   << " received again: replaces the earlier copy" << repeat_log_.Suppressed();
  }
  // Sites left waiting (a lost message or prior) are dropped once max_sites_waiting newer ones arrive.
  const int64_t oldest_kept =
      static_cast<int64_t>(newest_site_) - static_cast<int64_t>(options_.max_sites_waiting - 1) * options_.fix_every;
  while (!waiting_.empty() &&
         (waiting_.begin()->first < oldest_kept || static_cast<int>(waiting_.size()) > options_.max_sites_waiting))
    DropSite(waiting_.begin(), "newer sites arrived (max_sites_waiting " +
                                   std::to_string(options_.max_sites_waiting) + ")");
  ProcessReadySites();
}

void MapLocalizerAdapter::DropSite(std::map<int, WaitingSite>::iterator it, const std::string& why) {
  const bool complete = static_cast<int>(it->second.pairs.size()) >= it->second.num_pairs;
  LOG(WARNING) << "site " << it->first << ": "
               << (complete ? "no prior pose" : "panorama incomplete (" + std::to_string(it->second.pairs.size()) +
                                                    " of " + std::to_string(it->second.num_pairs) + " pairs)")
               << " when " << why << "; no fix attempted";
  ++sites_dropped_;
  waiting_.erase(it);
}

bool MapLocalizerAdapter::KeepPose(int site_id, const PoseWithCovariance& pose,
                                   std::map<int, PoseWithCovariance>* poses) {
  ++pose_sites_seen_;
  std::string why;
  if (site_id < 0 || !IsPlausiblePose(pose, &why)) return false;
  if (site_id % options_.fix_every != 0) return true;  // never localised here
  (*poses)[site_id] = pose;
  KeepNewestSites(poses, static_cast<size_t>(options_.site_window));
  return true;
}

void MapLocalizerAdapter::OnTraverse(const traverse_t& msg) {
  const size_t n = std::min(msg.site_ids.size(), msg.poses.size());
  for (size_t k = 0; k < n; ++k) KeepPose(msg.site_ids[k], PoseFromMessage(msg.poses[k]), &graph_poses_);
  ProcessReadySites();
}

void MapLocalizerAdapter::OnDeadReckoning(const site_pose_t& msg) {
  PoseWithCovariance pose = PoseFromMessage(msg.pose);
  pose.utime = msg.utime;
  std::string why;
  if (!IsPlausiblePose(pose, &why) || msg.site_id < 0) {
    LOG(WARNING) << "dead reckoning of site " << msg.site_id << " not plausible ("
                 << (why.empty() ? "negative site id" : why) << "): ignored";
    return;
  }
  KeepPose(msg.site_id, pose, &dr_poses_);
  ProcessReadySites();
}

void MapLocalizerAdapter::ProcessReadySites() {
  if (!HasMap()) return;  // the sites wait for it
  for (auto it = waiting_.begin(); it != waiting_.end();) {
    const int site = it->first;
    const bool complete = static_cast<int>(it->second.pairs.size()) >= it->second.num_pairs;
    const auto graph = graph_poses_.find(site);
    const auto dr = dr_poses_.find(site);
    if (!complete || (graph == graph_poses_.end() && dr == dr_poses_.end())) {
      ++it;
      continue;
    }
    PoseWithCovariance prior = graph != graph_poses_.end() ? graph->second : dr->second;
    if (dr != dr_poses_.end()) prior.utime = dr->second.utime;
    std::vector<StereoPair> pairs;
    for (auto& [index, pair] : it->second.pairs) pairs.push_back(std::move(pair));
    it = waiting_.erase(it);
    localised_.insert(site);
    KeepNewestSites(&localised_, static_cast<size_t>(options_.site_window));
    LocaliseSite(site, std::move(pairs), prior);
  }
}

void MapLocalizerAdapter::LocaliseSite(int site_id, std::vector<StereoPair> pairs, const PoseWithCovariance& prior) {
  const Eigen::Vector3d rpy = RollPitchYawFromRotation(prior.pose.linear());
  maploc::GroundOrthoSummary ortho_summary;
  const maploc::MapRaster ortho =
      maploc::BuildGroundOrtho(pairs, navcam_, rpy.x(), rpy.y(), options_.ortho, &ortho_summary);
  if (!ortho_summary.usable) {
    ++no_fixes_;
    last_result_ = "site " + std::to_string(site_id) + ": no fix: ground orthophoto: " + ortho_summary.message;
    LOG(WARNING) << last_result_;
    return;
  }
  if (RegisterSite(site_id, ortho, ortho_summary, prior)) return;
  ++no_fixes_;
  if (!options_.reload_map_on_change) return;
  // A map still growing (a UAV mosaic) may cover it later: tried again on each new map.
  to_retry_[site_id] = {ortho, ortho_summary, prior};
  while (static_cast<int>(to_retry_.size()) > options_.max_sites_waiting) to_retry_.erase(to_retry_.begin());
}

bool MapLocalizerAdapter::RegisterSite(int site_id, const maploc::MapRaster& ortho,
                                       const maploc::GroundOrthoSummary& ortho_summary,
                                       const PoseWithCovariance& prior) {
  const maploc::MapFix fix =
      maploc::RegisterToMap(ortho, map_, maploc::SitePriorFromPose(prior), options_.registration);
  last_result_ = "site " + std::to_string(site_id) + ": " + fix.BriefReport();
  if (!fix.usable) {
    LOG(WARNING) << "site " << site_id << ": no fix: " << fix.message << " (" << ortho_summary.BriefReport() << ")";
    return false;
  }
  ++fixes_;
  LOG(INFO) << last_result_ << "; ortho " << ortho_summary.BriefReport();
  const PoseWithCovariance pose = maploc::FixToPose(fix, prior, options_.registration);
  Publish(transport_, options_.fix_channel, SitePoseToMessage(site_id, kSourceMapFix, pose));
  return true;
}

void MapLocalizerAdapter::RetrySites() {
  for (auto it = to_retry_.begin(); it != to_retry_.end();) {
    LOG(INFO) << "site " << it->first << ": tried again on the new map";
    if (!RegisterSite(it->first, it->second.ortho, it->second.ortho_summary, it->second.prior)) {
      ++it;
      continue;
    }
    --no_fixes_;  // counted without a fix when it first failed
    it = to_retry_.erase(it);
  }
}

void MapLocalizerAdapter::OnIdle() {
  if (!HasMap()) {
    if (ReadMap()) ProcessReadySites();  // the sites that waited for it
    return;
  }
  if (options_.reload_map_on_change && ReadMap()) RetrySites();
}

bool MapLocalizerAdapter::LoadMap(std::string* error) {
  map_mtime_ = FileTime(options_.map_path);  // a file that cannot be read is not tried again until it changes
  maploc::MapRaster map;
  if (!maploc::LoadMapRaster(options_.map_path, &map, error, options_.Georeference())) return false;
  UseMap(std::move(map));
  return true;
}

void MapLocalizerAdapter::UseMap(maploc::MapRaster map) {
  map_ = std::move(map);
  options_.ortho.m_per_px = map_.m_per_px;  // the ground orthophoto on the map's grid
}

bool MapLocalizerAdapter::ReadMap() {
  const int64_t t = FileTime(options_.map_path);
  if (t == 0 || t == map_mtime_) return false;
  const bool first = !HasMap();
  std::string error;
  if (!LoadMap(&error)) {
    LOG(ERROR) << (first ? "map appeared but cannot be read: "
                         : "map changed but not reloaded, keeping the previous one: ")
               << error;
    return false;
  }
  LOG(INFO) << (first ? "map read: " : "map reloaded: ") << MapDescription()
            << (first ? "; " + std::to_string(waiting_.size()) + " sites waited for it" : std::string());
  return true;
}

std::string MapLocalizerAdapter::MapDescription() const {
  std::ostringstream out;
  out << map_.gray.cols << " x " << map_.gray.rows << " at " << map_.m_per_px << " m/px"
      << (map_.has_height() ? " with heights" : "") << ", x from " << map_.x_min << ", y up to " << map_.y_max;
  return out.str();
}

std::string MapLocalizerAdapter::StatusLine() const {
  return std::to_string(fixes_) + " fixes, " + std::to_string(no_fixes_) + " sites without a fix, " +
         std::to_string(skipped_pairs_) + " implausible pairs skipped, " + std::to_string(pairs_replaced_) +
         " repeated pairs replaced, " + std::to_string(pairs_after_done_) + " pairs of localised sites ignored, " +
         std::to_string(sites_dropped_) + " waiting sites dropped; poses kept for " +
         std::to_string(graph_poses_.size()) + " graph / " + std::to_string(dr_poses_.size()) + " DR sites of " +
         std::to_string(pose_sites_seen_) + " received; last: " + last_result_ + "; " +
         SubscriptionSummary({stereo_stats_, traverse_stats_, dr_stats_});
}

}  // namespace vloc
